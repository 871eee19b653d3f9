"""What ``hier-ssl train`` drives: a learner that learns until a step budget and hands each checkpoint to
a callback (model selection scores it there), with its current policy, and its state saved into and
loaded from its run directory (``--resume``).

Three learners take this form: SAC + CAPS (``hier_ssl.policies.sac_runner.SACRunner``), PPO through
rsl-rl (``hier_ssl.policies.ppo.PPOLearner``) and the choice among the sampling planner's candidates
(``hier_ssl.policies.candidates.CandidateLearner``).

Each collects at one torch thread (``torch_threads(1)``) and updates at the run's (``threads``): while the
fields step on several cores, a second torch thread left waiting after an operator holds the core a
shard's worker process steps on. ``obstacle/ppo_frame_skip``'s 512 fields and a 256-wide network, 32 steps
on two cores: 0.27 s with one torch thread, 0.44 s with two; on one core 0.40-0.44 s either way (median of
five rounds, ``benchmarks/collect_threads.py``; docs/guide/benchmarks.md, "Every core").
"""

from __future__ import annotations

import contextlib
import functools
import os
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import torch

from hier_ssl.policies.networks import NumpyPolicy

T = TypeVar("T")


@dataclass(frozen=True)
class Checkpoint:
    """A point of the learning curve.

    ``step`` is the learner's step counter (vector steps for SAC and PPO; DAgger rounds, then rounds + PPO
    iterations for the candidate learner), ``transitions`` what it has learned from, ``train_time_s`` its
    wall time without the callbacks'. ``policy`` acts with the weights of that moment; ``state()`` is
    what ``best_actor.pt`` keeps of it (``hier_ssl.checkpoints.actor`` reads it back).
    """

    step: int
    transitions: int
    train_time_s: float
    policy: NumpyPolicy
    state: Callable[[], dict[str, Any]]


OnCheckpoint = Callable[[Checkpoint], Mapping[str, float] | None]
"""Called at each checkpoint; a returned mapping is logged to TensorBoard under ``eval/``."""


class Learner(Protocol):
    """A learner behind ``hier-ssl train``."""

    @property
    def train_time_s(self) -> float:
        """Wall time spent collecting and learning, without the callbacks'."""
        ...

    def learn(self, total_steps: int, on_checkpoint: OnCheckpoint | None = None) -> None:
        """Learn until the step counter reaches ``total_steps`` (a resumed learner continues to the same
        end), calling ``on_checkpoint`` at each checkpoint and once at the end."""
        ...

    def policy(self) -> NumpyPolicy:
        """The current policy, deterministic, as a live view of the weights."""
        ...

    def save(self) -> None:
        """Write the resumable state into the run directory."""
        ...

    def load(self, run_dir: str | os.PathLike[str]) -> None:
        """Continue from the state ``save`` wrote into ``run_dir``."""
        ...


@contextlib.contextmanager
def torch_threads(count: int) -> Iterator[None]:
    """torch's intra-op threads set to ``count`` inside, restored after; nothing set where they already
    are (SAC enters it every vector step, mostly at one thread)."""
    before = torch.get_num_threads()
    if before == count:
        yield
        return
    torch.set_num_threads(count)
    try:
        yield
    finally:
        torch.set_num_threads(before)


def on_threads(count: int, function: Callable[..., T]) -> Callable[..., T]:
    """``function`` run at ``count`` torch threads (an update called from inside a collecting loop)."""

    @functools.wraps(function)
    def run(*args: Any, **kwargs: Any) -> T:
        with torch_threads(count):
            return function(*args, **kwargs)

    return run


__all__ = ["Checkpoint", "Learner", "OnCheckpoint", "on_threads", "torch_threads"]
