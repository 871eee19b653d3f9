"""The Gymnasium ids, the single-agent view under Gymnasium's and Stable-Baselines3's wrappers, render
modes and frame rates."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from gymnasium.wrappers import HumanRendering, RecordEpisodeStatistics

import hier_ssl
from hier_ssl.envs import ManagerEnv, ManagerVectorEnv
from hier_ssl.registration import ID_SETTINGS, IDS

TASK_KEYS = {"return", "length", "decisions", "success", "collision", "cpad"}


@pytest.mark.filterwarnings("ignore:.*is different from the unwrapped version")  # make's own wrappers
@pytest.mark.parametrize("env_id", sorted(set(IDS) - set(ID_SETTINGS)))  # the games': test_game_scenarios
def test_every_id_makes_an_env_with_its_spec_that_passes_check_env(env_id: str) -> None:
    env = gymnasium.make(env_id, frame_skip=16)
    assert isinstance(env.unwrapped, ManagerEnv) and env.spec.id == env_id
    assert env.spec.kwargs == {"config": IDS[env_id], "frame_skip": 16}
    assert env.spec.max_episode_steps == 75  # 1200 control steps in decisions of 16
    # The render check makes the env again from its spec in every listed mode, "human" too.
    check_env(env, skip_render_check=env_id != "hier_ssl/Proposed-v0")


def test_the_time_limit_follows_frame_skip_and_max_steps() -> None:
    assert gymnasium.make("hier_ssl/Proposed-v0").spec.max_episode_steps == 1200  # frame_skip 1
    assert gymnasium.make("hier_ssl/Crowd-v0").spec.max_episode_steps == 75  # the scenario's 16
    env = gymnasium.make("hier_ssl/Obstacle-v0", frame_skip=16, max_steps=100)
    assert env.spec.max_episode_steps == 7
    env.reset(seed=0)
    away = np.array([0.9, 0.9, 0.0, 1.0])  # a corner: the robot cannot finish before the limit
    steps, truncated = 0, False
    while not truncated:
        _, _, terminated, truncated, info = env.step(away)
        steps += 1
        assert not terminated
    assert steps == 7 and info["task"]["length"] == 100


def test_record_episode_statistics_over_several_episodes() -> None:
    # A CleanRL-style loop: the wrapper's "episode" and the task's statistics side by side.
    env = RecordEpisodeStatistics(gymnasium.make("hier_ssl/Proposed-v0", frame_skip=16, max_steps=320))
    obs, _ = env.reset(seed=0)
    env.action_space.seed(0)
    episodes, total, decisions = 0, 0.0, 0
    while episodes < 4:
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        total, decisions = total + reward, decisions + 1
        if terminated or truncated:
            assert set(info["episode"]) == {"r", "l", "t"} and set(info["task"]) == TASK_KEYS
            assert info["episode"]["l"] == decisions == info["task"]["decisions"]
            np.testing.assert_allclose(info["episode"]["r"], info["task"]["return"], rtol=1e-5)
            np.testing.assert_allclose(info["episode"]["r"], total, rtol=1e-6)
            episodes, total, decisions = episodes + 1, 0.0, 0
            obs, _ = env.reset()
    assert len(env.return_queue) == 4


@pytest.mark.usefixtures("one_thread")
def test_stable_baselines3_sac_trains_on_the_made_env() -> None:
    from stable_baselines3 import SAC
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.monitor import Monitor

    class Ends(BaseCallback):
        """The infos of the steps that ended an episode."""

        def __init__(self) -> None:
            super().__init__()
            self.infos: list[dict] = []

        def _on_step(self) -> bool:
            self.infos += [i for i in self.locals["infos"] if "episode" in i]
            return True

    env = Monitor(gymnasium.make("hier_ssl/Proposed-v0", frame_skip=16, max_steps=480))
    small = {"net_arch": [32, 32]}
    model = SAC(
        "MlpPolicy", env, learning_starts=64, batch_size=64, policy_kwargs=small, seed=0, device="cpu"
    )
    ends = Ends()
    model.learn(total_timesteps=300, callback=ends)
    assert model.num_timesteps == 300 and len(ends.infos) >= 10  # 30 decisions an episode at most
    for info in ends.infos:  # Monitor's episode beside the task's statistics, success and CPAD kept
        assert set(info["episode"]) == {"r", "l", "t"} and set(info["task"]) == TASK_KEYS
        assert info["episode"]["l"] == info["task"]["decisions"]
        np.testing.assert_allclose(info["episode"]["r"], info["task"]["return"], rtol=1e-5, atol=1e-3)
    assert len(env.get_episode_rewards()) == len(ends.infos)


def test_render_modes_are_those_the_metadata_lists() -> None:
    assert ManagerEnv.metadata["render_modes"] == ["human", "rgb_array"]
    with pytest.raises(ValueError, match=r"render_mode 'ansi' is not one of \['human', 'rgb_array'\]"):
        hier_ssl.manager_env(task="proposed", render_mode="ansi")
    human = gymnasium.make("hier_ssl/Proposed-v0", render_mode="human")
    assert human.unwrapped.render_mode == "human"  # drawn natively: no HumanRendering wrapper
    assert not any(isinstance(w, HumanRendering) for w in _wrappers(human))
    human.close()
    env = gymnasium.make("hier_ssl/Obstacle-v0", render_mode="rgb_array", frame_skip=16)
    env.reset(seed=0)
    frame = env.render()
    assert frame.ndim == 3 and frame.dtype == np.uint8


def _wrappers(env: gymnasium.Env) -> list[gymnasium.Env]:
    chain = [env]
    while isinstance(chain[-1], gymnasium.Wrapper):
        chain.append(chain[-1].env)
    return chain


def test_render_fps_is_one_frame_per_step() -> None:
    assert hier_ssl.parallel_env(task="proposed", frame_skip=16).metadata["render_fps"] == 2.5
    assert hier_ssl.parallel_env(task="proposed").metadata["render_fps"] == 40.0
    # With exposed agents one step is one 25 ms control step, whatever the decision period.
    exposed = hier_ssl.parallel_env(task="obstacle", frame_skip=16, expose_worker=True)
    assert exposed.metadata["render_fps"] == 40.0
    assert hier_ssl.manager_env(task="proposed", frame_skip=8).metadata["render_fps"] == 5.0
    assert gymnasium.make("hier_ssl/Crowd-v0").metadata["render_fps"] == 2.5


def test_make_vec_gives_the_batched_view() -> None:
    envs = gymnasium.make_vec("hier_ssl/Obstacle-v0", num_envs=3, frame_skip=16)
    assert isinstance(envs, ManagerVectorEnv) and envs.num_envs == 3
    assert envs.spec.id == "hier_ssl/Obstacle-v0" and envs.single_observation_space.shape == (18,)
    with pytest.raises(ValueError, match=r"num_envs=2 counts rows, but this task has 3 controlled robots"):
        gymnasium.make_vec("hier_ssl/Crowd-v0", num_envs=2, num_agents=3)
