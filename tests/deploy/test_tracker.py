"""The tracker: recorded noisy tracks with known truth (the world driving a robot, overlapping cameras
with noise, drops, duplicates and latency), and the cases a field throws at it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.deploy.bench import tracking_error
from hier_ssl.deploy.tracker import (
    COMMANDS_KEPT,
    PREDICT_HORIZON,
    Track,
    Tracker,
    TrackerSettings,
    _Axis,
    follow,
)
from hier_ssl.deploy.wire import Detection, DetectionFrame
from hier_ssl.world.robot import RobotSpec

BLUE0 = ("blue", 0)


def _frame(t: float, *robots: Detection, camera: int = 0, latency: float = 0.0) -> DetectionFrame:
    return DetectionFrame(t, t + latency, camera, robots)


def test_on_a_recorded_noisy_track_the_filter_beats_the_raw_detections() -> None:
    # 20 s of the paper worker's driving, 2 mm / 0.5 deg noise, 10 % dropped, 20 ms capture-to-send.
    error = tracking_error(seconds=20.0)
    assert error["velocity_rmse_m_s"] < 0.2
    assert error["position_rmse_m"] < 0.01
    # Predicted to the acting time, the filter is several times closer than the newest detection.
    assert error["position_rmse_m"] < error["detection_rmse_m"] / 3


def test_a_constant_velocity_is_learned_and_predicted_over_the_latency() -> None:
    tracker, rng = Tracker(), np.random.default_rng(0)
    for k in range(120):  # 2 s at 60 Hz, 1.5 m/s along x, 0.8 m/s along y, turning 1 rad/s
        t = k / 60
        seen = Detection("blue", 0, 1.5 * t + rng.normal(0, 0.002), 0.8 * t + rng.normal(0, 0.002), 0.1 + t)
        tracker.update(_frame(t, seen, latency=0.03), arrival=100.0 + t + 0.03)
    now = 100.0 + 119 / 60 + 0.03 + 0.005  # 5 ms after the last frame arrived
    x, y, angle, vx, vy, w = tracker.state([BLUE0], tracker.vision_time(now))[0]
    t = 119 / 60 + 0.035  # the frame's capture + its 30 ms to send + 5 ms here
    assert (x, y) == pytest.approx((1.5 * t, 0.8 * t), abs=0.015)  # 2 mm noise, 6 m/s^2 of agility
    assert (vx, vy, w) == pytest.approx((1.5, 0.8, 1.0), abs=0.15)
    assert angle == pytest.approx(0.1 + t, abs=0.02)


def test_duplicates_from_overlapping_cameras_and_late_frames_do_not_upset_it() -> None:
    tracker = Tracker()
    for k in range(60):
        t = k / 60
        seen = Detection("blue", 0, 1.0 * t, 0.0, 0.0)
        for camera in (0, 1):  # the robot in the overlap: two cameras, same capture time
            tracker.update(_frame(t, seen, camera=camera), arrival=t)
        if k % 10 == 9:  # a frame of an older capture time arrives late
            tracker.update(_frame(t - 0.05, Detection("blue", 0, t - 0.05, 0.0, 0.0)), arrival=t)
    x, _, _, vx, _, _ = tracker.state([BLUE0], 59 / 60)[0]
    assert x == pytest.approx(59 / 60, abs=0.01)
    assert vx == pytest.approx(1.0, abs=0.1)


def test_a_jump_past_the_gate_restarts_the_filter_where_the_robot_is_seen() -> None:
    tracker = Tracker(TrackerSettings(gate=0.5))
    for k in range(30):
        tracker.update(_frame(k / 60, Detection("blue", 0, k / 60, 0.0, 0.0)), arrival=k / 60)
    tracker.update(_frame(0.5, Detection("blue", 0, -2.0, 1.0, 0.0)), arrival=0.5)  # carried across
    x, y, _, vx, vy, _ = tracker.state([BLUE0], 0.5)[0]
    assert (x, y, vx, vy) == (-2.0, 1.0, 0.0, 0.0)


def test_headings_wrap_and_unseen_robots_are_neither_flown_on_nor_invented() -> None:
    tracker = Tracker()
    for k in range(30):  # turning through +-pi at 2 rad/s
        angle = (math.pi - 0.5 + 2 * k / 60 + math.pi) % (2 * math.pi) - math.pi
        tracker.update(_frame(k / 60, Detection("yellow", 3, 0.0, 0.0, angle)), arrival=k / 60)
    angle, w = tracker.state([("yellow", 3)], 29 / 60)[0, [2, 5]]
    assert w == pytest.approx(2.0, abs=0.1)
    assert -math.pi <= angle < math.pi
    assert angle == pytest.approx(math.pi - 0.5 + 2 * 29 / 60 - 2 * math.pi, abs=0.02)
    late = tracker.state([("yellow", 3)], 29 / 60 + 5.0)[0, 2]
    assert late == pytest.approx(angle + 2.0 * PREDICT_HORIZON, abs=0.05)  # stopped at the horizon
    assert np.isnan(tracker.state([("blue", 9)], 1.0)).all()
    assert tracker.fresh(("yellow", 3), 29 / 60 + 0.04, 0.05)
    assert not tracker.fresh(("yellow", 3), 29 / 60 + 0.06, 0.05)


def test_settings_are_checked() -> None:
    with pytest.raises(ValueError, match="pos_noise must be > 0"):
        TrackerSettings(pos_noise=0.0)


def test_told_its_commands_an_own_robots_velocity_error_is_a_fifth_of_the_untold_filters() -> None:
    # The same recorded track (speeding up, braking and turning to a new sub-goal every 2 s, 2 mm noise,
    # 20 ms latency), the tracker told the commands the robot was driven by, or not.
    told = tracking_error(seconds=20.0, commands=True)
    untold = tracking_error(seconds=20.0)
    assert told["velocity_rmse_m_s"] < 0.04 < untold["velocity_rmse_m_s"]
    assert told["position_rmse_m"] < 0.003 and told["position_rmse_m"] < untold["position_rmse_m"]


def _accelerating(told: bool) -> tuple[Tracker, float]:
    """A robot at rest commanded to 2 m/s forward (heading 0) from t = 0.01 s, between two frames; exact
    detections at 60 Hz until 0.3 s (3 m/s^2 from 0.01 s: 0.87 m/s). The tracker and the last frame's time."""
    tracker = Tracker()
    for k in range(19):
        t = k / 60
        x = 1.5 * max(t - 0.01, 0.0) ** 2
        tracker.update(_frame(t, Detection("blue", 0, x, 0.0, 0.0)), arrival=t)
        if told and k == 0:
            tracker.command(BLUE0, 0.005, (0.0, 0.0, 0.0))
            tracker.command(BLUE0, 0.02, (0.0, 0.0, 0.0))
            tracker.command(BLUE0, 0.01, (2.0, 0.0, 0.0))  # one for an earlier time replaces those after
    return tracker, 18 / 60


def test_a_told_robot_speeding_up_is_followed_and_predicted_without_the_lag() -> None:
    told, t = _accelerating(True)
    untold, _ = _accelerating(False)
    truth = 3.0 * (t - 0.01)
    assert told.state([BLUE0], t)[0, 3] == pytest.approx(truth, abs=0.01)
    assert untold.state([BLUE0], t)[0, 3] < truth - 0.05  # a constant-velocity filter lags
    # Predicted 30 ms on, the held command keeps it speeding up.
    x, _, _, vx, _, _ = told.state([BLUE0], t + 0.03)[0]
    assert vx == pytest.approx(3.0 * (t + 0.02), abs=0.01)
    assert x == pytest.approx(1.5 * (t + 0.02) ** 2, abs=0.002)


def test_a_robot_not_seen_yet_is_not_told_and_commands_are_kept_for_a_short_while() -> None:
    tracker = Tracker()
    tracker.command(BLUE0, 0.0, (1.0, 0.0, 0.0))
    assert BLUE0 not in tracker.tracks
    tracker.update(_frame(0.0, Detection("blue", 0, 0.0, 0.0, 0.0)), arrival=0.0)
    for k in range(20):
        tracker.command(BLUE0, k * 0.025, (1.0, 0.0, 0.0))
    assert len(tracker.tracks[BLUE0].commands) == COMMANDS_KEPT


def _textbook(state, cov, dt: float, q: float, dv: float, z: float | None, r: float):
    """One constant-velocity Kalman step as the textbooks write it: x' = F x + (dv dt / 2, dv),
    P' = F P F^T + q G G^T with G = (dt^2 / 2, dt), then (if z) the update with H = (1, 0)."""
    f = np.array([[1.0, dt], [0.0, 1.0]])
    g = np.array([[dt * dt / 2], [dt]])
    state = f @ state + np.array([dv * dt / 2, dv])
    cov = f @ cov @ f.T + q * (g @ g.T)
    if z is not None:
        gain = cov[:, 0] / (cov[0, 0] + r)
        state = state + gain * (z - state[0])
        cov = cov - np.outer(gain, cov[0])
    return state, cov


def _axis_matches(axis: _Axis, state, cov) -> None:
    np.testing.assert_allclose([axis.p, axis.v], state, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose([[axis.a, axis.b], [axis.b, axis.c]], cov, rtol=1e-12, atol=1e-15)


def test_an_axis_predicts_and_measures_as_the_textbook_kalman_filter() -> None:
    # From the prior (value 0.2, variance 0.01; rate 0 of variance 5^2): 0.1 s on with a known rate change
    # of 0.3 and q = 36, measured at 0.25 (r = 1e-4), then 0.05 s on with a change of -0.2.
    axis = _Axis(0.2, 0.01)
    state, cov = np.array([0.2, 0.0]), np.diag([0.01, 25.0])
    _axis_matches(axis, state, cov)
    axis.predict(0.1, 36.0, 0.3)
    state, cov = _textbook(state, cov, 0.1, 36.0, 0.3, None, 0.0)
    _axis_matches(axis, state, cov)
    axis.update(0.25 - axis.p, 1e-4)
    state, cov = _textbook(state, cov, 0.0, 0.0, 0.0, 0.25, 1e-4)
    _axis_matches(axis, state, cov)
    axis.predict(0.05, 36.0, -0.2)
    _axis_matches(axis, *_textbook(state, cov, 0.05, 36.0, -0.2, None, 0.0))


def test_an_axis_without_a_rate_change_moves_at_constant_rate_and_a_zero_step_changes_nothing() -> None:
    axis = _Axis(1.0, 0.01)
    axis.update(0.0, 1e-4)  # a covariance with every entry set
    before = (axis.p, axis.v, axis.a, axis.b, axis.c)
    axis.predict(0.0, 36.0, 0.5)
    assert (axis.p, axis.v, axis.a, axis.b, axis.c) == before
    axis.v = 2.0
    axis.predict(0.1, 0.0)
    assert (axis.p, axis.v) == pytest.approx((1.2, 2.0))


SETTINGS = TrackerSettings(pos_noise=0.01, angle_noise=0.05, accel=3.0, ang_accel=5.0, command_accel=0.5)


def test_an_untold_robot_is_filtered_with_the_white_noise_acceleration_of_its_settings() -> None:
    # Seen at rest at (0, 0) heading 0.1, then 0.1 s later at (0.02, -0.01) heading 0.15: x and y with
    # q = 3^2 and r = 0.01^2, the heading with q = 5^2 and r = 0.05^2, each from its prior.
    tracker = Tracker(SETTINGS)
    tracker.update(_frame(0.0, Detection("blue", 0, 0.0, 0.0, 0.1)), arrival=0.0)
    tracker.update(_frame(0.1, Detection("blue", 0, 0.02, -0.01, 0.15)), arrival=0.1)
    x, y, angle, vx, vy, w = tracker.state([BLUE0], 0.1)[0]
    for (value, rate), z, start, q, r in (
        ((x, vx), 0.02, 0.0, 9.0, 1e-4),
        ((y, vy), -0.01, 0.0, 9.0, 1e-4),
        ((angle, w), 0.15, 0.1, 25.0, 0.0025),
    ):
        expected, _ = _textbook(np.array([start, 0.0]), np.diag([r, 25.0]), 0.1, q, 0.0, z, r)
        np.testing.assert_allclose([value, rate], expected, rtol=1e-9)


def test_a_told_robot_is_predicted_with_the_commanded_change_and_its_own_process_noise() -> None:
    # At rest heading 0, told (1 m/s forward, 4 rad/s) from 0 s: in 0.1 s at 3 m/s^2 and 60 rad/s^2 the
    # rates change by 0.3 m/s along x and 4 rad/s, with q = 0.5^2 (position) and 10^2 (heading).
    tracker = Tracker(SETTINGS)
    tracker.update(_frame(0.0, Detection("blue", 0, 0.0, 0.0, 0.0)), arrival=0.0)
    tracker.command(BLUE0, 0.0, (1.0, 0.0, 4.0))
    tracker.update(_frame(0.1, Detection("blue", 0, 0.02, 0.0, 0.19)), arrival=0.1)
    track = tracker.tracks[BLUE0]
    _axis_matches(track.x, *_textbook(np.zeros(2), np.diag([1e-4, 25.0]), 0.1, 0.25, 0.3, 0.02, 1e-4))
    expected = _textbook(np.zeros(2), np.diag([0.0025, 25.0]), 0.1, 100.0, 4.0, 0.19, 0.0025)
    _axis_matches(track.angle, *expected)


def test_follow_caps_a_command_above_max_speed_along_its_direction() -> None:
    # (3, 4) m/s in the robot's frame at heading pi/2 is (-4, 3) in the field's: 5 m/s, capped to 2.5.
    vx, vy, spin = follow(0.0, 0.0, 0.0, (3.0, 4.0, 0.0), math.pi / 2, 10.0, RobotSpec())
    assert (vx, vy, spin) == pytest.approx((-2.0, 1.5, 0.0))


def test_follow_limits_the_change_of_velocity_as_a_vector() -> None:
    # From rest towards (1.2, 1.6) m/s (2 m/s): 0.1 s at 3 m/s^2 gives 0.3 m/s of it, (0.18, 0.24).
    vx, vy, _ = follow(0.0, 0.0, 0.0, (1.2, 1.6, 0.0), 0.0, 0.1, RobotSpec())
    assert (vx, vy) == pytest.approx((0.18, 0.24))


def test_a_track_without_a_command_or_time_has_no_rate_change() -> None:
    track = Track(_Axis(0.0, 1e-4), _Axis(0.0, 1e-4), _Axis(0.0, 1e-4), 0.0, 0.0)
    assert track.change(None, 0.1, RobotSpec()) == (0.0, 0.0, 0.0)
    assert track.change((1.0, 1.0, 1.0), 0.0, RobotSpec()) == (0.0, 0.0, 0.0)


def _moving(tracker: Tracker) -> None:
    """Blue 0 seen along x at 1 m/s, 60 Hz from 0 s to 0.5 s."""
    for k in range(31):
        tracker.update(_frame(k / 60, Detection("blue", 0, k / 60, 0.0, 0.0)), arrival=k / 60)


def test_a_robot_unseen_longer_than_forget_restarts_where_it_is_seen_again() -> None:
    # Last seen at 0.5 s; at 1.6 s it is where 1 m/s would have taken it, but 1.1 s > forget (1 s).
    tracker = Tracker()
    _moving(tracker)
    tracker.update(_frame(1.6, Detection("blue", 0, 1.6, 0.0, 0.0)), arrival=1.6)
    x, _, _, vx, _, _ = tracker.state([BLUE0], 1.6)[0]
    assert (x, vx) == (1.6, 0.0)


def test_a_robot_unseen_for_exactly_forget_is_still_tracked() -> None:
    tracker = Tracker()
    _moving(tracker)
    tracker.update(_frame(1.5, Detection("blue", 0, 1.5, 0.0, 0.0)), arrival=1.5)
    assert tracker.state([BLUE0], 1.5)[0, 3] == pytest.approx(1.0, abs=0.05)


def _at_rest() -> Tracker:
    """Blue 0 seen exactly at the origin, at rest, three times: its filter stands exactly there."""
    tracker = Tracker()
    for k in range(3):
        tracker.update(_frame(k / 60, Detection("blue", 0, 0.0, 0.0, 0.0)), arrival=k / 60)
    return tracker


@pytest.mark.parametrize(("x", "y"), [(0.6, 0.0), (0.0, -0.6)])
def test_a_jump_past_the_gate_along_one_axis_restarts_the_filter(x: float, y: float) -> None:
    tracker = _at_rest()
    tracker.update(_frame(3 / 60, Detection("blue", 0, x, y, 0.0)), arrival=3 / 60)
    assert tuple(tracker.state([BLUE0], 3 / 60)[0, [0, 1, 3, 4]]) == (x, y, 0.0, 0.0)


def test_a_detection_exactly_at_the_gate_is_measured() -> None:
    tracker = _at_rest()
    tracker.update(_frame(3 / 60, Detection("blue", 0, 0.5, 0.0, 0.0)), arrival=3 / 60)
    x, _, _, vx, _, _ = tracker.state([BLUE0], 3 / 60)[0]
    assert 0.0 < x < 0.5 and vx > 0.0  # filtered towards it, not restarted on it


def test_a_robot_restarted_past_the_gate_keeps_its_commands() -> None:
    tracker = _at_rest()
    tracker.command(BLUE0, 2 / 60, (1.0, 0.0, 0.0))
    tracker.update(_frame(3 / 60, Detection("blue", 0, 2.0, 0.0, 0.0)), arrival=3 / 60)
    assert tracker.tracks[BLUE0].commands == [(2 / 60, (1.0, 0.0, 0.0))]


def test_a_robot_seen_without_orientation_is_tracked_at_heading_zero() -> None:
    tracker = Tracker()
    for k in range(30):
        tracker.update(_frame(k / 60, Detection("blue", 0, 0.5 * k / 60, 0.0, None)), arrival=k / 60)
    x, _, angle, vx, _, w = tracker.state([BLUE0], 29 / 60)[0]
    assert x == pytest.approx(0.5 * 29 / 60, abs=0.005) and vx == pytest.approx(0.5, abs=0.05)
    assert (angle, w) == (0.0, 0.0)


def test_commands_superseded_at_the_filters_time_are_dropped_and_a_same_time_command_replaces() -> None:
    tracker = _at_rest()  # its filter stands at 2/60 s
    for since in (0.0, 0.02, 2 / 60):
        tracker.command(BLUE0, since, (since, 0.0, 0.0))
    tracker.command(BLUE0, 2 / 60, (1.0, 0.0, 0.0))
    assert tracker.tracks[BLUE0].commands[1:] == [(0.02, (0.02, 0.0, 0.0)), (2 / 60, (1.0, 0.0, 0.0))]
    tracker.update(_frame(2 / 60, Detection("blue", 0, 0.0, 0.0, 0.0)), arrival=2 / 60)
    assert tracker.tracks[BLUE0].commands == [(2 / 60, (1.0, 0.0, 0.0))]


def test_the_vision_clock_reads_zero_before_any_frame_and_follows_the_last_arrival_of_a_send_time() -> None:
    tracker = Tracker()
    assert tracker.vision_time(5.0) == 0.0
    for arrival in (10.0, 10.25):  # two cameras' frames sent at 1 s, the second read 0.25 s later
        tracker.update(DetectionFrame(0.9, 1.0, 0, ()), arrival=arrival)
    assert tracker.vision_time(10.5) == 1.25


def test_a_robot_seen_exactly_max_age_ago_is_fresh() -> None:
    tracker = Tracker()
    tracker.update(_frame(0.0, Detection("blue", 0, 0.0, 0.0, 0.0)), arrival=0.5)
    assert tracker.fresh(BLUE0, 0.75, 0.25)
