from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.config import EnvConfig, ObstacleConfig
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.scenario import Placement
from hier_ssl.manager import encode_subgoal, task_reward


def _core(num_fields: int = 8, **settings: object) -> HierarchicalCore:
    return HierarchicalCore(EnvConfig(**settings), num_fields)


def _direct(core: HierarchicalCore) -> np.ndarray:
    """Actions (N, 1, 4) that name the target itself: the trivial planner of an empty field."""
    return encode_subgoal(core.target[:, 0], "pose4", core.field.half_length, core.field.half_width)[:, None]


def test_reset_sampling_respects_spec() -> None:
    core = _core(256)
    core.reset(seed=0)
    s, target = core.state, core.target[:, 0]
    assert np.all(np.abs(target[:, 0]) <= 2.9) and np.all(np.abs(target[:, 1]) <= 1.9)
    assert np.all(np.linalg.norm(s.pos[:, 0] - target[:, :2], axis=1) >= 0.2)
    np.testing.assert_array_equal(target[:, 3:], 0.0)


def test_midpoint_obstacle_starts_between_robot_and_target() -> None:
    core = _core(
        32, task="obstacle", obstacles=[ObstacleConfig(behaviour="stationary")], min_start_distance=0.6
    )
    core.reset(seed=0)
    s = core.state
    np.testing.assert_allclose(s.pos[:, 1], (s.pos[:, 0] + core.target[:, 0, :2]) / 2)


def test_direct_planner_solves_proposed_and_episode_stats_are_reported() -> None:
    core = _core(16, frame_skip=16)
    core.reset(seed=1)
    lengths, successes, cpads = [], [], []
    for _ in range(30):
        result = core.step(_direct(core))
        episode = result.info["task"]
        lengths += list(episode["length"])
        successes += list(episode["success"])
        cpads += list(episode["cpad"])
    assert len(lengths) >= 16
    assert np.mean(successes) == 1.0
    # The sub-goal never moves within an episode, so CPAD is exactly zero.
    assert np.max(cpads) == 0.0
    assert 40 < np.median(lengths) < 150


def test_frame_skip_sum_and_last_rewards() -> None:
    rewards = {}
    for mode in ("sum", "last"):
        core = _core(4, frame_skip=4, frame_skip_reward=mode)
        core.reset(seed=2)
        action = np.tile([0.1, 0.1, 0.0, 1.0], (4, 1, 1))
        rewards[mode] = core.step(action).reward
    # Proposed reward depends only on the held sub-goal, so 4 held steps sum to 4x the last one.
    np.testing.assert_allclose(rewards["sum"], 4 * rewards["last"], rtol=1e-6)


def test_reward_is_the_pure_function_of_the_step() -> None:
    core = _core(4, task="baseline")
    core.reset(seed=3)
    action = np.tile([0.2, -0.3, 0.0, 1.0], (4, 1, 1))
    result = core.step(action)
    s = core.state
    success = result.info["success"][:, 0]
    expected, _ = task_reward(
        "baseline", core.target[:, 0], s.pos[:, 0], s.angle[:, 0], core.subgoal[:, 0], success
    )
    np.testing.assert_allclose(result.reward[:, 0], expected, rtol=1e-6)


def test_same_seed_same_episode_bit_for_bit() -> None:
    def run() -> np.ndarray:
        core = _core(4, task="obstacle", obstacles=[ObstacleConfig()], min_start_distance=0.6, frame_skip=2)
        obs = [core.reset(seed=7)]
        rng = np.random.default_rng(0)
        for _ in range(40):
            obs.append(core.step(rng.uniform(-1, 1, (4, 1, 4))).obs)
        return np.stack(obs)

    np.testing.assert_array_equal(run(), run())


def test_collision_ends_obstacle_episode_as_failure() -> None:
    core = _core(
        8,
        task="obstacle",
        obstacles=[ObstacleConfig(behaviour="stationary")],
        min_start_distance=0.6,
        frame_skip=16,
    )
    core.reset(seed=4)
    collisions = 0
    for _ in range(20):
        result = core.step(_direct(core))
        collisions += int(result.info["task"]["collision"].sum())
        assert not (result.info["success"] & result.info["collision"]).any()
    # Driving straight at a target with a still obstacle on the midpoint always hits it.
    assert collisions >= 8


def _settled_beside_an_obstacle(num_fields: int, rng: np.random.Generator) -> Placement:
    """Each robot at rest on its target (heading 0.3 rad), a still obstacle 0.15 m from it: inside the
    collision distance (0.2 m), so its first control step both reaches the target and hits."""
    pos = np.tile([[0.5, 0.2], [0.65, 0.2]], (num_fields, 1, 1))
    target = np.tile([0.5, 0.2, 0.3, 0.0, 0.0], (num_fields, 1, 1))
    return Placement(pos, np.tile([0.3, 0.0], (num_fields, 1)), target)


def test_a_hit_on_the_step_of_a_success_is_a_collision_in_the_core_and_the_pettingzoo_view() -> None:
    """The paper: hitting an obstacle fails the episode, also on the control step that reaches the target
    (before: a success, paid +1000 and the hit penalty both)."""
    from hier_ssl.envs import parallel_env

    settings = {
        "task": "obstacle",
        "obstacles": [ObstacleConfig(behaviour="stationary")],
        "min_start_distance": 0.6,
        "frame_skip": 16,
    }
    core = _core(2, **settings)
    core.scenario.reset_world_at = _settled_beside_an_obstacle
    core.reset(seed=0)
    result = core.step(_direct(core))
    assert result.info["collision"].all() and not result.info["success"].any()
    assert result.terminated.all() and (result.info["task"]["collision"] == 1).all()
    assert (result.reward < -900).all()  # R_hit without R_t

    env = parallel_env(**settings)
    env.core.scenario.reset_world_at = _settled_beside_an_obstacle
    env.reset(seed=0)
    action = _direct(env.core)[0, 0]
    _, reward, terminated, _, info = env.step({"manager_0": action})
    assert info["manager_0"]["collision"] and not info["manager_0"]["success"]
    assert terminated["manager_0"] and reward["manager_0"] < -900


def test_bad_config_key_names_it() -> None:
    with pytest.raises(ValueError, match="frame_skp"):
        EnvConfig(frame_skp=4)
    with pytest.raises(ValueError, match="frame_skip"):
        EnvConfig(frame_skip=0)


def test_neighbour_observation_and_target_frame_keep_the_planners_results() -> None:
    """The relative ("neighbours") observation and the target action frame change what a manager reads and
    writes, not the task: a planner that reads and writes either gets the same episodes."""
    from hier_ssl.envs import env_config
    from hier_ssl.envs.planners import make_planner
    from hier_ssl.evaluation.evaluate import evaluate

    results = []
    for layout in ({}, {"observation": "neighbours", "neighbours": 2, "action_frame": "target"}):
        config = env_config(task="obstacle", frame_skip=16, **layout)
        result = evaluate(make_planner("sampling", config), config, 40, seed=4)
        results.append((result["success_rate"], result["collision_rate"]))
    assert results[0] == results[1] and results[0][0] > 0.9

    core = HierarchicalCore(env_config(task="obstacle", observation="neighbours", neighbours=2), 3)
    obs, s = core.reset(seed=0), core.state
    assert obs.shape == (3, 1, 13 + 2 * 6) == (3, 1, core.obs_dim)
    obs = obs[:, 0]
    rel = (s.pos[:, 1] - s.pos[:, 0]) / core.field.max_pos
    np.testing.assert_allclose(obs[:, 13:15], rel, atol=1e-6)
    assert obs[:, 17:19].tolist() == [[0.0, 1.0]] * 3  # an obstacle, present
    assert not obs[:, 19:].any()  # the second slot is padding


def test_target_frame_zero_action_drives_to_the_target() -> None:
    core = HierarchicalCore(
        EnvConfig(frame_skip=16, action_frame="target", max_steps=400), 4, autoreset=False
    )
    core.reset(seed=1)
    success = np.zeros(4, dtype=bool)
    while not core.done.all():
        result = core.step(np.zeros((4, 1, 4)))
        success[result.info["task"]["field"]] = result.info["task"]["success"] > 0
    assert success.all() and core.ep_cpad.max() == 0.0  # the direct sub-goal, never moved


def test_starts_in_contact_are_refused_unless_allowed_and_then_end_as_collisions() -> None:
    from hier_ssl.config import ConfigError
    from hier_ssl.envs import parse_config

    public_code = {"task": "obstacle", "obstacles": [{"behaviour": "stationary"}], "min_start_distance": 0.2}
    with pytest.raises(ConfigError, match="env.min_start_distance: .*allow_start_contact"):
        parse_config(public_code, EnvConfig, root="env")
    core = HierarchicalCore(EnvConfig(**public_code, allow_start_contact=True, frame_skip=16), 512)
    core.reset(seed=3)
    gap = np.linalg.norm(core.state.pos[:, 0] - core.state.pos[:, 1], axis=1)
    inside = gap < core.config.collision_distance
    assert 0 < inside.sum() < 64  # about 2 % of uniform starts lie within 0.4 m of their target
    result = core.step(_direct(core))
    # Every episode that began inside the collision distance ended in its first period as a collision.
    assert result.info["collision"][inside, 0].all()
    assert result.terminated[inside, 0].all()


def test_a_scenario_placement_of_the_wrong_shape_is_named_at_reset() -> None:
    """A scenario is a user's class: what its ``reset_world_at`` returns is checked where it enters (the
    core's reset, and ``World.set_state`` for the robots), naming the array; nothing is reset."""
    from hier_ssl.envs import make_scenario

    scenario = make_scenario(EnvConfig(task="obstacle", obstacles=[ObstacleConfig()], min_start_distance=0.6))
    core = HierarchicalCore(scenario, 2)
    core.reset(seed=0)
    before = core.state.pos.copy()
    good = scenario.reset_world_at
    bad = {
        "target": lambda f, rng: Placement(good(f, rng).pos, good(f, rng).angle, np.zeros((f, 5))),
        "pos": lambda f, rng: Placement(np.zeros((f, 1, 2)), np.zeros((f, 2)), np.zeros((f, 1, 5))),
    }
    for name, reset in bad.items():
        scenario.reset_world_at = reset
        with pytest.raises(ValueError, match=f"{name} has shape"):
            core.reset()
        np.testing.assert_array_equal(core.state.pos, before)
