"""A manager observation read back in physical units: what every scripted planner knows of the world."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from hier_ssl.game.legal import RowRules, cap_speed, nearest_legal
from hier_ssl.manager.actions import encode_subgoal
from hier_ssl.manager.neighbours import as_obstacle_observation, drop_encounters
from hier_ssl.manager.observation import (
    MANAGER_OBS_BASE_DIM,
    MANAGER_OBS_SLICES,
    OBSTACLE_OBS_DIM,
    OBSTACLE_OBS_SLICES,
    check_array,
)
from hier_ssl.world.field import Field

OBSERVATIONS = ("paper", "neighbours", "encounters")


@dataclass(frozen=True)
class Scene:
    """A manager observation in physical units, fields on the leading axis.

    Shapes: target (N, 5) x, y, theta, vx, vy; robot_pos, robot_vel (N, 2); obstacle_pos, obstacle_vel
    (N, K, 2). Metres, radians, m/s, field frame.
    """

    target: np.ndarray
    robot_pos: np.ndarray
    robot_vel: np.ndarray
    obstacle_pos: np.ndarray
    obstacle_vel: np.ndarray


def read_scene(obs: np.ndarray, max_pos: float, max_v: float, observation: str = "paper") -> Scene:
    """Undo the observation's normalisation (positions / max_pos, velocities / max_v).

    ``obs`` (N, 13 + 5K) in the "paper" layout, or (N, 13 + 6K) in the "neighbours" one (every neighbour
    an obstacle), or (N, 13 + 12K) in the "encounters" one (its extra columns unread); K is read from its
    width. Values clipped by the observation stay clipped.
    """
    if observation not in OBSERVATIONS:
        raise ValueError(f"unknown observation layout {observation!r}; expected one of {list(OBSERVATIONS)}")
    if observation == "encounters":
        obs = drop_encounters(check_array("obs", obs, (None, None)))
    if observation != "paper":
        obs = as_obstacle_observation(obs)
    obs = check_array("obs", obs, (None, None))
    n, width = obs.shape
    k, rest = divmod(width - MANAGER_OBS_BASE_DIM, OBSTACLE_OBS_DIM)
    if width < MANAGER_OBS_BASE_DIM or rest:
        raise ValueError(f"obs must have 13 + 5K columns, got {width}")
    s = MANAGER_OBS_SLICES
    sincos = obs[:, s["target_sincos"]]
    target = np.concatenate(
        [
            obs[:, s["target_pos"]] * max_pos,
            np.arctan2(sincos[:, 0], sincos[:, 1])[:, None],
            obs[:, s["target_vel"]] * max_v,
        ],
        axis=1,
    )
    blocks = obs[:, MANAGER_OBS_BASE_DIM:].reshape(n, k, OBSTACLE_OBS_DIM)
    return Scene(
        target=target,
        robot_pos=obs[:, s["robot_pos"]] * max_pos,
        robot_vel=obs[:, s["robot_vel"]] * max_v,
        obstacle_pos=blocks[:, :, OBSTACLE_OBS_SLICES["pos"]] * max_pos,
        obstacle_vel=blocks[:, :, OBSTACLE_OBS_SLICES["vel"]] * max_v,
    )


def subgoal_poses(scene: Scene, chosen: np.ndarray) -> np.ndarray:
    """Sub-goal poses (N, 5) at positions ``chosen`` (N,) complex: the target's heading, zero velocity."""
    subgoal = np.zeros((len(chosen), 5))
    subgoal[:, 0], subgoal[:, 1], subgoal[:, 2] = chosen.real, chosen.imag, scene.target[:, 2]
    return subgoal


def ruled_scene(scene: Scene, rules: RowRules | None, margin: float = 0.0) -> Scene:
    """``scene`` with its target where the rules let the robot go: moved to the nearest point that keeps
    ``margin`` m beyond every zone's clearance (``nearest_legal``) if it is not there already, and its
    velocity capped at the robot's speed limit. Without rules, the scene itself."""
    if rules is None:
        return scene
    if len(rules.speed) != len(scene.target):
        raise ValueError(f"rules for {len(rules.speed)} robots, observations of {len(scene.target)}")
    target = scene.target.copy()
    zones = rules.zones
    if margin:
        zones = dataclasses.replace(zones, clearance=zones.clearance + margin)
    target[:, 0:2] = nearest_legal(zones, target[:, 0:2])
    target[:, 3:5] = cap_speed(target[:, 3:5], rules.speed)
    return dataclasses.replace(scene, target=target)


def halted(scene: Scene, rules: RowRules | None, subgoal: np.ndarray) -> np.ndarray:
    """Sub-goal poses (N, 5) with every robot a HALT holds (speed limit 0) given its own position, at rest:
    the rules forbid it to move, wherever its zones are."""
    if rules is None or not (rules.speed <= 0).any():
        return subgoal
    stop = rules.speed <= 0
    subgoal = subgoal.copy()
    subgoal[stop, 0:2], subgoal[stop, 3:5] = scene.robot_pos[stop], 0.0
    return subgoal


def scene_action(
    scene: Scene, subgoal: np.ndarray, field: Field, max_v: float, action_form: str, action_frame: str
) -> np.ndarray:
    """The actions (N, A) that name sub-goal poses ``subgoal`` (N, 5) in ``scene``'s task, as a planner
    with that field, speed scale, action form and frame emits them."""
    return encode_subgoal(
        subgoal,
        action_form,
        field.half_length,
        field.half_width,
        max_v,
        frame=action_frame,
        target=scene.target,
    )


__all__ = ["OBSERVATIONS", "Scene", "halted", "read_scene", "ruled_scene", "scene_action", "subgoal_poses"]
