"""The scripted managers with their worker: ``make_planner`` resolves the worker a sampling planner rolls
out with and a trajectory planner reads the limits of (a spec, a worker object, class or factory, or the
one the config names) and hands it to ``hier_ssl.manager.planners.build_planner``, so the manager layer
never builds a worker itself. A planner is named alone ("sampling") or with settings of its own,
``"sampling+trapped=brake+margin=0.1"`` (``planner_spec``), as the command line names them."""

from __future__ import annotations

import dataclasses
import math

from hier_ssl.config import ScenarioConfig, TaskSettings
from hier_ssl.envs.scenarios import SCENARIOS
from hier_ssl.manager.game_observation import RuledPlanner
from hier_ssl.manager.planners import (
    PLANNERS,
    DirectPlanner,
    SamplingPlanner,
    TrajectoryParams,
    TrajectoryPlanner,
    build_planner,
)
from hier_ssl.worker import resolve_worker
from hier_ssl.world.physics import RobotSpec

# The planners' settings a spec can spell (a number or a word), less those ``build_planner`` sets itself.
_SETTINGS = {
    "direct": (DirectPlanner,),
    "sampling": (SamplingPlanner,),
    "trajectory": (TrajectoryPlanner, TrajectoryParams),
}
_SET_BY_BUILD = {"action_form", "observation", "action_frame", "max_v"}


def _settings(name: str) -> dict[str, object]:
    """The settings (name: default) a spec may give the planner ``name``."""
    return {
        f.name: f.default
        for cls in _SETTINGS[name]
        for f in dataclasses.fields(cls)
        if f.name not in _SET_BY_BUILD and (f.default is None or type(f.default) in (int, float, str))
    }


def is_planner(spec: object) -> bool:
    """Whether ``spec`` (a string or a path) names a planner, alone or with settings (``planner_spec``)."""
    return str(spec).split("+", 1)[0] in PLANNERS


def planner_spec(spec: str) -> tuple[str, dict[str, object]]:
    """Split ``"sampling+trapped=brake+margin=0.1"`` into the planner's name and its settings, each a number
    where its default is one. ValueError naming the bad part: an unknown planner or setting, a part that is
    not key=value, a setting given twice, a word or NaN for a number."""
    name, *parts = str(spec).split("+")
    if name not in PLANNERS:
        raise ValueError(f"unknown planner {name!r} in {spec!r}; known: {list(PLANNERS)}")
    known, options = _settings(name), {}
    for part in parts:
        key, eq, value = part.partition("=")
        if not eq:
            raise ValueError(f"planner {spec!r}: expected key=value after '+', got {part!r}")
        if key not in known:
            raise ValueError(f"planner {spec!r}: {name} has no setting {key!r}; known: {sorted(known)}")
        if key in options:
            raise ValueError(f"planner {spec!r}: {key} given twice")
        kind = str if isinstance(known[key], str) else float if known[key] is None else type(known[key])
        try:
            options[key] = kind(value)
        except ValueError:
            options[key] = None
        if options[key] is None or kind is not str and not math.isfinite(options[key]):
            what = "a whole number" if kind is int else "a finite number"
            raise ValueError(f"planner {spec!r}: {key} must be {what}, got {value!r}")
    return name, options


def make_planner(
    name: str, config: TaskSettings, worker: object = None, **options: object
) -> DirectPlanner | SamplingPlanner | TrajectoryPlanner | RuledPlanner:
    """The scripted manager ``name`` ("direct", "sampling" or "trajectory", or a spec with settings of its
    own: ``planner_spec``) for environments built from ``config``, driven by ``worker`` (a spec, or an
    object, class or factory of the worker protocol) where given, else by the worker ``config`` names. The
    direct planner reads no worker, so none is built for it. ``options`` override planner settings (e.g.
    ``margin=0.1``). For a scenario whose observation carries the rules (the game's), the planner reads
    them there and plans under them (``RuledPlanner``)."""
    name, given = planner_spec(name)
    options = {**given, **options}
    ready = None
    if name in ("sampling", "trajectory"):
        ready = resolve_worker(config.worker if worker is None else worker, RobotSpec(), config.dt)
    planner = build_planner(name, config, ready, **options)
    scenario = SCENARIOS.get(config.scenario) if isinstance(config, ScenarioConfig) else None
    if scenario is None or not scenario.rules_in_observation:
        return planner
    return RuledPlanner(planner, planner.max_pos or planner.field.max_pos, RobotSpec().max_speed)


__all__ = ["is_planner", "make_planner", "planner_spec"]
