"""The deploy view of the core: tracked robots in, held sub-goals and robot-frame commands out.

One more view of ``HierarchicalCore``, as the PettingZoo and torch views are: a manager given as a run
directory or a scripted planner acts through a one-step core of its own task, whose ``observe`` (given
the tracked state instead of the world's), ``set_subgoal`` (the action decoding) and ``worker`` are the
functions every evaluation calls; only the state's source differs. An exported TorchScript or ONNX file
(``hier-ssl export``) carries observation and decoding inside its graph and is called on the raw state
rows its stored layout names; the worker is the one ``hier_ssl.worker.resolve_worker`` builds for the
same spec.

Robots: a one-robot manager (the paper's tasks) acts for each controlled robot in a field of its own
(N = robots, M = 1), a scenario manager for all of them in one field (N = 1, M = robots). Each field
holds its M controlled robots and the task's K other robots: the tracked robots nearest to the field's
controlled ones, any team; missing ones stand still in the far corner of the walls.
"""

from __future__ import annotations

import json
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from hier_ssl.config import ScenarioConfig, TaskConfig
from hier_ssl.deploy.tracker import follow
from hier_ssl.envs import make_scenario, task_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.game import GameScenario
from hier_ssl.envs.planners import is_planner, make_planner
from hier_ssl.game.legal import RowRules, cap_speed, nearest_legal
from hier_ssl.game.referee import RefereeState
from hier_ssl.manager.planners import PLANNERS
from hier_ssl.worker import Worker, resolve_worker
from hier_ssl.world.field import get_field
from hier_ssl.world.physics import RobotSpec, RobotState

EXPORTED = (".pt", ".onnx")
PLANNER_FRAME_SKIP = 16  # the paper's FSCAPS decision period, as ``hier-ssl eval`` gives planners


def load_exported(path: str | Path) -> tuple[Callable[[np.ndarray], np.ndarray], dict[str, Any]]:
    """An exported manager file as ``rows (B, D) float32 -> sub-goals (B, 5)`` and its stored layout.
    Needs torch (TorchScript) or onnxruntime (ONNX), no hier_ssl policy code. A TorchScript file runs on
    torch's threads: a controller process sets ``torch.set_num_threads(1)`` (``hier-ssl deploy`` does)."""
    path = Path(path)
    if path.suffix == ".pt":
        import torch

        extra = {"layout.json": ""}
        with warnings.catch_warnings():  # torch 2.13 deprecates TorchScript, which C++ stacks still load
            warnings.simplefilter("ignore", DeprecationWarning)
            module = torch.jit.load(str(path), _extra_files=extra)

        def call(rows: np.ndarray) -> np.ndarray:
            with torch.inference_mode():
                return module(torch.from_numpy(rows)).numpy()

        return call, json.loads(extra["layout.json"])
    if path.suffix == ".onnx":
        try:
            import onnxruntime
        except ModuleNotFoundError:  # an optional extra: say which, not a traceback
            raise ValueError(
                f"{path} is ONNX, which runs on onnxruntime: pip install -e '.[export]' (or pip install "
                "onnxruntime), or export the run as TorchScript (--format torchscript)"
            ) from None

        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = 1  # a few rows a call: a pool's wake-ups cost more than they save
        session = onnxruntime.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        meta = session.get_modelmeta().custom_metadata_map
        return (lambda rows: session.run(None, {"state": rows})[0]), json.loads(meta["layout"])
    raise ValueError(f"exported manager {str(path)!r}: expected a {' or '.join(EXPORTED)} file")


def exported_rows(target: np.ndarray, state: RobotState, m: int) -> np.ndarray:
    """An exported file's input (N * M, 11 + w J) float32 for fields whose first ``m`` robots are
    controlled: each one's target (from ``target`` (N, M, 5)) and own state, then every other robot of its
    field (``state``: (N, R) robots), with a teammate flag (w = 6) where M > 1."""
    n, r = state.pos.shape[:2]
    own = np.concatenate(
        [state.pos[:, :m], state.angle[:, :m, None], state.vel[:, :m], state.ang_vel[:, :m, None]], axis=2
    )
    motion = [state.pos, state.vel, state.ang_vel[..., None]]  # (N, R, 5) once joined
    others = _others(m, r)  # (M, R - 1): robot i's others in order
    if m > 1:
        motion.append(np.broadcast_to((np.arange(r) < m).astype(np.float64)[None, :, None], (n, r, 1)))
    block = np.concatenate(motion, axis=2)[:, others]  # (N, M, R - 1, 5 or 6)
    rows = np.concatenate([target, own, block.reshape(n, m, -1)], axis=2)
    return rows.reshape(n * m, -1).astype(np.float32)


@lru_cache(maxsize=8)
def _others(m: int, r: int) -> np.ndarray:
    """(M, R - 1) the indices of every robot but i, in order, for each of the first ``m`` of ``r``."""
    return np.array([[j for j in range(r) if j != i] for i in range(m)], dtype=np.int64)


def manager_task(
    manager: str, task: str | None = None, frame_skip: int | None = None, worker: str | None = None
) -> TaskConfig:
    """The task a manager acts in: a run's own, an exported file's stored task, or for a planner the
    ``task`` (default "obstacle") deciding every ``PLANNER_FRAME_SKIP`` control steps; ``frame_skip`` and
    ``worker`` override."""
    overrides: dict[str, Any] = {}
    if worker is not None:
        overrides["worker"] = worker
    if frame_skip is not None:
        overrides["frame_skip"] = frame_skip
    if is_planner(manager):
        overrides.setdefault("frame_skip", PLANNER_FRAME_SKIP)
        return task_config(task or "obstacle", **overrides)
    if Path(manager).suffix in EXPORTED:
        layout = load_exported(manager)[1]
        keys = ("field", "action_form", "observation", "action_frame", "frame_skip")
        return task_config(layout["task"], **{k: layout[k] for k in keys} | overrides)
    from hier_ssl.checkpoints.actor import run_config

    if not Path(manager).is_dir():
        raise ValueError(
            f"manager {manager!r}: neither a planner {list(PLANNERS)}, an exported file nor a run"
        )
    base = run_config(manager).task_config
    return task_config(base, **overrides) if overrides else base


@dataclass
class Fields:
    """Which tracked robots fill each field: ``controlled`` (N, M) and ``others`` (N, K) row indices into
    the tracked state, -1 where a robot is missing."""

    controlled: np.ndarray
    others: np.ndarray


class DeployView:
    """Sub-goals and commands for ``robots`` controlled robots from tracked states (module docstring)."""

    def __init__(self, manager: str, num_robots: int, config: TaskConfig) -> None:
        if isinstance(config, ScenarioConfig) and config.num_agents not in (1, num_robots):
            config = config.model_copy(update={"num_agents": num_robots})
        scenario = make_scenario(config)
        m = scenario.num_agents
        n = num_robots // m
        self.core = HierarchicalCore(scenario, num_fields=n, autoreset=False)
        self.exported: Callable[[np.ndarray], np.ndarray] | None = None
        self.policy: Callable[[np.ndarray], np.ndarray] | None = None
        k = self.core.num_obstacles
        if Path(manager).suffix in EXPORTED:
            self.exported, layout = load_exported(manager)
            k = layout["obstacles"] + layout["teammates"] + 1 - m
            for _ in range(2):  # TorchScript optimises its graph on the first calls (0.1 s): not in a period
                self.exported(np.zeros((n * m, layout["input_shape"][1]), dtype=np.float32))
        elif is_planner(manager):
            self.policy = make_planner(manager, config)
        else:
            from hier_ssl.policies.actor import load_policy

            self.policy = load_policy(manager)
        self.n, self.m, self.k = n, m, k
        self.frame_skip = config.frame_skip
        self.worker: Worker = (
            self.core.worker
            if self.exported is None
            else resolve_worker(config.worker, RobotSpec(), config.dt)
        )
        self.worker.reset(np.arange(n))
        self.robot, self.dt = RobotSpec(), config.dt
        self.field = get_field(config.field)
        self.reach = np.array(self.field.wall_half_extent) - self.robot.radius
        self.planner = is_planner(manager)
        # A game scenario observes the referee's state and the ball (its planner reads its rules there).
        self.game = isinstance(scenario, GameScenario)
        # The core's arrays: its decoding writes sub-goals there, the observation reads targets there.
        self.target, self.subgoal = self.core.target, self.core.subgoal

    def fields(self, rows: np.ndarray) -> Fields:
        """Fill the fields from tracked rows (T, 6) whose first N * M are the controlled robots in order;
        NaN rows are robots not seen. A field's others are the K seen robots nearest to its own, the
        other fields' controlled robots included."""
        n, m, k = self.n, self.m, self.k
        controlled = np.arange(n * m).reshape(n, m)
        others = np.full((n, k), -1, dtype=np.int64)
        if k:
            gap = np.linalg.norm(rows[controlled, None, 0:2] - rows[None, None, :, 0:2], axis=-1).min(axis=1)
            gap = np.where(np.isnan(gap), 1e9, gap)  # a field whose own robot is unseen: any robot will do
            gap[:, np.isnan(rows[:, 0])] = np.inf
            gap[np.arange(n)[:, None], controlled] = np.inf  # (N, T): to the field's nearest own robot
            order = np.argsort(gap, axis=1, kind="stable")[:, :k]
            found = np.isfinite(gap[np.arange(n)[:, None], order])
            others[:, : order.shape[1]] = np.where(found, order, -1)
        return Fields(controlled, others)

    def state(self, rows: np.ndarray, fields: Fields) -> RobotState:
        """The fields' robots (N, M + K) as the core's state; missing robots in the far corner, at rest."""
        index = np.concatenate([fields.controlled, fields.others], axis=1)  # (N, R)
        picked = rows[np.maximum(index, 0)]  # (N, R, 6)
        missing = (index < 0) | np.isnan(picked[..., 0])
        own = rows[fields.controlled[:, :1], 0:2]  # (N, 1, 2): the corner away from it, any if unseen
        corner = np.where(np.isnan(own), -1.0, -np.sign(own)) * self.reach
        picked = np.where(missing[..., None], 0.0, picked)
        pos = np.where(missing[..., None], corner, np.clip(picked[..., 0:2], -self.reach, self.reach))
        return RobotState(pos, picked[..., 2], picked[..., 3:5], picked[..., 5])

    def set_game(self, referee: RefereeState, ball: tuple[float, float] | None) -> None:
        """What a game scenario observes besides the robots, which it reads from its own state and world:
        the ``referee``'s state received (one field) and the ``ball`` tracked (m; None: not seen, where it
        was), in every field."""
        n = self.n
        self.core.scenario.referee = RefereeState(
            np.repeat(referee.command, n),
            np.repeat(referee.placement, n, axis=0),
            np.repeat(referee.keeper, n, axis=0),
            np.repeat(referee.blue_on_positive_half, n),
            np.repeat(referee.in_play, n),
        )
        if ball is not None:
            pos = np.broadcast_to(np.asarray(ball, dtype=float), (n, 1, 2))
            self.core.world.set_balls(np.arange(n), pos, np.zeros((n, 1, 2)))

    def decide(self, state: RobotState, live: np.ndarray, rules: RowRules | None = None) -> None:
        """New sub-goals for the ``live`` (N, M) robots, held in ``self.subgoal`` until the next call; under
        ``rules`` (one row per robot, field by field) where given: a planner plans with them, and every
        manager's sub-goal is moved to its nearest legal point, its speed capped at the limit (a learned
        manager was not trained with the rules: this is the least they ask of it)."""
        if not live.any():
            return
        rows = live.ravel()
        if self.exported is None:
            obs = self.core.observe(state=state)
            action = np.zeros((self.n, self.m, self.core.act_dim))
            if self.planner and rules is not None and not self.game:  # a game's reads them in its obs
                live_rules = RowRules(rules.zones.take(rows), rules.speed[rows])
                action[live] = self.policy(obs[live], rules=live_rules)
            else:
                action[live] = self.policy(obs[live])
            self.core.set_subgoal(action, live)
        else:
            self.subgoal[live] = self.exported(exported_rows(self.target, state, self.m)[rows])
        if rules is not None:
            subgoal = self.subgoal.reshape(-1, 5)  # a view: written through to the core's array
            subgoal[rows, 0:2] = nearest_legal(rules.zones.take(rows), subgoal[rows, 0:2])
            subgoal[rows, 3:5] = cap_speed(subgoal[rows, 3:5], rules.speed[rows])

    def commanded(self, state: RobotState, sent: np.ndarray) -> RobotState:
        """``state`` with the controlled robots moving as ``sent`` (N, M, 3) commands them: (forward, left,
        w) in each robot's frame, turned into the field frame."""
        m = self.m
        heading = np.exp(1j * state.angle[:, :m])
        field = (sent[..., 0] + 1j * sent[..., 1]) * heading
        vel, spin = state.vel.copy(), state.ang_vel.copy()
        vel[:, :m] = np.stack([field.real, field.imag], axis=-1)
        spin[:, :m] = sent[..., 2]
        return RobotState(state.pos, state.angle, vel, spin)

    def respond(self, vel: np.ndarray, spin: np.ndarray, sent: np.ndarray, angle: np.ndarray) -> tuple:
        """The controlled robots' velocities (N, M, 2) m/s and spins (N, M) rad/s one period after ``sent``
        (N, M, 3) robot-frame commands at headings ``angle`` (N, M), as the world's robots answer them
        (``hier_ssl.deploy.tracker.follow``, the tracker's model of its own robots)."""
        # Python floats: numpy's scalars would cost more than the arithmetic.
        flat = (vel.reshape(-1, 2), spin.ravel(), sent.reshape(-1, 3), angle.ravel())
        rows = zip(*(a.tolist() for a in flat), strict=True)
        new = [follow(vx, vy, w, command, a, self.dt, self.robot) for (vx, vy), w, command, a in rows]
        new = np.array(new).reshape(*spin.shape, 3)
        return new[..., 0:2], new[..., 2]

    def commands(self, state: RobotState) -> np.ndarray:
        """The worker's commands (N, M, 3) toward the held sub-goals: (forward, left, w), robot frame."""
        return self.worker(state.robots(slice(0, self.m)), self.subgoal)


__all__ = ["EXPORTED", "DeployView", "Fields", "exported_rows", "load_exported", "manager_task"]
