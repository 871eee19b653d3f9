"""The one episode loop: a policy plays one seeded episode per field of a core to its end.

With the same seed every policy meets the same starts, targets and obstacle motion. ``Recorder`` keeps
the poses and sub-goals of chosen episodes, every control step, for figures and videos.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from tqdm import tqdm

from hier_ssl.envs.core import HierarchicalCore

Policy = Callable[[np.ndarray], np.ndarray]
"""Manager observations (B, obs_dim) -> actions (B, act_dim) in [-1, 1], one row per live robot."""


def play(
    core: HierarchicalCore, policy: Policy, seed: int, record: Sequence[int] = (), progress: str | None = None
) -> dict[str, Any]:
    """Reset ``core`` (built without auto-reset) with ``seed``, one episode per field, and play every
    episode to its end; the policy acts for the live robots only (its input rows shrink as robots leave).
    The one episode loop: training's model selection, ``hier-ssl eval``, the goToPoint workers'
    evaluation and ``hier-ssl render`` all run it.

    Returns length (control steps), success, collision, cpad, cpad_public, distance (start to target, m),
    start_gap (to the nearest other robot at reset, m) and the scenario's ``stat_names`` (the game's
    ``foul`` and ``foul_<kind>``), arrays (N, M) of the controlled robots, and
    "trajectories": the ``record`` fields' episodes (``Recorder.episode``). ``cpad`` is the paper's
    definition (the sum of the sub-goal's moves); ``cpad_public`` what the paper's public code computed for
    its tables, the square root of the sum of the squared moves (``hier_ssl.manager.metrics.cpad``).

    With ``progress`` (its label) a tqdm bar on stderr counts control steps up to the episode limit, the
    robots whose episode ended beside it.

    A policy with a ``forget(count)`` method keeps a memory per robot: it is told to forget at the reset
    (``count`` = N * M robots) and called as ``policy(obs, rows=...)``, the rows' robot indices
    (field * M + robot), so that each robot's memory follows it and starts empty with its episode.
    """
    record = check_record(record, core.num_fields)
    obs = core.reset(seed)
    recorder = Recorder(core, record) if record else None
    shape = core.active.shape
    pos = core.world.state.pos
    start = pos[:, : shape[1]]
    distance = np.linalg.norm(start - core.target[..., 0:2], axis=2)
    # Centre distance to the nearest other robot at reset: under the collision distance the episode
    # begins in contact (the public code's 0.2 m starts with a midpoint obstacle allow it).
    gaps = np.linalg.norm(start[:, :, None] - pos[:, None], axis=-1)
    gaps[:, np.arange(shape[1]), np.arange(shape[1])] = np.inf
    start_gap = gaps.min(axis=2, initial=np.inf)
    ends = {
        "length": np.zeros(shape, dtype=np.int64),
        "success": np.zeros(shape, dtype=bool),
        "collision": np.zeros(shape, dtype=bool),
        "cpad": np.zeros(shape),
        # The scenario's own statistics (the game's fouls), as its episode statistics give them.
        **{name: np.zeros(shape) for name in core.scenario.stat_names},
    }
    action = np.zeros(shape + (core.act_dim,))
    squared_moves = np.zeros(shape)
    # A policy with a memory per robot (the ``trajectory`` planner) starts afresh and learns which robots
    # its rows are: row field * M + robot.
    remembers = callable(getattr(policy, "forget", None))
    if remembers:
        policy.forget(int(np.prod(shape)))
    # Control steps, not finished robots: most episodes end near the same step, so a count of them would
    # stand still and then jump, while the time an evaluation takes grows with its steps.
    bar = tqdm(total=core.config.max_steps, desc=progress, unit="step", disable=progress is None, leave=False)
    while core.active.any():
        live = core.active
        if remembers:
            action[live] = policy(obs[live], rows=np.flatnonzero(live))
        else:
            action[live] = policy(obs[live])
        # The first decision's move away from the reset sub-goal (the robot's own pose) is no move.
        moving, before = live & (core.decisions > 0), core.subgoal[..., 0:2].copy()
        result = core.step(action)
        moved = np.sum((core.subgoal[..., 0:2] - before) ** 2, axis=-1)
        squared_moves += np.where(moving, moved, 0.0)
        episode = result.info["task"]
        at = (episode["field"], episode["agent"])
        for key in ends:
            ends[key][at] = episode[key] > 0 if ends[key].dtype == bool else episode[key]
        obs = result.obs
        if progress is not None:  # the bar's figures cost two reductions a decision: only for a shown bar
            bar.update(int(core.steps.max()) - bar.n)
            done = live.size - int(core.active.sum())
            bar.set_postfix_str(f"{done}/{live.size} robots done", refresh=False)
    bar.close()
    # A field's control steps stop counting when its last robot leaves: the recorded episode's length.
    trajectories = [recorder.episode(j, int(core.steps[i])) for j, i in enumerate(record)] if recorder else []
    cpad_public = np.sqrt(squared_moves)
    return {
        **ends,
        "cpad_public": cpad_public,
        "distance": distance,
        "start_gap": start_gap,
        "trajectories": trajectories,
    }


def check_record(record: Sequence[int], episodes: int) -> list[int]:
    """Episode indices to record, as ints; ValueError naming them if any is out of range."""
    record = [int(i) for i in record]
    if any(not 0 <= i < episodes for i in record):
        raise ValueError(f"record: episode indices must be in [0, {episodes}), got {record}")
    return record


class Recorder:
    """Poses and sub-goals of chosen fields after every control step, by wrapping a core's
    ``control_step`` (the batched path of ``step`` is unchanged; the copies are of a few rows)."""

    def __init__(self, core: Any, fields: Sequence[int]) -> None:
        self.core, self.fields = core, np.asarray(fields)
        self.target = core.target[self.fields].copy()
        s = core.world.state
        self.pos, self.angle, self.subgoal = [s.pos[self.fields]], [s.angle[self.fields]], []
        self._step = core.control_step
        core.control_step = self.control_step  # instance attribute: only this core is affected

    def control_step(self, live: np.ndarray, *args: object, **kwargs: object) -> tuple:
        out = self._step(live, *args, **kwargs)
        s = self.core.world.state  # replaced by every world step; fancy indexing copies
        self.pos.append(s.pos[self.fields])
        self.angle.append(s.angle[self.fields])
        self.subgoal.append(self.core.subgoal[self.fields])
        return out

    def episode(self, j: int, length: int) -> dict[str, object]:
        """Recorded field ``j`` over its ``length`` control steps, M controlled robots (robots 0..M-1) of
        R: ``controlled`` M; target (M, 5); robots (T+1, R, 2) and angles (T+1, R) from the reset on;
        subgoal (T, M, 5), the sub-goals in force at each control step. Metres, radians, field frame."""
        return {
            "field": int(self.fields[j]),
            "controlled": self.target.shape[1],
            "target": self.target[j],
            "robots": np.stack([p[j] for p in self.pos[: length + 1]]),
            "angles": np.stack([a[j] for a in self.angle[: length + 1]]),
            "subgoal": np.stack([g[j] for g in self.subgoal[:length]]).reshape(length, -1, 5),
        }


__all__ = ["Policy", "Recorder", "check_record", "play"]
