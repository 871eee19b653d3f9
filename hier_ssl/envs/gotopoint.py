"""The goToPoint task, where the worker is the learner: drive to a sub-goal pose and stop there.

Every one of N fields holds one robot and one sub-goal (x, y, theta, 0, 0). At reset the robot is placed
uniformly on the field with a uniform heading, at rest or (``moving_fraction`` of episodes) at a random
velocity; the sub-goal is uniform on the field or (``near_fraction``) within ``near_radius`` of the
robot, with a uniform heading. A manager that moves its sub-goal while the robot drives poses the same
problem as a fresh episode that starts moving, so the moving starts train for that.

The worker observes ``worker_observation`` (9 values) and acts with a normalised robot-frame command
(vx, vy, w) in [-1, 1]; rewards are ``hier_ssl.worker.rewards``; success is the Baseline predicate on
the sub-goal (within ``reach_d_th`` and ``reach_theta_th_deg``, by default the env's d_th and
theta_th_deg, and slower than speed_th) and ends the episode; ``env.max_steps`` truncates it.
``evaluate_worker`` runs any worker (scripted, learned, perturbed) on the same episodes.
"""

from __future__ import annotations

import numpy as np
import torch

from hier_ssl.config import EnvConfig, GoToPointConfig, TrainConfig
from hier_ssl.envs.core import HierarchicalCore, StepResult
from hier_ssl.envs.planners import make_planner
from hier_ssl.envs.play import play
from hier_ssl.envs.rules import check_action
from hier_ssl.envs.scenario import Placement, Scenario
from hier_ssl.envs.vector import TorchView
from hier_ssl.manager import baseline_success, min_time_to_pose, pose_errors, summarize
from hier_ssl.worker import Worker, make_worker
from hier_ssl.worker.learned import LearnedWorker, WorkerPolicy
from hier_ssl.worker.observation import WORKER_OBS_DIM, controlled_worker_observation
from hier_ssl.worker.rewards import gotopoint_reward, pose_potential
from hier_ssl.world.frames import to_robot_frame
from hier_ssl.world.physics import World

ACT_DIM = 3


class GoToPoint(Scenario):
    """The goToPoint task's episodes as a scenario: one robot, no obstacle, its sub-goal as the target.

    Played by the ``direct`` manager (the sub-goal is the target, decided once) with the worker under test,
    the core scores it by the Baseline task's success (within d_th and theta_th of the target, slower than
    speed_th), so ``evaluate_worker`` is the one episode loop of every evaluation (``hier_ssl.envs.play``).
    The worker-learning task (``GoToPointCore``) draws its episodes from the same ``reset_world_at``.
    """

    name = "gotopoint"
    reward_task = "baseline"

    def __init__(self, config: EnvConfig, task: GoToPointConfig) -> None:
        # The direct manager reads the paper's observation layout and writes field-frame pose4 actions, once
        # an episode.
        update = {"observation": "paper", "action_form": "pose4", "action_frame": "field"}
        super().__init__(config.model_copy(update={**update, "frame_skip": config.max_steps}), 1, [])
        self.task = task

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> Placement:
        """Starts (uniform, at rest or ``moving_fraction`` of them moving) and sub-goals (uniform or
        ``near_fraction`` of them within ``near_radius`` of the start) of ``num_fields`` episodes."""
        task, half, robot = self.task, self.half, self.robot
        robot_xy = rng.uniform(-half, half, (num_fields, 2))
        angle = rng.uniform(-np.pi, np.pi, num_fields)
        radius = task.near_radius * np.sqrt(rng.uniform(0.0, 1.0, num_fields))
        bearing = rng.uniform(-np.pi, np.pi, num_fields)
        near_xy = np.clip(
            robot_xy + radius[:, None] * np.stack([np.cos(bearing), np.sin(bearing)], 1), -half, half
        )
        near = rng.uniform(size=num_fields) < task.near_fraction
        goal_xy = np.where(near[:, None], near_xy, rng.uniform(-half, half, (num_fields, 2)))
        moving = rng.uniform(size=num_fields) < task.moving_fraction
        speed = np.where(moving, rng.uniform(0.0, robot.max_speed, num_fields), 0.0)
        heading = rng.uniform(-np.pi, np.pi, num_fields)
        vel = speed[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=1)
        spin = np.where(moving, rng.uniform(-0.5, 0.5, num_fields) * robot.max_ang_speed, 0.0)
        target = np.zeros((num_fields, 1, 5))
        target[:, 0, 0:2] = goal_xy
        target[:, 0, 2] = rng.uniform(-np.pi, np.pi, num_fields)
        return Placement(robot_xy[:, None], angle[:, None], target, vel[:, None], spin[:, None])


class GoToPointCore:
    """N fields of the goToPoint task as numpy arrays.

    ``autoreset`` resets finished fields inside ``step`` (training); without it a finished field holds
    still and scores nothing until ``reset`` (evaluation, one episode per field).
    """

    def __init__(
        self, config: EnvConfig, task: GoToPointConfig, num_fields: int = 1, autoreset: bool = True
    ) -> None:
        self.config, self.task = config, task
        self.num_fields, self.autoreset = num_fields, autoreset
        self.episodes = GoToPoint(config, task)
        self.world = World(num_fields, 1, config.field, dt=config.dt, substeps=config.substeps)
        self.field, self.robot = self.world.field, self.world.robot
        self.scale = np.array([self.robot.max_speed, self.robot.max_speed, self.robot.max_ang_speed])
        self.d_th = config.d_th if task.reach_d_th is None else task.reach_d_th
        self.theta_th = np.deg2rad(
            config.theta_th_deg if task.reach_theta_th_deg is None else task.reach_theta_th_deg
        )
        self.rng = np.random.default_rng()

        n = num_fields
        self.subgoal = np.zeros((n, 5))
        self.start_distance = np.zeros(n)  # m, robot to sub-goal at reset
        self.phi = np.zeros(n)  # pose potential after the last step
        self.prev_action = np.zeros((n, ACT_DIM))
        self.steps = np.zeros(n, dtype=np.int64)
        self.ep_return = np.zeros(n)
        self.done = np.ones(n, dtype=bool)

    # -- reset ---------------------------------------------------------------------------------------------

    def reset(self, seed: int | None = None) -> np.ndarray:
        """Start a new episode in every field. Returns the worker observations (N, 9)."""
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        self.reset_fields(np.arange(self.num_fields))
        return self.observe()

    def reset_fields(self, fields: np.ndarray) -> None:
        """Starts, start velocities and sub-goals for ``fields`` (M,) ints (``GoToPoint.reset_world_at``)."""
        if len(fields) == 0:
            return
        placement = self.episodes.reset_world_at(len(fields), self.rng)
        self.world.set_state(fields, placement.pos, placement.angle, placement.vel, placement.ang_vel)
        self.subgoal[fields] = placement.target[:, 0]
        angle, vel, spin = placement.angle[:, 0], placement.vel[:, 0], placement.ang_vel[:, 0]
        s = self.world.state
        d, delta = pose_errors(np.column_stack([s.pos[fields, 0], s.angle[fields, 0]]), self.subgoal[fields])
        self.start_distance[fields] = d
        self.phi[fields] = pose_potential(d, delta, self.task.angle_weight)
        # The command that would keep the robot as it is: what a smooth first command changes least.
        self.prev_action[fields, 0:2] = to_robot_frame(vel, angle) / self.robot.max_speed
        self.prev_action[fields, 2] = spin / self.robot.max_ang_speed
        self.steps[fields] = 0
        self.ep_return[fields] = 0.0
        self.done[fields] = False

    # -- observing and acting ------------------------------------------------------------------------------

    def observe(self) -> np.ndarray:
        """Worker observations (N, 9) float32."""
        state, subgoal = self.world.state, self.subgoal[:, None]
        return controlled_worker_observation(state, subgoal, self.robot, self.field.max_pos)[:, 0]

    def step_command(self, command: np.ndarray) -> StepResult:
        """``step`` with robot-frame commands (N, 3) in m/s and rad/s, as scripted workers give them."""
        return self._advance(check_action("worker", command, (self.num_fields, ACT_DIM)) / self.scale)

    def step(self, action: np.ndarray) -> StepResult:
        """One 25 ms control step of every live field with normalised commands ``action`` (N, 3), clipped
        to [-1, 1]; see ``_advance``."""
        return self._advance(np.clip(check_action("worker", action, (self.num_fields, ACT_DIM)), -1.0, 1.0))

    def _advance(self, action: np.ndarray) -> StepResult:
        """One 25 ms control step of every live field with normalised commands ``action`` (N, 3).

        Returns obs (N, 9), reward (N,), terminated (N,) on success, truncated (N,) at ``max_steps``, and
        info: "success" (N,), reward "terms", "final_obs" (N, 9) before any auto-reset, and "task" with
        one entry per finished episode (field, return, length in control steps, success, start_distance).
        """
        cfg, task = self.config, self.task
        live = ~self.done
        if not live.any():
            raise RuntimeError("step() with every episode finished: call reset() first")
        command = np.where(live[:, None], action * self.scale, 0.0)
        s = self.world.step(command[:, None])
        self.steps += live

        pos, angle, vel = s.pos[:, 0], s.angle[:, 0], s.vel[:, 0]
        d, delta = pose_errors(np.column_stack([pos, angle]), self.subgoal)
        phi = pose_potential(d, delta, task.angle_weight)
        success = baseline_success(
            self.subgoal, pos, angle, vel, d_th=self.d_th, theta_th=self.theta_th, speed_th=cfg.speed_th
        )
        reward, terms = gotopoint_reward(
            self.phi,
            phi,
            action,
            self.prev_action,
            success,
            time_cost=task.time_cost,
            smooth_cost=task.smooth_cost,
            success_bonus=task.success_bonus,
        )
        reward = np.where(live, reward, 0.0)
        self.phi = np.where(live, phi, self.phi)
        self.prev_action = np.where(live[:, None], action, self.prev_action)
        self.ep_return += reward
        terminated = success & live
        truncated = (self.steps >= cfg.max_steps) & live & ~terminated

        ended = terminated | truncated
        idx = np.flatnonzero(ended)
        info: dict[str, object] = {
            "success": terminated,
            "terms": terms,
            "task": {
                "field": idx,
                "return": self.ep_return[idx].copy(),
                "length": self.steps[idx].copy(),
                "success": terminated[idx].astype(np.float64),
                "start_distance": self.start_distance[idx].copy(),
            },
        }
        obs = self.observe()
        info["final_obs"] = obs
        self.done |= ended
        if self.autoreset and len(idx):
            self.reset_fields(idx)
            obs = self.observe()
        return StepResult(obs, reward.astype(np.float32), terminated, truncated, info)


class GoToPointEnv(TorchView):
    """The batched torch view of ``GoToPointCore`` (auto-reset), with ``VectorEnv``'s protocol, so that
    ``RslRlVecEnv`` and ``make_ppo_runner`` take it as they are.

    ``step(actions (N, 3) in [-1, 1])`` returns obs (N, 9) float32, reward (N,), terminated (N,),
    truncated (N,), info with "final_obs" and "task" (1-D tensors: return, length, success,
    start_distance).
    """

    def __init__(
        self,
        config: EnvConfig,
        task: GoToPointConfig,
        num_envs: int,
        device: str | torch.device = "cpu",
        seed: int | None = None,
    ) -> None:
        self.config, self.task = config, task
        core = GoToPointCore(config, task, num_envs, autoreset=True)
        core.rng = np.random.default_rng(seed)
        super().__init__(core, WORKER_OBS_DIM, (num_envs, ACT_DIM), config.max_steps, device)


def evaluate_worker(
    worker: Worker, config: EnvConfig, task: GoToPointConfig, episodes: int, seed: int = 0
) -> dict[str, object]:
    """Run ``worker`` (``__call__(state, subgoal) -> command``, ``reset(fields)``) on ``episodes`` seeded
    goToPoint episodes (``GoToPoint``), one per field: the same starts and sub-goals for every worker given
    one seed. The ``direct`` manager names each sub-goal; the episode loop is ``play``'s.

    Returns success_rate; time_s and min_time_s ({median, q1, q3, min, max} over successful episodes,
    NaN if there are none): the time to reach the sub-goal and the analytic rest-to-rest minimum for its
    distance under the robot's limits (``min_time_to_pose``; it ignores the turn and any start velocity);
    optimal_ratio_median (time over minimum); and the per-episode arrays under "per_episode".
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    scenario = GoToPoint(config, task)
    core = HierarchicalCore(scenario, episodes, autoreset=False, worker=worker)
    ends = play(core, make_planner("direct", scenario.config), seed)
    length, success, distance = ends["length"][:, 0], ends["success"][:, 0], ends["distance"][:, 0]
    robot = core.robot
    time_s = length * config.dt
    bound = min_time_to_pose(distance, robot.max_speed, robot.max_accel)
    if success.any():
        time_stats, bound_stats = summarize(time_s[success]), summarize(bound[success])
        ratio = float(np.median(time_s[success] / np.maximum(bound[success], config.dt)))
    else:  # nothing reached: no time to report
        time_stats = bound_stats = dict.fromkeys(("median", "q1", "q3", "min", "max"), float("nan"))
        ratio = float("nan")
    return {
        "episodes": episodes,
        "success_rate": float(success.mean()),
        "time_s": time_stats,
        "min_time_s": bound_stats,
        "optimal_ratio_median": ratio,
        "per_episode": {"length": length, "success": success, "distance": distance},
    }


def uniform_task(task: GoToPointConfig) -> GoToPointConfig:
    """The evaluation episodes: ``task`` with every sub-goal uniform on the field, every start at rest,
    and success at the env's thresholds (d_th, theta_th_deg, speed_th)."""
    update = {"near_fraction": 0.0, "moving_fraction": 0.0, "reach_d_th": None, "reach_theta_th_deg": None}
    return task.model_copy(update=update)


def worker_summary(policy: WorkerPolicy, config: TrainConfig, seed: int) -> dict[str, object]:
    """A trained worker's policy beside the scripted workers on the same ``config.eval_episodes``
    episodes (``uniform_task``): eval.json of a ``kind: worker`` run."""
    env, episodes = config.env, config.eval_episodes
    world = World(1, 1, env.field, dt=env.dt)
    workers = {"learned": LearnedWorker(policy, world.robot, world.field.max_pos)}
    workers |= {name: make_worker(name, world.robot, env.dt) for name in ("paper", "bangbang")}
    rows = {}
    for name, worker in workers.items():
        result = evaluate_worker(worker, env, uniform_task(config.gotopoint), episodes, seed)
        rows[name] = {k: v for k, v in result.items() if k != "per_episode"}
    learned = rows["learned"]
    return {
        "task": "gotopoint",
        "worker": "learned",
        "episodes": episodes,
        "success_rate": learned["success_rate"],
        "time_s_median": learned["time_s"]["median"],
        "min_time_s_median": learned["min_time_s"]["median"],
        "optimal_ratio_median": learned["optimal_ratio_median"],
        "workers": rows,
    }


def print_worker_summary(summary: dict[str, object]) -> None:
    """The ``worker_summary`` table as Markdown."""
    print(
        f"| worker ({summary['episodes']} goToPoint episodes from rest) | success | time s, median (Q1 - Q3) "
        "| analytic minimum s, median | time / minimum, median |"
    )
    print("|---|---|---|---|---|")
    for name, row in summary["workers"].items():
        t, bound = row["time_s"], row["min_time_s"]
        print(
            f"| {name} | {100 * row['success_rate']:.1f} % "
            f"| {t['median']:.3f} ({t['q1']:.3f} - {t['q3']:.3f}) "
            f"| {bound['median']:.3f} | {row['optimal_ratio_median']:.2f} |"
        )
    if "train_wall_s" in summary:
        print(f"training wall time: {summary['train_wall_s']:.0f} s")


__all__ = [
    "GoToPoint",
    "GoToPointCore",
    "GoToPointEnv",
    "evaluate_worker",
    "print_worker_summary",
    "uniform_task",
    "worker_summary",
]
