"""The paper's three environments (docs/paper.md) as scenarios: one controlled robot, its target, and the
obstacles its ``EnvConfig`` lists, each with its own behaviour and placement.

- ``baseline``: robot-centric reward (the robot's distance and angle to the target), success when the
  robot stops on the target; ``pose6`` sub-goals keep their velocity.
- ``proposed``: action-centric reward (the sub-goal's distance and angle to the target), success when the
  sub-goal names the target and the robot has stopped there.
- ``obstacle``: proposed plus R_obst and R_hit; a collision ends the episode as a failure. Without
  obstacles in its config it gets one at the midpoint and starts at least 0.6 m from the target.

Reset sampling (docs/paper.md "Starts"): target and robot uniform on the field (less ``spawn_margin``), the
robot at least ``min_start_distance`` from the target; each obstacle at the robot-target midpoint (the
public code) or uniform, clear of robot, target and earlier obstacles; uniform headings.
"""

from __future__ import annotations

import numpy as np

from hier_ssl.config import EnvConfig
from hier_ssl.envs.scenario import ObstacleGroup, Placement, Scenario


class PaperTask(Scenario):
    """One controlled robot (robot 0) and the obstacles of ``config.obstacles`` (robots 1..K), each moved
    by its own behaviour object, in the observation layout ``config.observation`` names."""

    def __init__(self, config: EnvConfig) -> None:
        groups = [ObstacleGroup(o.behaviour, o.options) for o in config.obstacles]
        super().__init__(config, 1, groups)
        if any(o.placement == "midpoint" for o in config.obstacles) and not config.allow_start_contact:
            if config.min_start_distance < self.gap:
                raise ValueError(
                    f"min_start_distance: {config.min_start_distance} m puts a midpoint obstacle inside the "
                    f"collision distance at reset; use >= {self.gap}, or set allow_start_contact: true to "
                    "play and count such episodes"
                )

    def _uniform_xy(self, rng: np.random.Generator, num_fields: int) -> np.ndarray:
        return rng.uniform(-self.half, self.half, (num_fields, 2))

    def _too_close(self, xy: np.ndarray, placed: list[np.ndarray]) -> np.ndarray:
        return np.any([np.linalg.norm(xy - other, axis=1) < self.gap for other in placed], axis=0)

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> Placement:
        config = self.config
        target_xy = self._uniform_xy(rng, num_fields)
        robot_xy = self._uniform_xy(rng, num_fields)
        while (bad := np.linalg.norm(robot_xy - target_xy, axis=1) < config.min_start_distance).any():
            robot_xy[bad] = self._uniform_xy(rng, int(bad.sum()))
        placed = [robot_xy, target_xy]
        for obstacle in config.obstacles:
            if obstacle.placement == "midpoint":
                xy = (robot_xy + target_xy) / 2
            else:
                xy = self._uniform_xy(rng, num_fields)
                while (bad := self._too_close(xy, placed)).any():
                    xy[bad] = self._uniform_xy(rng, int(bad.sum()))
            placed.append(xy)
        pos = np.stack([robot_xy, *placed[2:]], axis=1)
        angle = rng.uniform(-np.pi, np.pi, (num_fields, 1 + self.num_obstacles))
        target = np.zeros((num_fields, 1, 5))
        target[:, 0, 0:2] = target_xy
        target[:, 0, 2] = rng.uniform(-np.pi, np.pi, num_fields)
        return Placement(pos, angle, target)


class Baseline(PaperTask):
    name = "baseline"
    reward_task = "baseline"
    zero_velocity = False


class Proposed(PaperTask):
    name = "proposed"
    reward_task = "proposed"


class Obstacle(PaperTask):
    name = "obstacle"
    reward_task = "obstacle"
    defaults = {"obstacles": [{}], "min_start_distance": 0.6}

    def __init__(self, config: EnvConfig) -> None:
        if not config.obstacles:
            raise ValueError("obstacles: the 'obstacle' task needs at least one obstacle")
        super().__init__(config)


TASKS: dict[str, type[PaperTask]] = {cls.name: cls for cls in (Baseline, Proposed, Obstacle)}

__all__ = ["TASKS", "Baseline", "Obstacle", "PaperTask", "Proposed"]
