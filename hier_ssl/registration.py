"""Gymnasium ids of the single-agent manager tasks, registered when ``hier_ssl`` is imported.

=================================  ================================================================
id                                 environment (``gymnasium.make(id, **settings)``; settings as
                                   ``hier_ssl.manager_env`` takes them: ``frame_skip=16``, ...)
=================================  ================================================================
``hier_ssl/Baseline-v0``           the paper's Baseline task (robot-centric reward)
``hier_ssl/Proposed-v0``           the paper's Proposed task (action-centric reward)
``hier_ssl/Obstacle-v0``           the paper's Obstacle task (one obstacle at the midpoint)
``hier_ssl/Crowd-v0``              the ``crowd`` scenario: one robot across a band of 8 random-walking
                                   obstacles
``hier_ssl/GameStop-v0``           ``game_stop``: one robot of ours against the six opponents
``hier_ssl/GameFreeKick-v0``       ``game_free_kick``: one robot of ours against the six opponents
``hier_ssl/GameBallPlacement-v0``  ``game_ball_placement``: one robot of ours against the six
``hier_ssl/GameMatch-v0``          ``game_match``: one robot of ours against the eleven opponents
=================================  ================================================================

A Gymnasium env has one agent, so only the tasks with one controlled robot have ids: the paper's three
and ``crowd`` (one robot by default). ``crossing`` and ``formation`` are about several robots meeting
(6 each by default); with one robot they are not the scenario any more, so they stay PettingZoo
environments (``hier_ssl.scenario_env``). The game scenarios are about one team among the other: their
ids play one robot of ours (``num_agents=1``) among all the opponents, who mark it and the ball; the
whole team is the PettingZoo environment (``hier_ssl.scenario_env("game_stop")``).

Each id's default settings are the task's own (``frame_skip`` 1 for the paper's tasks, 16 for
``crowd``). One step is one manager decision, so the number of steps before a truncation depends on
``frame_skip``: the made env carries a ``TimeLimit`` of ``ceil(max_steps / frame_skip)`` decisions
(``env.spec.max_episode_steps``: 75 for ``frame_skip=16``), set when it is made, rather than one fixed
number in the registry that would be wrong for every other ``frame_skip``. The env truncates at the
same decision itself.

``worker=`` may be a spec string or a worker object; Gymnasium copies ``make``'s keyword arguments into
``env.spec``, so an object must be deep-copyable (the env runs the object given, not the copy).

``gymnasium.make_vec(id, num_envs=N)`` gives the batched ``hier_ssl.envs.ManagerVectorEnv`` (one core
stepping N fields, same-step autoreset) rather than N copies of the env.

This module imports only gymnasium; the environments are imported when one is made.
"""

from __future__ import annotations

from typing import Any

import gymnasium
from gymnasium.wrappers import TimeLimit

IDS = {
    "hier_ssl/Baseline-v0": "baseline",
    "hier_ssl/Proposed-v0": "proposed",
    "hier_ssl/Obstacle-v0": "obstacle",
    "hier_ssl/Crowd-v0": "crowd",
    "hier_ssl/GameStop-v0": "game_stop",
    "hier_ssl/GameFreeKick-v0": "game_free_kick",
    "hier_ssl/GameBallPlacement-v0": "game_ball_placement",
    "hier_ssl/GameMatch-v0": "game_match",
}
# Settings an id makes its task with besides the task's own defaults: one robot of ours for a game's.
ID_SETTINGS = {env_id: {"num_agents": 1} for env_id, name in IDS.items() if name.startswith("game_")}


def make_env(config: Any = None, render_mode: str | None = None, worker: Any = None, **settings: Any):
    """Entry point of the ids: ``hier_ssl.manager_env(...)`` inside a ``TimeLimit`` of its decisions."""
    # here, not at the top: the environments (pymunk, pettingzoo, pydantic), for a made env alone
    from hier_ssl.envs import manager_env

    env = manager_env(config, render_mode=render_mode, worker=worker, **settings)
    return TimeLimit(env, env.max_episode_steps)


def make_vector_env(num_envs: int, config: Any = None, worker: Any = None, **settings: Any):
    """Vector entry point of the ids: ``hier_ssl.manager_vector_env`` over ``num_envs`` fields, one row
    each (a task with several robots a field has more rows than fields: refused, naming them)."""
    # here, not at the top: the environments (pymunk, pettingzoo, pydantic), for a made env alone
    from hier_ssl.envs import manager_vector_env

    env = manager_vector_env(config, num_envs, worker=worker, **settings)
    if env.num_envs != num_envs:
        raise ValueError(
            f"gymnasium.make_vec: num_envs={num_envs} counts rows, but this task has "
            f"{env.core.num_agents} controlled robots a field; use hier_ssl.manager_vector_env(..., "
            "num_fields=...) for several robots a field"
        )
    return env


def register_envs() -> None:
    """Register ``IDS`` with Gymnasium (again after a reload: an id already there is kept)."""
    for env_id, name in IDS.items():
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(
            env_id,
            entry_point=f"{__name__}:make_env",
            vector_entry_point=f"{__name__}:make_vector_env",
            kwargs={"config": name, **ID_SETTINGS.get(env_id, {})},
        )


__all__ = ["IDS", "ID_SETTINGS", "make_env", "make_vector_env", "register_envs"]
