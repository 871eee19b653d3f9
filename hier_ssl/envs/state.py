"""The global state of a field, for centralised critics (MAPPO, QMIX-style mixers): every robot's pose and
velocity, every controlled robot's target and held sub-goal, and whether it is still in its episode.

Normalised like the manager observations (``hier_ssl.manager.observation``): positions / max_pos,
velocities / max_v, angular velocities / max_w, angles as sin and cos, every value clipped to +-1.2;
float32. Field frame. With R = M + K robots, controlled robots (``manager_i``) first, then obstacles
(``obstacle_j``), and B balls (none unless the scenario's world holds some), the D = 7 R + 13 M + 4 B
columns are:

======================  =================================================================================
columns                 values
======================  =================================================================================
7 r .. 7 r + 6          robot r: x, y, sin theta, cos theta, vx, vy, omega (r = 0 .. R - 1)
7 R + 13 i + 0 .. 5     controlled robot i's target: x, y, sin theta, cos theta, vx, vy
7 R + 13 i + 6 .. 11    its held sub-goal: x, y, sin theta, cos theta, vx, vy (its own pose before the
                        first decision)
7 R + 13 i + 12         1.0 while it is in its episode, 0.0 once it has left (reached its target or
                        collided; it then holds still where it is)
7 R + 13 M + 4 b + 0..3 ball b: x, y, vx, vy (b = 0 .. B - 1)
======================  =================================================================================

``state_columns`` names them (``manager_0_x`` ... ``obstacle_0_omega``, ``manager_0_target_x`` ...,
``manager_0_subgoal_x`` ..., ``manager_0_active``, ``ball_0_x`` ...). The PettingZoo view returns one
field's row from ``state()``; the arrays here are batched over the core's N fields.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from hier_ssl.envs.core import HierarchicalCore

ROBOT_COLUMNS = ("x", "y", "sin", "cos", "vx", "vy", "omega")
POSE_COLUMNS = ("x", "y", "sin", "cos", "vx", "vy")
BALL_COLUMNS = ("x", "y", "vx", "vy")
CLIP = 1.2


def state_dim(num_agents: int, num_obstacles: int, num_balls: int = 0) -> int:
    """D: columns of the state of a field with M controlled robots, K obstacles and B balls."""
    robots = len(ROBOT_COLUMNS) * (num_agents + num_obstacles) + (2 * len(POSE_COLUMNS) + 1) * num_agents
    return robots + len(BALL_COLUMNS) * num_balls


def state_columns(num_agents: int, num_obstacles: int, num_balls: int = 0) -> list[str]:
    """The D column names, in order."""
    robots = [f"manager_{i}" for i in range(num_agents)] + [f"obstacle_{j}" for j in range(num_obstacles)]
    names = [f"{robot}_{c}" for robot in robots for c in ROBOT_COLUMNS]
    for i in range(num_agents):
        names += [f"manager_{i}_target_{c}" for c in POSE_COLUMNS]
        names += [f"manager_{i}_subgoal_{c}" for c in POSE_COLUMNS]
        names.append(f"manager_{i}_active")
    return names + [f"ball_{b}_{c}" for b in range(num_balls) for c in BALL_COLUMNS]


def _pose(pose: np.ndarray, max_pos: float, max_v: float) -> np.ndarray:
    """(..., 5) x, y, theta, vx, vy -> (..., 6) normalised, angle as sin and cos."""
    theta = pose[..., 2:3]
    return np.concatenate(
        [pose[..., 0:2] / max_pos, np.sin(theta), np.cos(theta), pose[..., 3:5] / max_v], axis=-1
    )


def global_state(core: HierarchicalCore) -> np.ndarray:
    """The state (N, D) float32 of every field of ``core`` (a ``HierarchicalCore``), as laid out above."""
    s, scales = core.world.state, core.scenario.scales
    max_pos, max_v = scales["max_pos"], scales["max_v"]
    n = core.num_fields
    robots = np.concatenate(
        [
            s.pos / max_pos,
            np.sin(s.angle)[..., None],
            np.cos(s.angle)[..., None],
            s.vel / max_v,
            s.ang_vel[..., None] / scales["max_w"],
        ],
        axis=-1,
    )
    agents = np.concatenate(
        [
            _pose(core.target, max_pos, max_v),
            _pose(core.subgoal, max_pos, max_v),
            core.active[..., None].astype(np.float64),
        ],
        axis=-1,
    )
    parts = [robots.reshape(n, -1), agents.reshape(n, -1)]
    ball = core.world.ball
    if ball is not None:
        parts.append(np.concatenate([ball.pos / max_pos, ball.vel / max_v], axis=-1).reshape(n, -1))
    state = np.concatenate(parts, axis=1)
    return np.clip(state, -CLIP, CLIP).astype(np.float32)


__all__ = [
    "BALL_COLUMNS",
    "CLIP",
    "POSE_COLUMNS",
    "ROBOT_COLUMNS",
    "global_state",
    "state_columns",
    "state_dim",
]
