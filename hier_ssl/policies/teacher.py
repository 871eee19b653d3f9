"""Learning from a scripted planner: SAC's actor is pulled towards the planner's action where it helps.

The ``sampling`` planner (``hier_ssl.manager.planners``) reads the same observation rows the manager does,
so its action for every observation the runner collects costs one batched call per vector step. Those
actions are kept as labels beside the transitions (``ReplayBuffer(teacher=True)``) and used three ways,
each a key of ``SACConfig`` (``teacher_*``):

- an imitation term in the actor loss, w * mean|Q| * mean_b ||tanh(mean(s_b)) - a_teacher(s_b)||^2, the
  weight w falling linearly to 0 over ``teacher_steps`` updates (TD3+BC's Q-normalised behaviour cloning,
  annealed as in DDPGfD-style schedules). Labels are taken on the student's own states, as DAgger does.
  With ``teacher_filter`` a row is imitated only where the critic rates the teacher's action above the
  actor's mean action (the Q-filter of Nair et al. 2018);
- warm-up transitions acted by the teacher plus Gaussian noise instead of uniform random actions;
- a supervised pretraining of the actor on the warm-up's labels when the warm-up ends.

The trained policy never calls the planner: it is the actor network alone.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import torch

from hier_ssl.config.learners import SACConfig
from hier_ssl.envs.planners import make_planner

Teacher = Callable[[np.ndarray], np.ndarray]
"""A numpy policy: observations (N, obs_dim) -> actions (N, act_dim) in [-1, 1]."""

LABEL_BOUND = 0.999  # tanh(3.8): labels the actor's squashed mean can reach with a finite pre-activation


def make_teacher(name: str, env: object) -> Teacher:
    """The planner ``name`` for the task of ``env`` (a vector env with a ``config``, the task config),
    reading the limits of the worker the env's core runs (``env.core.worker``) where it has one, else of
    the worker the config names."""
    config = getattr(env, "config", None)
    if config is None:
        raise ValueError(f"teacher: {name!r} needs an env with the task config it plans for")
    return make_planner(name, config, getattr(getattr(env, "core", None), "worker", None))


def teacher_labels(teacher: Teacher, obs: torch.Tensor) -> torch.Tensor:
    """The teacher's actions for ``obs`` (N, obs_dim), on obs's device, float32 (N, act_dim).

    Rows that are all zeros (robots that have left their episode, ``hier_ssl.envs.vector.TorchView``) are
    not shown to the teacher and get zeros: no learner stores them. Labels are clipped to
    +-``LABEL_BOUND``: the actor's tanh reaches +-1 only at infinite pre-activations, and a planner's
    sub-goal on the target's heading is a cos of exactly 1 in the target frame.
    """
    source = obs.detach().cpu().numpy()
    rows = source.any(axis=1)
    labels = np.zeros((len(source), 0), dtype=np.float32)
    if rows.any():
        acted = np.clip(np.asarray(teacher(source[rows]), dtype=np.float32), -LABEL_BOUND, LABEL_BOUND)
        labels = np.zeros((len(source), acted.shape[1]), dtype=np.float32)
        labels[rows] = acted
    return torch.from_numpy(labels).to(obs.device)


def teacher_weight(config: SACConfig, num_updates: int) -> float:
    """The imitation weight at update ``num_updates``: ``teacher_weight`` falling linearly to 0 at update
    ``teacher_steps`` (constant when ``teacher_steps`` is 0)."""
    if config.teacher_steps == 0:
        return config.teacher_weight
    return config.teacher_weight * max(0.0, 1.0 - num_updates / config.teacher_steps)


def imitation_loss(
    mean_action: torch.Tensor,
    teacher_actions: torch.Tensor,
    q_scale: torch.Tensor,
    weight: float,
    keep: torch.Tensor | None = None,
) -> torch.Tensor:
    """weight * q_scale * mean_b keep_b ||mean_action_b - teacher_actions_b||^2 (a scalar).

    Shapes: mean_action, teacher_actions (B, act_dim); q_scale a scalar (the batch's mean |Q|, without
    gradient); keep (B,) bool, the rows imitated (all when None), averaged over all B rows.
    """
    error = (mean_action - teacher_actions).square().sum(dim=-1)
    if keep is not None:
        error = error * keep
    return weight * q_scale * error.mean()


__all__ = ["LABEL_BOUND", "Teacher", "imitation_loss", "make_teacher", "teacher_labels", "teacher_weight"]
