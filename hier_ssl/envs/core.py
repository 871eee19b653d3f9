"""The one batched core: N fields of a scenario, M controlled robots and K obstacles each, as numpy arrays.

Every field holds M controlled robots (robots 0..M-1, agents ``manager_i``) and K obstacles (robots
M..M+K-1) placed and moved as the scenario (``hier_ssl.envs.scenario``) says: the paper's tasks (M = 1) and
the multi-robot scenarios run here alike. Each controlled robot has its own target, manager decision,
sub-goal and worker; one manager decision holds every sub-goal for ``frame_skip`` control steps of 25 ms,
the workers and obstacles act every control step. The scenario observes, scores and ends; the core is the
loop around it, generic over scenarios:

- a robot leaves the episode when the scenario's ``score`` says it succeeded or collided; a robot that has
  left holds still where it is and stays an obstacle to the others;
- the field's episode ends when no robot is left in it, or at ``max_steps`` (the rest are truncated).

``step`` runs a decision period, ``step_control`` one control step (for views whose workers or obstacles
are agents). The core trusts its inputs (the views and ``World`` check what enters); arrays are (N, M, ...)
throughout.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from hier_ssl.config import TaskConfig
from hier_ssl.envs.decisions import Period, take_decisions
from hier_ssl.envs.registry import make_scenario
from hier_ssl.envs.scenario import Scenario
from hier_ssl.envs.step_guard import abandon, snapshot
from hier_ssl.manager.actions import SubgoalDecoder
from hier_ssl.manager.rewards import angle_reward, distance_reward, pose_errors
from hier_ssl.worker import Worker, resolve_worker
from hier_ssl.worker.observation import controlled_worker_observation, scale_command
from hier_ssl.world.obstacles import make_obstacle
from hier_ssl.world.physics import RobotState


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
        self.world = scenario.make_world(num_fields)
        self.field, self.robot = self.world.field, self.world.robot
        self.worker = resolve_worker(cfg.worker if worker is None else worker, self.robot, cfg.dt)
        # Each obstacle group's behaviour moves its robots (the world's robot groups after the controlled
        # one) as rows (field f, obstacle j) -> f * count + j.
        self.obstacles: list[tuple[Any, slice]] = []
        moved = self.world.entities.of("robot")[1:]
        for group, robots in zip(scenario.groups, moved, strict=True):
            behaviour = make_obstacle(group.behaviour, num_fields * group.count, **group.options)
            self.obstacles.append((behaviour, robots.rows))
        self.obs_dim, self.act_dim = scenario.obs_dim, scenario.act_dim
        self.theta_th = np.deg2rad(cfg.theta_th_deg)
        sizes = [scenario.scales[k] for k in ("half_length", "half_width", "max_v")]
        self._decode = SubgoalDecoder(cfg.action_form, *sizes, scenario.zero_velocity, cfg.action_frame)
        self._sum_rewards = cfg.frame_skip_reward == "sum"
        # The step hooks the scenario overrides; those it leaves as Scenario's do nothing and are not called.
        kind = type(scenario)
        self._pre_step = None if kind.pre_step is Scenario.pre_step else scenario.pre_step
        self._post_step = None if kind.post_step is Scenario.post_step else scenario.post_step
        self._post_reset = None if kind.post_reset is Scenario.post_reset else scenario.post_reset
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
        self._terms = None  # the scenario's decision terms of the current sub-goals and targets
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
        placement = self.scenario.reset_world_at(len(fields), self.rng)
        # A scenario is a user's class: its placement is checked here, once a reset (World.set_state
        # checks the robots' part), and trusted afterwards.
        if placement.target.shape != (len(fields), m, 5):
            raise ValueError(
                f"scenario {self.scenario.name!r}: placement target has shape {placement.target.shape}, "
                f"expected {(len(fields), m, 5)}"
            )
        self.world.set_state(fields, placement.pos, placement.angle, placement.vel, placement.ang_vel)
        if self.world.ball is not None:
            if placement.ball_pos is None:
                raise ValueError(
                    f"scenario {self.scenario.name!r}: its world holds balls, its placement has no ball_pos"
                )
            self.world.set_balls(fields, placement.ball_pos, placement.ball_vel)
        self.target[fields] = placement.target
        # Until the first decision the sub-goal is the robot's own pose: the worker holds still.
        self.subgoal[fields] = 0.0
        self.subgoal[fields, :, 0:2] = placement.pos[:, :m]
        self.subgoal[fields, :, 2] = placement.angle[:, :m]
        self.active[fields] = True
        self.steps[fields], self.decisions[fields], self.ep_length[fields] = 0, 0, 0
        self.ep_return[fields], self.ep_cpad[fields] = 0.0, 0.0
        self.worker.reset(fields)
        for behaviour, robots in self.obstacles:
            count = robots.stop - robots.start
            behaviour.reset((fields[:, None] * count + np.arange(count)).ravel(), self.rng)
        if self._post_reset is not None:
            self._post_reset(self, fields, placement)
        self._update_terms()

    def set_targets(self, fields: np.ndarray, target: np.ndarray) -> None:
        """New targets (F, M, 5) for ``fields`` (F,) ints in mid-episode (a scenario's hook, when the
        referee's command changes what the robots must reach)."""
        self.target[fields] = target
        self._update_terms()

    def _update_terms(self) -> None:
        """The scenario's decision terms of the current sub-goals and targets (after every change)."""
        self._terms = self.scenario.decision_terms(self.target, self.subgoal)

    # -- observations --------------------------------------------------------------------------------------

    def observe(self, fields: np.ndarray | None = None, state: RobotState | None = None) -> np.ndarray:
        """Manager observations (F, M, obs_dim) float32 of ``fields`` (default all), the scenario's
        ``observation`` of the world's robots or of ``state`` (N, M + K: the deploy view's tracked ones);
        left ones too."""
        s = self.world.state if state is None else state
        s = s if fields is None else s.fields(fields)
        target = self.target if fields is None else self.target[fields]
        return self.scenario.observation(target, s, fields)

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
        clipped = np.empty((n, m), dtype=np.int64)
        counters = (self.subgoal, self.decisions, self.ep_cpad)
        take_decisions(action, decoded.reshape(n, m, 5), live, *counters, clipped)
        self._update_terms()
        return clipped

    def hold_subgoal(self, subgoal: np.ndarray) -> None:
        """Hold ``subgoal`` (N, M, 5) as if decoded (the deploy field server's managers act elsewhere)."""
        np.copyto(self.subgoal, subgoal)
        self._update_terms()

    def control_step(
        self,
        live: np.ndarray,
        worker_action: np.ndarray | None = None,
        obstacle_actions: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One 25 ms step of every field; robots not ``live`` (N, M) hold still and score nothing, and so do
        the obstacles of fields without a live robot. ``worker_action`` (N, M, 3) and ``obstacle_actions``
        (N, K, 3), normalised to [-1, 1], replace the workers and obstacles when those are exposed as agents.
        The scenario's ``pre_step`` sees the commands before the world steps, its ``post_step`` the world
        after, and its ``score`` gives the step's reward, success and collision.

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
        if self._pre_step is not None:
            self._pre_step(self, command)
        self.world.step(command)
        self.control_steps += 1
        self.steps = self.steps + field_live.astype(np.int64)
        if self._post_step is not None:
            self._post_step(self)
        reward, success, hit = self.scenario.score(self._terms, self.target, self.subgoal, self.world)
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
        steps), ``decisions``, ``success``, ``collision``, ``cpad``, and the scenario's ``stat_names``
        (``Scenario.episode_stats``: the game scenarios' fouls). (Not ``episode``: Gymnasium's
        ``RecordEpisodeStatistics`` and SB3's ``Monitor`` write that key; every view passes ``task`` on.)
        """
        cfg = self.config
        start = self.active.copy()
        if not np.count_nonzero(start):
            raise RuntimeError("step() with every episode finished: call reset() first")
        kept = snapshot(self)
        clipped = self.set_subgoal(action, start)
        # One compiled loop a control step tallies the period's running values in place.
        period = Period(start)
        try:
            for k in range(cfg.frame_skip):
                outcome = self.control_step(period.live)
                add, count = k > 0 and self._sum_rewards, k + 1 < cfg.frame_skip
                if not period.tally(outcome, self.steps, cfg.max_steps, add, count):
                    break
        except Exception:  # from the worker: undone, or the core needs a reset (step_guard)
            abandon(self, kept)
            raise
        return self.finish(period, clipped)

    def step_control(
        self,
        action: np.ndarray,
        worker_action: np.ndarray | None = None,
        obstacle_actions: np.ndarray | None = None,
    ) -> StepResult:
        """One control step of every field, for views whose workers (``worker_action`` (N, M, 3)) or
        obstacles (``obstacle_actions`` (N, K, 3)) are agents: the managers' ``action`` (N, M, A) is decoded
        into sub-goals on a field's decision steps only (every ``frame_skip``-th control step since its
        reset), and rewards are those of the one control step.

        ``info`` as ``step``'s, with ``decision`` (N,) bool, whether the managers' actions were used, and
        ``worker_reward`` (N, M), R_d + R_theta of each robot measured against its sub-goal.
        """
        cfg, m = self.config, self.num_agents
        kept = snapshot(self)
        live = self.active.copy()
        decision = self.steps % cfg.frame_skip == 0
        if decision.any():
            clipped = self.set_subgoal(action, live & decision[:, None])
        else:
            clipped = np.zeros(live.shape, dtype=np.int64)
        try:
            reward, success, hit = self.control_step(live, worker_action, obstacle_actions)
        except Exception:  # from the worker: the sub-goals set above go back (step_guard)
            abandon(self, kept)
            raise
        s = self.world.state
        pose = np.concatenate([s.pos[:, :m], s.angle[:, :m, None]], axis=-1)
        d, delta = pose_errors(pose, self.subgoal)
        worker_reward = distance_reward(d, cfg.d_th) + angle_reward(delta, self.theta_th)
        period = Period(live)
        period.tally((reward, success, hit), self.steps, cfg.max_steps, False, False)
        result = self.finish(period, clipped)
        result.info["decision"] = decision
        result.info["worker_reward"] = worker_reward
        return result

    def finish(self, period: Period, clipped: np.ndarray) -> StepResult:
        """Book-keeping after a decision ``period`` (or one control step): returns, per-robot episode
        statistics, auto-reset; ``clipped`` (N, M), the action values clipped at the decision."""
        # New arrays rather than updates in place (see ``Period``): the counters are replaced, never kept.
        success, collision = period.success, period.collision
        self.ep_return = self.ep_return + period.reward
        self.ep_length = self.ep_length + period.elapsed
        left = success | collision | period.timeout
        # Rows of the robots that left, row = field * M + robot; most decisions have none, and share the
        # same empty columns (an empty array cannot change).
        rows = left.ravel().nonzero()[0]
        stats = self._stats(rows, success, collision) if len(rows) else dict(self._no_stats)
        info: dict[str, Any] = {
            "control_steps": period.elapsed,
            "success": success,
            "collision": collision,
            "action_clipped": clipped,
            "subgoal": self.subgoal.copy(),
            "live": period.start,
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
        reward = period.reward.astype(np.float32)
        return StepResult(obs, reward, success | collision, period.timeout, info)

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
            **self.scenario.episode_stats(rows),
        }


__all__ = [
    "HierarchicalCore",
    "StepResult",
]
