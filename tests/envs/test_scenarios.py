from __future__ import annotations

import numpy as np
import pytest
import torch
from pettingzoo.test import parallel_api_test, parallel_seed_test

from hier_ssl.config import ConfigError
from hier_ssl.envs import (
    SCENARIOS,
    HierarchicalCore,
    HierarchicalSSLEnv,
    RslRlVecEnv,
    TorchVectorEnv,
    make_scenario,
    scenario_config,
)
from hier_ssl.envs.planners import make_planner
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.manager import HIT_REWARD, SUCCESS_REWARD, encode_subgoal
from hier_ssl.manager.neighbours import (
    NEIGHBOUR_OBS_SLICES,
    as_obstacle_observation,
    neighbour_obs_dim,
    neighbour_obs_slice,
    neighbour_observation,
)


def _build_env(scenario: str = "crossing", **overrides: object) -> HierarchicalSSLEnv:
    return HierarchicalSSLEnv(scenario_config(scenario, **overrides))


def _place(env: HierarchicalSSLEnv, pos: np.ndarray, angle: np.ndarray | None = None) -> None:
    """Put the robots of field 0 at ``pos`` (R, 2), standing still, and their sub-goals on themselves."""
    core, m = env.core, env.config.num_agents
    angle = np.zeros(len(pos)) if angle is None else angle
    core.world.set_state([0], pos[None], angle[None])
    core.subgoal[0, :, 0:2], core.subgoal[0, :, 2] = pos[:m], angle[:m]


def _hold(env: HierarchicalSSLEnv) -> dict[str, np.ndarray]:
    """Actions naming each live robot's current pose as its sub-goal."""
    core = env.core
    pose = np.zeros((env.config.num_agents, 5))
    pose[:, 0:2], pose[:, 2] = core.world.state.pos[0, : len(pose)], core.world.state.angle[0, : len(pose)]
    field = core.field
    actions = encode_subgoal(pose, "pose4", field.half_length, field.half_width)
    return {agent: actions[int(agent.split("_")[1])] for agent in env.agents}


# The SSL game's scenarios pass these tests in test_game_scenarios, at a size that keeps them fast.
SHIPPED = sorted(n for n in SCENARIOS if not SCENARIOS[n].rules_in_observation)


@pytest.mark.parametrize("name", SHIPPED)
def test_pettingzoo_parallel_api(name: str) -> None:
    parallel_api_test(_build_env(name), num_cycles=100)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scenario_configs_build_through_the_entry_point(name: str) -> None:
    import hier_ssl

    env = hier_ssl.scenario_env(f"configs/scenarios/{name}.yaml")
    assert env.config.scenario == name and env.config.action_frame == "target"
    parallel_api_test(env, num_cycles=20)


def test_pettingzoo_seed() -> None:
    parallel_seed_test(lambda: _build_env("formation"), num_cycles=10)


def test_k_nearest_observation_on_hand_made_positions() -> None:
    # The robot at (1, 1) moving at (0.5, 0); three others at distances 2, 0.5 and 1 (in that order).
    others_pos = np.array([[[3.0, 1.0], [1.0, 1.5], [0.0, 1.0]]])
    others_vel = np.array([[[0.0, 0.0], [0.5, 1.0], [-1.0, 0.0]]])
    teammate = np.array([[True, False, True]])
    target = np.array([[2.0, 0.0, 0.0, 0.0, 0.0]])
    args = (target, np.array([[1.0, 1.0]]), np.zeros(1), np.array([[0.5, 0.0]]), np.zeros(1))
    obs = neighbour_observation(*args, others_pos, others_vel, teammate, 4, max_pos=2.0, max_v=2.5)
    assert obs.shape == (1, neighbour_obs_dim(4)) == (1, 37)
    blocks = np.stack([obs[0, neighbour_obs_slice(i)] for i in range(4)])
    # Nearest first: (1, 1.5) an obstacle, then (0, 1) a teammate, then (3, 1) a teammate, then padding.
    # Relative positions / 2 m; relative velocities / 2.5 m/s.
    np.testing.assert_allclose(
        blocks,
        [
            [0.0, 0.25, 0.0, 0.4, 0.0, 1.0],
            [-0.5, 0.0, -0.6, 0.0, 1.0, 1.0],
            [1.0, 0.0, -0.2, 0.0, 1.0, 1.0],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        ],
        atol=1e-7,
    )
    np.testing.assert_array_equal(obs[0, neighbour_obs_slice(0)][NEIGHBOUR_OBS_SLICES["present"]], [1.0])
    # The paper's layout of the same robot: the three neighbours as absolute obstacles, nearest first.
    paper = as_obstacle_observation(obs[:, : neighbour_obs_dim(3)])
    np.testing.assert_allclose(paper[0, 13:15] * 2.0, [1.0, 1.5], atol=1e-6)
    np.testing.assert_allclose(paper[0, 15:17] * 2.5, [0.5, 1.0], atol=1e-6)
    mixed = np.concatenate([obs, obs])
    mixed[1, neighbour_obs_slice(2)] = 0.0  # the second row sees one neighbour less
    with pytest.raises(ValueError, match="same number of present"):
        as_obstacle_observation(mixed)


def test_neighbour_slots_are_clipped_and_count_agnostic() -> None:
    core = HierarchicalSSLEnv(scenario_config("crowd", num_obstacles=2, neighbours=6)).core
    obs = core.reset(seed=0)
    assert obs.shape == (1, 1, 13 + 6 * 6) and np.abs(obs).max() <= 1.2
    present = obs[0, 0, 13:].reshape(6, 6)[:, 5]
    np.testing.assert_array_equal(present, [1, 1, 0, 0, 0, 0])


@pytest.mark.parametrize("success_weight", [1.0, 3.0])
def test_agent_leaves_on_reaching_its_target(success_weight: float) -> None:
    env = _build_env("crossing", num_agents=2, success_weight=success_weight)
    env.reset(seed=0)
    target = env.core.target[0]
    # Robot 0 stands on its target; robot 1 stands far from everything.
    _place(env, np.array([target[0, 0:2], [-target[0, 0], 2.5]]), np.array([target[0, 2], 0.0]))
    actions = _hold(env)
    field = env.core.field
    actions["manager_0"] = encode_subgoal(target[:1], "pose4", field.half_length, field.half_width)[0]
    _, rewards, terms, truncs, infos = env.step(actions)
    assert terms == {"manager_0": True, "manager_1": False} and not any(truncs.values())
    assert infos["manager_0"]["success"] and not infos["manager_0"]["collision"]
    assert infos["manager_0"]["control_steps"] == 1 and infos["manager_0"]["task"]["success"] == 1.0
    # One control step inside the thresholds (+10 +1) plus R_t times its weight.
    assert rewards["manager_0"] == pytest.approx(11.0 + success_weight * SUCCESS_REWARD)
    assert env.agents == ["manager_1"]
    # The robot that left holds still on its target while the other plays on.
    before = env.core.world.state.pos[0, 0].copy()
    _, _, terms, _, _ = env.step(_hold(env))
    assert set(terms) == {"manager_1"}
    np.testing.assert_allclose(env.core.world.state.pos[0, 0], before, atol=1e-9)


def _collide(hit_weight: float) -> tuple[HierarchicalSSLEnv, dict, dict, dict]:
    env = _build_env("crossing", num_agents=3, hit_weight=hit_weight)
    env.reset(seed=0)
    # Robots 0 and 1 within the 0.2 m collision distance (not overlapping), robot 2 far away.
    _place(env, np.array([[0.0, 0.0], [0.19, 0.0], [-3.0, 2.0]]))
    _, rewards, terms, _, infos = env.step(_hold(env))
    return env, rewards, terms, infos


def test_teammate_collision_counts_for_both() -> None:
    env, rewards, terms, infos = _collide(hit_weight=1.0)
    assert terms == {"manager_0": True, "manager_1": True, "manager_2": False}
    for agent in ("manager_0", "manager_1"):
        assert infos[agent]["collision"] and infos[agent]["task"]["collision"] == 1.0
        assert rewards[agent] < HIT_REWARD / 2
    assert env.agents == ["manager_2"]
    # hit_weight scales R_hit alone: the same collision at weight 3 costs two more R_hit.
    _, heavier, _, _ = _collide(hit_weight=3.0)
    for agent in ("manager_0", "manager_1"):
        assert heavier[agent] - rewards[agent] == pytest.approx(2 * HIT_REWARD)
    assert heavier["manager_2"] == pytest.approx(rewards["manager_2"])


def test_target_frame_actions_are_offsets_from_the_target() -> None:
    core = HierarchicalCore(scenario_config("crowd", num_agents=2, action_frame="target"), num_fields=3)
    core.reset(seed=0)
    core.set_subgoal(np.zeros((3, 2, 4)), core.active)  # the zero action: the target itself
    np.testing.assert_allclose(core.subgoal, core.target)
    # x, y offsets are cubed and scaled by the field's half length and width (4.5, 3 m), then kept on the
    # field: 0.5^3 * 4.5 = 0.5625, -1 * 3 = -3. The turn is atan2(1, 1 + -1) = 90 deg.
    core.set_subgoal(np.broadcast_to([0.5, -1.0, 1.0, -1.0], (3, 2, 4)), core.active)
    expected = np.clip(core.target[..., 0:2] + [0.5625, -3.0], [-4.5, -3.0], [4.5, 3.0])
    np.testing.assert_allclose(core.subgoal[..., 0:2], expected)
    np.testing.assert_allclose(np.cos(core.subgoal[..., 2] - core.target[..., 2]), 0.0, atol=1e-12)


def test_same_seed_same_episode() -> None:
    def rollout(seed: int) -> list[np.ndarray]:
        env = _build_env("formation")
        obs, _ = env.reset(seed=seed)
        trace = [np.stack(list(obs.values()))]
        rng = np.random.default_rng(1)
        for _ in range(8):
            if not env.agents:
                break
            obs, rewards, *_ = env.step({a: rng.uniform(-1, 1, 4) for a in env.agents})
            trace += [np.stack(list(obs.values())), np.array(list(rewards.values()))]
        return trace

    first, again, other = rollout(5), rollout(5), rollout(6)
    assert len(first) == len(again)
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    assert not np.array_equal(first[0], other[0])


def test_vector_view_rows_absorb_after_leaving_and_reset_with_their_field() -> None:
    env = TorchVectorEnv(scenario_config("crossing", num_agents=2, max_steps=64), num_fields=2)
    obs = env.reset(seed=0)
    assert obs.shape == (4, env.num_obs) and env.num_envs == 4
    # Field 0: robot 0 stands on its target and names it, robot 1 (which started there) a quarter turn
    # away on the circle; everything holds still.
    core = env.core
    target = core.target[0, 0]
    pos = core.world.state.pos.copy()
    pos[0, 0], pos[0, 1] = target[0:2], [-target[1], target[0]]
    core.world.set_state([0, 1], pos, core.world.state.angle.copy())
    core.subgoal[..., 0:2] = pos[:, :2]
    field = core.field
    hold = encode_subgoal(core.subgoal.reshape(-1, 5), "pose4", field.half_length, field.half_width)
    hold[0] = encode_subgoal(target[None], "pose4", field.half_length, field.half_width)[0]
    actions = torch.as_tensor(hold, dtype=torch.float32)
    obs, reward, terminated, truncated, info = env.step(actions)
    assert terminated.tolist() == [True, False, False, False] and info["live"].all()
    assert info["final_obs"][0].abs().sum() > 0 and obs[0].abs().sum() == 0
    assert info["task"]["success"].tolist() == [1.0]
    # Next step: row 0 is absorbing (zero reward, terminated, not live); the others play on.
    obs, reward, terminated, truncated, info = env.step(actions)
    assert info["live"].tolist() == [False, True, True, True]
    assert terminated[0] and reward[0] == 0 and info["final_obs"][0].abs().sum() == 0
    # At max_steps the rest are truncated and both fields start over: every row is live again.
    for _ in range(2):
        obs, reward, terminated, truncated, info = env.step(actions)
    assert truncated[1:].all() and (obs.abs().sum(dim=1) > 0).all() and core.active.all()


def test_rsl_rl_adapter_accepts_the_vector_view() -> None:
    env = RslRlVecEnv(TorchVectorEnv(scenario_config("formation"), num_fields=2))
    assert env.get_observations()["policy"].shape == (12, 49)
    _, reward, dones, extras = env.step(torch.zeros(12, 4))
    assert reward.shape == dones.shape == extras["time_outs"].shape == (12,)


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_placements_keep_robots_apart_on_the_field(name: str) -> None:
    config = scenario_config(name, num_agents=4, num_obstacles=3)
    scenario = make_scenario(config)
    placement = scenario.reset_world_at(50, np.random.default_rng(0))
    gap = 2 * config.collision_distance
    for points in (placement.pos, placement.target[..., 0:2]):
        d = np.linalg.norm(points[:, :, None] - points[:, None], axis=-1)
        d[:, np.arange(d.shape[1]), np.arange(d.shape[1])] = np.inf
        assert d.min() >= gap
    half = np.array([scenario.field.half_length, scenario.field.half_width])
    assert (np.abs(placement.pos) <= half).all() and (np.abs(placement.target[..., 0:2]) <= half).all()


def test_crossing_targets_are_antipodal() -> None:
    placement = make_scenario(scenario_config("crossing")).reset_world_at(5, np.random.default_rng(0))
    np.testing.assert_allclose(placement.target[..., 0:2], -placement.pos[:, :6])
    np.testing.assert_allclose(np.linalg.norm(placement.pos, axis=-1), 2.5)


def test_config_errors_name_the_key() -> None:
    cases = {
        "scenario.num_agents": {"num_agents": 12},
        "options.radius": {"options": {"radius": 9.0}},
        "options.radiu": {"options": {"radiu": 1.0}},
        "scenario.obstacles": {"obstacles": {"behaviour": "teleport"}},
        "field": {"field": "division_c"},
        "scenario: unknown scenario": {"scenario": "rugby"},
    }
    for key, settings in cases.items():
        with pytest.raises(ConfigError, match=key):
            scenario_config("crossing", **settings)


def test_evaluation_is_seeded_and_direct_crossing_collides() -> None:
    config = scenario_config("crossing", num_agents=4)
    direct = make_planner("direct", config)
    result = evaluate(direct, config, episodes=6, seed=3)
    again = evaluate(direct, config, episodes=6, seed=3)
    np.testing.assert_array_equal(result["per_robot"]["length"], again["per_robot"]["length"])
    # Straight lines through the centre: every robot hits another one.
    assert result["robots"] == 24 and result["collision_rate"] == 1.0
