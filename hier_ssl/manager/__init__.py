"""The manager's pure functions: observation, action decoding, rewards, success and metrics.

Everything works on numpy arrays batched over N fields (leading axis).
"""

from __future__ import annotations

from hier_ssl.manager.actions import (
    ACTION_DIMS,
    ACTION_FRAMES,
    action_dim,
    decode_subgoal,
    encode_subgoal,
)
from hier_ssl.manager.metrics import CPAD_VARIANTS, cpad, cpad_increment, min_time_to_pose, summarize
from hier_ssl.manager.observation import (
    MANAGER_OBS_BASE_DIM,
    MANAGER_OBS_SLICES,
    OBSTACLE_OBS_DIM,
    OBSTACLE_OBS_SLICES,
    check_array,
    manager_obs_dim,
    manager_observation,
    obstacle_obs_slice,
)
from hier_ssl.manager.rewards import (
    ANGLE_BONUS,
    ANGLE_THRESHOLD,
    DIST_BONUS,
    DIST_THRESHOLD,
    HIT_MODES,
    HIT_REWARD,
    OBSTACLE_FROM,
    REWARD_TERMS,
    SUCCESS_MODES,
    SUCCESS_REWARD,
    TASKS,
    angle_reward,
    distance_reward,
    nearest_obstacle_distance,
    obstacle_reward,
    pose_errors,
    task_reward,
    wrap_angle,
)
from hier_ssl.manager.success import (
    COLLISION_DISTANCE,
    SPEED_THRESHOLD,
    baseline_success,
    collided,
    proposed_success,
    task_success,
)

__all__ = [
    "ACTION_FRAMES",
    "ACTION_DIMS",
    "ANGLE_BONUS",
    "ANGLE_THRESHOLD",
    "COLLISION_DISTANCE",
    "CPAD_VARIANTS",
    "DIST_BONUS",
    "DIST_THRESHOLD",
    "HIT_MODES",
    "HIT_REWARD",
    "OBSTACLE_FROM",
    "MANAGER_OBS_BASE_DIM",
    "MANAGER_OBS_SLICES",
    "OBSTACLE_OBS_DIM",
    "OBSTACLE_OBS_SLICES",
    "REWARD_TERMS",
    "SPEED_THRESHOLD",
    "SUCCESS_MODES",
    "SUCCESS_REWARD",
    "TASKS",
    "action_dim",
    "angle_reward",
    "baseline_success",
    "check_array",
    "collided",
    "cpad",
    "cpad_increment",
    "decode_subgoal",
    "distance_reward",
    "encode_subgoal",
    "manager_obs_dim",
    "manager_observation",
    "min_time_to_pose",
    "nearest_obstacle_distance",
    "obstacle_obs_slice",
    "obstacle_reward",
    "pose_errors",
    "proposed_success",
    "summarize",
    "task_reward",
    "task_success",
    "wrap_angle",
]
