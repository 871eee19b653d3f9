"""Environment views over the one batched core: PettingZoo, Gymnasium, vector, rsl-rl."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from pettingzoo.utils.conversions import parallel_to_aec

from hier_ssl.config import EnvConfig, ScenarioConfig, load_yaml, parse_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.multi import MultiRobotParallelEnv, MultiVectorEnv
from hier_ssl.envs.parallel import HierarchicalSSLEnv, ManagerEnv
from hier_ssl.envs.scenarios import scenario_config
from hier_ssl.envs.vector import RslRlVecEnv, VectorEnv


def env_config(config: str | Path | EnvConfig | None = None, **settings: Any) -> EnvConfig:
    """An EnvConfig from a YAML file (its ``env`` section if it is a training config), an EnvConfig, or
    keyword settings; settings override what the file gives."""
    if isinstance(config, EnvConfig):
        data = config.model_dump()
    elif config is not None:
        data = load_yaml(config)
        data = data.get("env", data) if "env" in data else data
    else:
        data = {}
    if "obstacles" not in settings and not data.get("obstacles") and settings.get("task") == "obstacle":
        settings.setdefault("obstacles", [{}])
        settings.setdefault("min_start_distance", 0.6)
    return parse_config({**data, **settings}, EnvConfig, root="env")


def parallel_env(
    config: str | Path | EnvConfig | None = None, render_mode: str | None = None, **settings: Any
) -> HierarchicalSSLEnv:
    """The PettingZoo ParallelEnv, e.g. ``parallel_env(task="proposed", frame_skip=16)``."""
    return HierarchicalSSLEnv(env_config(config, **settings), render_mode=render_mode)


def env(config: str | Path | EnvConfig | None = None, render_mode: str | None = None, **settings: Any):
    """The AEC view of ``parallel_env``."""
    return parallel_to_aec(parallel_env(config, render_mode=render_mode, **settings))


def vector_env(
    config: str | Path | EnvConfig | None = None, num_envs: int = 16, device: str = "cpu", **settings: Any
) -> VectorEnv:
    """The batched torch view over ``num_envs`` fields."""
    return VectorEnv(env_config(config, **settings), num_envs, device)


def manager_env(
    config: str | Path | EnvConfig | None = None, render_mode: str | None = None, **settings: Any
) -> ManagerEnv:
    """A single-agent Gymnasium env of the manager (worker and obstacles scripted)."""
    return ManagerEnv(env_config(config, **settings), render_mode=render_mode)


def scenario_env(
    scenario: str | Path | ScenarioConfig, render_mode: str | None = None, **settings: Any
) -> MultiRobotParallelEnv:
    """The PettingZoo ParallelEnv of a multi-robot scenario (a name, a YAML file or a config), e.g.
    ``scenario_env("crossing", num_agents=4)``: agents ``manager_i`` leave as they finish."""
    return MultiRobotParallelEnv(scenario_config(scenario, **settings), render_mode=render_mode)


def scenario_vector_env(
    scenario: str | Path | ScenarioConfig, num_fields: int = 16, device: str = "cpu", **settings: Any
) -> MultiVectorEnv:
    """The batched torch view of a scenario for a shared policy: one row per (field, controlled robot)."""
    return MultiVectorEnv(scenario_config(scenario, **settings), num_fields, device)


__all__ = [
    "HierarchicalCore",
    "HierarchicalSSLEnv",
    "ManagerEnv",
    "MultiRobotParallelEnv",
    "MultiVectorEnv",
    "RslRlVecEnv",
    "VectorEnv",
    "env",
    "env_config",
    "manager_env",
    "parallel_env",
    "scenario_env",
    "scenario_vector_env",
    "vector_env",
]
