"""Multi-robot scenarios over N fields: a batched core, its PettingZoo view and its torch vector view.

Every field holds M controlled robots (robots 0..M-1, agents ``manager_i``) and K scripted obstacles
(robots M..M+K-1). Each controlled robot has its own target, manager decision, sub-goal and scripted
worker; one manager decision holds every sub-goal for ``frame_skip`` control steps of 25 ms. Rewards
(the Obstacle task's, R_t and R_hit times ``success_weight`` and ``hit_weight``), success and collisions
are per robot, from the pure functions of ``hier_ssl.manager`` applied to the (field, robot) pairs as
rows:

- a robot leaves the episode when it succeeds (SPEC "Proposed" success) or collides (centres closer than
  ``collision_distance`` to any other robot, or touching one); a collision between two controlled robots
  counts for both. A robot that has left holds still where it is and stays an obstacle to the others;
- the field's episode ends when no robot is left in it, or at ``max_steps`` (the rest are truncated).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from gymnasium import spaces
from pettingzoo import ParallelEnv

from hier_ssl.envs.core import check_action, score_control_step
from hier_ssl.envs.scenarios import ScenarioConfig, make_scenario
from hier_ssl.envs.vector import TorchView
from hier_ssl.manager import action_dim, cpad_increment, decode_subgoal
from hier_ssl.manager.neighbours import neighbour_obs_dim, neighbour_observation
from hier_ssl.worker import make_worker
from hier_ssl.world.obstacles import make_obstacle
from hier_ssl.world.physics import World


@dataclass
class MultiStepResult:
    """One manager decision period in every field. Shapes: obs (N, M, O) float32; reward (N, M) float32;
    terminated, truncated (N, M) bool, True for robots that left in this period; info as documented in
    ``MultiRobotCore.step``."""

    obs: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    info: dict[str, Any]


class MultiRobotCore:
    """N fields of one scenario as numpy arrays: ``reset``, ``step(actions (N, M, A))``, ``observe``.

    ``active`` (N, M) says which robots are still in their episode. ``autoreset`` resets a field inside
    ``step`` once no robot is left in it (vector view); without it a finished field holds still until
    ``reset`` (PettingZoo view, evaluation).
    """

    def __init__(self, config: ScenarioConfig, num_fields: int = 1, autoreset: bool = True) -> None:
        self.config = config
        self.scenario = make_scenario(config)
        self.num_fields, self.autoreset = num_fields, autoreset
        m, k = config.num_agents, config.num_obstacles
        self.num_agents, self.num_obstacles = m, k
        self.world = World(num_fields, m + k, config.field, dt=config.dt, substeps=config.substeps)
        self.field, self.robot = self.world.field, self.world.robot
        self.worker = make_worker(config.worker, self.robot, config.dt)
        # One behaviour object moves all N * K obstacles as rows (field f, obstacle j) -> f * K + j.
        options = config.obstacles.options
        self.obstacles = make_obstacle(config.obstacles.behaviour, num_fields * k, **options) if k else None
        self.obs_dim = neighbour_obs_dim(config.neighbours)
        self.act_dim = action_dim(config.action_form)
        # A robot alone in its field has nothing to avoid: the obstacle terms would have no obstacle.
        self.task = "obstacle" if m + k > 1 else "proposed"
        # others[i]: every robot but robot i, the ones it sees and can hit; teammate: which are controlled.
        r = m + k
        self._others = np.array([[j for j in range(r) if j != i] for i in range(m)], dtype=np.int64)
        self._others = self._others.reshape(m, r - 1)
        self._teammate = self._others < m
        self.rng = np.random.default_rng()
        self.control_steps = 0  # world steps taken since construction, for throughput figures

        n = num_fields
        self.target = np.zeros((n, m, 5))
        self.subgoal = np.zeros((n, m, 5))
        self.active = np.zeros((n, m), dtype=bool)
        self.steps = np.zeros(n, dtype=np.int64)  # control steps of each field since its reset
        self.decisions = np.zeros((n, m), dtype=np.int64)
        self.ep_return = np.zeros((n, m))
        self.ep_length = np.zeros((n, m), dtype=np.int64)  # control steps each robot was live for
        self.ep_cpad = np.zeros((n, m))

    @property
    def done(self) -> np.ndarray:
        """(N,) bool: no robot is left in the field's episode."""
        return ~self.active.any(axis=1)

    # -- reset ---------------------------------------------------------------------------------------------

    def seed(self, seed: int | None) -> None:
        self.rng = np.random.default_rng(seed)

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Start a new episode in every field. Returns the observations (N, M, obs_dim)."""
        if seed is not None:
            self.seed(seed)
        self.reset_fields(np.arange(self.num_fields))
        return self.observe()

    def reset_fields(self, fields: np.ndarray) -> None:
        """New starts, targets and obstacles for ``fields`` (F,) ints, from the scenario."""
        if len(fields) == 0:
            return
        m, k = self.num_agents, self.num_obstacles
        layout = self.scenario.reset_world_at(len(fields), self.rng)
        self.world.set_state(fields, layout.pos, layout.angle)
        self.target[fields] = layout.target
        # Until the first decision the sub-goal is the robot's own pose: the worker holds still.
        self.subgoal[fields] = 0.0
        self.subgoal[fields, :, 0:2] = layout.pos[:, :m]
        self.subgoal[fields, :, 2] = layout.angle[:, :m]
        self.active[fields] = True
        self.steps[fields] = 0
        self.decisions[fields] = 0
        self.ep_return[fields] = 0.0
        self.ep_length[fields] = 0
        self.ep_cpad[fields] = 0.0
        self.worker.reset(fields)
        if self.obstacles is not None:
            self.obstacles.reset((fields[:, None] * k + np.arange(k)).ravel(), self.rng)

    # -- observations --------------------------------------------------------------------------------------

    def observe(self, fields: np.ndarray | None = None) -> np.ndarray:
        """Observations (F, M, obs_dim) float32 of ``fields`` (default all), finished robots included."""
        s = self.world.state if fields is None else self.world.state.fields(fields)
        target = self.target if fields is None else self.target[fields]
        f, m = target.shape[:2]
        b, j = f * m, self._others.shape[1]
        own = s.robots(slice(0, m))
        obs = neighbour_observation(
            target.reshape(b, 5),
            own.pos.reshape(b, 2),
            own.angle.reshape(b),
            own.vel.reshape(b, 2),
            own.ang_vel.reshape(b),
            s.pos[:, self._others].reshape(b, j, 2),
            s.vel[:, self._others].reshape(b, j, 2),
            np.broadcast_to(self._teammate, (f, m, j)).reshape(b, j),
            self.config.neighbours,
            max_pos=self.field.max_pos,
            max_v=self.robot.max_speed,
            max_w=self.robot.max_ang_speed,
        )
        return obs.reshape(f, m, self.obs_dim)

    # -- acting --------------------------------------------------------------------------------------------

    def set_subgoal(self, action: np.ndarray, live: np.ndarray) -> np.ndarray:
        """Decode actions (N, M, act_dim) into held sub-goals of the ``live`` (N, M) robots, in the field or
        the target frame (``action_frame``); values outside [-1, 1] are clipped, sub-goals to the field.
        Returns how many values were clipped per robot (N, M), 0 where not live."""
        n, m = live.shape
        action = check_action("manager", action, (n, m, self.act_dim))
        clipped = np.where(live, np.count_nonzero(np.abs(action) > 1.0, axis=2), 0)
        subgoal = decode_subgoal(
            action.reshape(n * m, self.act_dim),
            self.config.action_form,
            self.field.half_length,
            self.field.half_width,
            self.robot.max_speed,
            zero_velocity=True,
            frame=self.config.action_frame,
            target=self.target.reshape(n * m, 5),
        ).reshape(n, m, 5)
        moved = cpad_increment(self.subgoal[..., 0:2].reshape(-1, 2), subgoal[..., 0:2].reshape(-1, 2))
        self.ep_cpad += np.where(live & (self.decisions > 0), moved.reshape(n, m), 0.0)
        self.subgoal[live] = subgoal[live]
        self.decisions += live
        return clipped

    def control_step(
        self, live: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, np.ndarray]]:
        """One 25 ms step of every field; robots not ``live`` (N, M) hold still and score nothing, and so do
        the obstacles of fields without a live robot.

        Returns reward (N, M), success (N, M), collision (N, M) (both only where live) and the reward terms.
        """
        cfg, s = self.config, self.world.state
        n, m, k = self.num_fields, self.num_agents, self.num_obstacles
        command = np.zeros((n, m + k, 3))
        command[:, :m] = self.worker(s.robots(slice(0, m)), self.subgoal)
        if self.obstacles is not None:
            pos, angle = s.pos[:, m:].reshape(n * k, 2), s.angle[:, m:].reshape(n * k)
            command[:, m:] = self.obstacles(pos, angle, self.rng).reshape(n, k, 3)
        command[:, :m][~live] = 0.0
        field_live = live.any(axis=1)
        command[~field_live] = 0.0
        s = self.world.step(command)
        self.control_steps += 1
        self.steps += field_live

        b, j = n * m, m + k - 1
        own = s.robots(slice(0, m))
        target, subgoal = self.target.reshape(b, 5), self.subgoal.reshape(b, 5)
        others = s.pos[:, self._others].reshape(b, j, 2)
        touching = self.world.robot_contacts[:, :m].any(axis=2).reshape(b)
        reward, success, hit, terms = score_control_step(
            self.task,
            cfg,
            target,
            subgoal,
            own.pos.reshape(b, 2),
            own.angle.reshape(b),
            own.vel.reshape(b, 2),
            others,
            touching,
        )
        return (
            reward.reshape(n, m),
            success.reshape(n, m) & live,
            hit.reshape(n, m) & live,
            {name: term.reshape(n, m) for name, term in terms.items()},
        )

    def step(self, action: np.ndarray) -> MultiStepResult:
        """One manager decision in every field: the live robots' sub-goals held for ``frame_skip`` control
        steps, rewards summed over them ("sum") or the last one taken ("last").

        A robot that leaves inside the period stops scoring there. ``info`` holds, per robot (N, M):
        ``control_steps`` it was live for, ``success``, ``collision``, ``action_clipped``, ``subgoal``
        (N, M, 5) and ``live`` (the robots this decision acted for); ``final_obs`` (N, M, O), the
        observation before any auto-reset; and ``episode``, one entry per robot that left: ``field``,
        ``agent``, ``return``, ``length`` (control steps), ``decisions``, ``success``, ``collision``,
        ``cpad``.
        """
        cfg = self.config
        start = self.active.copy()
        if not start.any():
            raise RuntimeError("step() with every episode finished: call reset() first")
        clipped = self.set_subgoal(action, start)
        live = start.copy()
        shape = live.shape
        reward = np.zeros(shape)
        success, collision, timeout = (np.zeros(shape, dtype=bool) for _ in range(3))
        elapsed = np.zeros(shape, dtype=np.int64)
        for _ in range(cfg.frame_skip):
            r, succ, hit, _ = self.control_step(live)
            reward = np.where(live, reward + r if cfg.frame_skip_reward == "sum" else r, reward)
            elapsed += live
            success |= succ
            collision |= hit & ~succ
            timeout |= live & ~succ & ~hit & (self.steps >= cfg.max_steps)[:, None]
            live &= ~(success | collision | timeout)
            if not live.any():
                break
        return self._finish(start, reward, success, collision, timeout, elapsed, clipped)

    def _finish(
        self,
        start: np.ndarray,
        reward: np.ndarray,
        success: np.ndarray,
        collision: np.ndarray,
        timeout: np.ndarray,
        elapsed: np.ndarray,
        clipped: np.ndarray,
    ) -> MultiStepResult:
        """Book-keeping after a decision period: returns, per-robot episode statistics, auto-reset."""
        self.ep_return += reward
        self.ep_length += elapsed
        left = success | collision | timeout
        field, agent = np.nonzero(left)
        info: dict[str, Any] = {
            "control_steps": elapsed,
            "success": success,
            "collision": collision,
            "action_clipped": clipped,
            "subgoal": self.subgoal.copy(),
            "live": start,
            "episode": {
                "field": field,
                "agent": agent,
                "return": self.ep_return[field, agent].copy(),
                "length": self.ep_length[field, agent].copy(),
                "decisions": self.decisions[field, agent].copy(),
                "success": success[field, agent].astype(np.float64),
                "collision": collision[field, agent].astype(np.float64),
                "cpad": self.ep_cpad[field, agent].copy(),
            },
        }
        self.active &= ~left
        obs = self.observe()
        info["final_obs"] = obs
        finished = np.flatnonzero(self.done)
        if self.autoreset and len(finished):
            obs = obs.copy()
            self.reset_fields(finished)
            obs[finished] = self.observe(finished)
        return MultiStepResult(obs, reward.astype(np.float32), success | collision, timeout, info)


AGENT_PREFIX = "manager_"


class MultiRobotParallelEnv(ParallelEnv):
    """PettingZoo view of one field: agents ``manager_0 .. manager_{M-1}``, one ``step`` per manager
    decision. ``agents`` shrinks as robots reach their targets or collide; the episode is over when it is
    empty. Obstacles and workers are scripted inside."""

    metadata = {"name": "hier_ssl_multi_v0", "render_modes": ["rgb_array"], "is_parallelizable": True}

    def __init__(self, config: ScenarioConfig, render_mode: str | None = None) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} not in {self.metadata['render_modes']}")
        self.config, self.render_mode = config, render_mode
        self.core = MultiRobotCore(config, 1, autoreset=False)
        self.metadata = {**self.metadata, "render_fps": round(1 / (config.dt * config.frame_skip))}
        self.possible_agents = [f"{AGENT_PREFIX}{i}" for i in range(config.num_agents)]
        self._index = {agent: i for i, agent in enumerate(self.possible_agents)}
        box = functools.partial(spaces.Box, dtype=np.float32)
        self._obs_space = box(-1.2, 1.2, (self.core.obs_dim,))
        self._act_spaces = {a: box(-1.0, 1.0, (self.core.act_dim,)) for a in self.possible_agents}
        self.agents: list[str] = []
        self._trails: list[list[np.ndarray]] = []

    def observation_space(self, agent: str) -> spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._act_spaces[agent]

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if seed is not None:
            for i, agent in enumerate(self.possible_agents):
                self._act_spaces[agent].seed(seed + i)
        obs = self.core.reset(seed)[0]
        self.agents = list(self.possible_agents)
        self._trails = [[p.copy()] for p in self.core.world.state.pos[0, : self.config.num_agents]]
        return {a: obs[i] for a, i in self._index.items()}, {a: {} for a in self.agents}

    def step(self, actions: dict[str, np.ndarray]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("step() after the episode ended: call reset() first")
        unknown, missing = set(actions) - set(self.agents), set(self.agents) - set(actions)
        if unknown:
            raise ValueError(f"actions for agents that are not live: {sorted(unknown)}; live: {self.agents}")
        if missing:
            raise ValueError(f"no action for live agents {sorted(missing)}")
        batch = np.zeros((1, self.config.num_agents, self.core.act_dim))
        for agent in self.agents:
            batch[0, self._index[agent]] = check_action(agent, actions[agent], (self.core.act_dim,))
        result = self.core.step(batch)
        for trail, pos in zip(self._trails, self.core.world.state.pos[0, : len(self._trails)], strict=True):
            trail.append(pos.copy())

        info, episode = result.info, result.info["episode"]
        ended = {int(i): j for j, i in enumerate(episode["agent"])}
        obs, rewards, terms, truncs, infos = {}, {}, {}, {}, {}
        for agent in self.agents:
            i = self._index[agent]
            obs[agent] = result.obs[0, i]
            rewards[agent] = float(result.reward[0, i])
            terms[agent] = bool(result.terminated[0, i])
            truncs[agent] = bool(result.truncated[0, i])
            infos[agent] = {
                "control_steps": int(info["control_steps"][0, i]),
                "success": bool(info["success"][0, i]),
                "collision": bool(info["collision"][0, i]),
                "action_clipped": int(info["action_clipped"][0, i]),
                "subgoal": info["subgoal"][0, i],
            }
            if i in ended:
                row = ended[i]
                infos[agent]["episode"] = {
                    key: value[row] for key, value in episode.items() if key not in ("field", "agent")
                }
        self.agents = [a for a in self.agents if self.core.active[0, self._index[a]]]
        return obs, rewards, terms, truncs, infos

    def render(self) -> np.ndarray | None:
        """The field as an RGB image (H, W, 3): controlled robots blue, obstacles yellow, targets, sub-goals
        and each controlled robot's path."""
        if self.render_mode is None:
            return None
        from hier_ssl.world.render import render_fields

        m, k = self.config.num_agents, self.config.num_obstacles
        return render_fields(
            self.core.field,
            self.core.world.state,
            targets=self.core.target,
            subgoals=self.core.subgoal,
            trails=[np.array(trail) for trail in self._trails[:m]],
            team=[0] * m + [1] * k,
        )


class MultiVectorEnv(TorchView):
    """The torch view for parameter sharing: every (field, robot) pair is one row, row = field * M + robot.

    ``step(actions (N*M, A) in [-1, 1])`` returns obs (N*M, O) float32, reward (N*M,), terminated (N*M,),
    truncated (N*M,) and info, following the ``hier_ssl.policies.sac_runner.VectorEnv`` protocol. A robot
    that has left while its field plays on is a row in an absorbing state: observation all zeros (no live
    observation is: it holds sin and cos of two angles), reward 0, terminated every step, so learners that
    store every row learn a value of 0 there and never bootstrap into it. ``info["live"]`` (N*M,) bool marks
    the rows whose transition is real, for learners that can mask. A field resets once all its robots have
    left; its rows' ``obs`` then start the new episode and ``info["final_obs"]`` keeps the last one.
    ``info["episode"]`` has one entry per robot that left (return, length, decisions, success, collision,
    cpad).
    """

    def __init__(self, config: ScenarioConfig, num_fields: int, device: str | torch.device = "cpu") -> None:
        self.config = config
        core = MultiRobotCore(config, num_fields, autoreset=True)
        decisions = -(-config.max_steps // config.frame_skip)
        super().__init__(core, core.obs_dim, core.act_dim, decisions, device)
        self.num_fields = num_fields
        self.num_envs = num_fields * config.num_agents  # rows, not fields

    def _rows(self, obs: np.ndarray, keep: np.ndarray) -> torch.Tensor:
        """(N, M, O) observations as (N*M, O) rows, zeros where not ``keep`` (N, M)."""
        return self._tensor(np.where(keep[..., None], obs, np.float32(0.0)).reshape(self.num_envs, -1))

    def reset(self, seed: int | None = None) -> torch.Tensor:
        return self._tensor(self.core.reset(seed).reshape(self.num_envs, -1))

    def observe(self) -> torch.Tensor:
        return self._rows(self.core.observe(), self.core.active)

    def step(
        self, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]:
        n, m = self.num_fields, self.config.num_agents
        action = actions.detach().to("cpu", torch.float64).numpy().reshape(n, m, self.num_actions)
        result = self.core.step(action)
        info, live = result.info, result.info["live"]
        episode = {k: self._tensor(v) for k, v in info["episode"].items() if k not in ("field", "agent")}
        out = {
            "final_obs": self._rows(info["final_obs"], live),
            "episode": episode,
            "live": self._tensor(live.ravel(), torch.bool),
            "control_steps": self._tensor(info["control_steps"].ravel(), torch.int64),
            "action_clipped": self._tensor(info["action_clipped"].ravel(), torch.int64),
        }
        return (
            self._rows(result.obs, self.core.active),
            self._tensor(result.reward.ravel()),
            self._tensor((result.terminated | ~live).ravel(), torch.bool),
            self._tensor(result.truncated.ravel(), torch.bool),
            out,
        )


__all__ = ["MultiRobotCore", "MultiRobotParallelEnv", "MultiStepResult", "MultiVectorEnv"]
