"""The field server's cameras: strips of the walled area along x that overlap, each reporting what it sees
of the world as SSL-Vision detection frames, with Gaussian noise, each detection dropped with probability
``drop``, sent ``latency`` s after capture."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hier_ssl.deploy.wire import Detection, DetectionFrame


@dataclass(frozen=True)
class Cameras:
    """``count`` cameras over strips of the walled area along x, overlapping by ``overlap`` m; ``rate``
    frames/s each; noise (one standard deviation) ``pos_noise`` m and ``angle_noise`` rad; ``drop`` the
    probability of missing a detection; ``latency`` s from capture to send."""

    count: int = 2
    overlap: float = 0.6
    rate: float = 60.0
    pos_noise: float = 0.002
    angle_noise: float = 0.01
    drop: float = 0.0
    latency: float = 0.0

    def __post_init__(self) -> None:
        if self.count < 1 or not self.rate > 0 or not 0 <= self.drop < 1:
            raise ValueError(f"cameras: count >= 1, rate > 0 and drop in [0, 1) expected, got {self}")
        if min(self.overlap, self.pos_noise, self.angle_noise, self.latency) < 0:
            raise ValueError(f"cameras: overlap, noise and latency must be >= 0, got {self}")


def camera_strips(cameras: Cameras, half_extent: float) -> np.ndarray:
    """(count, 2) x range each camera sees: equal strips of [-half_extent, half_extent], widened by half
    the overlap on each inner side."""
    edges = np.linspace(-half_extent, half_extent, cameras.count + 1)
    strips = np.stack([edges[:-1], edges[1:]], axis=1)
    strips[1:, 0] -= cameras.overlap / 2
    strips[:-1, 1] += cameras.overlap / 2
    return strips


def camera_frames(
    pos: np.ndarray,
    angle: np.ndarray,
    teams: list[tuple[str, int]],
    cameras: Cameras,
    strips: np.ndarray,
    t_capture: float,
    rng: np.random.Generator,
    ball: tuple[float, float] | None = None,
) -> list[DetectionFrame]:
    """One frame per camera of robots at ``pos`` (R, 2) m, ``angle`` (R,) labelled ``teams``: each camera
    reports the robots inside its strip, with noise and drops, and the ``ball`` (m; None: none) where it
    lies inside the strip, as it is. Shapes of the outputs: a tuple per frame."""
    frames = []
    for c, (low, high) in enumerate(strips):
        inside = (pos[:, 0] >= low) & (pos[:, 0] <= high) & (rng.random(len(pos)) >= cameras.drop)
        noisy = pos + rng.normal(0.0, cameras.pos_noise, pos.shape)
        turned = angle + rng.normal(0.0, cameras.angle_noise, angle.shape)
        seen = tuple(
            Detection(team, robot, float(noisy[i, 0]), float(noisy[i, 1]), float(turned[i]))
            for i, (team, robot) in enumerate(teams)
            if inside[i]
        )
        sees_ball = ball is not None and low <= ball[0] <= high
        frames.append(
            DetectionFrame(t_capture, t_capture + cameras.latency, c, seen, ball if sees_ball else None)
        )
    return frames
