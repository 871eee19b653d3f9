"""The observation layouts a scenario's managers read by default, one class each: ``PaperObservation``
(robot 0 observes the field's other robots as its obstacles, ``hier_ssl.manager.observation``) and
``NeighbourObservation`` (each controlled robot observes its nearest other robots, with their encounter
columns in the "encounters" layout, ``hier_ssl.manager.neighbours``). ``observation_layout`` picks the one
a config's ``observation`` names. A scenario with an observation of its own overrides
``Scenario.observation`` instead.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from hier_ssl.manager import manager_obs_dim
from hier_ssl.manager.neighbours import neighbour_obs_dim, neighbour_observation
from hier_ssl.manager.observation import first_robot_observation, observation_scales
from hier_ssl.world.robot import RobotState


class Neighbourhood(Protocol):
    """What a neighbour layout reads of its scenario: which robots each controlled robot sees."""

    num_agents: int
    teammate: np.ndarray

    def others_of(self, values: np.ndarray) -> np.ndarray: ...


class PaperObservation:
    """The paper's layout: robot 0 (the one controlled robot) and the field's other robots as its
    obstacles, ``13 + 5 (R - 1)`` values."""

    name = "paper"

    def __init__(self, num_robots: int, scales: dict[str, float]) -> None:
        self.dim = manager_obs_dim(num_robots - 1)
        limits = (scales["max_pos"], scales["max_v"], scales["max_w"])
        self._scales = observation_scales(num_robots - 1, *(float(v) for v in limits))

    def __call__(self, target: np.ndarray, state: RobotState) -> np.ndarray:
        """Observations (F, 1, dim) float32 of targets (F, 1, 5) and ``state`` (F, R)."""
        return first_robot_observation(target, state, self._scales)[:, None]


class NeighbourObservation:
    """The "neighbours" layout (and "encounters", with ``encounters``): each controlled robot, its target
    and its ``neighbours`` nearest other robots, relative, ``neighbour_obs_dim`` values."""

    def __init__(
        self, scenario: Neighbourhood, neighbours: int, encounters: bool, scales: dict[str, float]
    ) -> None:
        self.name = "encounters" if encounters else "neighbours"
        self.dim = neighbour_obs_dim(neighbours, encounters)
        self.scenario, self.neighbours, self.encounters = scenario, neighbours, encounters
        # The scales as 0-d arrays: a Python float operand is converted on every numpy call.
        self._limits = {k: np.array(scales[k]) for k in ("max_pos", "max_v", "max_w")}

    def __call__(self, target: np.ndarray, state: RobotState) -> np.ndarray:
        """Observations (F, M, dim) float32 of targets (F, M, 5) and ``state`` (F, R)."""
        f, m = target.shape[:2]
        b, scenario = f * m, self.scenario
        rows = (
            target.reshape(b, 5),
            state.pos[:, :m].reshape(b, 2),
            state.angle[:, :m].reshape(b),
            state.vel[:, :m].reshape(b, 2),
            state.ang_vel[:, :m].reshape(b),
        )
        j = scenario.teammate.shape[1]
        teammate = np.broadcast_to(scenario.teammate, (f, m, j)).reshape(b, j)
        others_pos = scenario.others_of(state.pos).reshape(b, j, 2)
        others_vel = scenario.others_of(state.vel).reshape(b, j, 2)
        obs = neighbour_observation(
            *rows,
            others_pos,
            others_vel,
            teammate,
            self.neighbours,
            **self._limits,
            encounters=self.encounters,
        )
        return obs.reshape(f, m, self.dim)


def observation_layout(
    name: str, scenario: Neighbourhood, num_robots: int, neighbours: int, scales: dict[str, float]
) -> PaperObservation | NeighbourObservation:
    """The layout ``name`` ("paper", "neighbours" or "encounters") for ``scenario``'s robots."""
    if name == "paper":
        return PaperObservation(num_robots, scales)
    return NeighbourObservation(scenario, neighbours, name == "encounters", scales)


__all__ = ["NeighbourObservation", "PaperObservation", "observation_layout"]
