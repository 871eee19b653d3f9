"""The scripted managers with their worker: ``make_planner`` resolves the worker a sampling planner rolls
out with and a trajectory planner reads the limits of (a spec, a worker object, class or factory, or the
one the config names) and hands it to ``hier_ssl.manager.planners.build_planner``, so the manager layer
never builds a worker itself."""

from __future__ import annotations

from hier_ssl.config import ScenarioConfig, TaskSettings
from hier_ssl.envs.scenarios import SCENARIOS
from hier_ssl.manager.game_observation import RuledPlanner
from hier_ssl.manager.planners import DirectPlanner, SamplingPlanner, TrajectoryPlanner, build_planner
from hier_ssl.worker import resolve_worker
from hier_ssl.world.physics import RobotSpec


def make_planner(
    name: str, config: TaskSettings, worker: object = None, **options: object
) -> DirectPlanner | SamplingPlanner | TrajectoryPlanner | RuledPlanner:
    """The scripted manager ``name`` ("direct", "sampling" or "trajectory") for environments built from
    ``config``, driven by ``worker`` (a spec, or an object, class or factory of the worker protocol) where
    given, else by the worker ``config`` names. The direct planner reads no worker, so none is built for
    it. ``options`` override planner settings (e.g. ``margin=0.1``). For a scenario whose observation
    carries the rules (the game's), the planner reads them there and plans under them (``RuledPlanner``)."""
    ready = None
    if name in ("sampling", "trajectory"):
        ready = resolve_worker(config.worker if worker is None else worker, RobotSpec(), config.dt)
    planner = build_planner(name, config, ready, **options)
    scenario = SCENARIOS.get(config.scenario) if isinstance(config, ScenarioConfig) else None
    if scenario is None or not scenario.rules_in_observation:
        return planner
    return RuledPlanner(planner, planner.max_pos or planner.field.max_pos, RobotSpec().max_speed)


__all__ = ["make_planner"]
