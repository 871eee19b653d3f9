from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

import hier_ssl
from hier_ssl.config.learners import PPOConfig
from hier_ssl.policies.learner import Checkpoint
from hier_ssl.policies.ppo import (
    PPOLearner,
    clipped_surrogate,
    gae,
    load_ppo,
    make_ppo_runner,
    minibatches,
    normalized,
    ppo_policy,
    ppo_train_cfg,
    value_loss,
)


def _build_runner(seed: int = 0, **overrides: object):
    """A tiny PPO runner on 32 Proposed fields with frame skip 16."""
    torch.manual_seed(seed)
    settings = {"hidden": (32, 32), "num_steps_per_env": 8, "num_learning_epochs": 2, "num_mini_batches": 2}
    cfg = PPOConfig(**{**settings, **overrides})
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=32)
    return make_ppo_runner(env, cfg, log_dir=None, device="cpu")


def _obs(n: int = 16) -> np.ndarray:
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=n)
    return env.reset(seed=7).numpy()


def test_train_cfg_maps_ppo_config_and_is_fresh() -> None:
    cfg = PPOConfig(hidden=(64, 32), learning_rate=3e-4, entropy_coef=0.001, init_noise_std=0.3, gamma=0.98)
    a, b = ppo_train_cfg(cfg), ppo_train_cfg(cfg)
    assert a == b and a is not b and a["algorithm"] is not b["algorithm"]
    assert a["obs_groups"] == {"actor": ["policy"], "critic": ["policy"]}
    assert a["algorithm"]["learning_rate"] == 3e-4 and a["algorithm"]["entropy_coef"] == 0.001
    assert a["algorithm"]["gamma"] == 0.98
    assert a["actor"]["hidden_dims"] == [64, 32] and a["critic"]["hidden_dims"] == [64, 32]
    assert a["actor"]["distribution_cfg"]["init_std"] == 0.3
    assert not a["actor"]["obs_normalization"] and not a["critic"]["obs_normalization"]


def test_learn_updates_and_policy_acts_in_bounds() -> None:
    runner = _build_runner()
    actor, critic = runner.alg.get_policy(), runner.alg.critic
    before = [p.detach().clone() for p in (*actor.parameters(), *critic.parameters())]
    runner.learn(2)
    after = list((*actor.parameters(), *critic.parameters()))
    # Every tensor, the learned std included, has moved: the update path ran for actor and critic.
    assert all(not torch.equal(b, a) for b, a in zip(before, after, strict=True))
    obs = _obs()
    policy = ppo_policy(runner)
    actions = policy(obs)
    assert actions.shape == (16, 4) and actions.dtype == np.float32
    assert np.all(np.abs(actions) <= 1.0)
    # Deterministic, and the actor's train/eval mode is left as it was.
    assert np.array_equal(actions, policy(obs))
    assert actor.training


def test_policy_clips_the_gaussian_mean() -> None:
    runner = _build_runner()
    last = runner.alg.get_policy().mlp[-1]
    with torch.no_grad():
        last.bias.copy_(torch.tensor([5.0, -5.0, 0.5, 0.0]))
        last.weight.zero_()
    actions = ppo_policy(runner)(_obs(4))
    np.testing.assert_array_equal(actions, np.tile(np.float32([1.0, -1.0, 0.5, 0.0]), (4, 1)))


def test_save_load_round_trip_gives_same_actions(tmp_path: Path) -> None:
    trained = _build_runner(seed=0)
    trained.learn(1)
    path = tmp_path / "model.pt"
    trained.save(str(path))
    # rsl-rl's checkpoint holds only tensors and plain data: the safe loader accepts it.
    assert set(torch.load(path, weights_only=True)) >= {"actor_state_dict", "critic_state_dict", "iter"}
    obs = _obs()
    fresh = _build_runner(seed=1)
    assert not np.array_equal(ppo_policy(fresh)(obs), ppo_policy(trained)(obs))
    load_ppo(fresh, path)
    np.testing.assert_array_equal(ppo_policy(fresh)(obs), ppo_policy(trained)(obs))
    assert fresh.current_learning_iteration == trained.current_learning_iteration


def test_load_missing_checkpoint_names_it(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nope.pt"):
        load_ppo(_build_runner(), tmp_path / "nope.pt")


def test_gae_stops_at_episode_ends() -> None:
    rewards = torch.tensor([[1.0], [2.0], [3.0]])
    values = torch.tensor([[0.5], [0.25], [1.0]])
    dones = torch.tensor([[0.0], [1.0], [0.0]])
    adv = gae(rewards, values, torch.tensor([2.0]), dones, gamma=0.9, lam=0.5)
    last = 3.0 + 0.9 * 2.0 - 1.0  # bootstraps from the value after the rollout
    second = 2.0 - 0.25  # the episode ended: no bootstrap, nothing from the next episode
    first = (1.0 + 0.9 * 0.25 - 0.5) + 0.9 * 0.5 * second
    torch.testing.assert_close(adv, torch.tensor([[first], [second], [last]]))


def test_gae_at_lambda_one_is_the_discounted_return_less_the_value() -> None:
    # Two fields, four steps, no episode end: A_t = sum_k gamma^k r_{t+k} + gamma^(T-t) V_T - V_t.
    rewards = torch.tensor([[1.0, 0.0], [0.0, 1.0], [2.0, 0.0], [1.0, 1.0]])
    values = torch.tensor([[0.5, 1.0], [0.0, 2.0], [1.0, 0.0], [0.5, 0.5]])
    last = torch.tensor([4.0, -1.0])
    adv = gae(rewards, values, last, torch.zeros(4, 2), gamma=0.5, lam=1.0)
    want = torch.tensor(
        [
            [1.0 + 0.25 * 2.0 + 0.125 * 1.0 + 0.0625 * 4.0 - 0.5, 0.5 + 0.125 - 0.0625 - 1.0],
            [0.5 * 2.0 + 0.25 * 1.0 + 0.125 * 4.0 - 0.0, 1.0 + 0.25 - 0.125 - 2.0],
            [2.0 + 0.5 * 1.0 + 0.25 * 4.0 - 1.0, 0.5 - 0.25 - 0.0],
            [1.0 + 0.5 * 4.0 - 0.5, 1.0 - 0.5 - 0.5],
        ]
    )
    torch.testing.assert_close(adv, want)


def test_gae_at_lambda_zero_is_the_one_step_error() -> None:
    rewards, values = torch.tensor([[1.0], [2.0]]), torch.tensor([[0.5], [1.5]])
    adv = gae(rewards, values, torch.tensor([3.0]), torch.zeros(2, 1), gamma=0.9, lam=0.0)
    torch.testing.assert_close(adv, torch.tensor([[1.0 + 0.9 * 1.5 - 0.5], [2.0 + 0.9 * 3.0 - 1.5]]))


def test_the_clipped_surrogate_takes_the_pessimistic_side() -> None:
    # Ratio 1.5 on a positive advantage is clipped to 1.2; ratio 0.5 on a negative one to 0.8; ratio 1.1
    # inside the clip range counts as it is.
    log_probs = torch.log(torch.tensor([1.5, 0.5, 1.1]))
    old = torch.zeros(3)
    loss = clipped_surrogate(log_probs, old, torch.tensor([1.0, -1.0, 2.0]), clip=0.2)
    torch.testing.assert_close(loss, -torch.tensor((1.2 - 0.8 + 2.2) / 3))
    # A ratio that moved against the advantage is not clipped: its full cost counts.
    loss = clipped_surrogate(torch.log(torch.tensor([0.5])), torch.zeros(1), torch.tensor([1.0]), 0.2)
    torch.testing.assert_close(loss, torch.tensor(-0.5))


def test_normalized_advantages_and_the_value_loss() -> None:
    torch.testing.assert_close(normalized(torch.tensor([1.0, 3.0])), torch.tensor([-1.0, 1.0]) / 2**0.5)
    assert normalized(torch.tensor([5.0])).tolist() == [0.0]  # one row has no spread
    loss = value_loss(torch.tensor([1.0, 2.0]), torch.tensor([0.0, 4.0]))
    torch.testing.assert_close(loss, torch.tensor((1.0 + 4.0) / 2))


def test_minibatches_cover_every_row_once_an_epoch_in_near_equal_shares() -> None:
    torch.manual_seed(0)
    batches = list(minibatches(5, count=4, epochs=2))
    assert [len(b) for b in batches] == [2, 1, 1, 1, 2, 1, 1, 1]
    for epoch in (batches[:4], batches[4:]):
        assert sorted(torch.cat(epoch).tolist()) == [0, 1, 2, 3, 4]
    assert [len(b) for b in minibatches(3, count=4, epochs=1)] == [1, 1, 1]  # no empty minibatch


def test_the_ppo_learner_scores_each_save_once_and_resumes_from_its_own_save(tmp_path: Path) -> None:
    cfg = PPOConfig(hidden=(16, 16), num_steps_per_env=4, num_learning_epochs=1, num_mini_batches=1)

    def learner() -> PPOLearner:
        env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=8)
        return PPOLearner(env, cfg, tmp_path, seed=1, checkpoint_interval=8)

    trained, calls = learner(), []
    trained.learn(12, calls.append)
    # Three iterations, saved after the first and the third; the final save repeats the third's.
    assert [(c.step, c.transitions) for c in calls] == [(4, 32), (12, 96)]
    assert calls[-1].state()["iter"] == 2 and calls[-1].policy is trained.policy()
    for path in tmp_path.glob("model_*.pt"):
        path.unlink()
    trained.save()
    assert [p.name for p in tmp_path.glob("model_*.pt")] == ["model_2.pt"]
    resumed = learner()
    resumed.load(tmp_path)
    obs = _obs()
    np.testing.assert_array_equal(resumed.policy()(obs), trained.policy()(obs))
    more: list[Checkpoint] = []
    resumed.learn(16, more.append)  # one iteration after the three
    assert [c.step for c in more] == [16] and (tmp_path / "model_3.pt").is_file()


def test_the_ppo_learner_collects_on_one_torch_thread_and_updates_on_the_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, torch_threads_seen
) -> None:
    """While the fields step on several cores a second torch thread holds a worker's core: rsl-rl's
    collection runs at one thread, its update at the run's, and the run's count is back afterwards."""
    seen, counted = torch_threads_seen
    cfg = PPOConfig(hidden=(16, 16), num_steps_per_env=4, num_learning_epochs=1, num_mini_batches=1)
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=8)
    learner = PPOLearner(env, cfg, tmp_path, seed=1, checkpoint_interval=8)
    monkeypatch.setattr(env, "step", counted("step", env.step))
    monkeypatch.setattr(learner.runner.alg, "update", counted("update", learner.runner.alg.update))
    learner.learn(8)
    assert seen == {"step": {1}, "update": {2}} and torch.get_num_threads() == 2
