"""Ring replay buffer of preallocated tensors."""

from __future__ import annotations

from typing import NamedTuple

import torch


class Batch(NamedTuple):
    """A set of transitions. Shapes: obs, next_obs (B, obs_dim); actions (B, act_dim); rewards,
    terminated (B,) float32 (terminated is 1.0 where the episode truly ended, 0.0 otherwise);
    teacher_actions (B, act_dim), a teacher's action for obs, in a buffer that keeps them (else None)."""

    obs: torch.Tensor
    actions: torch.Tensor
    rewards: torch.Tensor
    next_obs: torch.Tensor
    terminated: torch.Tensor
    teacher_actions: torch.Tensor | None = None


class ReplayBuffer:
    """Fixed-capacity FIFO of transitions stored in preallocated tensors on ``device``.

    ``terminated`` is kept as float32 so the Bellman target can use it without a cast per update. With
    ``teacher`` the buffer also keeps a teacher's action for each observation (``Batch.teacher_actions``).
    """

    def __init__(
        self,
        capacity: int,
        obs_dim: int,
        act_dim: int,
        device: torch.device | str = "cpu",
        teacher: bool = False,
    ) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be >= 1, got {capacity}")
        self.capacity = capacity
        self.device = torch.device(device)
        self.obs = torch.zeros(capacity, obs_dim, device=self.device)
        self.actions = torch.zeros(capacity, act_dim, device=self.device)
        self.rewards = torch.zeros(capacity, device=self.device)
        self.next_obs = torch.zeros(capacity, obs_dim, device=self.device)
        self.terminated = torch.zeros(capacity, device=self.device)
        self._fields = Batch._fields if teacher else Batch._fields[:-1]
        if teacher:
            self.teacher_actions = torch.zeros(capacity, act_dim, device=self.device)
        self.pos = 0  # row the next transition is written to
        self.size = 0  # rows holding data

    def __len__(self) -> int:
        return self.size

    def add(
        self,
        obs: torch.Tensor,
        actions: torch.Tensor,
        rewards: torch.Tensor,
        next_obs: torch.Tensor,
        terminated: torch.Tensor,
        teacher_actions: torch.Tensor | None = None,
    ) -> None:
        """Append n transitions, overwriting the oldest ones once full.

        Shapes: obs, next_obs (n, obs_dim); actions (n, act_dim); rewards (n,); terminated (n,) bool or float;
        teacher_actions (n, act_dim), required by and only by a buffer that keeps them.
        """
        columns = (obs, actions, rewards, next_obs, terminated, teacher_actions)[: len(self._fields)]
        if (teacher_actions is None) != (len(columns) < len(Batch._fields)):
            keeps = "keeps" if len(columns) == len(Batch._fields) else "does not keep"
            raise ValueError(f"teacher_actions: this replay buffer {keeps} them")
        n = obs.shape[0]
        if n > self.capacity:
            # Only the newest `capacity` rows would survive; dropping the rest up front keeps the copy to
            # at most two contiguous slices.
            columns = tuple(x[-self.capacity :] for x in columns)
            n = self.capacity
        first = min(n, self.capacity - self.pos)  # rows before the wrap
        for name, src in zip(self._fields, columns, strict=True):
            dst = getattr(self, name)
            dst[self.pos : self.pos + first] = src[:first]
            dst[: n - first] = src[first:]
        self.pos = (self.pos + n) % self.capacity
        self.size = min(self.size + n, self.capacity)

    def sample(self, batch_size: int, generator: torch.Generator | None = None) -> Batch:
        """Uniform sample with replacement. Shapes as in ``Batch`` with B = batch_size."""
        if self.size == 0:
            raise RuntimeError("cannot sample from an empty replay buffer")
        idx = torch.randint(self.size, (batch_size,), generator=generator, device=self.device)
        return Batch(*(getattr(self, name)[idx] for name in self._fields))

    def state_dict(self) -> dict[str, torch.Tensor | int]:
        """Filled rows only (clones, so later writes do not change a saved dict), plus the write position."""
        state: dict[str, torch.Tensor | int] = {
            name: getattr(self, name)[: self.size].clone() for name in self._fields
        }
        state["pos"] = self.pos
        return state

    def load_state_dict(self, state: dict[str, torch.Tensor | int]) -> None:
        """Restore rows saved by ``state_dict``; the buffer may be larger than the saved one."""
        size = state["obs"].shape[0]
        if size > self.capacity:
            raise ValueError(f"saved buffer holds {size} transitions, more than capacity {self.capacity}")
        if ("teacher_actions" in state) != ("teacher_actions" in self._fields):
            raise ValueError("saved buffer and this one disagree on keeping teacher_actions")
        for name in self._fields:
            getattr(self, name)[:size] = state[name]
        self.size = size
        # A full saved ring keeps its write position only if the capacity is unchanged; otherwise new rows go
        # after the restored ones.
        self.pos = int(state["pos"]) % self.capacity if size == self.capacity else size
