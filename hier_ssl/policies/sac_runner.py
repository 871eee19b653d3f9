"""Off-policy training loop for SAC over a batched vector env: collect, store, update, log, save."""

from __future__ import annotations

import os
import time
from collections import defaultdict
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Protocol

import torch
from torch.utils.tensorboard import SummaryWriter
from tqdm import tqdm

from hier_ssl.checkpoints.tensors import load_checkpoint, save_checkpoint
from hier_ssl.policies.learner import Checkpoint, OnCheckpoint, torch_threads
from hier_ssl.policies.networks import NumpyPolicy, sac_policy
from hier_ssl.policies.sac import SAC, SACConfig
from hier_ssl.policies.teacher import Teacher, make_teacher, teacher_labels, teacher_weight

MODEL_FILE = "model.pt"
REPLAY_FILE = "replay.pt"


class VectorEnv(Protocol):
    """Batched environment consumed by ``SACRunner``; every env auto-resets when its episode ends."""

    num_envs: int
    num_obs: int
    num_actions: int
    device: torch.device

    def reset(self, seed: int | None = None) -> torch.Tensor:
        """Reset all envs. Returns obs, shape (num_envs, num_obs) float32."""
        ...

    def step(
        self, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]:
        """Advance all envs by one step.

        actions: (num_envs, num_actions) in [-1, 1].
        Returns obs (num_envs, num_obs), already the reset observation where an episode finished;
        reward (num_envs,) float32; terminated, truncated (num_envs,) bool; info with
        ``info["final_obs"]`` (num_envs, num_obs), the true last observation (equal to obs where nothing
        finished), and ``info["task"]``, a dict of 1-D tensors with one entry per episode that ended
        this step (e.g. "return", "length", "success"), possibly empty.
        """
        ...


def to_learner(
    device: torch.device,
    next_obs: torch.Tensor,
    rewards: torch.Tensor,
    final_obs: torch.Tensor,
    terminated: torch.Tensor,
    live: torch.Tensor | None,
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor | None]:
    """What a vector step gives the learner, moved to ``device`` in one copy.

    Shapes: next_obs, final_obs (N, num_obs); rewards, terminated, live (N,). The five are packed as
    float32 columns of one (N, 2 num_obs + 3) tensor (in pinned memory when it goes from the CPU to a
    GPU, so that the copy runs asynchronously), copied with one ``.to``, and split there. Returns them in
    the same order on ``device``, terminated as float32 (0/1) and live as bool (None stays None).
    """
    n, num_obs = next_obs.shape
    source = next_obs.device
    all_live = torch.ones(n, dtype=torch.bool, device=source)
    flags = [rewards, terminated, live if live is not None else all_live]
    # The caching host allocator keeps a pinned block until the copy that reads it has finished.
    pin = source.type == "cpu" and device.type == "cuda"
    packed = torch.empty((n, 2 * num_obs + 3), device=source, pin_memory=pin)
    torch.cat([next_obs, final_obs, torch.stack(flags, dim=1)], dim=1, out=packed)
    packed = packed.to(device, non_blocking=True)
    next_obs, final_obs, flags = packed.split([num_obs, num_obs, 3], dim=1)
    live_mask = flags[:, 2] > 0.5 if live is not None else None
    return next_obs, flags[:, 0], final_obs, flags[:, 1], live_mask


class SACRunner:
    """Owns the SAC training loop over a ``VectorEnv``; a ``Learner`` (``hier_ssl.policies.learner``).

    Step counts are vector steps (one call of ``env.step``, ``num_envs`` transitions). ``learning_starts``
    in the config counts transitions collected, vector steps x num_envs (rows of robots that have left
    their episode included, though not stored): actions are uniform random through the vector step that
    reaches it, and the first update follows that step. The paper's public code warms up for 5,000
    vector steps x 16 envs, ``learning_starts: 80000``. A warm-up longer than the run only collects; a
    resumed run continues the warm-up from its saved step counter. With ``sac.teacher`` the runner asks
    that planner for its action on every observation it stores while the teacher is in use (warm-up,
    imitation weight above 0), acts with it during the warm-up with ``teacher_warmup``, and pretrains the
    actor on it before the first update with ``teacher_pretrain`` (``hier_ssl.policies.teacher``); the
    env must then carry its task config (``env.config``). The run directory receives
    TensorBoard events, ``model.pt`` (plain state dicts, loadable with ``torch.load(weights_only=True)``)
    and ``replay.pt``.

    The learner (networks, optimisers, replay buffer) lives on ``device``, the env on its own device
    (the CPU for the batched world). Each vector step then costs one copy each way: the actions to the
    env, and what is stored (obs, reward, final_obs, terminated, live mask) packed into one tensor to the
    learner (``to_learner``).

    Args:
        env: the vector env.
        config: SAC hyper-parameters.
        run_dir: folder for logs and checkpoints (created if missing).
        seed: seeds the networks, SAC's generator and the first ``env.reset``.
        device: where the learner lives; None means the env's device.
        log_interval: vector steps between TensorBoard writes.
        save_interval: vector steps between saves into ``run_dir`` (one is always written when ``learn``
            returns).
        eval_interval: vector steps between the checkpoints ``learn`` hands to its ``on_checkpoint``.
        progress: show a tqdm progress bar.
        teacher: the numpy policy that teaches, in place of the planner ``config.teacher`` names (which
            must then be set).
    """

    def __init__(
        self,
        env: VectorEnv,
        config: SACConfig,
        run_dir: str | os.PathLike[str],
        *,
        seed: int = 0,
        device: str | torch.device | None = None,
        log_interval: int = 100,
        save_interval: int = 10_000,
        eval_interval: int | None = None,
        progress: bool = True,
        teacher: Teacher | None = None,
    ) -> None:
        for name, value in (("log_interval", log_interval), ("save_interval", save_interval)):
            if value < 1:
                raise ValueError(f"{name} must be >= 1, got {value}")
        if eval_interval is not None and eval_interval < 1:
            raise ValueError(f"eval_interval must be >= 1, got {eval_interval}")
        self.env = env
        self.seed = seed
        self.device = torch.device(device) if device is not None else env.device
        if self.device.type == "cuda" and not torch.cuda.is_available():
            raise ValueError(f"device {str(self.device)!r}: torch sees no CUDA device on this machine")
        self.sac = SAC(env.num_obs, env.num_actions, config, device=self.device, seed=seed)
        if teacher is not None and config.teacher is None:
            raise ValueError("teacher: given to the runner, but the config's sac.teacher is not set")
        if teacher is None and config.teacher is not None:
            teacher = make_teacher(config.teacher, env)
        self.teacher = teacher
        self.run_dir = Path(run_dir)
        self.log_interval = log_interval
        self.save_interval = save_interval
        self.eval_interval = eval_interval
        self.progress = progress
        self.step = 0  # vector steps taken
        self.train_time_s = 0.0  # wall time spent collecting and learning, summed over resumes
        self._update_debt = 0.0  # fractional updates owed when updates_per_step is not an integer
        self._obs: torch.Tensor | None = None  # on the learner's device
        self._writer: SummaryWriter | None = None

    @property
    def num_transitions(self) -> int:
        """Transitions collected so far (vector steps x num_envs)."""
        return self.step * self.env.num_envs

    def learn(self, total_steps: int, on_checkpoint: OnCheckpoint | None = None) -> None:
        """Train until ``self.step == total_steps`` vector steps (a resumed run continues to the same end),
        calling ``on_checkpoint`` every ``eval_interval`` vector steps and with the final policy. What it
        returns is logged under ``eval/``; its time is not counted in ``train_time_s``."""
        if on_checkpoint is not None and self.eval_interval is None:
            raise ValueError("on_checkpoint: this runner has no eval_interval")
        cfg = self.sac.config
        self.run_dir.mkdir(parents=True, exist_ok=True)
        if self._writer is None:
            # purge_step drops events a killed run wrote after its last checkpoint.
            self._writer = SummaryWriter(self.run_dir, purge_step=self.step)
        if self._obs is None:
            self._obs = self.env.reset(seed=self.seed + self.step).to(self.device)
        start = self.step
        update_stats: dict[str, list[float]] = defaultdict(list)
        episode_stats: dict[str, list[torch.Tensor]] = defaultdict(list)
        bar = tqdm(
            total=total_steps, initial=self.step, disable=not self.progress, unit="step", dynamic_ncols=True
        )
        try:
            while self.step < total_steps:
                step_start = time.perf_counter()
                # Act: uniform random (or the teacher's) during warm-up, then the stochastic policy; on one
                # torch thread, as the fields step (hier_ssl.policies.learner), the updates on the run's.
                with torch_threads(1):
                    labels = self._labels()
                    actions = self._act(labels)
                    # The true last observation is the next_obs of finished episodes.
                    next_obs, rewards, terminated, _, info = self.env.step(actions.to(self.env.device))
                next_obs, rewards, final_obs, terminated, live = to_learner(
                    self.device, next_obs, rewards, info["final_obs"], terminated, info.get("live")
                )
                rows = (self._obs, actions, rewards, final_obs, terminated)
                rows += (labels,) if labels is not None else ()
                if live is not None:  # rows of robots that have left their episode are not transitions
                    rows = tuple(x[live] for x in rows)
                self.sac.process_env_step(*rows)
                self._obs = next_obs
                self.step += 1
                for key, values in info["task"].items():
                    if values.numel():
                        episode_stats[key].append(values.detach())
                # Learn: updates_per_step gradient updates per vector step, once warm-up data is in.
                if self.num_transitions >= cfg.learning_starts:
                    if self.sac.num_updates == 0 and cfg.teacher_pretrain and self._update_debt == 0.0:
                        update_stats["pretrain_loss"].append(self.sac.imitate(cfg.teacher_pretrain))
                    self._update_debt += cfg.updates_per_step
                    while self._update_debt >= 1.0:
                        for key, value in self.sac.update().items():
                            update_stats[key].append(value)
                        self._update_debt -= 1.0
                self.train_time_s += time.perf_counter() - step_start
                bar.update(1)
                # Log, evaluate and save on their intervals; the evaluation's time is not training time.
                if self.step % self.log_interval == 0 or self.step == total_steps:
                    self._log(update_stats, episode_stats, bar)
                    update_stats.clear()
                    episode_stats.clear()
                if on_checkpoint is not None and self.step % self.eval_interval == 0:
                    self._checkpoint(on_checkpoint)
                if self.step % self.save_interval == 0:
                    self.save()
            # The final policy is scored too (a run shorter than eval_interval still has a curve and a best),
            # once: not again by a finished run resumed.
            if on_checkpoint is not None and self.step % self.eval_interval and self.step > start:
                self._checkpoint(on_checkpoint)
            self.save()
        finally:
            bar.close()
            self.close()

    def _labels(self) -> torch.Tensor | None:
        """The teacher's actions (num_envs, num_actions) for the current observations, while they are used
        (warm-up, imitation weight above 0); zeros once they no longer are; None without a teacher."""
        if self.teacher is None:
            return None
        cfg = self.sac.config
        if self.num_transitions < cfg.learning_starts or teacher_weight(cfg, self.sac.num_updates) > 0.0:
            return teacher_labels(self.teacher, self._obs)
        return torch.zeros((self.env.num_envs, self.env.num_actions), device=self.device)

    def _act(self, labels: torch.Tensor | None) -> torch.Tensor:
        """Actions (num_envs, num_actions): during warm-up uniform, or the teacher's ``labels`` plus
        Gaussian noise (``teacher_warmup``); afterwards samples of the policy."""
        cfg = self.sac.config
        if self.num_transitions >= cfg.learning_starts:
            return self.sac.act(self._obs)
        if labels is None or not cfg.teacher_warmup:
            return self._random_actions()
        noise = torch.randn(labels.shape, generator=self.sac.generator, device=self.device)
        return (labels + cfg.teacher_noise * noise).clamp(-1.0, 1.0)

    def _random_actions(self) -> torch.Tensor:
        """Uniform actions in [-1, 1], shape (num_envs, num_actions), from SAC's checkpointed generator
        (on the learner's device, where the generator lives)."""
        shape = (self.env.num_envs, self.env.num_actions)
        return torch.rand(shape, generator=self.sac.generator, device=self.device) * 2.0 - 1.0

    def _log(
        self,
        update_stats: Mapping[str, list[float]],
        episode_stats: Mapping[str, list[torch.Tensor]],
        bar: tqdm,
    ) -> None:
        """Write means since the last log: losses over the updates that reported them, episode stats over
        finished episodes."""
        assert self._writer is not None
        for key, values in update_stats.items():
            self._writer.add_scalar(f"losses/{key}", sum(values) / len(values), self.step)
        postfix = {}
        for key, chunks in episode_stats.items():
            mean = torch.cat(chunks).float().mean().item()
            self._writer.add_scalar(f"episode/{key}", mean, self.step)
            postfix[key] = f"{mean:.3g}"
        self._writer.add_scalar("charts/transitions", self.num_transitions, self.step)
        self._writer.add_scalar("charts/train_time_s", self.train_time_s, self.step)
        if postfix:
            bar.set_postfix(postfix, refresh=False)

    def policy(self) -> NumpyPolicy:
        """The actor's deterministic policy, tanh of its mean, as a live view of its weights."""
        return sac_policy(self.sac.actor)

    def _checkpoint(self, on_checkpoint: OnCheckpoint) -> None:
        """Hand the current policy to ``on_checkpoint``; log what it returns under ``eval/``."""
        assert self._writer is not None
        actor, step = self.sac.actor, self.step
        checkpoint = Checkpoint(
            step,
            self.num_transitions,
            self.train_time_s,
            self.policy(),
            lambda: {"actor": actor.state_dict(), "step": step},
        )
        for key, value in (on_checkpoint(checkpoint) or {}).items():
            self._writer.add_scalar(f"eval/{key}", value, self.step)

    def save(self) -> None:
        """Write ``replay.pt`` then ``model.pt`` into the run directory, each atomically.

        The replay is written first so that ``model.pt``, which holds the step counter, never runs ahead of
        the replay content it was saved with.
        """
        self.run_dir.mkdir(parents=True, exist_ok=True)
        save_checkpoint(self.sac.replay.state_dict(), self.run_dir / REPLAY_FILE)
        save_checkpoint(
            {
                "sac": self.sac.state_dict(),
                "config": self.sac.config.model_dump(),
                "step": self.step,
                "train_time_s": self.train_time_s,
                "update_debt": self._update_debt,
            },
            self.run_dir / MODEL_FILE,
        )

    def load(self, run_dir: str | os.PathLike[str]) -> None:
        """Resume from a run directory written by ``save``: networks, optimisers, replay, step counter.

        The env's in-progress episodes are not saved: the next ``learn`` starts from a fresh reset.
        """
        run_dir = Path(run_dir)
        # On CPU: the generator state must stay there; load_state_dict moves the rest to the learner's device.
        model = load_checkpoint(run_dir / MODEL_FILE, "cpu")
        if SACConfig(**model["config"]) != self.sac.config:
            raise ValueError(f"config in {run_dir / MODEL_FILE} differs from this runner's config")
        self.sac.load_state_dict(model["sac"])
        self.sac.replay.load_state_dict(load_checkpoint(run_dir / REPLAY_FILE, "cpu"))
        self.step = int(model["step"])
        self.train_time_s = float(model["train_time_s"])
        self._update_debt = float(model["update_debt"])
        self._obs = None
        self.close()

    def close(self) -> None:
        """Close the TensorBoard writer (``learn`` does as it returns); a later ``learn`` opens a new one."""
        if self._writer is not None:
            self._writer.close()
            self._writer = None
