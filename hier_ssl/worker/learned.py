"""A frozen learned goToPoint worker behind the scripted workers' interface.

``LearnedWorker`` turns any numpy policy over ``worker_observation`` (N, 9) -> normalised commands
(N, 3) into a worker: ``__call__(state (N, R), subgoal (N, R, 5)) -> (N, R, 3)`` robot-frame commands
in m/s and rad/s. ``load_learned_worker`` builds one from a run directory of ``hier-ssl train
configs/worker/gotopoint_ppo.yaml``: the actor is read with ``torch.load(weights_only=True)``, put in
eval mode with ``requires_grad`` off, and run under ``torch.inference_mode``; nothing is written back.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch
from torch import nn

from hier_ssl.checkpoints.actor import load_actor
from hier_ssl.config import ConfigError
from hier_ssl.worker.observation import WORKER_OBS_DIM, scale_command, worker_observation
from hier_ssl.world.field import get_field
from hier_ssl.world.physics import RobotSpec, RobotState

WorkerPolicy = Callable[[np.ndarray], np.ndarray]
"""Worker observations (N, 9) float32 -> normalised robot-frame commands (N, 3) in [-1, 1]."""


def torch_policy(actor: nn.Module) -> WorkerPolicy:
    """A torch module (B, 9) -> (B, 3) as a numpy policy, run without autograd."""

    def policy(obs: np.ndarray) -> np.ndarray:
        with torch.inference_mode():
            return actor(torch.as_tensor(obs, dtype=torch.float32)).numpy()

    return policy


class LearnedWorker:
    """A learned goToPoint policy as a worker. Stateless: ``reset`` has nothing to forget.

    ``max_pos`` is the position normaliser the policy was trained with (its field's ``max_pos``), not
    the current field's: the observation must mean what it meant in training.
    """

    def __init__(
        self, policy: WorkerPolicy, robot: RobotSpec, max_pos: float, source: str = "policy"
    ) -> None:
        self.policy, self.robot, self.max_pos, self.source = policy, robot, max_pos, source
        self.actor: nn.Module | None = None  # the frozen module, when loaded from a run directory

    def __repr__(self) -> str:
        return f"LearnedWorker({self.source!r})"

    @property
    def max_speed(self) -> float:
        """The fastest it can command: the robot's limit (planners read a worker's speed cap)."""
        return self.robot.max_speed

    def reset(self, fields: np.ndarray) -> None:
        """Stateless: nothing to forget."""

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        """Commands (N, R, 3) for robots ``state`` (N, R) to reach ``subgoal`` (N, R, 5)."""
        n, r = state.angle.shape
        obs = worker_observation(
            state.pos.reshape(n * r, 2),
            state.angle.reshape(n * r),
            state.vel.reshape(n * r, 2),
            state.ang_vel.reshape(n * r),
            np.asarray(subgoal, dtype=np.float64).reshape(n * r, 5),
            self.robot,
            self.max_pos,
        )
        action = np.clip(np.asarray(self.policy(obs), dtype=np.float64), -1.0, 1.0)
        return scale_command(action, self.robot).reshape(n, r, 3)


def load_learned_worker(run_dir: str | Path, robot: RobotSpec, dt: float) -> LearnedWorker:
    """The frozen worker trained in ``run_dir``; ValueErrors name the directory or checkpoint when they
    are not a usable worker run, or when it was trained at another control period than ``dt``."""
    actor, config = load_actor(run_dir)
    if config.kind != "worker":
        raise ConfigError(
            f"{run_dir}: a {config.kind} run, not a goToPoint worker (a worker run has kind: worker)"
        )
    in_dim, out_dim = actor[0].in_features, actor[-2].out_features
    if (in_dim, out_dim) != (WORKER_OBS_DIM, 3):
        raise ConfigError(
            f"{run_dir}: actor maps {in_dim} -> {out_dim} values, a worker maps {WORKER_OBS_DIM} -> 3"
        )
    if not np.isclose(config.env.dt, dt):
        raise ConfigError(
            f"{run_dir}: worker trained at dt {config.env.dt} s, the environment steps at {dt} s"
        )
    worker = LearnedWorker(
        torch_policy(actor), robot, get_field(config.env.field).max_pos, source=str(run_dir)
    )
    worker.actor = actor
    return worker


__all__ = ["LearnedWorker", "WorkerPolicy", "load_learned_worker", "torch_policy"]
