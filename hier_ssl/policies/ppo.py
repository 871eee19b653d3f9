"""PPO: through rsl-rl-lib 5.x for the Gaussian actors (``algo: ppo`` managers, the goToPoint worker), and
its pieces as functions for the candidate learner's categorical policy (``hier_ssl.policies.candidates``).

For the Gaussian actors: our typed ``PPOConfig`` as rsl-rl's nested ``train_cfg``, a runner over the
batched vector env, and the trained actor as a numpy policy for ``hier_ssl.evaluation.evaluate``.

rsl-rl owns the loop, the update, logging and checkpoints (``runner.learn``, ``runner.save``). Two of
its habits matter here:

- ``OnPolicyRunner.load`` calls ``torch.load(weights_only=False)``, which unpickles arbitrary objects.
  Its checkpoints hold only tensors, numbers and ``None``, so ``load_ppo`` reads them with
  ``weights_only=True`` and hands the dict to the algorithm's own ``load``.
- The runner writes resolved fields (``obs_groups``, ``multi_gpu``) into the train_cfg it is given, so
  every call of ``ppo_train_cfg`` returns a fresh dict and ``make_ppo_runner`` never shares one.

rsl-rl's ``PPO`` cannot train the candidate learner: its distributions are Gaussian only, its update one
optimiser over actor and critic with a clipped value loss, an entropy bonus and gradient clipping, where
the candidate learner has a categorical policy over a variable set of candidates, a KL penalty towards its
DAgger fit, and a value fitted alone before the policy moves. That learner builds its update from
``gae``, ``minibatches``, ``value_loss``, ``normalized`` and ``clipped_surrogate`` here.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import torch
from rsl_rl.runners import OnPolicyRunner
from tensordict import TensorDict

from hier_ssl.checkpoints.tensors import load_checkpoint, save_checkpoint
from hier_ssl.config import ConfigError
from hier_ssl.config.learners import CandidatePPOConfig, PPOConfig
from hier_ssl.envs.vector import RslRlVecEnv, TorchView
from hier_ssl.policies.learner import Checkpoint, OnCheckpoint, on_threads, torch_threads
from hier_ssl.policies.networks import NumpyPolicy


def ppo_train_cfg(
    cfg: PPOConfig,
    *,
    save_interval: int = 50,
    activation: str = "elu",
    schedule: str = "adaptive",
    desired_kl: float = 0.01,
    max_grad_norm: float = 1.0,
    value_loss_coef: float = 1.0,
    clip_value_loss: bool = True,
    run_name: str = "",
) -> dict[str, Any]:
    """rsl-rl-lib 5.x ``train_cfg`` for ``OnPolicyRunner`` from ``cfg``.

    The keyword arguments are rsl-rl settings that ``PPOConfig`` does not carry; their defaults are
    rsl-rl's own. Actor and critic are ``MLPModel``s over the "policy" observation group with a
    state-independent Gaussian head (std initialised to ``cfg.init_noise_std``, learned). Empirical
    observation normalisation is off: the manager's observations are already scaled to about [-1, 1]
    (docs/paper.md "Observations"), and a running normaliser would drift the deterministic policy
    between evaluations.
    """
    hidden = list(cfg.hidden)
    return {
        "num_steps_per_env": cfg.num_steps_per_env,
        "save_interval": save_interval,
        "run_name": run_name,
        "logger": "tensorboard",
        "check_for_nan": True,
        "obs_groups": {"actor": ["policy"], "critic": ["policy"]},
        "algorithm": {
            "class_name": "rsl_rl.algorithms:PPO",
            "num_learning_epochs": cfg.num_learning_epochs,
            "num_mini_batches": cfg.num_mini_batches,
            "clip_param": cfg.clip_param,
            "gamma": cfg.gamma,
            "lam": cfg.lam,
            "value_loss_coef": value_loss_coef,
            "entropy_coef": cfg.entropy_coef,
            "learning_rate": cfg.learning_rate,
            "max_grad_norm": max_grad_norm,
            "optimizer": "adam",
            "use_clipped_value_loss": clip_value_loss,
            "schedule": schedule,
            "desired_kl": desired_kl,
            "normalize_advantage_per_mini_batch": False,
            "rnd_cfg": None,
            "symmetry_cfg": None,
        },
        "actor": {
            "class_name": "rsl_rl.models:MLPModel",
            "hidden_dims": hidden,
            "activation": activation,
            "obs_normalization": False,
            "distribution_cfg": {
                "class_name": "rsl_rl.modules:GaussianDistribution",
                "init_std": cfg.init_noise_std,
                "std_type": "scalar",
            },
        },
        "critic": {
            "class_name": "rsl_rl.models:MLPModel",
            "hidden_dims": hidden,
            "activation": activation,
            "obs_normalization": False,
        },
    }


class SelectingRunner(OnPolicyRunner):
    """rsl-rl's ``OnPolicyRunner`` that writes its checkpoints atomically and calls ``on_save(self)`` after
    every one (every ``save_interval`` iterations and at the end), so a run can score and keep its best
    policy there."""

    on_save: Callable[[OnPolicyRunner], None] | None = None

    def save(self, path: str, infos: dict | None = None) -> None:
        # rsl-rl's own save, through save_checkpoint: its torch.save straight to the path leaves a truncated
        # file when the run is killed mid-write, and --resume reads the newest file.
        save_checkpoint({**self.alg.save(), "iter": self.current_learning_iteration, "infos": infos}, path)
        self.logger.save_model(path, self.current_learning_iteration)
        if self.on_save is not None:
            self.on_save(self)


def make_ppo_runner(
    env: TorchView,
    cfg: PPOConfig,
    log_dir: str | Path | None = None,
    device: str | torch.device = "cpu",
    seed: int | None = None,
    **train_cfg_settings: Any,
) -> SelectingRunner:
    """An ``OnPolicyRunner`` training on ``env`` (wrapped in ``RslRlVecEnv``, first reset with ``seed``).

    ``log_dir=None`` writes nothing: no TensorBoard, no console log, no checkpoints from ``learn``.
    ``train_cfg_settings`` go to ``ppo_train_cfg``. Train with ``runner.learn(iterations)``; each
    iteration collects ``cfg.num_steps_per_env`` decisions from every field.
    """
    train_cfg = ppo_train_cfg(cfg, **train_cfg_settings)
    return SelectingRunner(
        RslRlVecEnv(env, seed), train_cfg, None if log_dir is None else str(log_dir), str(device)
    )


def ppo_policy(runner: OnPolicyRunner) -> NumpyPolicy:
    """The runner's actor as a deterministic numpy policy: the Gaussian mean, clipped to [-1, 1].

    A live view, not a copy: it acts with the actor's current weights, so one policy serves every
    evaluation during training. Each call runs in eval mode under ``torch.inference_mode`` and then
    restores the actor's previous mode. Input (N, obs_dim), output (N, num_actions) float32.
    """
    actor = runner.alg.get_policy()
    device = runner.device

    def policy(obs: np.ndarray) -> np.ndarray:
        was_training = actor.training
        actor.eval()
        try:
            with torch.inference_mode():
                x = torch.as_tensor(obs, dtype=torch.float32, device=device)
                group = TensorDict({"policy": x}, batch_size=[x.shape[0]], device=device)
                return actor(group).clamp(-1.0, 1.0).cpu().numpy()
        finally:
            actor.train(was_training)

    return policy


def load_ppo(runner: OnPolicyRunner, path: str | Path, map_location: str | None = None) -> None:
    """Restore actor, critic, optimizer and iteration from ``runner.save(path)``'s file.

    Same effect as ``runner.load(path)`` but with ``torch.load(weights_only=True)``, which refuses to
    run pickled code (rsl-rl's ``load`` passes ``weights_only=False``). Raises FileNotFoundError
    naming the path when it is missing.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"PPO checkpoint not found: {path}")
    loaded = load_checkpoint(path, map_location)
    if runner.alg.load(loaded, None, strict=True):
        runner.current_learning_iteration = loaded["iter"]


class PPOLearner:
    """PPO through rsl-rl as a ``Learner`` (``hier_ssl.policies.learner``): its runner over ``env`` writes
    ``model_<iteration>.pt`` into ``run_dir`` every ``checkpoint_interval`` vector steps (in whole
    iterations, at least one) and at the end, and each is a checkpoint. ``seed`` seeds the networks'
    initial weights, the exploration noise and the env's first reset."""

    def __init__(
        self,
        env: TorchView,
        cfg: PPOConfig,
        run_dir: str | Path,
        device: str | torch.device = "cpu",
        *,
        seed: int = 0,
        checkpoint_interval: int,
    ) -> None:
        self.steps_per_iteration, self.num_envs = cfg.num_steps_per_env, env.num_envs
        self.run_dir = Path(run_dir)
        torch.manual_seed(seed)  # the networks' initial weights and the policy's exploration noise
        every = max(1, checkpoint_interval // self.steps_per_iteration)
        self.runner = make_ppo_runner(env, cfg, self.run_dir, device, seed=seed, save_interval=every)
        self.train_time_s = 0.0  # of the last ``learn``: rsl-rl keeps no clock across resumes
        self._policy = ppo_policy(self.runner)
        self._on_checkpoint: OnCheckpoint | None = None
        self._started, self._evaluating, self._last_step = 0.0, 0.0, -1

    def learn(self, total_steps: int, on_checkpoint: OnCheckpoint | None = None) -> None:
        """Learn until iteration ``total_steps // num_steps_per_env`` (at least one)."""
        remaining = max(1, total_steps // self.steps_per_iteration) - self.runner.current_learning_iteration
        self._started, self._evaluating = time.perf_counter(), 0.0
        if remaining > 0:  # a resumed run that had finished has nothing left to learn
            self._on_checkpoint, self.runner.on_save = on_checkpoint, self._saved
            alg, update = self.runner.alg, self.runner.alg.update
            alg.update = on_threads(torch.get_num_threads(), update)  # the run's threads; collect on one
            try:
                with torch_threads(1):
                    self.runner.learn(remaining)
            finally:
                self._on_checkpoint, self.runner.on_save, alg.update = None, None, update
        self.train_time_s = time.perf_counter() - self._started - self._evaluating

    def policy(self) -> NumpyPolicy:
        """The actor's Gaussian mean clipped to [-1, 1] (``ppo_policy``), a live view of its weights."""
        return self._policy

    def save(self) -> None:
        """``model_<iteration>.pt`` of the iteration reached, as rsl-rl's own saves."""
        self.runner.save(str(self.run_dir / f"model_{self.runner.current_learning_iteration}.pt"))

    def load(self, run_dir: str | Path) -> None:
        """Continue after the highest-numbered ``model_<iteration>.pt`` in ``run_dir``."""
        run_dir = Path(run_dir)
        saved = sorted(run_dir.glob("model_*.pt"), key=lambda p: int(p.stem.split("_")[1]))
        if not saved:
            raise ConfigError(f"cannot resume {run_dir}: no PPO checkpoint model_*.pt in it")
        load_ppo(self.runner, saved[-1])
        self.runner.current_learning_iteration += 1  # rsl-rl saves the index of the last finished iteration

    def _saved(self, runner: OnPolicyRunner) -> None:
        """``on_save``: the file rsl-rl just wrote is a checkpoint."""
        step = (runner.current_learning_iteration + 1) * self.steps_per_iteration
        if self._on_checkpoint is None or step == self._last_step:  # the final save repeats the last one
            return
        began = time.perf_counter()
        self.train_time_s = began - self._started - self._evaluating
        iteration = runner.current_learning_iteration

        def state() -> dict[str, Any]:  # what runner.save writes
            return {**runner.alg.save(), "iter": iteration}

        self._on_checkpoint(Checkpoint(step, step * self.num_envs, self.train_time_s, self._policy, state))
        self._last_step = step
        self._evaluating += time.perf_counter() - began


def gae(
    rewards: torch.Tensor,
    values: torch.Tensor,
    last_values: torch.Tensor,
    dones: torch.Tensor,
    gamma: float,
    lam: float,
) -> torch.Tensor:
    """Generalised advantage estimates (T, N) of a rollout (Schulman et al., 2016): rewards, values, dones
    (T, N) with dones 0 or 1, the values of the observations after its last step (N,). A done step does
    not bootstrap (a truncation's bootstrap belongs in its reward); the returns are advantages + values."""
    out = torch.zeros_like(rewards)
    running = torch.zeros_like(last_values)
    for t in reversed(range(len(rewards))):
        following = last_values if t == len(rewards) - 1 else values[t + 1]
        keep = 1.0 - dones[t]
        delta = rewards[t] + gamma * following * keep - values[t]
        running = delta + gamma * lam * keep * running
        out[t] = running
    return out


def minibatches(rows: int, count: int, epochs: int) -> Iterator[torch.Tensor]:
    """The row indices of ``epochs`` passes over ``rows`` rows, each a fresh permutation (torch's global
    generator) cut into ``count`` near-equal minibatches: a rollout's live rows rarely divide evenly. Empty
    ones (fewer rows than ``count``) are skipped."""
    for _ in range(epochs):
        for minibatch in torch.tensor_split(torch.randperm(rows), count):
            if len(minibatch):
                yield minibatch


def value_loss(predicted: torch.Tensor, returns: torch.Tensor) -> torch.Tensor:
    """Mean squared error of the value's predictions (B,) against the returns (B,)."""
    return (predicted - returns).square().mean()


def normalized(advantages: torch.Tensor) -> torch.Tensor:
    """A minibatch's advantages (B,) at zero mean and unit spread; a single row, which has no spread, is
    only centred."""
    centred = advantages - advantages.mean()
    return centred / (centred.std() + 1e-8) if len(advantages) > 1 else centred


def clipped_surrogate(
    log_probs: torch.Tensor, old_log_probs: torch.Tensor, advantages: torch.Tensor, clip: float
) -> torch.Tensor:
    """PPO's clipped surrogate loss (Schulman et al., 2017), to minimise: log-probabilities of the taken
    actions now and at the rollout, advantages, all (B,)."""
    ratio = (log_probs - old_log_probs).exp()
    clipped = ratio.clamp(1.0 - clip, 1.0 + clip)
    return -torch.min(ratio * advantages, clipped * advantages).mean()


def categorical_kl(log_probs: torch.Tensor, anchor: torch.Tensor) -> torch.Tensor:
    """Mean KL(p || q) of log-probabilities (B, C) of p and q. A class p rules out (-inf, as a residual
    rules out what its planner does not rank, and its anchor alike) counts 0: masked before the product,
    whose gradient would be 0 x nan."""
    gap = torch.where(torch.isfinite(log_probs), log_probs - anchor, 0.0)
    return (log_probs.exp() * gap).sum(1).mean()


def outcome_reward(
    settings: CandidatePPOConfig,
    control_steps: np.ndarray,
    ended_rows: np.ndarray,
    success: np.ndarray,
    collision: np.ndarray,
    gap: np.ndarray | None = None,
) -> np.ndarray:
    """PPO's reward per row (R,) for one decision: minus ``time_cost`` per 100 control steps the decision
    took (``control_steps`` (R,)), plus ``success_reward`` / minus ``collision_cost`` on the rows
    ``ended_rows`` (E,) whose episodes ended in a success / collision (``success``, ``collision`` (E,)).
    With ``gap`` (R,), m from each robot to its nearest other robot after the decision: minus
    ``near_cost`` x (1 - gap / ``near_distance``) inside ``near_distance``, on the rows still playing (an
    ended row's next observation is a new episode's)."""
    reward = -settings.time_cost * control_steps.astype(np.float32) / 100.0
    if gap is not None:
        near = settings.near_cost * np.clip(1.0 - gap / settings.near_distance, 0.0, 1.0)
        near[ended_rows] = 0.0
        reward -= near.astype(np.float32)
    np.add.at(reward, ended_rows, settings.success_reward * success - settings.collision_cost * collision)
    return reward


__all__ = [
    "NumpyPolicy",
    "PPOLearner",
    "SelectingRunner",
    "categorical_kl",
    "clipped_surrogate",
    "gae",
    "load_ppo",
    "make_ppo_runner",
    "minibatches",
    "normalized",
    "outcome_reward",
    "ppo_policy",
    "ppo_train_cfg",
    "value_loss",
]
