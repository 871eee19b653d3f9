"""``hier-ssl demo``: a scripted worker drives a robot to random targets around an obstacle; a PNG of the
paths is written.

As in the paper's public code, each target is drawn at least ``MIN_LEG`` m from the robot and the obstacle
(here a slow random walk) is placed at the midpoint between them, so the straight line is blocked. The
only planning is a side waypoint: while the line from robot to target passes within ``CLEARANCE`` of the
obstacle, the sub-goal is a point beside the obstacle, otherwise the target itself. Sub-goals are at
rest: the paper's controller tracks a sub-goal's velocity across the line to it from the first step, so a
velocity to pass the waypoint with would steer the robot into the obstacle.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hier_ssl.worker import make_worker
from hier_ssl.world.obstacles import RandomWalk
from hier_ssl.world.physics import RobotState, World

MIN_LEG = 1.5  # m from the robot to its next target
CLEARANCE = 0.4  # m between the obstacle's centre and the robot's line: 2 radii and a 22 cm margin
SIDE_STEP = 0.45  # m from the obstacle's centre to the waypoint beside it
TARGET_TIME = 400  # control steps (10 s) before moving on to the next target
_D_TH, _THETA_TH, _V_TH = 0.05, np.deg2rad(5.0), 0.05  # the paper's success thresholds (docs/paper.md)


@dataclass(frozen=True)
class DemoResult:
    """What ``run_demo`` did: the PNG, targets reached of those set, control steps, steps in contact."""

    path: Path
    reached: int
    targets: int
    steps: int
    contact_steps: int


def run_demo(
    out: str | Path = "runs/demo.png",
    seed: int = 0,
    worker: str = "paper",
    targets: int = 4,
    size: tuple[int, int] = (1320, 920),
) -> DemoResult:
    """Drive robot 0 of a one-field world to ``targets`` random targets past obstacle robot 1 and write
    the paths to ``out`` (PNG; parent folders are created)."""
    # here, not at the top: matplotlib, for drawing alone
    from matplotlib.image import imsave

    from hier_ssl.world.render import render_fields

    if not (isinstance(targets, int) and targets >= 1):
        raise ValueError(f"targets must be an integer >= 1, got {targets!r}")
    out = Path(out)
    if out.suffix.lower() != ".png":
        raise ValueError(f"out must be a .png path, got {str(out)!r}")

    rng = np.random.default_rng(seed)
    world = World(1, 2)
    controller = make_worker(worker, world.robot, world.dt)
    obstacle = RandomWalk(speed=(0.0, 0.3))
    half = np.array([world.field.half_length - 0.3, world.field.half_width - 0.3])
    world.set_state([0], rng.uniform(-half, half, (1, 2, 2)), rng.uniform(-np.pi, np.pi, (1, 2)))

    robot_trail = [world.state.pos[0, 0].copy()]
    obstacle_trails, goals, waypoints = [], [], []
    reached = steps = contact_steps = 0
    command = np.zeros((1, 2, 3))
    for _ in range(targets):
        state = world.state
        goal = _target(state.pos[0, 0], half, rng)
        goals.append(goal)
        # The robot keeps its motion; the obstacle moves to the middle of the new leg, at rest.
        pos = np.stack([state.pos[0, 0], (state.pos[0, 0] + goal[0:2]) / 2])
        world.set_state(
            [0],
            pos[None],
            state.angle,
            np.stack([state.vel[0, 0], np.zeros(2)])[None],
            state.ang_vel * [1.0, 0.0],
        )
        state = world.state
        obstacle_trails.append([state.pos[0, 1].copy()])
        for t in range(TARGET_TIME):
            subgoal, detour = _subgoal(state.pos[0, 0], state.pos[0, 1], goal)
            if detour and t % 8 == 0:
                waypoints.append(subgoal[0:2])
            command[:, 0:1] = controller(state.robots(slice(0, 1)), subgoal[None, None])
            command[:, 1] = obstacle(state.pos[:, 1], state.angle[:, 1], rng)
            state = world.step(command)
            steps += 1
            contact_steps += bool(world.robot_contacts[0, 0, 1])
            robot_trail.append(state.pos[0, 0].copy())
            obstacle_trails[-1].append(state.pos[0, 1].copy())
            if _arrived(state, goal):
                reached += 1
                break

    image = render_fields(
        world.field,
        world.state,
        targets=np.array(goals)[None],
        subgoals=np.array(waypoints).reshape(1, -1, 2),
        trails=[np.array(robot_trail)] + [np.array(trail) for trail in obstacle_trails],
        trail_robot=[0] + [1] * len(obstacle_trails),
        size=size,
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    imsave(out, image)
    return DemoResult(out, reached, targets, steps, contact_steps)


def _target(robot: np.ndarray, half: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A target (x, y, theta) inside ``half`` (2,), at least ``MIN_LEG`` from ``robot``."""
    while True:
        xy = rng.uniform(-half, half)
        if np.hypot(*(xy - robot)) >= MIN_LEG:
            return np.array([xy[0], xy[1], rng.uniform(-np.pi, np.pi)])


def _subgoal(robot: np.ndarray, obstacle: np.ndarray, goal: np.ndarray) -> tuple[np.ndarray, bool]:
    """The sub-goal (x, y, theta, vx, vy) towards ``goal`` (x, y, theta), and whether it is a waypoint."""
    line = goal[0:2] - robot
    length_sq = float(line @ line)
    s = float((obstacle - robot) @ line) / length_sq if length_sq > 1e-12 else 0.0
    closest = robot + min(max(s, 0.0), 1.0) * line
    gap = closest - obstacle
    if not (0.0 < s < 1.0 and float(np.hypot(*gap)) < CLEARANCE):
        return np.array([goal[0], goal[1], goal[2], 0.0, 0.0]), False
    direction = line / np.sqrt(length_sq)
    normal = np.array([-direction[1], direction[0]])
    # Pass on the side the line already leans to, so the detour is the shorter one.
    if float(gap @ normal) < 0:
        normal = -normal
    point = obstacle + SIDE_STEP * normal
    return np.array([point[0], point[1], goal[2], 0.0, 0.0]), True


def _arrived(state: RobotState, goal: np.ndarray) -> bool:
    """Robot 0 of field 0 within the success thresholds of ``goal`` (the paper's, docs/paper.md)."""
    error = (state.angle[0, 0] - goal[2] + np.pi) % (2 * np.pi) - np.pi
    return bool(
        np.hypot(*(state.pos[0, 0] - goal[0:2])) < _D_TH
        and abs(error) < _THETA_TH
        and np.hypot(*state.vel[0, 0]) < _V_TH
    )
