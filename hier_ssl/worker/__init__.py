"""goToPoint workers: (robot state, sub-goal) -> velocity command, batched; chosen by name in configs."""

from __future__ import annotations

from hier_ssl.worker.scripted import BangBangGoToPoint, PaperGoToPoint
from hier_ssl.world.physics import RobotSpec

WORKERS = ("paper", "bangbang")


def make_worker(name: str, robot: RobotSpec, dt: float) -> PaperGoToPoint | BangBangGoToPoint:
    """The scripted worker called ``name``, tuned to the world's robot and control period."""
    if name == "paper":
        return PaperGoToPoint(dt=dt)
    if name == "bangbang":
        return BangBangGoToPoint(
            dt=dt,
            max_speed=robot.max_speed,
            max_accel=robot.max_accel,
            max_ang_speed=robot.max_ang_speed,
            max_ang_accel=robot.max_ang_accel,
        )
    raise ValueError(f"unknown worker {name!r}; known: {list(WORKERS)}")


__all__ = ["WORKERS", "BangBangGoToPoint", "PaperGoToPoint", "make_worker"]
