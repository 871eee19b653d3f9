"""hier_ssl: hierarchical RL path planning for RoboCup SSL (manager / worker / obstacles).

Importing the package registers its Gymnasium ids (``hier_ssl.registration``: ``hier_ssl/Proposed-v0``
...) and imports the environments without learning: no torch until a torch view is made.
"""

from __future__ import annotations

from hier_ssl.envs import (
    env,
    manager_env,
    manager_vector_env,
    parallel_env,
    scenario_env,
    scenario_vector_env,
    vector_env,
)
from hier_ssl.registration import register_envs

__all__ = [
    "env",
    "manager_env",
    "manager_vector_env",
    "parallel_env",
    "scenario_env",
    "scenario_vector_env",
    "vector_env",
]
__version__ = "0.1.0"

register_envs()

