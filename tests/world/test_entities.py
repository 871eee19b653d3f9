"""A world's entities by kind: groups take consecutive rows of their kind's state, a scenario adds its
robots in groups (controlled first, then each obstacle group), and more entities of a kind the world
simulates are a larger count, not a change to the world."""

from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.config import EnvConfig, ObstacleConfig
from hier_ssl.envs import HierarchicalCore, make_scenario, scenario_config
from hier_ssl.world import Entities, World


def test_groups_take_consecutive_rows_of_their_kind() -> None:
    entities = Entities()
    first, second = entities.add("robot", 2, "controlled"), entities.add("robot", 3, "obstacles")
    assert (first.rows, second.rows) == (slice(0, 2), slice(2, 5))
    assert entities.count("robot") == 5 and [g.name for g in entities.of("robot")] == [
        "controlled",
        "obstacles",
    ]
    assert entities.add("ball", 1, "ball").rows == slice(0, 1) and entities.count("ball") == 1
    with pytest.raises(ValueError, match="unknown entity kind 'goal'"):
        entities.add("goal", 1, "goals")
    with pytest.raises(ValueError, match="count of 'some' must be an integer >= 0"):
        entities.add("robot", -1, "some")


def test_a_world_of_entities_is_the_world_of_as_many_robots() -> None:
    entities = Entities()
    entities.add("robot", 1, "controlled")
    entities.add("robot", 2, "obstacles")
    grouped, counted = World(3, entities), World(3, 3)
    assert grouped.num_robots == counted.num_robots == 3
    assert grouped.states["robot"] is grouped.state and grouped.state.pos.shape == (3, 3, 2)
    pos = np.random.default_rng(0).uniform(-1, 1, (3, 3, 2))
    command = np.tile([0.5, -0.2, 1.0], (3, 3, 1))
    for world in (grouped, counted):
        world.set_state(np.arange(3), pos, np.zeros((3, 3)))
        world.step(command)
    np.testing.assert_array_equal(grouped.state.pos, counted.state.pos)
    with pytest.raises(ValueError, match="at least one robot"):
        World(1, Entities())


def test_a_scenario_adds_its_robots_in_groups_and_the_core_moves_each_obstacle_group_by_its_rows() -> None:
    config = EnvConfig(
        task="obstacle",
        obstacles=[ObstacleConfig(behaviour="stationary"), ObstacleConfig(behaviour="random_walk")],
        min_start_distance=0.6,
    )
    core = HierarchicalCore(config, 2)
    groups = core.world.entities.of("robot")
    assert [g.rows for g in groups] == [slice(0, 1), slice(1, 2), slice(2, 3)]
    assert [g.name for g in groups] == ["controlled", "obstacles 0: stationary", "obstacles 1: random_walk"]
    assert [rows for _, rows in core.obstacles] == [slice(1, 2), slice(2, 3)]
    crowd = make_scenario(scenario_config("crowd", num_agents=3, num_obstacles=5)).make_world(4)
    assert [g.count for g in crowd.entities.of("robot")] == [3, 5] and crowd.state.pos.shape == (4, 8, 2)
