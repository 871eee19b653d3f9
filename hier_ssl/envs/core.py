"""The hierarchical SSL task over N fields: one code path under the PettingZoo and the vector views.

Robot 0 of every field is the controlled robot (its manager picks sub-goals, its worker drives to
them); robots 1..K are obstacles. A manager decision holds its sub-goal for ``frame_skip`` control
steps of 25 ms; the worker and the obstacles act every control step. Observations, rewards and ends are
the pure functions of ``hier_ssl.manager``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from hier_ssl.config import EnvConfig, TaskSettings
from hier_ssl.manager import (
    collided,
    cpad_increment,
    decode_subgoal,
    manager_observation,
    task_reward,
    task_success,
)
from hier_ssl.manager.neighbours import neighbour_observation
from hier_ssl.worker import make_worker
from hier_ssl.worker.observation import scale_command, worker_observation
from hier_ssl.world.field import Field
from hier_ssl.world.obstacles import make_obstacle
from hier_ssl.world.physics import RobotSpec, RobotState, World

OBSTACLE_OBS_DIM = 7


@dataclass
class StepResult:
    """What one manager decision period (or one control step) returns. Shapes (N, ...)."""

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    info: dict[str, object]


def check_action(name: str, action: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    """``action`` as float64 of ``shape``; a ValueError names ``name`` for a wrong shape, NaN or inf."""
    action = np.asarray(action, dtype=np.float64)
    if action.shape != shape:
        raise ValueError(f"action of {name} has shape {action.shape}, expected {shape}")
    if not np.isfinite(action).all():
        raise ValueError(f"action of {name} holds NaN or infinite values: {action.tolist()}")
    return action


def score_control_step(
    task: str,
    config: TaskSettings,
    target: np.ndarray,
    subgoal: np.ndarray,
    pos: np.ndarray,
    angle: np.ndarray,
    vel: np.ndarray,
    others: np.ndarray,
    touching: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """Success, collision and reward of one control step of B controlled robots (rows), by the pure
    functions of ``hier_ssl.manager`` with ``config``'s thresholds, reward modes and weights. Shared by the
    paper core and the multi-robot core.

    Shapes: target, subgoal (B, 5); pos, vel (B, 2); angle (B,); others (B, J, 2), the robots each one can
    hit; touching (B,) bool, a contact the physics reported. Returns reward, success, hit (B,) and the
    reward terms.
    """
    thresholds = {"d_th": config.d_th, "theta_th": np.deg2rad(config.theta_th_deg)}
    success = task_success(task, target, subgoal, pos, angle, vel, speed_th=config.speed_th, **thresholds)
    hit = collided(pos, others, config.collision_distance) | touching
    extra = {"obs_pos": others, "hit": hit} if task == "obstacle" else {}
    reward, terms = task_reward(
        task,
        target,
        pos,
        angle,
        subgoal,
        success,
        success_mode=config.success_mode,
        hit_mode=config.hit_mode,
        success_weight=config.success_weight,
        hit_weight=config.hit_weight,
        obstacle_from=config.obstacle_from,
        **extra,
        **thresholds,
    )
    return reward, success, hit, terms


def end_period(core: Any, ended: np.ndarray, info: dict[str, object]) -> np.ndarray:
    """Close a period of ``core`` (any core with ``observe``, ``done``, ``autoreset`` and ``reset_fields``):
    record the last observation as ``info["final_obs"]``, mark ``ended`` (N,) fields done and, with
    auto-reset, start their next episode. Returns the observation the agent acts on next.
    """
    obs = core.observe()
    info["final_obs"] = obs
    core.done |= ended
    idx = np.flatnonzero(ended)
    if core.autoreset and len(idx):
        core.reset_fields(idx)
        obs = core.observe()
    return obs


def controlled_worker_observation(
    state: RobotState, subgoal: np.ndarray, robot: RobotSpec, field: Field
) -> np.ndarray:
    """The worker observation (N, 9) of robot 0 of every field towards ``subgoal`` (N, 5)."""
    return worker_observation(
        state.pos[:, 0],
        state.angle[:, 0],
        state.vel[:, 0],
        state.ang_vel[:, 0],
        subgoal,
        robot,
        field.max_pos,
    )


class HierarchicalCore:
    """N fields of the Baseline, Proposed or Obstacle task (SPEC.md), as numpy arrays.

    ``autoreset`` resets finished fields inside ``step`` (vector view); without it a finished field
    waits for ``reset`` (PettingZoo view).
    """

    def __init__(self, config: EnvConfig, num_fields: int = 1, autoreset: bool = True) -> None:
        self.config = config
        self.num_fields = num_fields
        self.num_obstacles = len(config.obstacles)
        self.autoreset = autoreset
        self.world = World(
            num_fields, 1 + self.num_obstacles, config.field, dt=config.dt, substeps=config.substeps
        )
        self.field, self.robot = self.world.field, self.world.robot
        self.worker = make_worker(config.worker, self.robot, config.dt)
        self.obstacles = [make_obstacle(o.behaviour, num_fields, **o.options) for o in config.obstacles]
        self.obs_dim, self.act_dim = config.obs_dim, config.act_dim
        self.theta_th = np.deg2rad(config.theta_th_deg)
        self.rng = np.random.default_rng()

        n = num_fields
        self.target = np.zeros((n, 5))
        self.subgoal = np.zeros((n, 5))
        self.steps = np.zeros(n, dtype=np.int64)  # control steps since reset
        self.decisions = np.zeros(n, dtype=np.int64)
        self.ep_return = np.zeros(n)
        self.ep_cpad = np.zeros(n)
        self.done = np.ones(n, dtype=bool)

    # -- reset ---------------------------------------------------------------------------------------------

    def seed(self, seed: int | None) -> None:
        self.rng = np.random.default_rng(seed)

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Start a new episode in every field. Returns the manager observations (N, obs_dim)."""
        if seed is not None:
            self.seed(seed)
        self.reset_fields(np.arange(self.num_fields))
        return self.observe()

    def _uniform_xy(self, m: int) -> np.ndarray:
        margin = self.config.spawn_margin
        half = np.array([self.field.half_length - margin, self.field.half_width - margin])
        return self.rng.uniform(-half, half, (m, 2))

    def reset_fields(self, fields: np.ndarray) -> None:
        """Sample targets, starts and obstacles for ``fields`` (SPEC "Reset sampling")."""
        m, cfg = len(fields), self.config
        if m == 0:
            return
        target_xy = self._uniform_xy(m)
        robot_xy = self._uniform_xy(m)
        while (bad := np.linalg.norm(robot_xy - target_xy, axis=1) < cfg.min_start_distance).any():
            robot_xy[bad] = self._uniform_xy(int(bad.sum()))
        placed = [robot_xy, target_xy]
        for obstacle in cfg.obstacles:
            if obstacle.placement == "midpoint":
                xy = (robot_xy + target_xy) / 2
            else:
                xy = self._uniform_xy(m)
                while (bad := self._too_close(xy, placed)).any():
                    xy[bad] = self._uniform_xy(int(bad.sum()))
            placed.append(xy)
        pos = np.stack([robot_xy, *placed[2:]], axis=1)
        angle = self.rng.uniform(-np.pi, np.pi, (m, 1 + self.num_obstacles))
        self.world.set_state(fields, pos, angle)

        self.target[fields] = 0.0
        self.target[fields, 0:2] = target_xy
        self.target[fields, 2] = self.rng.uniform(-np.pi, np.pi, m)
        # Until the first decision the sub-goal is the robot's own pose: the worker holds still.
        self.subgoal[fields] = 0.0
        self.subgoal[fields, 0:2] = robot_xy
        self.subgoal[fields, 2] = angle[:, 0]
        self.steps[fields] = 0
        self.decisions[fields] = 0
        self.ep_return[fields] = 0.0
        self.ep_cpad[fields] = 0.0
        self.done[fields] = False
        self.worker.reset(fields)
        for behaviour in self.obstacles:
            behaviour.reset(fields, self.rng)

    @property
    def active(self) -> np.ndarray:
        """(N,) bool: fields whose episode is still running (``MultiRobotCore.active`` is per robot)."""
        return ~self.done

    def _too_close(self, xy: np.ndarray, placed: list[np.ndarray]) -> np.ndarray:
        gap = 2 * self.config.collision_distance
        return np.any([np.linalg.norm(xy - other, axis=1) < gap for other in placed], axis=0)

    # -- observations --------------------------------------------------------------------------------------

    @property
    def state(self) -> RobotState:
        return self.world.state

    def observe(self) -> np.ndarray:
        """Manager observations (N, obs_dim) float32, in the config's ``observation`` layout."""
        s = self.state
        own = (self.target, s.pos[:, 0], s.angle[:, 0], s.vel[:, 0], s.ang_vel[:, 0])
        scales = {
            "max_pos": self.field.max_pos,
            "max_v": self.robot.max_speed,
            "max_w": self.robot.max_ang_speed,
        }
        if self.config.observation == "neighbours":
            teammate = np.zeros((self.num_fields, self.num_obstacles), dtype=bool)
            return neighbour_observation(
                *own, s.pos[:, 1:], s.vel[:, 1:], teammate, self.config.neighbours, **scales
            )
        return manager_observation(*own, s.pos[:, 1:], s.vel[:, 1:], s.ang_vel[:, 1:], **scales)

    def observe_worker(self) -> np.ndarray:
        """Worker observations (N, 9) float32."""
        return controlled_worker_observation(self.state, self.subgoal, self.robot, self.field)

    def observe_obstacle(self, j: int) -> np.ndarray:
        """Obstacle ``j``'s view of itself (N, 7): position, sin/cos heading, velocity, angular velocity."""
        s, k = self.state, 1 + j
        obs = np.concatenate(
            [
                s.pos[:, k] / self.field.max_pos,
                np.sin(s.angle[:, k])[:, None],
                np.cos(s.angle[:, k])[:, None],
                s.vel[:, k] / self.robot.max_speed,
                s.ang_vel[:, k, None] / self.robot.max_ang_speed,
            ],
            axis=1,
        )
        return np.clip(obs, -1.2, 1.2).astype(np.float32)

    # -- acting --------------------------------------------------------------------------------------------

    def set_subgoal(self, action: np.ndarray, fields: np.ndarray) -> np.ndarray:
        """Decode manager actions (N, act_dim) into held sub-goals for ``fields`` (M,) ints.

        Values outside [-1, 1] are clipped; returns how many were clipped per field (N,).
        """
        action = check_action("manager", action, (self.num_fields, self.act_dim))
        clipped = np.count_nonzero(np.abs(action) > 1.0, axis=1)
        subgoal = decode_subgoal(
            action,
            self.config.action_form,
            self.field.half_length,
            self.field.half_width,
            self.robot.max_speed,
            zero_velocity=self.config.task != "baseline",
            frame=self.config.action_frame,
            target=self.target,
        )
        clipped = np.where(np.isin(np.arange(self.num_fields), fields), clipped, 0)
        moved = cpad_increment(self.subgoal[fields, 0:2], subgoal[fields, 0:2])
        self.ep_cpad[fields] += np.where(self.decisions[fields] > 0, moved, 0.0)
        self.subgoal[fields] = subgoal[fields]
        self.decisions[fields] += 1
        return clipped

    def control_step(
        self,
        live: np.ndarray,
        worker_action: np.ndarray | None = None,
        obstacle_actions: np.ndarray | None = None,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """One 25 ms step of every field; fields not ``live`` (N,) bool hold still and score nothing.

        ``worker_action`` (N, 3) and ``obstacle_actions`` (N, K, 3), normalised to [-1, 1], replace the
        scripted worker and obstacles when those are exposed as agents.
        Returns reward (N,), success (N,), collision (N,), timeout (N,) and the reward terms.
        """
        s, n = self.state, self.num_fields
        command = np.zeros((n, 1 + self.num_obstacles, 3))
        if worker_action is None:
            command[:, 0] = self.worker(s.robots(slice(0, 1)), self.subgoal[:, None])[:, 0]
        else:
            command[:, 0] = scale_command(np.clip(worker_action, -1.0, 1.0), self.robot)
        if obstacle_actions is None:
            for j, behaviour in enumerate(self.obstacles):
                command[:, 1 + j] = behaviour(s.pos[:, 1 + j], s.angle[:, 1 + j], self.rng)
        else:
            command[:, 1:] = scale_command(np.clip(obstacle_actions, -1.0, 1.0), self.robot)
        command[~live] = 0.0
        s = self.world.step(command)
        self.steps += live

        cfg = self.config
        touching = self.world.robot_contacts[:, 0, 1:].any(axis=1)
        reward, success, hit, terms = score_control_step(
            cfg.task,
            cfg,
            self.target,
            self.subgoal,
            s.pos[:, 0],
            s.angle[:, 0],
            s.vel[:, 0],
            s.pos[:, 1:],
            touching,
        )
        timeout = self.steps >= cfg.max_steps
        return reward, success & live, hit & live, timeout & live, terms

    def step(self, action: np.ndarray) -> StepResult:
        """One manager decision in every field: hold the sub-goal for ``frame_skip`` control steps.

        Rewards are summed over the held steps ("sum") or taken from the last one ("last", the public
        code). A field whose episode ends inside the period stops scoring there; without auto-reset a
        finished field holds still until ``reset`` (so evaluation can run one episode per field).
        """
        n, cfg = self.num_fields, self.config
        live = ~self.done
        if not live.any():
            raise RuntimeError("step() with every episode finished: call reset() first")
        clipped = self.set_subgoal(action, np.flatnonzero(live))
        reward = np.zeros(n)
        success, failure, timeout = (np.zeros(n, dtype=bool) for _ in range(3))
        elapsed = np.zeros(n, dtype=np.int64)
        for _ in range(cfg.frame_skip):
            r, succ, hit, out, _ = self.control_step(live)
            reward = (
                reward + np.where(live, r, 0.0)
                if cfg.frame_skip_reward == "sum"
                else np.where(live, r, reward)
            )
            elapsed += live
            success |= succ
            failure |= hit & ~succ
            timeout |= out & ~succ & ~hit
            live &= ~(succ | hit | out)
            if not live.any():
                break
        return self.finish_period(reward, success | failure, timeout, success, failure, elapsed, clipped)

    def finish_period(
        self,
        reward: np.ndarray,
        terminated: np.ndarray,
        truncated: np.ndarray,
        success: np.ndarray,
        collision: np.ndarray,
        elapsed: np.ndarray,
        clipped: np.ndarray,
    ) -> StepResult:
        """Book-keeping after a decision period (or, for a view with exposed agents, one control step):
        returns, episode statistics, auto-reset. Shapes: every argument (N,)."""
        self.ep_return += reward
        ended = terminated | truncated
        info: dict[str, object] = {
            "control_steps": elapsed,
            "subgoal": self.subgoal.copy(),
            "action_clipped": clipped,
            "success": success,
            "collision": collision,
        }
        idx = np.flatnonzero(ended)
        info["episode"] = {
            "field": idx,
            "return": self.ep_return[idx].copy(),
            "length": self.steps[idx].copy(),
            "decisions": self.decisions[idx].copy(),
            "success": success[idx].astype(np.float64),
            "collision": collision[idx].astype(np.float64),
            "cpad": self.ep_cpad[idx].copy(),
        }
        obs = end_period(self, ended, info)
        return StepResult(obs, reward.astype(np.float32), terminated, truncated, info)
