"""hier_ssl: hierarchical RL path planning for RoboCup SSL (manager / worker / obstacles).

Importing the package registers its Gymnasium ids (``hier_ssl.registration``: ``hier_ssl/Proposed-v0``
...), which imports gymnasium and nothing of the environments.
"""

from __future__ import annotations

from typing import Any

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


def __getattr__(name: str) -> Any:
    if name in __all__:
        # here, not at the top: the environments (pymunk, pettingzoo, pydantic), for their entry points alone
        from hier_ssl import envs

        return getattr(envs, name)
    raise AttributeError(f"module 'hier_ssl' has no attribute {name!r}")
