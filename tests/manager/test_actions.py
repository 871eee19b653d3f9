from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.manager.actions import action_dim, decode_subgoal, encode_subgoal

HALF_LENGTH, HALF_WIDTH = 3.0, 2.0


def test_action_dims() -> None:
    assert action_dim("pose4") == 4
    assert action_dim("pose6") == 6
    with pytest.raises(ValueError, match="pose5"):
        action_dim("pose5")


def test_decode_pose4_by_hand() -> None:
    subgoal = decode_subgoal(np.array([[0.5, -0.5, 1.0, 0.0]]), "pose4", HALF_LENGTH, HALF_WIDTH)
    # x = 0.5 * 3, y = -0.5 * 2, theta = atan2(1, 0), velocity fixed to 0
    np.testing.assert_allclose(subgoal, [[1.5, -1.0, math.pi / 2, 0.0, 0.0]])


def test_decode_pose6_by_hand_and_zero_velocity() -> None:
    action = np.array([[0.5, -0.5, 0.4, -1.0, 0.0, -1.0]])
    subgoal = decode_subgoal(action, "pose6", HALF_LENGTH, HALF_WIDTH, max_v=2.5)
    # vx = 0.4 * 2.5, vy = -1 * 2.5, theta = atan2(0, -1) = pi
    np.testing.assert_allclose(subgoal, [[1.5, -1.0, math.pi, 1.0, -2.5]])
    held = decode_subgoal(action, "pose6", HALF_LENGTH, HALF_WIDTH, zero_velocity=True)
    np.testing.assert_allclose(held, [[1.5, -1.0, math.pi, 0.0, 0.0]])


def test_decode_clips_out_of_range_positions() -> None:
    subgoal = decode_subgoal(np.array([[2.0, -3.0, 0.0, 1.0]]), "pose4", HALF_LENGTH, HALF_WIDTH)
    np.testing.assert_allclose(subgoal[0, :2], [HALF_LENGTH, -HALF_WIDTH])


@pytest.mark.parametrize("form", ["pose4", "pose6"])
def test_encode_inverts_decode_for_unit_sincos(form: str) -> None:
    rng = np.random.default_rng(1)
    n = 64
    angle = rng.uniform(-math.pi, math.pi, n)
    linear = rng.uniform(-1, 1, (n, action_dim(form) - 2))
    action = np.column_stack([linear, np.sin(angle), np.cos(angle)])
    subgoal = decode_subgoal(action, form, HALF_LENGTH, HALF_WIDTH)
    np.testing.assert_allclose(encode_subgoal(subgoal, form, HALF_LENGTH, HALF_WIDTH), action, atol=1e-12)


def test_decode_inverts_encode_for_on_field_subgoals() -> None:
    subgoal = np.array([[-2.9, 1.9, 3.0, 2.4, -0.3], [0.0, 0.0, -math.pi / 3, 0.0, 0.0]])
    action = encode_subgoal(subgoal, "pose6", HALF_LENGTH, HALF_WIDTH)
    np.testing.assert_allclose(decode_subgoal(action, "pose6", HALF_LENGTH, HALF_WIDTH), subgoal, atol=1e-12)


def test_bad_input_raises() -> None:
    with pytest.raises(ValueError, match="pose8"):
        encode_subgoal(np.zeros((2, 5)), "pose8", HALF_LENGTH, HALF_WIDTH)
    with pytest.raises(ValueError, match="half_width"):
        decode_subgoal(np.zeros((2, 4)), "pose4", HALF_LENGTH, 0.0)


def test_target_frame_zero_action_is_the_target_pose() -> None:
    target = np.array([[1.0, -0.5, 2.0, 0.0, 0.0], [-2.9, 1.9, -3.0, 0.0, 0.0]])
    zero = decode_subgoal(np.zeros((2, 4)), "pose4", HALF_LENGTH, HALF_WIDTH, frame="target", target=target)
    np.testing.assert_allclose(zero, target, atol=1e-12)
    # Offsets are cubed: 0.5 of the way is an eighth of the half length; sub-goals stay on the field.
    action = np.array([[0.5, 0.0, 0.0, 1.0], [-1.0, 1.0, 0.0, 1.0]])
    far = decode_subgoal(action, "pose4", 3.0, 2.0, frame="target", target=target)
    assert far[0, 0] == pytest.approx(1.0 + 3.0 / 8) and far[1, 0:2].tolist() == [-3.0, 2.0]
    # The turn is atan2(sin, 1 + cos): sin = 1, cos = 0 turns 45 deg from the target heading.
    turned = decode_subgoal(
        np.array([[0.0, 0.0, 1.0, 0.0]]), "pose4", 3.0, 2.0, frame="target", target=target[:1]
    )
    assert turned[0, 2] == pytest.approx(2.0 + math.pi / 4)
    with pytest.raises(ValueError, match="target"):
        decode_subgoal(action, "pose4", 3.0, 2.0, frame="target")


@pytest.mark.parametrize("form", ["pose4", "pose6"])
@pytest.mark.parametrize("frame", ["field", "target"])
def test_encode_inverts_decode_in_either_frame(form: str, frame: str) -> None:
    rng = np.random.default_rng(3)
    n, dim = 200, action_dim(form)
    target = np.column_stack([rng.uniform(-1, 1, (n, 2)), rng.uniform(-3, 3, n), np.zeros((n, 2))])
    action = rng.uniform(-0.6, 0.6, (n, dim))  # in reach of the frame from every target
    turn = rng.uniform(-1.2, 1.2, n)  # unit (sin, cos) pairs, within +-90 deg in the target frame
    action[:, -2], action[:, -1] = np.sin(turn), np.cos(turn)
    where = {"frame": frame, "target": target}
    subgoal = decode_subgoal(action, form, HALF_LENGTH, HALF_WIDTH, **where)
    again = decode_subgoal(
        encode_subgoal(subgoal, form, HALF_LENGTH, HALF_WIDTH, **where), form, 3.0, 2.0, **where
    )
    np.testing.assert_allclose(again[:, 0:2], subgoal[:, 0:2], atol=1e-9)
    np.testing.assert_allclose(np.cos(again[:, 2] - subgoal[:, 2]), 1.0, atol=1e-9)
    with pytest.raises(ValueError, match="robot"):
        decode_subgoal(action, form, HALF_LENGTH, HALF_WIDTH, frame="robot", target=target)
