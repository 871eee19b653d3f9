"""The manager's reward terms (paper section 3, docs/paper.md "Rewards") as vectorised pure functions.

R = R_d + R_theta + R_t (+ R_obst + R_hit in the obstacle task), with d and delta the
distance and angle difference to the target, measured on the robot (Baseline) or on the
manager's sub-goal (Proposed, Obstacle: "action-centric").

The paper prints R_t = 1000 "if dist > D_th and delta > theta_th", an evident sign slip:
R_t is paid on the success step, whose predicate lives in `hier_ssl.manager.success`.

Each term is written once, as a numba ufunc (``distance_term``, ``angle_term``, ``obstacle_reward``) or a
compiled function of one robot (``reward_terms``, how the terms combine): numpy calls them on arrays, and the
core's compiled scoring (``hier_ssl.envs.rules``) calls the same definitions on one value, so the two paths
cannot drift apart. On the few rows of one field a step's cost is per-call overhead, not arithmetic: one
ufunc call replaces the several numpy calls of a masked expression.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from hier_ssl.world.frames import as_float, wrap, wrap_angle

DIST_THRESHOLD = 0.05  # D_th, m
ANGLE_THRESHOLD = math.radians(5.0)  # theta_th, rad
DIST_BONUS = 10.0  # R_d inside D_th
ANGLE_BONUS = 1.0  # R_theta inside theta_th
SUCCESS_REWARD = 1000.0
HIT_REWARD = -1000.0

TASKS = ("baseline", "proposed", "obstacle")
SUCCESS_MODES = ("add", "replace")
HIT_MODES = ("add", "replace")
# Where R_obst measures its distance to the nearest obstacle: the paper's text says the sub-goal, its public
# code the robot.
OBSTACLE_FROM = ("subgoal", "robot")
REWARD_TERMS = ("distance", "angle", "success", "obstacle", "hit")


def vector_length(xy: np.ndarray) -> np.ndarray:
    """Lengths (...) of 2-D vectors (..., 2): sqrt(x^2 + y^2), bit for bit what ``np.linalg.norm(xy,
    axis=-1)`` computes, at a third of its cost on a few rows."""
    square = xy * xy
    return np.sqrt(square[..., 0] + square[..., 1])


def _errors(xy: np.ndarray, theta: np.ndarray, pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (...) from points ``xy`` (..., 2) to ``pose`` (..., >= 3), and absolute angle (...) in
    [0, pi] from headings ``theta`` (...) to its heading."""
    return vector_length(xy - pose[..., 0:2]), np.abs(wrap_angle(theta - pose[..., 2]))


def pose_errors(pose_a: np.ndarray, pose_b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance and absolute angle difference between two batches of poses.

    Args:
        pose_a, pose_b: (N, 3) x, y, theta or (N, 5) x, y, theta, vx, vy; only x, y, theta
            are read, so sub-goals and targets can be passed as they are. Any leading axes may stand
            for N, as in all the per-step functions here.

    Returns:
        distance (N,) in m and delta (N,) in [0, pi] rad.
    """
    # One subtraction of (x, y, theta): the same differences as ``_errors`` takes, in a call less.
    diff = pose_a[..., 0:3] - pose_b[..., 0:3]
    return vector_length(diff[..., 0:2]), np.abs(wrap_angle(diff[..., 2]))


@numba.njit(cache=True)
def pose_error(pose_a: np.ndarray, pose_b: np.ndarray) -> tuple[float, float]:
    """``pose_errors`` of one pair of poses (>= 3,), for the compiled per-robot loops: the same operations
    (tests/manager/test_rewards.py holds the two equal)."""
    dx, dy = pose_a[0] - pose_b[0], pose_a[1] - pose_b[1]
    return math.sqrt(dx * dx + dy * dy), abs(wrap(pose_a[2] - pose_b[2]))


def measured_errors(
    task: str, target: np.ndarray, subgoal: np.ndarray, robot_pos: np.ndarray, robot_angle: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """d and delta (N,) of the pose ``task``'s reward and success measure against the target (N, 5): the
    robot's, robot_pos (N, 2) and robot_angle (N,), for "baseline"; the sub-goal's (N, 5) otherwise."""
    if task == "baseline":
        return _errors(robot_pos, robot_angle, target)
    return pose_errors(subgoal, target)


@numba.njit(cache=True)
def nearest_distance(x: float, y: float, obs_pos: np.ndarray) -> float:
    """Centre distance from the point (x, y) to its nearest obstacle of ``obs_pos`` (K, 2): the root of the
    least square (sqrt is correctly rounded and monotonic, so this is the least of the roots bit for bit,
    at one root instead of one per obstacle); +inf where K = 0, so thresholds and Gaussians of it read "no
    obstacle"."""
    least = math.inf
    for j in range(obs_pos.shape[0]):
        dx, dy = obs_pos[j, 0] - x, obs_pos[j, 1] - y
        least = min(least, dx * dx + dy * dy)
    return math.sqrt(least)


@numba.njit(cache=True)
def _nearest_rows(point: np.ndarray, obs_pos: np.ndarray, out: np.ndarray) -> None:
    for b in range(out.shape[0]):
        out[b] = nearest_distance(point[b, 0], point[b, 1], obs_pos[b])


def nearest_obstacle_distance(point: np.ndarray, obs_pos: np.ndarray) -> np.ndarray:
    """``nearest_distance`` of each field's point to its obstacles.

    Args:
        point: (N, 2) m. obs_pos: (N, K, 2) m, K >= 0; any leading axes may stand for N.

    Returns:
        (N,) m; +inf where K = 0.
    """
    lead = obs_pos.shape[:-2]
    out = np.empty(lead)
    rows = int(np.prod(lead))
    points = np.ascontiguousarray(np.broadcast_to(as_float(point), (*lead, 2))).reshape(rows, 2)
    obstacles = np.ascontiguousarray(as_float(obs_pos)).reshape(rows, *obs_pos.shape[-2:])
    _nearest_rows(points, obstacles, out.reshape(rows))
    return out


def obstacle_distance(
    obstacle_from: str, subgoal: np.ndarray, robot_pos: np.ndarray, obs_pos: np.ndarray
) -> np.ndarray:
    """The distance (N,) R_obst reads: from the sub-goal (N, 5) or the robot (N, 2) to the nearest obstacle
    of obs_pos (N, K, 2)."""
    point = subgoal[..., 0:2] if obstacle_from == "subgoal" else robot_pos
    return nearest_obstacle_distance(point, obs_pos)


@numba.vectorize(["float64(float64, float64)"], cache=True)
def distance_term(d: float, d_th: float) -> float:
    """R_d: -d where d > d_th, else +10; d in m. A ufunc over arrays of any shape and, inside compiled
    code, a function of one value."""
    return DIST_BONUS if d <= d_th else -d


@numba.vectorize(["float64(float64, float64)"], cache=True)
def angle_term(delta: float, theta_th: float) -> float:
    """R_theta: -delta / pi where delta > theta_th, else +1; delta in rad, in [0, pi]. A ufunc, as
    ``distance_term``."""
    return ANGLE_BONUS if delta <= theta_th else delta / -math.pi


def distance_reward(d: ArrayLike, d_th: float = DIST_THRESHOLD) -> np.ndarray:
    """R_d (``distance_term``) of distances d (any shape, m), the paper's D_th by default."""
    return distance_term(d, d_th)


def angle_reward(delta: ArrayLike, theta_th: float = ANGLE_THRESHOLD) -> np.ndarray:
    """R_theta (``angle_term``) of angle differences delta (any shape, rad), the paper's theta_th by
    default."""
    return angle_term(delta, theta_th)


@numba.njit(cache=True)
def shaping_term(d: float, delta: float, d_th: float, theta_th: float) -> float:
    """R_d + R_theta of one distance d (m) and angle difference delta (rad), for the compiled loops."""
    return distance_term(d, d_th) + angle_term(delta, theta_th)


@numba.vectorize(["float64(float64)"], cache=True)
def obstacle_reward(o: float) -> float:
    """R_obst = -N(o; 0, 1) = -exp(-o^2 / 2) / sqrt(2 pi). o: any shape, m (may be +inf). A ufunc, as
    ``distance_reward``."""
    return math.exp(o * o * -0.5) / -math.sqrt(2.0 * math.pi)


@numba.njit(cache=True)
def reward_terms(
    success: bool,
    hit: bool,
    nearest: float,
    success_paid: float,
    hit_paid: float,
    replace_success: bool,
    replace_hit: bool,
    obstacle_task: bool,
) -> tuple[bool, float, float, float]:
    """How one robot's control step pays beyond R_d + R_theta: (whether the shaping terms count, R_t,
    R_obst, R_hit); the step's reward is their sum in that order. A hit fails the episode, so R_t is not
    paid on the step of a hit even where ``success`` holds; "replace" modes pay R_t instead of the
    shaping terms and R_hit alone. ``nearest``: the distance R_obst reads (m, may be +inf);
    ``success_paid`` and ``hit_paid``: R_t and R_hit as weighted; R_obst and R_hit only in the Obstacle
    task (``obstacle_task``)."""
    success = success and not hit
    shaping = not (replace_success and success)
    paid = success_paid if success else 0.0
    if not obstacle_task:
        return shaping, paid, 0.0, 0.0
    if replace_hit and hit:
        return False, 0.0, 0.0, hit_paid
    return shaping, paid, obstacle_reward(nearest), hit_paid if hit else 0.0


@numba.njit(cache=True)
def _reward_rows(
    success: np.ndarray,
    hit: np.ndarray,
    nearest: np.ndarray,
    paid: np.ndarray,
    modes: tuple[bool, bool, bool],
    shaping: np.ndarray,
    terms: np.ndarray,
) -> None:
    """``reward_terms`` of rows (B,): whether the shaping counts into ``shaping`` (B,), R_t, R_obst and R_hit
    into ``terms`` (B, 3)."""
    for b in range(success.shape[0]):
        shaping[b], terms[b, 0], terms[b, 1], terms[b, 2] = reward_terms(
            success[b], hit[b], nearest[b], paid[0], paid[1], *modes
        )


@dataclass(frozen=True)
class RewardOptions:
    """How ``combine_rewards`` weighs and combines the terms (see ``task_reward``), checked when made."""

    success_mode: str = "add"
    hit_mode: str = "add"
    success_weight: float = 1.0
    hit_weight: float = 1.0
    obstacle_from: str = "subgoal"

    def __post_init__(self) -> None:
        if self.success_mode not in SUCCESS_MODES:
            raise ValueError(f"unknown success_mode {self.success_mode!r}; expected one of {SUCCESS_MODES}")
        if self.hit_mode not in HIT_MODES:
            raise ValueError(f"unknown hit_mode {self.hit_mode!r}; expected one of {HIT_MODES}")
        if self.obstacle_from not in OBSTACLE_FROM:
            raise ValueError(f"unknown obstacle_from {self.obstacle_from!r}; expected one of {OBSTACLE_FROM}")
        for name, weight in (("success_weight", self.success_weight), ("hit_weight", self.hit_weight)):
            if not math.isfinite(weight) or weight < 0:
                raise ValueError(f"{name} must be finite and >= 0, got {weight}")


def check_task(task: str) -> None:
    if task not in TASKS:
        raise ValueError(f"unknown task {task!r}; expected one of {TASKS}")


def combine_rewards(
    shaping: dict[str, np.ndarray],
    success: np.ndarray,
    options: RewardOptions,
    nearest: np.ndarray | None = None,
    hit: np.ndarray | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The reward (N,) of one control step and its terms.

    ``shaping``: the shaping terms (N,) by name, R_d and R_theta ("distance", "angle") or their sum; then
    R_t of success (N,) bool, and with ``nearest`` (N,) and ``hit`` (N,) bool (the Obstacle task) R_obst
    and R_hit, each zeroed as ``options`` say. The total adds the terms in that order, so a sum of the
    shaping terms made beforehand gives the same bits. A hit fails the episode: R_t is not paid on the step
    of a hit, even where ``success`` holds.
    """
    success = np.asarray(success, dtype=bool)
    rows = success.size
    obstacle_task = nearest is not None
    hit = np.zeros(success.shape, dtype=bool) if hit is None else np.asarray(hit, dtype=bool)
    nearest = np.zeros(success.shape) if nearest is None else as_float(nearest)
    paid = np.array([options.success_weight * SUCCESS_REWARD, options.hit_weight * HIT_REWARD])
    modes = (options.success_mode == "replace", options.hit_mode == "replace", obstacle_task)
    keep, paid_terms = np.empty(rows, dtype=bool), np.empty((rows, 3))
    flat = (a.reshape(rows) for a in np.broadcast_arrays(success, hit, nearest))
    _reward_rows(*flat, paid, modes, keep, paid_terms)
    keep, paid_terms = keep.reshape(success.shape), paid_terms.reshape(*success.shape, 3)
    terms = {name: np.where(keep, term, 0.0) for name, term in shaping.items()}
    terms["success"] = paid_terms[..., 0]
    if obstacle_task:
        terms["obstacle"], terms["hit"] = paid_terms[..., 1], paid_terms[..., 2]
    total, *rest = terms.values()
    for term in rest:
        total = total + term
    return total, terms


def task_reward(
    task: str,
    target: np.ndarray,
    robot_pos: np.ndarray,
    robot_angle: np.ndarray,
    subgoal: np.ndarray,
    success: np.ndarray,
    *,
    obs_pos: np.ndarray | None = None,
    hit: np.ndarray | None = None,
    success_mode: str = "add",
    hit_mode: str = "add",
    success_weight: float = 1.0,
    hit_weight: float = 1.0,
    obstacle_from: str = "subgoal",
    d_th: float = DIST_THRESHOLD,
    theta_th: float = ANGLE_THRESHOLD,
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Reward of one control step in N fields for the Baseline, Proposed or Obstacle task.

    Args:
        task: "baseline" (d, delta of the robot), "proposed" (d, delta of the sub-goal) or
            "obstacle" (proposed, plus R_obst on the sub-goal's distance to the nearest
            obstacle and R_hit).
        target: (N, 5) target pose. robot_pos: (N, 2). robot_angle: (N,) rad. Arrays of these shapes are
            trusted (the views and the world check what enters).
        subgoal: (N, 5) the manager's decoded sub-goal.
        success: (N,) bool, this step reached the task's success predicate.
        obs_pos: (N, K, 2) obstacle positions; required by, and only accepted for, "obstacle".
        hit: (N,) bool, the robot collided this step; same rule as obs_pos.
        success_mode: "add" (paper text: R_d + R_theta + 1000 on success) or "replace"
            (public code: 1000 instead of R_d + R_theta on success; R_obst still added).
        hit_mode: "add" (paper text: R_hit = -1000 added to the other terms) or "replace"
            (public code: the step's reward is -1000 alone).
        success_weight, hit_weight: multiply R_t (+1000) and R_hit (-1000); 1 is the paper's. A detour's
            shaping cost can exceed the expected cost of driving into an obstacle, and the in-threshold
            bonuses summed over a frame-skip period can pay more for dithering near the target than R_t
            pays for finishing: these re-price both.
        obstacle_from: "subgoal" (paper text) or "robot" (public code): the point R_obst measures from.
        d_th, theta_th: thresholds of R_d (m) and R_theta (rad).

    Returns:
        total (N,) and a dict of the (N,) terms named in REWARD_TERMS, zero where a term does
        not apply, so that the terms always sum to the total and can be logged as they are.
    """
    check_task(task)
    options = RewardOptions(success_mode, hit_mode, success_weight, hit_weight, obstacle_from)
    if task == "obstacle":
        if obs_pos is None or hit is None:
            raise ValueError("task 'obstacle' needs obs_pos and hit")
    elif obs_pos is not None or hit is not None:
        raise ValueError(f"obs_pos and hit are only used by task 'obstacle', not {task!r}")
    d, delta = measured_errors(task, target, subgoal, robot_pos, robot_angle)
    nearest = None if obs_pos is None else obstacle_distance(obstacle_from, subgoal, robot_pos, obs_pos)
    shaping = {"distance": distance_reward(d, d_th), "angle": angle_reward(delta, theta_th)}
    total, terms = combine_rewards(shaping, success, options, nearest, hit)
    return total, {name: terms.get(name, np.zeros(d.shape)) for name in REWARD_TERMS}
