"""The PettingZoo ``ParallelEnv`` view (one field) and a single-agent Gymnasium view of its manager.

Agents: ``manager_0`` always; ``worker_0`` when ``expose_worker``; ``obstacle_j`` when
``expose_obstacles``. With only the manager exposed, one ``step`` is one manager decision
(``frame_skip`` control steps, reward summed or last). With a worker or obstacles exposed, one
``step`` is one 25 ms control step, and the manager's action is used on decision steps only
(``infos["manager_0"]["decision"]`` says whether it was); its reward is then per control step.
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from hier_ssl.config import EnvConfig
from hier_ssl.envs.core import OBSTACLE_OBS_DIM, HierarchicalCore, check_action
from hier_ssl.manager import angle_reward, distance_reward, pose_errors
from hier_ssl.worker.observation import WORKER_OBS_DIM

MANAGER, WORKER = "manager_0", "worker_0"


class HierarchicalSSLEnv(ParallelEnv):
    metadata = {"name": "hier_ssl_v0", "render_modes": ["human", "rgb_array"], "is_parallelizable": True}

    def __init__(self, config: EnvConfig | None = None, render_mode: str | None = None) -> None:
        self.config = config or EnvConfig()
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} not in {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.core = HierarchicalCore(self.config, 1, autoreset=False)
        k = self.core.num_obstacles
        self.obstacle_agents = [f"obstacle_{j}" for j in range(k)] if self.config.expose_obstacles else []
        self.possible_agents = (
            [MANAGER] + ([WORKER] if self.config.expose_worker else []) + self.obstacle_agents
        )
        self.per_control_step = self.config.expose_worker or self.config.expose_obstacles
        self.metadata = {**self.metadata, "render_fps": round(1 / self.config.dt)}
        box = functools.partial(spaces.Box, dtype=np.float32)
        self._obs_spaces = {MANAGER: box(-1.2, 1.2, (self.core.obs_dim,))}
        self._act_spaces = {MANAGER: box(-1.0, 1.0, (self.core.act_dim,))}
        if self.config.expose_worker:
            self._obs_spaces[WORKER] = box(-1.2, 1.2, (WORKER_OBS_DIM,))
            self._act_spaces[WORKER] = box(-1.0, 1.0, (3,))
        for agent in self.obstacle_agents:
            self._obs_spaces[agent] = box(-1.2, 1.2, (OBSTACLE_OBS_DIM,))
            self._act_spaces[agent] = box(-1.0, 1.0, (3,))
        self.agents: list[str] = []
        self._trail: list[np.ndarray] = []
        self._window = None

    def observation_space(self, agent: str) -> spaces.Box:
        return self._obs_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        return self._act_spaces[agent]

    def _observations(self) -> dict[str, np.ndarray]:
        obs = {MANAGER: self.core.observe()[0]}
        if WORKER in self.agents:
            obs[WORKER] = self.core.observe_worker()[0]
        for j, agent in enumerate(self.obstacle_agents):
            obs[agent] = self.core.observe_obstacle(j)[0]
        return obs

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if seed is not None:
            for i, agent in enumerate(self.possible_agents):
                self._act_spaces[agent].seed(seed + i)
        self.core.reset(seed)
        self.agents = list(self.possible_agents)
        self._trail = [self.core.state.pos[0, 0].copy()]
        return self._observations(), {agent: {} for agent in self.agents}

    def step(self, actions: dict[str, np.ndarray]) -> tuple[dict, dict, dict, dict, dict]:
        if not self.agents:
            raise RuntimeError("step() after the episode ended: call reset() first")
        unknown = set(actions) - set(self.agents)
        if unknown:
            raise ValueError(f"actions for agents that are not live: {sorted(unknown)}; live: {self.agents}")
        missing = set(self.agents) - set(actions)
        if missing:
            raise ValueError(f"no action for live agents {sorted(missing)}")
        checked = {a: check_action(a, actions[a], self._act_spaces[a].shape) for a in self.agents}
        manager_action = checked[MANAGER][None]
        if self.per_control_step:
            result = self._control_step(checked, manager_action)
        else:
            result = self.core.step(manager_action)
        self._trail.append(self.core.state.pos[0, 0].copy())

        terminated, truncated = bool(result.terminated[0]), bool(result.truncated[0])
        info = {
            key: value[0] for key, value in result.info.items() if key in ("control_steps", "action_clipped")
        }
        info.update(
            subgoal=self.core.subgoal[0].copy(),
            success=bool(result.info["success"][0]),
            collision=bool(result.info["collision"][0]),
            decision=result.info.get("decision", True),
        )
        if terminated or truncated:
            info["episode"] = {k: v[0] for k, v in result.info["episode"].items() if k != "field"}
        rewards = {agent: 0.0 for agent in self.agents}
        rewards[MANAGER] = float(result.reward[0])
        if WORKER in self.agents:
            rewards[WORKER] = float(result.info["worker_reward"][0])
        observations = self._observations()
        infos = {agent: {} for agent in self.agents}
        infos[MANAGER] = info
        terminations = {agent: terminated for agent in self.agents}
        truncations = {agent: truncated for agent in self.agents}
        if terminated or truncated:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def _control_step(self, actions: dict[str, np.ndarray], manager_action: np.ndarray) -> Any:
        """One control step with exposed agents; the manager acts on decision steps only."""
        core = self.core
        decision = core.steps[0] % self.config.frame_skip == 0
        clipped = core.set_subgoal(manager_action, np.arange(1)) if decision else np.zeros(1, dtype=np.int64)
        worker = actions[WORKER][None] if WORKER in actions else None
        obstacles = (
            np.stack([actions[a] for a in self.obstacle_agents])[None] if self.obstacle_agents else None
        )
        live = np.ones(1, dtype=bool)
        reward, success, hit, timeout, _ = core.control_step(live, worker, obstacles)
        s = core.state
        d, delta = pose_errors(np.column_stack([s.pos[:, 0], s.angle[:, 0]]), core.subgoal)
        result = core.finish_period(
            reward,
            success | (hit & ~success),
            timeout & ~success & ~hit,
            success,
            hit & ~success,
            np.ones(1, dtype=np.int64),
            clipped,
        )
        result.info["decision"] = bool(decision)
        result.info["worker_reward"] = distance_reward(d, self.config.d_th) + angle_reward(
            delta, core.theta_th
        )
        return result

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'.")
            return None
        from hier_ssl.world.render import render_fields

        frame = render_fields(
            self.core.field,
            self.core.state,
            targets=self.core.target,
            subgoals=self.core.subgoal,
            trails=[np.array(self._trail)],
        )
        if self.render_mode == "human":
            self._show(frame)
            return None
        return frame

    def _show(self, frame: np.ndarray) -> None:
        import matplotlib.pyplot as plt

        if self._window is None:
            plt.ion()
            self._window = plt.imshow(frame)
            plt.axis("off")
        else:
            self._window.set_data(frame)
        plt.pause(1e-3)

    def close(self) -> None:
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window.figure)
            self._window = None


class ManagerEnv(gymnasium.Env):
    """Single-agent Gymnasium view: the manager of one field; worker and obstacles scripted."""

    metadata = {"render_modes": ["rgb_array"]}

    def __init__(self, config: EnvConfig | None = None, render_mode: str | None = None) -> None:
        config = (config or EnvConfig()).model_copy(
            update={"expose_worker": False, "expose_obstacles": False}
        )
        self.env = HierarchicalSSLEnv(config, render_mode=render_mode)
        self.render_mode = render_mode
        self.observation_space = self.env.observation_space(MANAGER)
        self.action_space = self.env.action_space(MANAGER)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        obs, infos = self.env.reset(seed=seed, options=options)
        return obs[MANAGER], infos[MANAGER]

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, rewards, terms, truncs, infos = self.env.step({MANAGER: action})
        return obs[MANAGER], rewards[MANAGER], terms[MANAGER], truncs[MANAGER], infos[MANAGER]

    def render(self) -> np.ndarray | None:
        return self.env.render()
