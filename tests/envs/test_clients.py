"""The envs under the clients people run them with, each on a budget of seconds: pickling round trips
(pickle, cloudpickle, ``copy.deepcopy``) that then step as the original does, SuperSuit's PettingZoo to
SB3 pipeline, TorchRL's Gymnasium and PettingZoo wrappers, and SB3's ``SubprocVecEnv`` making an id by
its ``hier_ssl:`` form. The clients are ``test`` extras."""

from __future__ import annotations

import copy
import pickle
from collections.abc import Callable
from typing import Any

import cloudpickle
import gymnasium
import numpy as np
import pytest
import torch

import hier_ssl
from hier_ssl.envs import SCENARIOS
from hier_ssl.registration import IDS

COPIES: dict[str, Callable[[Any], Any]] = {
    "pickle": lambda env: pickle.loads(pickle.dumps(env)),
    "cloudpickle": lambda env: cloudpickle.loads(cloudpickle.dumps(env)),
    "deepcopy": copy.deepcopy,
}


def _gym_step(env: gymnasium.Env, rng: np.random.Generator) -> Callable[[Any], tuple]:
    action = rng.uniform(-1, 1, env.action_space.shape).astype(np.float32)
    return lambda target: target.step(action)


def _torch_step(env: Any, rng: np.random.Generator) -> Callable[[Any], tuple]:
    action = rng.uniform(-1, 1, (env.num_envs, *env.single_action_space.shape))
    return lambda target: target.step(torch.as_tensor(action, dtype=torch.float32))


def _parallel_step(env: Any, rng: np.random.Generator) -> Callable[[Any], tuple]:
    actions = {a: rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32) for a in env.agents}
    return lambda target: target.step(actions)[:4]


ENVS = {
    **{env_id: (lambda i=env_id: gymnasium.make(i, frame_skip=4), _gym_step) for env_id in IDS},
    **{name: (lambda n=name: hier_ssl.scenario_env(n, num_agents=3), _parallel_step) for name in SCENARIOS},
    "parallel_env exposed": (
        lambda: hier_ssl.parallel_env(task="obstacle", expose_worker=True, expose_obstacles=True),
        _parallel_step,
    ),
    "manager_vector_env": (lambda: hier_ssl.manager_vector_env("crossing", num_fields=2), _gym_step),
    "vector_env": (lambda: hier_ssl.vector_env(task="obstacle", num_envs=3, frame_skip=4), _torch_step),
}


def _same(a: Any, b: Any) -> None:
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for key in a:
            _same(a[key], b[key])
    elif isinstance(a, tuple):
        for x, y in zip(a, b, strict=True):
            _same(x, y)
    elif isinstance(a, torch.Tensor):
        torch.testing.assert_close(b, a, rtol=0, atol=0)
    else:
        np.testing.assert_array_equal(b, a)


@pytest.mark.parametrize("how", COPIES)
@pytest.mark.parametrize("name", ENVS)
def test_a_copied_env_steps_as_its_original(name: str, how: str) -> None:
    make, step = ENVS[name]
    env = make()
    env.reset(seed=1)
    rng = np.random.default_rng(0)
    for _ in range(3):
        step(env, rng)(env)
    copied = COPIES[how](env)
    for _ in range(8):
        if not getattr(env, "agents", True):  # a PettingZoo episode over
            break
        act = step(env, rng)
        _same(act(env), act(copied))
    assert copied is not env


def test_supersuit_vector_pipeline_trains_sb3_ppo() -> None:
    # The PettingZoo + SB3 tutorial's path: concat_vec_envs_v1 copies the env by cloudpickle.
    ss = pytest.importorskip("supersuit")
    from stable_baselines3 import PPO

    env = ss.black_death_v3(hier_ssl.scenario_env("crossing", num_agents=3))
    env = ss.pettingzoo_env_to_vec_env_v1(env)
    env = ss.concat_vec_envs_v1(env, 2, num_cpus=1, base_class="stable_baselines3")
    assert env.num_envs == 6
    model = PPO("MlpPolicy", env, n_steps=16, batch_size=48, n_epochs=1, device="cpu")
    model.learn(total_timesteps=96)
    assert model.num_timesteps >= 96


def test_supersuit_black_death_ends_an_episode_whose_robots_leave_apart() -> None:
    ss = pytest.importorskip("supersuit")
    env = ss.black_death_v3(hier_ssl.scenario_env("crossing", num_agents=3))
    env.reset(seed=0)
    steps = 0
    while env.agents:
        env.step({a: env.action_space(a).sample() for a in env.agents})
        steps += 1
    assert 0 < steps <= env.unwrapped.config.max_steps


def test_torchrl_gym_env_makes_an_id_and_takes_over_frame_skip() -> None:
    libs = pytest.importorskip("torchrl.envs")
    env = libs.GymEnv("hier_ssl/Proposed-v0")
    assert env.rollout(3)["next", "reward"].shape == (3, 1)
    # frame_skip= is TorchRL's: it offers frameskip= to the env, which refuses it as Python does.
    env = libs.GymEnv("hier_ssl/Proposed-v0", frame_skip=2)
    assert env.wrapper_frame_skip == 2 and env.rollout(3)["next", "reward"].shape == (3, 1)


def test_torchrl_wraps_the_vector_env_and_stacks_its_infos() -> None:
    libs = pytest.importorskip("torchrl.envs")
    env = libs.GymWrapper(hier_ssl.manager_vector_env(task="proposed", num_fields=3, frame_skip=16))
    data = env.rollout(80, break_when_any_done=False)  # 75 decisions a timeout: every field resets once
    assert data.batch_size == (3, 80)
    ended = data["next", "done"].squeeze(-1)
    assert ended.any(dim=1).all()
    np.testing.assert_array_equal(data["next", "task_length"][ended].numpy(), 1200)


def test_torchrl_pettingzoo_wrapper_plays_a_scenario_to_its_end() -> None:
    # TorchRL sends an action for every agent, the ones that have left included.
    libs = pytest.importorskip("torchrl.envs")
    scenario = hier_ssl.scenario_env("crossing", num_agents=3)
    env = libs.PettingZooWrapper(scenario, use_mask=True, done_on_any=False)
    data = env.rollout(200, break_when_any_done=True)
    assert data["next", "done"][-1].all() and len(data) < 200
    left = data["next", "manager", "done"].squeeze(-1)
    assert not left[0].all()  # the robots left one by one, not all at the first step


def test_sb3_subproc_vec_env_makes_the_hier_ssl_colon_form() -> None:
    # SB3's workers start with forkserver and never import hier_ssl: "hier_ssl:" makes Gymnasium do it.
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    env = make_vec_env(
        "hier_ssl:hier_ssl/Proposed-v0", 2, env_kwargs={"frame_skip": 16}, vec_env_cls=SubprocVecEnv
    )
    try:
        obs = env.reset()
        obs, rewards, dones, infos = env.step(np.zeros((2, 4), dtype=np.float32))
        assert obs.shape == (2, 13) and rewards.shape == (2,)
    finally:
        env.close()
