"""Environment views over the one batched core: PettingZoo, Gymnasium, torch vector, rsl-rl.

Every task is a scenario (``hier_ssl.envs.scenario``) of the core (``hier_ssl.envs.core``): the paper's
Baseline, Proposed and Obstacle tasks from an ``EnvConfig``, the multi-robot scenarios from a
``ScenarioConfig``. The torch views (``vector_env``, ``TorchVectorEnv``, ``RslRlVecEnv``) bring torch and
rsl-rl with them and are loaded on first use; the PettingZoo and Gymnasium views (``manager_env``, and
``manager_vector_env``, a ``gymnasium.vector.VectorEnv``) need neither. The SSL game's scenarios
(``hier_ssl.envs.game``) are registered here, with the shipped ones.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pettingzoo.utils.conversions import parallel_to_aec

from hier_ssl.config import EnvConfig, ScenarioConfig, TaskConfig
from hier_ssl.envs.core import HierarchicalCore, StepResult
from hier_ssl.envs.game import GameScenario
from hier_ssl.envs.gym_vector import ManagerVectorEnv
from hier_ssl.envs.parallel import HierarchicalSSLEnv, ManagerEnv
from hier_ssl.envs.play import Policy, play
from hier_ssl.envs.registry import (
    env_config,
    load_config,
    make_scenario,
    parse_config,
    register_scenario,
    scenario_config,
    task_config,
)
from hier_ssl.envs.scenario import Placement, Scenario
from hier_ssl.envs.scenarios import SCENARIOS
from hier_ssl.envs.tasks import TASKS

if TYPE_CHECKING:
    from hier_ssl.envs.vector import RslRlVecEnv, TorchVectorEnv

_TORCH_VIEWS = ("RslRlVecEnv", "TorchVectorEnv", "TorchView")


def _worker_apart(worker: Any, settings: dict[str, Any]) -> tuple[dict[str, Any], Any]:
    """(settings, worker object): a spec string (or run directory) goes into the config's ``worker`` key,
    where it is checked and recorded; an object, class or factory goes to the core as it is."""
    if isinstance(worker, (str, os.PathLike)):
        return {**settings, "worker": os.fspath(worker)}, None
    return settings, worker


def parallel_env(
    config: str | Path | TaskConfig | None = None,
    render_mode: str | None = None,
    worker: Any = None,
    **settings: Any,
) -> HierarchicalSSLEnv:
    """The PettingZoo ParallelEnv, e.g. ``parallel_env(task="proposed", frame_skip=16)``.

    ``worker``: a spec (``"bangbang"``, ``"my_pkg.control:Ctrl"``, as ``env.worker`` takes) or a Python
    object following the worker protocol (``hier_ssl.worker.Worker``), or its class or factory; every
    constructor below takes it the same way."""
    settings, worker = _worker_apart(worker, settings)
    return HierarchicalSSLEnv(task_config(config, **settings), render_mode=render_mode, worker=worker)


def env(
    config: str | Path | TaskConfig | None = None,
    render_mode: str | None = None,
    worker: Any = None,
    **settings: Any,
):
    """The AEC view of ``parallel_env``."""
    return parallel_to_aec(parallel_env(config, render_mode=render_mode, worker=worker, **settings))


def vector_env(
    config: str | Path | TaskConfig | None = None,
    num_envs: int = 16,
    device: str = "cpu",
    worker: Any = None,
    **settings: Any,
) -> TorchVectorEnv:
    """The batched torch view over ``num_envs`` fields (one row each for a paper task)."""
    # here, not at the top: torch, for the torch views alone
    from hier_ssl.envs.vector import TorchVectorEnv

    settings, worker = _worker_apart(worker, settings)
    return TorchVectorEnv(task_config(config, **settings), num_envs, device, worker=worker)


def manager_env(
    config: str | Path | TaskConfig | None = None,
    render_mode: str | None = None,
    worker: Any = None,
    **settings: Any,
) -> ManagerEnv:
    """A single-agent Gymnasium env of the manager (worker and obstacles scripted)."""
    settings, worker = _worker_apart(worker, settings)
    return ManagerEnv(task_config(config, **settings), render_mode=render_mode, worker=worker)


def manager_vector_env(
    config: str | Path | TaskConfig | None = None,
    num_fields: int = 16,
    worker: Any = None,
    **settings: Any,
) -> ManagerVectorEnv:
    """The batched view as a ``gymnasium.vector.VectorEnv``, numpy in and out, same-step autoreset: one
    row per (field, controlled robot), e.g. ``manager_vector_env(task="proposed", num_fields=8,
    frame_skip=16)`` (``hier_ssl.envs.gym_vector``)."""
    settings, worker = _worker_apart(worker, settings)
    return ManagerVectorEnv(task_config(config, **settings), num_fields, worker=worker)


def scenario_env(
    scenario: str | Path | ScenarioConfig,
    render_mode: str | None = None,
    worker: Any = None,
    **settings: Any,
) -> HierarchicalSSLEnv:
    """The PettingZoo ParallelEnv of a multi-robot scenario (a name, a YAML file or a config), e.g.
    ``scenario_env("crossing", num_agents=4)``: agents ``manager_i`` leave as they finish."""
    settings, worker = _worker_apart(worker, settings)
    config = scenario_config(scenario, **settings)
    return HierarchicalSSLEnv(config, render_mode=render_mode, worker=worker)


def scenario_vector_env(
    scenario: str | Path | ScenarioConfig,
    num_fields: int = 16,
    device: str = "cpu",
    worker: Any = None,
    **settings: Any,
) -> TorchVectorEnv:
    """The batched torch view of a scenario for a shared policy: one row per (field, controlled robot)."""
    # here, not at the top: torch, for the torch views alone
    from hier_ssl.envs.vector import TorchVectorEnv

    settings, worker = _worker_apart(worker, settings)
    return TorchVectorEnv(scenario_config(scenario, **settings), num_fields, device, worker=worker)


def __getattr__(name: str) -> Any:
    if name in _TORCH_VIEWS:  # loaded on first use: they bring torch
        from hier_ssl.envs import vector

        return getattr(vector, name)
    raise AttributeError(f"module 'hier_ssl.envs' has no attribute {name!r}")


__all__ = [
    "SCENARIOS",
    "TASKS",
    "EnvConfig",
    "GameScenario",
    "HierarchicalCore",
    "HierarchicalSSLEnv",
    "ManagerEnv",
    "ManagerVectorEnv",
    "Placement",
    "Policy",
    "RslRlVecEnv",
    "Scenario",
    "ScenarioConfig",
    "StepResult",
    "TorchVectorEnv",
    "TorchView",
    "env",
    "env_config",
    "load_config",
    "make_scenario",
    "manager_env",
    "manager_vector_env",
    "parse_config",
    "parallel_env",
    "play",
    "register_scenario",
    "scenario_config",
    "scenario_env",
    "scenario_vector_env",
    "task_config",
    "vector_env",
]
