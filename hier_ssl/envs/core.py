"""The one batched core: N fields of a scenario, M controlled robots and K obstacles each, as numpy arrays.

Every field holds M controlled robots (robots 0..M-1, agents ``manager_i``) and K obstacles (robots
M..M+K-1) placed and moved as the scenario (``hier_ssl.envs.scenario``) says: the paper's tasks (M = 1) and
the multi-robot scenarios run here alike. Each controlled robot has its own target, manager decision,
sub-goal and worker; one manager decision holds every sub-goal for ``frame_skip`` control steps of 25 ms,
the workers and obstacles act every control step. Observations, rewards, success and collisions are the
pure functions of ``hier_ssl.manager``, applied to the (field, robot) pairs as rows:

- a robot leaves the episode when it succeeds (the task's success rule) or collides (centres closer than
  ``collision_distance`` to any other robot, or touching one); a collision between two controlled robots
  counts for both. A robot that has left holds still where it is and stays an obstacle to the others;
- the field's episode ends when no robot is left in it, or at ``max_steps`` (the rest are truncated).

The core trusts its inputs (the views and ``World`` check what enters); arrays are (N, M, ...) throughout.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from operator import itemgetter
from typing import Any

import numpy as np

from hier_ssl.config import TaskConfig
from hier_ssl.envs.decisions import take_decisions, tally_control_step
from hier_ssl.envs.registry import make_scenario
from hier_ssl.envs.rules import Rules
from hier_ssl.envs.scenario import Scenario
from hier_ssl.envs.step_guard import abandon, hold
from hier_ssl.manager.actions import SubgoalDecoder
from hier_ssl.manager.neighbours import neighbour_observation
from hier_ssl.manager.observation import first_robot_observation, observation_scales
from hier_ssl.worker import Worker, resolve_worker
from hier_ssl.worker.observation import controlled_worker_observation, scale_command
from hier_ssl.world.obstacles import make_obstacle
from hier_ssl.world.physics import RobotState, World


@dataclass
class StepResult:
    """One manager decision period (or one control step) of every field. Shapes: obs (N, M, O) float32;
    reward (N, M) float32; terminated, truncated (N, M) bool, True for robots that left in this period;
    info as documented in ``HierarchicalCore.step``. (The goToPoint learning task's core, one robot a
    field, returns it without the M axis.)"""

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    info: dict[str, Any]


class HierarchicalCore:
    """N fields of one scenario: ``reset``, ``step(actions (N, M, A))``, ``observe``.

    ``task`` is a task config (``EnvConfig`` or ``ScenarioConfig``) or a built scenario; ``worker`` (a
    spec, or an object, class or factory of the worker protocol: ``hier_ssl.worker.resolve_worker``)
    replaces the one the config names. ``active`` (N, M) says which robots are still in their episode.
    ``autoreset`` resets a field inside ``step`` once no robot is left in it (vector view); without it a
    finished field holds still until ``reset`` (PettingZoo view, evaluation: one episode per field).
    """

    def __init__(
        self,
        task: TaskConfig | Scenario,
        num_fields: int = 1,
        autoreset: bool = True,
        worker: str | Worker | None = None,
    ) -> None:
        scenario = task if isinstance(task, Scenario) else make_scenario(task)
        self.scenario, self.config = scenario, scenario.config
        cfg = self.config
        self.num_fields, self.autoreset = num_fields, autoreset
        m, k = scenario.num_agents, scenario.num_obstacles
        self.num_agents, self.num_obstacles = m, k
        self.world = World(num_fields, m + k, scenario.field, dt=cfg.dt, substeps=cfg.substeps)
        self.field, self.robot = self.world.field, self.world.robot
        self.worker = resolve_worker(cfg.worker if worker is None else worker, self.robot, cfg.dt)
        # Each group's behaviour moves its obstacles as rows (field f, obstacle j) -> f * count + j.
        self.obstacles: list[tuple[Any, slice]] = []
        first = m
        for group in scenario.groups:
            behaviour = make_obstacle(group.behaviour, num_fields * group.count, **group.options)
            self.obstacles.append((behaviour, slice(first, first + group.count)))
            first += group.count
        self.obs_dim, self.act_dim = scenario.obs_dim, scenario.act_dim
        self._layout = scenario.observation
        self.theta_th = np.deg2rad(cfg.theta_th_deg)
        self.rules = Rules(scenario.reward_task, cfg)
        sizes = [scenario.scales[k] for k in ("half_length", "half_width", "max_v")]
        self._decode = SubgoalDecoder(cfg.action_form, *sizes, scenario.zero_velocity, cfg.action_frame)
        # The observation's scales as 0-d arrays (see ``Rules``).
        self._limits = {k: np.array(scenario.scales[k]) for k in ("max_pos", "max_v", "max_w")}
        # The paper layout's divisors (robot 0 observed, the others its obstacles).
        self._obs_scales = observation_scales(m + k - 1, *(float(v) for v in self._limits.values()))
        self._sum_rewards = cfg.frame_skip_reward == "sum"
        # others[i]: every robot but robot i, the ones it sees and can hit; teammate: which are controlled.
        # _others_of(pos) (N, M, R - 1, 2): a view for one controlled robot, else np.take (a tenth of the cost
        # of indexing with the array).
        others = np.array([[j for j in range(m + k) if j != i] for i in range(m)], dtype=np.int64)
        self._others = others.reshape(m, m + k - 1)
        self._teammate, take = self._others < m, partial(np.take, indices=self._others, axis=1)
        self._others_of = itemgetter(np.s_[:, None, 1:]) if m == 1 else take
        self._own = None if k == 0 else np.s_[:, :m]  # the controlled robots' columns, all if no obstacles
        self.rng = np.random.default_rng()
        self.control_steps = 0  # world steps taken since construction, for throughput figures
        self.interrupted = False  # an exception stopped a decision part-way: no step until reset()

        n = num_fields
        self.target = np.zeros((n, m, 5))
        self.subgoal = np.zeros((n, m, 5))
        self.active = np.zeros((n, m), dtype=bool)
        self.steps = np.zeros(n, dtype=np.int64)  # control steps of each field since its reset
        self.decisions = np.zeros((n, m), dtype=np.int64)
        self.ep_return = np.zeros((n, m))
        self.ep_length = np.zeros((n, m), dtype=np.int64)  # control steps each robot was live for
        self.ep_cpad = np.zeros((n, m))
        self._held = None  # the rules' part that sub-goals and targets fix (``Rules.decision_terms``)
        self._nobody = np.zeros((n, m), dtype=bool)
        self._no_stats = self._stats(np.zeros(0, dtype=np.int64), self._nobody, self._nobody)

    @property
    def done(self) -> np.ndarray:
        """(N,) bool: no robot is left in the field's episode."""
        return ~self.active.any(axis=1)

    @property
    def state(self) -> RobotState:
        return self.world.state

    # -- reset ---------------------------------------------------------------------------------------------

    def seed(self, seed: int | None) -> None:
        """Seed the episodes' draws and, where it takes a seed, the worker (``hier_ssl.worker.Worker``)."""
        self.rng = np.random.default_rng(seed)
        seed_worker = getattr(self.worker, "seed", None)
        if seed is not None and seed_worker is not None:
            seed_worker(seed)

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Start a new episode in every field. Returns the observations (N, M, obs_dim)."""
        if seed is not None:
            self.seed(seed)
        self.reset_fields(np.arange(self.num_fields))
        self.interrupted = False
        return self.observe()

    def reset_fields(self, fields: np.ndarray) -> None:
        """New starts, targets and obstacles for ``fields`` (F,) ints, from the scenario."""
        if len(fields) == 0:
            return
        m = self.num_agents
        layout = self.scenario.reset_world_at(len(fields), self.rng)
        # A scenario is a user's class: its layout is checked here, once a reset (World.set_state checks
        # the robots' part), and trusted afterwards.
        if layout.target.shape != (len(fields), m, 5):
            raise ValueError(
                f"scenario {self.scenario.name!r}: layout target has shape {layout.target.shape}, "
                f"expected {(len(fields), m, 5)}"
            )
        self.world.set_state(fields, layout.pos, layout.angle, layout.vel, layout.ang_vel)
        self.target[fields] = layout.target
        # Until the first decision the sub-goal is the robot's own pose: the worker holds still.
        self.subgoal[fields] = 0.0
        self.subgoal[fields, :, 0:2] = layout.pos[:, :m]
        self.subgoal[fields, :, 2] = layout.angle[:, :m]
        self.active[fields] = True
        self.steps[fields], self.decisions[fields], self.ep_length[fields] = 0, 0, 0
        self.ep_return[fields], self.ep_cpad[fields] = 0.0, 0.0
        self.worker.reset(fields)
        for behaviour, robots in self.obstacles:
            count = robots.stop - robots.start
            behaviour.reset((fields[:, None] * count + np.arange(count)).ravel(), self.rng)
        self._hold()

    def _hold(self) -> None:
        """Whatever the rules can compute once for the current sub-goals and targets (after every change)."""
        self._held = self.rules.decision_terms(self.target, self.subgoal)

    # -- observations --------------------------------------------------------------------------------------

    def observe(self, fields: np.ndarray | None = None, state: RobotState | None = None) -> np.ndarray:
        """Manager observations (F, M, obs_dim) float32 of ``fields`` (default all) in the scenario's layout,
        of the world's robots or of ``state`` (N, M + K: the deploy view's tracked ones); left ones too."""
        s = self.world.state if state is None else state
        s = s if fields is None else s.fields(fields)
        target = self.target if fields is None else self.target[fields]
        f, m = target.shape[:2]
        b, limits = f * m, self._limits
        if self._layout == "paper":  # one robot (column 0): the others are its obstacles
            obs = first_robot_observation(target, s, self._obs_scales)
        else:
            rows = (
                target.reshape(b, 5),
                s.pos[:, :m].reshape(b, 2),
                s.angle[:, :m].reshape(b),
                s.vel[:, :m].reshape(b, 2),
                s.ang_vel[:, :m].reshape(b),
            )
            j = self._others.shape[1]
            teammate = np.broadcast_to(self._teammate, (f, m, j)).reshape(b, j)
            others_pos = self._others_of(s.pos).reshape(b, j, 2)
            others_vel = self._others_of(s.vel).reshape(b, j, 2)
            extra = {"encounters": self._layout == "encounters"}
            obs = neighbour_observation(
                *rows, others_pos, others_vel, teammate, self.config.neighbours, **limits, **extra
            )
        return obs.reshape(f, m, self.obs_dim)

    def observe_worker(self) -> np.ndarray:
        """Worker observations (N, M, 9) float32."""
        return controlled_worker_observation(self.world.state, self.subgoal, self.robot, self.field.max_pos)

    # -- acting --------------------------------------------------------------------------------------------

    def set_subgoal(self, action: np.ndarray, live: np.ndarray) -> np.ndarray:
        """Decode actions (N, M, act_dim) float64 into held sub-goals of the ``live`` (N, M) robots, in the
        field or the target frame (``action_frame``); values outside [-1, 1] are clipped, sub-goals to the
        field. Returns how many values were clipped per robot (N, M), 0 where not live."""
        n, m = live.shape
        decoded = self._decode(action.reshape(n * m, self.act_dim), self.target.reshape(n * m, 5))
        clipped, held = np.empty((n, m), dtype=np.int64), (self.subgoal, self.decisions, self.ep_cpad)
        take_decisions(action, decoded.reshape(n, m, 5), live, *held, clipped)
        self._hold()
        return clipped

    def hold_subgoal(self, subgoal: np.ndarray) -> None:
        """Hold ``subgoal`` (N, M, 5) as if decoded (the deploy field server's managers act elsewhere)."""
        np.copyto(self.subgoal, subgoal)
        self._hold()

    def control_step(
        self,
        live: np.ndarray,
        worker_action: np.ndarray | None = None,
        obstacle_actions: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One 25 ms step of every field; robots not ``live`` (N, M) hold still and score nothing, and so do
        the obstacles of fields without a live robot. ``worker_action`` (N, M, 3) and ``obstacle_actions``
        (N, K, 3), normalised to [-1, 1], replace the workers and obstacles when those are exposed as agents.

        Returns reward (N, M), success (N, M) and collision (N, M), both only where live.
        """
        s, n, m = self.world.state, self.num_fields, self.num_agents
        # A field is live while any of its robots is (with one robot, a view of its column: no call).
        field_live = live[:, 0] if m == 1 else np.logical_or.reduce(live, axis=1)
        command = np.zeros((n, m + self.num_obstacles, 3))
        if worker_action is None:
            own = self.worker(self._controlled(s), self.subgoal)
        else:
            own = scale_command(np.clip(worker_action, -1.0, 1.0), self.robot)
        np.copyto(command[:, :m], own, where=live[..., None])
        moving = field_live[:, None, None]
        if obstacle_actions is None:
            for behaviour, robots in self.obstacles:
                count = robots.stop - robots.start
                pos, angle = s.pos[:, robots].reshape(n * count, 2), s.angle[:, robots].reshape(n * count)
                np.copyto(
                    command[:, robots], behaviour(pos, angle, self.rng).reshape(n, count, 3), where=moving
                )
        else:
            np.copyto(
                command[:, m:], scale_command(np.clip(obstacle_actions, -1.0, 1.0), self.robot), where=moving
            )
        s = self.world.step(command)
        self.control_steps += 1
        self.steps = self.steps + field_live.astype(np.int64)

        # The controlled robots' columns as views (a RobotState of them costs twice as many calls).
        own = self._own
        pos, angle, vel = (s.pos, s.angle, s.vel) if own is None else (s.pos[own], s.angle[own], s.vel[own])
        others, touching = self._others_of(s.pos), self.world.robot_touch[:, :m]
        reward, success, hit = self.rules(
            self._held, self.target, self.subgoal, pos, angle, vel, others, touching
        )
        return reward, success & live, hit & live

    def _controlled(self, s: RobotState) -> RobotState:
        """Robots 0..M-1 of ``s``: ``s`` itself when every robot is controlled (no slicing to do)."""
        return s if self.num_obstacles == 0 else s.robots(slice(0, self.num_agents))

    def step(self, action: np.ndarray) -> StepResult:
        """One manager decision in every field: the live robots' sub-goals (``action`` (N, M, A) float64)
        held for ``frame_skip`` control steps, rewards summed over them ("sum") or the last one taken
        ("last"). A robot that leaves inside the period stops scoring there.

        ``info`` holds, per robot (N, M): ``control_steps`` it was live for, ``success``, ``collision``,
        ``action_clipped``, ``subgoal`` (N, M, 5) and ``live`` (the robots this decision acted for);
        ``final_obs`` (N, M, O), the observation before any auto-reset; and ``task``, the task's episode
        statistics, one entry per robot that left: ``field``, ``agent``, ``return``, ``length`` (control
        steps), ``decisions``, ``success``, ``collision``, ``cpad``. (Not ``episode``: Gymnasium's
        ``RecordEpisodeStatistics`` and SB3's ``Monitor`` write that key; every view passes ``task`` on.)
        """
        cfg = self.config
        start = self.active.copy()
        if not np.count_nonzero(start):
            raise RuntimeError("step() with every episode finished: call reset() first")
        held = hold(self)
        clipped = self.set_subgoal(action, start)
        # New arrays every decision (the result hands them out), updated in place by one compiled loop a
        # control step.
        shape = start.shape
        live, reward, elapsed = start.copy(), np.zeros(shape), start.astype(np.int64)
        success, collision, timeout = np.zeros(shape, bool), np.zeros(shape, bool), np.zeros(shape, bool)
        running, max_steps = (live, reward, success, collision, elapsed, timeout), cfg.max_steps
        try:
            for k in range(cfg.frame_skip):
                r, succ, hit = self.control_step(live)
                add, count = k > 0 and self._sum_rewards, k + 1 < cfg.frame_skip
                if not tally_control_step(r, succ, hit, self.steps, max_steps, add, count, start, *running):
                    break
        except Exception:  # from the worker: undone, or the core needs a reset (step_guard)
            abandon(self, held)
            raise
        return self.finish(start, reward, success, collision, timeout, elapsed, clipped)

    def finish(
        self,
        start: np.ndarray,
        reward: np.ndarray,
        success: np.ndarray,
        collision: np.ndarray,
        timeout: np.ndarray,
        elapsed: np.ndarray,
        clipped: np.ndarray,
    ) -> StepResult:
        """Book-keeping after a decision period (or, for a view with exposed agents, one control step):
        returns, per-robot episode statistics, auto-reset. Every argument (N, M)."""
        # New arrays rather than updates in place (see ``step``): the counters are replaced, never kept.
        self.ep_return = self.ep_return + reward
        self.ep_length = self.ep_length + elapsed
        left = success | collision | timeout
        # Rows of the robots that left, row = field * M + robot; most decisions have none, and share the
        # same empty columns (an empty array cannot change).
        rows = left.ravel().nonzero()[0]
        stats = self._stats(rows, success, collision) if len(rows) else dict(self._no_stats)
        info: dict[str, Any] = {
            "control_steps": elapsed,
            "success": success,
            "collision": collision,
            "action_clipped": clipped,
            "subgoal": self.subgoal.copy(),
            "live": start,
            "task": stats,
        }
        self.active = self.active > left
        obs = info["final_obs"] = self.observe()
        if self.autoreset and len(rows):
            finished = np.flatnonzero(self.done)
            if len(finished):
                obs = obs.copy()
                self.reset_fields(finished)
                obs[finished] = self.observe(finished)
        return StepResult(obs, reward.astype(np.float32), success | collision, timeout, info)

    def _stats(self, rows: np.ndarray, success: np.ndarray, collision: np.ndarray) -> dict[str, Any]:
        """``info["task"]``: episode statistics of the robots at flat ``rows``; take() reads flat, copies."""
        field, agent = np.divmod(rows, self.num_agents)
        return {
            "field": field,
            "agent": agent,
            "return": self.ep_return.take(rows),
            "length": self.ep_length.take(rows),
            "decisions": self.decisions.take(rows),
            "success": success.take(rows).astype(np.float64),
            "collision": collision.take(rows).astype(np.float64),
            "cpad": self.ep_cpad.take(rows),
        }


__all__ = [
    "HierarchicalCore",
    "StepResult",
]
