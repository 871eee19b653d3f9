"""hier_ssl: hierarchical RL path planning for RoboCup SSL (manager / worker / obstacles)."""

from __future__ import annotations

from hier_ssl.envs import env, manager_env, parallel_env, vector_env

__all__ = ["env", "manager_env", "parallel_env", "vector_env"]
__version__ = "0.1.0"
