"""The PettingZoo ``ParallelEnv`` view of one field of the core, and a single-agent Gymnasium view.

| Import             | ``from hier_ssl.envs import parallel_env``; ``parallel_env(config)``                |
|--------------------|-------------------------------------------------------------------------------------|
| Actions            | Continuous                                                                          |
| Parallel API       | Yes                                                                                 |
| Manual control     | No                                                                                  |
| Agents             | ``["manager_0", ..., "manager_{M-1}"]``, + ``worker_i`` and ``obstacle_j`` exposed  |
| Agents count       | M; + M with ``expose_worker``; + K with ``expose_obstacles``                        |
| Action shape       | manager (4,) ``pose4`` or (6,) ``pose6``; worker and obstacle (3,)                  |
| Action values      | [-1, 1]; a manager's values beyond are clipped and counted (``action_clipped``)     |
| Observation shape  | manager (O,), the scenario's observation; worker (9,); obstacle (7,)                |
| Observation values | [-1.2, 1.2]                                                                         |
| State shape        | (7 R + 13 M,): ``hier_ssl.envs.state``                                              |
| State values       | [-1.2, 1.2]                                                                         |

Arguments: ``parallel_env(config=None, render_mode=None, worker=None, **settings)``: ``config`` a task or
scenario name, a YAML file or a config (``hier_ssl.envs.task_config``); ``render_mode`` "human" or
"rgb_array"; ``worker`` a worker spec or object (``hier_ssl.worker.resolve_worker``); ``settings`` override
config keys (``frame_skip=16``, ``expose_worker=True``, ...).

With only the managers exposed, one ``step`` is one manager decision (``frame_skip`` control steps, reward
summed or last: the core's ``step``). With workers or obstacles exposed, one ``step`` is one 25 ms control
step (the core's ``step_control``): the managers' actions are used on decision steps only
(``infos["manager_i"]["decision"]`` says whether they were), their rewards are per control step, and a
worker's reward is R_d + R_theta of its robot against its sub-goal. ``manager_i`` and ``worker_i`` leave
when robot i reaches its target or collides; obstacles leave with the last of them, when the episode is
over. The view converts dicts by agent to the core's arrays and back, and checks each action once, as it
enters, naming the agent.
"""

from __future__ import annotations

import functools
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from hier_ssl.config import EnvConfig, TaskConfig
from hier_ssl.envs.core import HierarchicalCore, StepResult
from hier_ssl.envs.rules import check_action
from hier_ssl.envs.state import CLIP, global_state, state_dim
from hier_ssl.worker.observation import WORKER_OBS_DIM
from hier_ssl.world.obstacles import OBSTACLE_AGENT_OBS_DIM, obstacle_observation

MANAGER = "manager_0"


class HierarchicalSSLEnv(ParallelEnv):
    """One field of a paper task or scenario as a PettingZoo ParallelEnv (module docstring). ``state()``
    is the field's global state for centralised critics, a (D,) float32 vector in ``state_space``
    (columns: ``hier_ssl.envs.state``)."""

    metadata = {"name": "hier_ssl_v0", "render_modes": ["human", "rgb_array"], "is_parallelizable": True}

    def __init__(
        self, config: TaskConfig | None = None, render_mode: str | None = None, worker: Any = None
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} not in {self.metadata['render_modes']}")
        self.render_mode = render_mode
        self.core = HierarchicalCore(config or EnvConfig(), 1, autoreset=False, worker=worker)
        self.config = cfg = self.core.config
        m, k = self.core.num_agents, self.core.num_obstacles
        self.managers = [f"manager_{i}" for i in range(m)]
        self.workers = [f"worker_{i}" for i in range(m)] if cfg.expose_worker else []
        self.obstacle_agents = [f"obstacle_{j}" for j in range(k)] if cfg.expose_obstacles else []
        self.possible_agents = self.managers + self.workers + self.obstacle_agents
        self._known = frozenset(self.possible_agents)
        # The controlled robot each manager and worker agent stands for.
        self._robot = {a: int(a.rsplit("_", 1)[1]) for a in self.managers + self.workers}
        self.per_control_step = cfg.expose_worker or cfg.expose_obstacles
        # One frame per step: a decision (frame_skip control steps), or one control step with exposed agents.
        period = cfg.dt * (1 if self.per_control_step else cfg.frame_skip)
        self.metadata = {**self.metadata, "render_fps": 1 / period}
        box = functools.partial(spaces.Box, dtype=np.float32)
        manager_obs = box(-1.2, 1.2, (self.core.obs_dim,))
        self._obs_spaces = {a: manager_obs for a in self.managers}
        self._act_spaces = {a: box(-1.0, 1.0, (self.core.act_dim,)) for a in self.managers}
        for agent in self.workers:
            self._obs_spaces[agent] = box(-1.2, 1.2, (WORKER_OBS_DIM,))
            self._act_spaces[agent] = box(-1.0, 1.0, (3,))
        for agent in self.obstacle_agents:
            self._obs_spaces[agent] = box(-1.2, 1.2, (OBSTACLE_AGENT_OBS_DIM,))
            self._act_spaces[agent] = box(-1.0, 1.0, (3,))
        self.state_space = box(-CLIP, CLIP, (state_dim(m, k, self.core.world.num_balls),))
        self._act_shapes = {a: space.shape for a, space in self._act_spaces.items()}
        self.agents: list[str] = []
        self._started = False  # reset() was called: an empty ``agents`` means the episode is over
        self._trail: list[np.ndarray] = []  # the controlled robots' positions (M, 2) after each step
        self._window = None

    def observation_space(self, agent: str) -> spaces.Box:
        return self._obs_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        return self._act_spaces[agent]

    def state(self) -> np.ndarray:
        """The global state (D,) float32 of the field: every robot's pose and velocity, every controlled
        robot's target, held sub-goal and whether it is still in its episode, normalised like the
        observations (``hier_ssl.envs.state`` lists the columns). Computed when called."""
        return global_state(self.core)[0]

    def _observations(self, manager_obs: np.ndarray) -> dict[str, np.ndarray]:
        """Observations of the live agents; ``manager_obs`` (M, O) of field 0."""
        live = set(self.agents)
        obs = {a: manager_obs[i] for i, a in enumerate(self.managers) if a in live}
        if self.workers:
            worker_obs = self.core.observe_worker()[0]
            obs |= {a: worker_obs[i] for i, a in enumerate(self.workers) if a in live}
        core = self.core
        for j, agent in enumerate(self.obstacle_agents):
            if agent in live:
                obs[agent] = obstacle_observation(core.state, core.num_agents + j, core.field, core.robot)[0]
        return obs

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        if seed is not None:
            for i, agent in enumerate(self.possible_agents):
                self._act_spaces[agent].seed(seed + i)
        obs = self.core.reset(seed)[0]
        self.agents, self._started = list(self.possible_agents), True
        # The world replaces its state, never changes it: views of it stay as they were.
        self._trail = [self.core.state.pos[0, : self.core.num_agents]]
        return self._observations(obs), {agent: {} for agent in self.agents}

    def step(self, actions: dict[str, np.ndarray]) -> tuple[dict, dict, dict, dict, dict]:
        """Actions for agents that have left are ignored, as PettingZoo's converted envs do (TorchRL's
        wrapper sends one for every agent); once every agent has left, a step returns five empty dicts."""
        if not self._started:
            raise RuntimeError("step() before reset(): call reset() first")
        if not actions.keys() <= self._known:
            raise ValueError(
                f"actions for agents this env does not have: {sorted(actions.keys() - self._known)}; "
                f"agents: {self.possible_agents}"
            )
        if not self.agents:
            return {}, {}, {}, {}, {}
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"no action for live agents {sorted(missing)}")
        shapes = self._act_shapes
        checked = {a: check_action(a, actions[a], shapes[a]) for a in self.agents}
        batch = np.zeros((1, self.core.num_agents, self.core.act_dim))
        for agent in self.managers:
            if agent in checked:
                batch[0, self._robot[agent]] = checked[agent]
        result = self._step_control(checked, batch) if self.per_control_step else self.core.step(batch)
        if self.render_mode is not None:  # without a render mode there is nothing to draw the trail on
            self._trail.append(self.core.state.pos[0, : self.core.num_agents])
        out = self._outputs(result)
        # A manager or worker stays while its robot is in the episode, an obstacle while any robot is.
        active = self.core.active[0].tolist()
        robot, field_live = self._robot, any(active)
        self.agents = [a for a in self.agents if (active[robot[a]] if a in robot else field_live)]
        if self.render_mode == "human":
            self.render()
        return out

    def _outputs(self, result: StepResult) -> tuple[dict, dict, dict, dict, dict]:
        """The five dicts of ``step`` for the agents live before it, from the core's result."""
        info, stats = result.info, result.info["task"]
        ended = {i: row for row, i in enumerate(stats["agent"].tolist())} if len(stats["agent"]) else {}
        obs = self._observations(result.obs[0])
        rewards, terms, truncs, infos = {}, {}, {}, {}
        decision = info["decision"].item(0) if "decision" in info else True
        for agent in self.agents:
            if agent in self.obstacle_agents:
                over = not self.core.active[0].any()
                truncated = bool(result.truncated[0].any())
                rewards[agent], terms[agent], truncs[agent] = 0.0, over and not truncated, over and truncated
                infos[agent] = {}
                continue
            # item() gives the Python bool, int or float of an element without a numpy scalar between.
            i = self._robot[agent]
            terms[agent], truncs[agent] = result.terminated.item(0, i), result.truncated.item(0, i)
            if agent in self.workers:
                rewards[agent], infos[agent] = float(info["worker_reward"][0, i]), {}
                continue
            rewards[agent] = result.reward.item(0, i)
            infos[agent] = {
                "control_steps": info["control_steps"].item(0, i),
                "action_clipped": info["action_clipped"].item(0, i),
                "subgoal": info["subgoal"][0, i],
                "success": info["success"].item(0, i),
                "collision": info["collision"].item(0, i),
                "decision": decision,
            }
            if i in ended:
                skip = ("field", "agent")
                infos[agent]["task"] = {k: v[ended[i]] for k, v in stats.items() if k not in skip}
        return obs, rewards, terms, truncs, infos

    def _step_control(self, actions: dict[str, np.ndarray], manager_action: np.ndarray) -> StepResult:
        """The core's ``step_control`` with the exposed workers' and obstacles' actions as arrays."""
        worker = None
        if self.workers:
            worker = np.stack([actions.get(a, np.zeros(3)) for a in self.workers])[None]
        obstacles = None
        if self.obstacle_agents:
            obstacles = np.stack([actions[a] for a in self.obstacle_agents])[None]
        return self.core.step_control(manager_action, worker, obstacles)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array'.")
            return None
        # here, not at the top: matplotlib, for rendering alone
        from hier_ssl.world.render import render_fields

        m, k = self.core.num_agents, self.core.num_obstacles
        trail = np.array(self._trail)
        frame = render_fields(
            self.core.field,
            self.core.state,
            targets=self.core.target,
            subgoals=self.core.subgoal,
            trails=[trail[:, i] for i in range(m)],
            team=[0] * m + [1] * k,
            ssl_teams=self.core.scenario.ssl_teams,
            extra=functools.partial(self.core.scenario.extra_render, field_index=0),
            balls=None if self.core.world.ball is None else self.core.world.ball.pos,
            ball=self.core.world.ball_spec,
        )
        if self.render_mode == "human":
            self._show(frame)
            return None
        return frame

    def _show(self, frame: np.ndarray) -> None:
        # here, not at the top: matplotlib, for rendering alone
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
            # here, not at the top: matplotlib, for rendering alone
            import matplotlib.pyplot as plt

            plt.close(self._window.figure)
            self._window = None


class ManagerEnv(gymnasium.Env):
    """Single-agent Gymnasium view: the manager of one field with one controlled robot; worker and
    obstacles scripted. One step is one decision; an episode ends, truncated, after ``max_episode_steps``
    decisions (``max_steps`` control steps) if the robot has not left it before. Render modes: "human"
    (a matplotlib window, drawn every step) and "rgb_array"; ``render_fps`` is one frame per decision."""

    metadata = {"render_modes": ["human", "rgb_array"]}

    def __init__(
        self, config: TaskConfig | None = None, render_mode: str | None = None, worker: Any = None
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"ManagerEnv: render_mode {render_mode!r} is not one of {self.metadata['render_modes']}"
            )
        config = (config or EnvConfig()).model_copy(
            update={"expose_worker": False, "expose_obstacles": False}
        )
        self.env = HierarchicalSSLEnv(config, render_mode=render_mode, worker=worker)
        if self.env.managers != [MANAGER]:
            raise ValueError(f"ManagerEnv drives one manager; this task has {len(self.env.managers)}")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.env.metadata["render_fps"]}
        self.observation_space = self.env.observation_space(MANAGER)
        self.action_space = self.env.action_space(MANAGER)
        self.max_episode_steps = -(-self.env.config.max_steps // self.env.config.frame_skip)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        obs, infos = self.env.reset(seed=seed, options=options)
        return obs[MANAGER], infos[MANAGER]

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        if not self.env.agents:
            raise RuntimeError("step() after the episode ended: call reset() first")
        obs, rewards, terms, truncs, infos = self.env.step({MANAGER: action})
        return obs[MANAGER], rewards[MANAGER], terms[MANAGER], truncs[MANAGER], infos[MANAGER]

    def render(self) -> np.ndarray | None:
        return self.env.render()

    def close(self) -> None:
        self.env.close()


__all__ = ["MANAGER", "HierarchicalSSLEnv", "ManagerEnv"]
