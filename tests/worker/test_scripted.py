from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.worker import make_worker
from hier_ssl.worker.scripted import BangBangGoToPoint, PaperGoToPoint
from hier_ssl.world.frames import to_field_frame
from hier_ssl.world.physics import RobotSpec, RobotState, World

SPEC = RobotSpec()
D_TH, THETA_TH, V_TH = 0.05, math.radians(5), 0.05  # the paper's thresholds (docs/paper.md)


def _reach(worker_name: str, distance: float, direction: float, turn: float) -> tuple[int, float, float]:
    """Drive one robot from rest at the origin (heading 0) to a sub-goal ``distance`` m away along
    ``direction`` with heading ``turn``. Returns the first step within all thresholds, the largest overshoot
    past the sub-goal along the line, and the largest distance from it over the second after arrival."""
    world = World(1, 1)
    worker = make_worker(worker_name, world.robot, world.dt)
    line = np.array([math.cos(direction), math.sin(direction)])
    goal = distance * line
    subgoal = np.array([[[goal[0], goal[1], turn, 0.0, 0.0]]])
    arrived, overshoot, settled = None, -np.inf, 0.0
    for step in range(1, 241):
        state = world.step(worker(world.state, subgoal))
        offset = state.pos[0, 0] - goal
        overshoot = max(overshoot, float(offset @ line))
        within = (
            np.hypot(*offset) < D_TH
            and abs((state.angle[0, 0] - turn + np.pi) % (2 * np.pi) - np.pi) < THETA_TH
            and np.hypot(*state.vel[0, 0]) < V_TH
        )
        if arrived is None and within:
            arrived = step
        if arrived is not None and step <= arrived + 40:
            settled = max(settled, float(np.hypot(*offset)))
    assert arrived is not None, f"{worker_name} never reached the sub-goal"
    return arrived, overshoot, settled


@pytest.mark.parametrize("worker_name", ["paper", "bangbang"])
@pytest.mark.parametrize(("direction", "turn"), [(0.0, 0.0), (math.radians(135), math.radians(-100))])
def test_worker_reaches_a_subgoal_2m_away_without_overshoot(
    worker_name: str, direction: float, turn: float
) -> None:
    distance = 2.0
    steps, overshoot, settled = _reach(worker_name, distance, direction, turn)
    # Fastest rest-to-rest move under the world's limits: a triangular speed profile (its peak,
    # sqrt(d a) = 2.45 m/s, stays under max_speed 2.5), 2 sqrt(d / a) = 1.633 s for 2 m at 3 m/s^2.
    minimum = 2 * math.sqrt(distance / SPEC.max_accel)
    seconds = steps * 0.025
    print(
        f"\n{worker_name:8s} 2 m at {math.degrees(direction):4.0f} deg, turn {math.degrees(turn):5.0f} deg: "
        f"{seconds:.3f} s ({steps} steps), analytic minimum {minimum:.3f} s, ratio {seconds / minimum:.2f}, "
        f"overshoot {max(overshoot, 0.0) * 100:.1f} cm"
    )
    assert seconds >= minimum - 0.025  # nothing beats the limits
    assert seconds <= 1.5 * minimum if worker_name == "bangbang" else seconds <= 2.5 * minimum
    assert overshoot <= 0.1
    assert settled < D_TH  # and it stays there


def test_bang_bang_is_within_a_few_steps_of_the_analytic_minimum() -> None:
    steps, _, _ = _reach("bangbang", 2.0, 0.0, 0.0)
    assert steps * 0.025 <= 2 * math.sqrt(2.0 / SPEC.max_accel) + 0.1


def _state(pos: list, angle: list, vel: list | None = None, ang_vel: list | None = None) -> RobotState:
    pos, angle = np.array(pos, dtype=float), np.array(angle, dtype=float)
    vel = np.zeros_like(pos) if vel is None else np.array(vel, dtype=float)
    ang_vel = np.zeros_like(angle) if ang_vel is None else np.array(ang_vel, dtype=float)
    return RobotState(pos, angle, vel, ang_vel)


def test_paper_worker_follows_the_spec_rule_by_hand() -> None:
    worker = PaperGoToPoint()
    # At rest, 1 m to the left (+y) of a robot facing +x: +0.1 m/s towards the sub-goal, which is the
    # robot's +y; spin 2 * dtheta with dtheta = 30 deg, outside the 2.5 deg dead band.
    command = worker(_state([[[0.0, 0.0]]], [[0.0]]), np.array([[[0.0, 1.0, math.radians(30), 0.0, 0.0]]]))
    np.testing.assert_allclose(command, [[[0.0, 0.1, 2 * math.radians(30)]]], atol=1e-12)
    # Moving at 1.5 m/s towards a sub-goal 1 m away: braking distance 1.5^2 / 2 = 1.125 m > 1 m, so slow
    # down by 0.1; heading error 2 deg is inside the dead band.
    subgoal = np.array([[[1.0, 0.0, math.radians(2), 0.0, 0.0]]])
    command = worker(_state([[[0.0, 0.0]]], [[0.0]], [[[1.5, 0.0]]]), subgoal)
    np.testing.assert_allclose(command, [[[1.4, 0.0, 0.0]]], atol=1e-12)
    # Moving away from the sub-goal at 0.05 m/s: brake towards 0 by at most 0.1, i.e. to 0.
    command = worker(_state([[[0.0, 0.0]]], [[0.0]], [[[-0.05, 0.0]]]), np.array([[[1.0, 0.0, 0.0, 0, 0]]]))
    np.testing.assert_allclose(command, [[[0.0, 0.0, 0.0]]], atol=1e-12)
    # The speed towards the sub-goal never exceeds distance / dt: 1 mm away at rest gives 0.04, not 0.1.
    command = worker(_state([[[0.0, 0.0]]], [[0.0]]), np.array([[[0.001, 0.0, 0.0, 0, 0]]]))
    np.testing.assert_allclose(command, [[[0.001 / 0.025, 0.0, 0.0]]], atol=1e-12)


def test_commands_are_in_the_robot_frame() -> None:
    rng = np.random.default_rng(0)
    n = 256
    state = _state(
        rng.uniform(-3, 3, (n, 2, 2)),
        rng.uniform(-np.pi, np.pi, (n, 2)),
        rng.uniform(-3, 3, (n, 2, 2)),
        rng.uniform(-12, 12, (n, 2)),
    )
    subgoal = np.concatenate([rng.uniform(-3, 3, (n, 2, 3)), rng.uniform(-1, 1, (n, 2, 2))], axis=-1)
    for worker in (PaperGoToPoint(), BangBangGoToPoint()):
        command = worker(state, subgoal)
        assert command.shape == (n, 2, 3) and np.isfinite(command).all()
        if isinstance(worker, PaperGoToPoint):  # the paper's controller caps |v| at 2.2 m/s itself
            assert np.linalg.norm(command[..., 0:2], axis=-1).max() <= 2.2 + 1e-9
        # The same robot turned by 90 deg gets the same field-frame velocity.
        turned = RobotState(state.pos, state.angle + np.pi / 2, state.vel, state.ang_vel)
        np.testing.assert_allclose(
            to_field_frame(worker(turned, subgoal)[..., 0:2], turned.angle),
            to_field_frame(command[..., 0:2], state.angle),
            atol=1e-9,
        )


def test_at_the_subgoal_the_worker_holds_still() -> None:
    for worker in (PaperGoToPoint(), BangBangGoToPoint()):
        command = worker(_state([[[0.5, -0.5]]], [[1.0]]), np.array([[[0.5, -0.5, 1.0, 0.0, 0.0]]]))
        np.testing.assert_allclose(command, 0.0, atol=1e-12)


def test_workers_are_stateless_and_read_only() -> None:
    worker = PaperGoToPoint()
    worker.reset(np.arange(3))
    with pytest.raises(AttributeError):
        worker.dv = 0.2  # type: ignore[misc]
    with pytest.raises(ValueError, match="unknown worker 'pid'"):
        make_worker("pid", SPEC, 0.025)


@pytest.mark.parametrize("name", ["paper", "bangbang"])
def test_the_first_command_heads_for_a_subgoal_in_every_quadrant(name: str) -> None:
    """From rest, each robot's first velocity points at its sub-goal, whichever quadrant it lies in (numpy
    before 2.0 took the sign of a complex number from its real part alone: half the field was wrong)."""
    world = World(1, 8)
    worker = make_worker(name, world.robot, world.dt)
    direction = np.linspace(-np.pi, np.pi, 8, endpoint=False) + 0.3
    line = np.stack([np.cos(direction), np.sin(direction)], axis=-1)
    subgoal = np.zeros((1, 8, 5))
    subgoal[0, :, 0:2] = world.state.pos[0] + 1.5 * line
    command = worker(world.state, subgoal)
    velocity = to_field_frame(command[0, :, 0:2], world.state.angle[0])
    speed = np.linalg.norm(velocity, axis=-1)
    assert (speed > 0).all()
    np.testing.assert_allclose(velocity / speed[:, None], line, atol=1e-9)
