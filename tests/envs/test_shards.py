"""N fields on K cores (``hier_ssl.envs.shards``): the same results for every K, shards that are cores of
their own fields, and no worker process left behind."""

from __future__ import annotations

import multiprocessing

import numpy as np
import pytest
import torch

import hier_ssl
from hier_ssl.envs import HierarchicalCore, ShardedCore, batched_core, play, shards, task_config
from hier_ssl.envs.shards import resolve_threads, shard_seeds
from hier_ssl.world.blocks import block_bounds, block_groups


@pytest.fixture(autouse=True)
def one_block_shards(monkeypatch: pytest.MonkeyPatch) -> None:
    """Shards of one block (64 fields), so that a few hundred fields make several shards; the shipped
    four-block shards are tested alone below."""
    monkeypatch.setattr(shards, "SHARD_BLOCKS", 1)


def _trajectory(env, steps: int, seed: int = 3) -> list[list[np.ndarray]]:
    """Everything ``steps`` seeded random steps of a torch vector view give, as numpy arrays."""
    generator = torch.Generator().manual_seed(5)
    out = [[env.reset(seed=seed).numpy(), env.core.state.pos]]
    for _ in range(steps):
        action = torch.rand(env.num_envs, env.num_actions, generator=generator) * 2 - 1
        obs, reward, terminated, truncated, info = env.step(action)
        stats = [value.numpy() for value in info["task"].values()]
        out.append([t.numpy() for t in (obs, reward, terminated, truncated, info["final_obs"])] + stats)
        out[-1] += [env.core.state.pos, env.core.state.vel, info["live"].numpy()]
    env.close()
    return out


@pytest.mark.parametrize(
    "make",
    [
        # A paper task over three shards, episodes ending and resetting inside the run.
        lambda k: hier_ssl.vector_env(task="obstacle", num_envs=130, frame_skip=4, max_steps=40, threads=k),
        # A scenario (6 + 6 robots a field, contacts between them) over two shards.
        lambda k: hier_ssl.scenario_vector_env(
            "formation", num_fields=70, frame_skip=4, max_steps=48, threads=k
        ),
        # A game (6 v 6, the ball, the referee, the opponents' planners) over two shards.
        lambda k: hier_ssl.scenario_vector_env(
            "game_stop", num_fields=70, frame_skip=4, max_steps=48, threads=k
        ),
    ],
    ids=["obstacle", "formation", "game_stop"],
)
def test_one_and_two_cores_give_identical_trajectories(make) -> None:
    one, two = make(1), make(2)
    assert isinstance(one.core, ShardedCore) and (one.core.threads, two.core.threads) == (1, 2)
    first, second = _trajectory(one, 14), _trajectory(two, 14)
    ended = sum(len(step[5]) for step in first[1:])
    assert ended > 0  # episodes ended, were counted and reset on both
    for a, b in zip(first, second, strict=True):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            assert x.dtype == y.dtype and np.array_equal(x, y)


def test_each_shard_is_a_core_of_its_own_fields_with_its_own_seed() -> None:
    config = task_config("obstacle", frame_skip=4)
    sharded = ShardedCore(config, 100, threads=1)
    bounds = block_bounds(100)
    assert len(bounds) == 2 and len(sharded.local_cores) == 2
    action = np.random.default_rng(0).uniform(-1, 1, (100, 1, sharded.act_dim))
    obs, result = sharded.reset(7), sharded.step(action)
    for (a, b), seed in zip(bounds, shard_seeds(7, 2), strict=True):
        core = HierarchicalCore(config, b - a)
        np.testing.assert_array_equal(core.reset(seed), obs[a:b])
        alone = core.step(action[a:b])
        np.testing.assert_array_equal(alone.obs, result.obs[a:b])
        np.testing.assert_array_equal(alone.reward, result.reward[a:b])
        np.testing.assert_array_equal(core.state.pos, sharded.state.pos[a:b])


def test_fields_within_one_block_are_one_core_as_ever() -> None:
    config = task_config("proposed", frame_skip=4)
    core = batched_core(config, 64, threads=2)
    assert type(core) is HierarchicalCore
    assert shard_seeds(11, 1) == [11] and shard_seeds(None, 3) == [None] * 3
    seeds = shard_seeds(11, 3)
    assert len(set(seeds)) == 3 and seeds == shard_seeds(11, 3)


def test_play_ends_alike_on_one_and_two_cores() -> None:
    # Without auto-reset a shard whose episodes have all ended waits for the others.
    config = task_config("obstacle", frame_skip=16, max_steps=160)
    cores = [ShardedCore(config, 100, autoreset=False, threads=k) for k in (1, 2)]

    def policy(obs: np.ndarray) -> np.ndarray:  # deterministic, of the observation alone
        return np.tanh(3.0 * obs[:, :4])

    first, second = (play(core, policy, seed=4) for core in cores)
    for core in cores:
        core.close()
    assert first["length"].min() < first["length"].max()  # shards finished at different decisions
    for key in ("length", "success", "collision", "cpad", "cpad_public", "distance", "start_gap"):
        np.testing.assert_array_equal(first[key], second[key])


def test_close_leaves_no_worker_process() -> None:
    env = hier_ssl.vector_env(task="proposed", num_envs=200, threads=3)
    workers = list(env.core._processes)
    assert len(workers) == 2 and all(w.is_alive() for w in workers)
    env.reset(seed=0)
    env.step(torch.zeros(env.num_envs, env.num_actions))
    env.close()
    assert not any(w.is_alive() for w in workers)
    assert not multiprocessing.active_children()
    env.close()  # again: nothing to do


def test_threads_are_checked_and_auto_is_this_process_cores() -> None:
    assert resolve_threads("auto") >= 1 and resolve_threads(3) == 3
    for bad in (0, -2, "two", 1.5, True):
        with pytest.raises(ValueError, match="threads must be an integer >= 1 or 'auto', got"):
            resolve_threads(bad)
    with pytest.raises(ValueError, match="got 0"):
        hier_ssl.vector_env(task="proposed", num_envs=4, threads=0)


def test_a_finished_sharded_core_asks_for_a_reset() -> None:
    core = ShardedCore(task_config("proposed"), 70, autoreset=False)
    with pytest.raises(RuntimeError, match="call reset"):
        core.step(np.zeros((70, 1, core.act_dim)))


def test_a_command_that_fails_part_way_leaves_the_core_refusing_all_but_close() -> None:
    core = ShardedCore(task_config("proposed"), 130, threads=2)
    core.reset(seed=0)
    action = np.zeros((130, 1, core.act_dim))
    run = core._lane.run

    def fails(*args: object) -> None:  # this process's shards fail after the worker's have stepped
        raise OSError("lost")

    core._lane.run = fails
    with pytest.raises(OSError, match="lost"):
        core.step(action)
    core._lane.run = run
    with pytest.raises(RuntimeError, match=r"a 'step' failed part-way; close\(\) this core"):
        core.step(action)
    with pytest.raises(RuntimeError, match="failed part-way"):
        core.reset(seed=0)
    core.close()
    assert not multiprocessing.active_children()


def test_the_gymnasium_vector_view_steps_alike_and_closes_its_workers() -> None:
    envs = [
        hier_ssl.manager_vector_env(task="proposed", num_fields=70, frame_skip=4, threads=k) for k in (1, 2)
    ]
    action = np.random.default_rng(2).uniform(-1, 1, (70, envs[0].single_action_space.shape[0]))
    results = [(env.reset(seed=9)[0], *env.step(action)[:4]) for env in envs]
    for x, y in zip(*results, strict=True):
        np.testing.assert_array_equal(x, y)
    workers = list(envs[1].core._processes)
    for env in envs:
        env.close()
    assert workers and not any(w.is_alive() for w in workers)


def test_the_shipped_shards_are_four_blocks(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(shards, "SHARD_BLOCKS", 4)
    assert block_groups(1024, 4) == [(0, 256), (256, 512), (512, 768), (768, 1024)]
    assert block_groups(300, 4) == [(0, 240), (240, 300)]  # 5 blocks of 60: four, then one
    assert isinstance(batched_core(task_config("proposed"), 256, threads=2), HierarchicalCore)
    core = batched_core(task_config("proposed"), 257, threads=1)
    assert isinstance(core, ShardedCore) and core._bounds == block_groups(257, 4)
    core.close()
