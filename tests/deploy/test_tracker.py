"""The tracker: recorded noisy tracks with known truth (the world driving a robot, overlapping cameras
with noise, drops, duplicates and latency), and the cases a field throws at it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.deploy.bench import tracking_error
from hier_ssl.deploy.tracker import COMMANDS_KEPT, PREDICT_HORIZON, Tracker, TrackerSettings
from hier_ssl.deploy.wire import Detection, DetectionFrame

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
