"""Configs as data: the typed models (``schema``), the learners' sections (``learners``), the shipped
config files with YAML and ``--set`` overrides (``files``), and how a launch runs its jobs
(``launch_options``).

Nothing here imports the rest of the package. This package exports the models of ``schema``; the
modules beside it are imported by name.
"""

from __future__ import annotations

from hier_ssl.config.schema import (
    BehaviourConfig,
    ConfigError,
    EnvConfig,
    GoToPointConfig,
    ObstacleConfig,
    ScenarioConfig,
    Strict,
    TaskConfig,
    TaskSettings,
    TrainConfig,
    UnknownSettingError,
    did_you_mean,
    dump_config,
    error_message,
    validate_config,
)

__all__ = [
    "BehaviourConfig",
    "ConfigError",
    "EnvConfig",
    "GoToPointConfig",
    "ObstacleConfig",
    "ScenarioConfig",
    "Strict",
    "TaskConfig",
    "TaskSettings",
    "TrainConfig",
    "UnknownSettingError",
    "did_you_mean",
    "dump_config",
    "error_message",
    "validate_config",
]
