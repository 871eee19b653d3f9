"""Where configs enter: task and scenario classes by name, their defaults, and the checks that need the
registries (fields, workers, obstacle behaviours, scenario options) with errors naming the key path.

``hier_ssl.config`` is data: pydantic models checking types and ranges. ``parse_config`` here is the one
place a config becomes usable: it fills in the defaults of the task or scenario class a section names,
validates the models, then checks what only the registries know (``field: unknown preset 'moon'``,
``scenario.options.radius: ...``), so a bad config fails before anything is built or written.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pydantic import ValidationError

from hier_ssl.config import (
    ConfigError,
    EnvConfig,
    ScenarioConfig,
    TaskConfig,
    TrainConfig,
    UnknownSettingError,
    did_you_mean,
    error_message,
    validate_config,
)
from hier_ssl.config.files import apply_overrides, find_config, load_yaml
from hier_ssl.envs.scenario import Scenario
from hier_ssl.envs.scenarios import SCENARIOS, FieldScenario
from hier_ssl.envs.tasks import TASKS
from hier_ssl.worker import check_worker_spec
from hier_ssl.world.field import FIELDS
from hier_ssl.world.obstacles import OBSTACLES, make_obstacle


def register_scenario(cls: type[FieldScenario]) -> type[FieldScenario]:
    """Make the multi-robot scenario class ``cls`` known by its ``name`` to configs (``scenario: name``),
    as the shipped ones are; usable as a class decorator. A name already taken is a ValueError."""
    if cls.name in SCENARIOS:
        taken = SCENARIOS[cls.name].__qualname__
        raise ValueError(f"scenario {cls.name!r} is already registered (by {taken})")
    SCENARIOS[cls.name] = cls
    return cls


def make_scenario(config: TaskConfig) -> Scenario:
    """The task (``EnvConfig``) or scenario (``ScenarioConfig``) object ``config`` describes."""
    if isinstance(config, EnvConfig):
        return TASKS[config.task](config)
    return SCENARIOS[config.scenario](config)


def _registry(model: type) -> tuple[str, str, dict[str, type[Scenario]]]:
    """(key naming the class, its default, the classes) of a task section's model."""
    if model is EnvConfig:
        return "task", "proposed", TASKS
    return "scenario", "", SCENARIOS


def with_defaults(data: dict[str, Any], model: type, root: str) -> dict[str, Any]:
    """``data`` (a task section) with the keys it leaves out taken from the ``defaults`` of the class it
    names; a ConfigError names the key when the class is unknown."""
    key, default, classes = _registry(model)
    name = data.get(key, default)
    if not isinstance(name, str) or name not in classes:
        path = ".".join(p for p in (root, key) if p)
        raise ConfigError(f"{path}: unknown {key} {name!r}; known: {sorted(classes)}")
    return {**classes[name].defaults, **data}


def _check_obstacle(behaviour: str, options: dict[str, Any], key: str) -> None:
    if behaviour not in OBSTACLES:
        raise ValueError(
            f"{key}.behaviour: unknown obstacle behaviour {behaviour!r}; known: {sorted(OBSTACLES)}"
        )
    try:
        make_obstacle(behaviour, 1, **options)
    except ValueError as err:
        raise ValueError(f"{key}.options: {err}") from None


def check_task(config: TaskConfig) -> None:
    """What the models cannot check alone: the field, worker and obstacle behaviours are known, and the
    task or scenario class accepts the config (its options, and that its placement fits the field). A
    ValueError's message starts with the key, relative to the section ("field: unknown preset ...")."""
    if config.field not in FIELDS:
        raise ValueError(f"field: unknown preset {config.field!r}; known: {sorted(FIELDS)}")
    try:
        check_worker_spec(config.worker)
    except ValueError as err:
        raise ValueError(f"worker: {err}") from None
    if isinstance(config, EnvConfig):
        for i, obstacle in enumerate(config.obstacles):
            _check_obstacle(obstacle.behaviour, obstacle.options, f"obstacles.{i}")
    else:
        _check_obstacle(config.obstacles.behaviour, config.obstacles.options, "obstacles")
    try:
        make_scenario(config)
    except ValidationError as err:  # the class's own Options model
        first = err.errors()[0]
        key = ".".join(str(p) for p in ("options", *first["loc"]))
        raise ValueError(f"{key}: {error_message(first)}") from None


def _checked(config: TaskConfig, root: str) -> TaskConfig:
    try:
        check_task(config)
    except ValueError as err:
        raise ConfigError(".".join(p for p in (root, str(err)) if p)) from None
    return config


def parse_config(data: dict[str, Any], model: type = TrainConfig, root: str = "") -> Any:
    """Validate a plain dict into ``model`` (``TrainConfig``, ``EnvConfig`` or ``ScenarioConfig``):
    class defaults filled in, then the models, then ``check_task`` on the task section. Raises a
    ConfigError naming the first bad key's full path; never mutates ``data``."""
    if model is TrainConfig:
        data = dict(data)
        for key, section in (("env", EnvConfig), ("scenario", ScenarioConfig)):
            if isinstance(data.get(key), dict):
                data[key] = with_defaults(data[key], section, key)
        config = validate_config(data, model, root)
        _checked(config.task_config, config.task_section)
        return config
    config = validate_config(with_defaults(data, model, root), model, root)
    return _checked(config, root)


def load_config(path: str | Path, overrides: Sequence[str] = ()) -> TrainConfig:
    """A TrainConfig from a YAML file with optional ``key=value`` overrides."""
    return parse_config(apply_overrides(load_yaml(path), list(overrides)))


def _check_settings(settings: dict[str, Any], model: type[TaskConfig], root: str) -> None:
    """Keyword settings must be keys of the task section: an UnknownSettingError (a TypeError) names the
    first that is not, in the words Python uses for an unexpected keyword argument."""
    for key in settings:
        if key not in model.model_fields:
            hint = did_you_mean(model, key)
            raise UnknownSettingError(f"{root}: got an unexpected keyword argument {key!r}{hint}")


def _task_overrides(overrides: Sequence[str]) -> list[str]:
    """``--set`` items for a task section: a key spelt as in a training config (``env.frame_skip``,
    ``scenario.num_agents``) loses its section, so every command takes the spelling ``train`` takes."""
    out = []
    for item in overrides:
        section, dot, rest = item.partition(".")
        out.append(rest if dot and section in ("env", "scenario") and "=" not in section else item)
    return out


def env_config(config: str | Path | EnvConfig | None = None, **settings: Any) -> EnvConfig:
    """An EnvConfig from a YAML file (its ``env`` section if it is a training config), an EnvConfig, or
    keyword settings; settings override what the file gives. Naming another task than the file's starts
    from that task's defaults: ``env_config(run_env, task="obstacle")`` gets the Obstacle task's obstacle."""
    _check_settings(settings, EnvConfig, "env")
    if isinstance(config, EnvConfig):
        data = config.model_dump()
    elif config is not None:
        data = load_yaml(config)
        data = data["env"] if isinstance(data.get("env"), dict) else data
    else:
        data = {}
    task = settings.get("task", data.get("task", "proposed"))
    if task != data.get("task", "proposed") and task in TASKS:
        data = {k: v for k, v in data.items() if k not in TASKS[task].defaults}
    return parse_config({**data, **settings}, EnvConfig, root="env")


def _config_file(spec: str | Path) -> Path:
    """The YAML file ``spec`` names (a path or a shipped config's name); a ConfigError lists what a task
    or scenario may be named when it is neither."""
    try:
        return find_config(spec)
    except ConfigError:
        if str(spec).endswith((".yaml", ".yml")):
            raise
        known = sorted(SCENARIOS)
        raise ConfigError(
            f"scenario: unknown scenario {str(spec)!r}; known: {known}, a task {sorted(TASKS)} or a YAML file"
        ) from None


def scenario_config(
    config: str | Path | ScenarioConfig | None = None, overrides: Sequence[str] = (), **settings: Any
) -> ScenarioConfig:
    """A ScenarioConfig from a registered name, a YAML file (a scenario, or a training config's
    ``scenario`` section) or a config; ``settings`` and then ``overrides`` (``key.sub=value`` strings, as
    ``--set`` takes them) override its keys. One that names another scenario starts from that scenario's
    defaults, not from ``config``'s keys.

    ``scenario_config("crossing", num_agents=4)``; ``scenario_config("configs/scenarios/crowd.yaml")``.
    Errors are ConfigErrors naming the key (``scenario.options.radius: ...``).
    """
    _check_settings(settings, ScenarioConfig, "scenario")
    overrides = _task_overrides(overrides)
    if isinstance(config, ScenarioConfig):
        data = config.model_dump(exclude_unset=True)
    elif isinstance(config, str) and config in SCENARIOS:
        data = {"scenario": config}
    elif config is not None:
        data = load_yaml(_config_file(config))
        if isinstance(data.get("scenario"), dict):  # a training config: its scenario section
            data = data["scenario"]
    else:
        data = {}
    merged = apply_overrides({**data, **settings}, list(overrides))
    if "scenario" in data and merged.get("scenario") != data["scenario"]:
        merged = apply_overrides(dict(settings), list(overrides))
    return parse_config(merged, ScenarioConfig, root="scenario")


def task_config(
    spec: str | Path | TaskConfig | None = None, overrides: Sequence[str] = (), **settings: Any
) -> TaskConfig:
    """A task's config from a paper task's name ("obstacle"), a scenario's name ("crossing"), a YAML file
    (a training config, whose ``scenario`` or ``env`` section is read, or a section alone), a config, or
    nothing (the default paper task); ``settings`` and then ``key=value`` ``overrides`` change its keys.
    What ``parallel_env``, ``hier-ssl render`` and ``eval --scenario`` take."""
    if isinstance(spec, ScenarioConfig) or (isinstance(spec, str) and spec in SCENARIOS):
        return scenario_config(spec, overrides, **settings)
    if isinstance(spec, str) and spec in TASKS:
        spec, settings = None, {"task": spec, **settings}
    elif isinstance(spec, (str, Path)):
        spec = _config_file(spec)
        if "scenario" in load_yaml(spec):
            return scenario_config(spec, overrides, **settings)
    _check_settings(settings, EnvConfig, "env")
    keys = apply_overrides({}, _task_overrides(overrides))
    for key in keys:  # --set items, not keyword arguments: a ConfigError in a config's words
        if key not in EnvConfig.model_fields:
            raise ConfigError(f"env.{key}: not a key of the task{did_you_mean(EnvConfig, key)}")
    settings = {**settings, **keys}
    return env_config(spec, **settings)


__all__ = [
    "check_task",
    "env_config",
    "load_config",
    "make_scenario",
    "parse_config",
    "register_scenario",
    "scenario_config",
    "task_config",
    "with_defaults",
]
