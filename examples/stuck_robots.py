"""Which robots a manager loses to the time limit, and whether they dither there; whom the others hit.

    python examples/stuck_robots.py sampling --scenario configs/scenarios/formation_residual.yaml \
        --episodes 1000 --seed 7
    python examples/stuck_robots.py runs/fr-s0 --policy final --episodes 1000 --seed 7

A replanning manager can lose a robot without a collision or a foul: its choice flips between two ways
round an obstacle on successive decisions and the robot, driven one way and back, stands still until the
episode's limit. This plays seeded episodes with any manager (a planner's name or a run directory, which
acts in its own scenario unless ``--scenario`` is given) and prints, for the robots that time out, how
often their sub-goal jumped by more than ``--jump`` metres over the last ``--window`` control steps, and
how many teammates stood on their own targets within ``--near`` metres of theirs when it ended; and for
the robots that collided, whether the robot nearest them at their last decision was a teammate (a
collision the team could have planned away) or an opponent.
"""

from __future__ import annotations

import argparse

import numpy as np

from hier_ssl.envs import task_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.play import play
from hier_ssl.evaluation.compare import is_planner, load_manager, run_config


class Watched:
    """A manager that counts, per robot of ``core``, the jumps of its sub-goal in force (m, field frame,
    whatever the action's frame) over the last ``window`` control steps of an episode of ``limit`` (frame
    skip 1: one decision a control step)."""

    def __init__(self, manager, core, jump: float, limit: int, window: int) -> None:
        self.manager, self.core, self.jump, self.late = manager, core, jump, limit - window
        self.remembers = callable(getattr(manager, "forget", None))  # a manager with a memory per robot

    def forget(self, count: int) -> None:
        self.last = np.full((count, 2), np.nan)
        self.jumps, self.steps = np.zeros(count, int), np.zeros(count, int)
        self.teammate, self.closing = np.zeros(count, bool), np.zeros(count)
        if self.remembers:
            self.manager.forget(count)

    def __call__(self, obs: np.ndarray, rows: np.ndarray) -> np.ndarray:
        # The sub-goal the last decision set (row = field * M + robot); the first is the robot's own pose.
        now = self.core.subgoal[..., 0:2].reshape(-1, 2)[rows]
        moved = np.linalg.norm(now - self.last[rows], axis=1)
        self.jumps[rows] += (self.steps[rows] >= self.late) & (moved > self.jump)
        self.last[rows], self.steps[rows] = now, self.steps[rows] + 1
        # The nearest other robot (the controlled ones first, then the opponents or obstacles): who a robot
        # that collides before its next decision most likely met, and how fast they were closing.
        m, pos, vel = self.core.subgoal.shape[1], self.core.state.pos, self.core.state.vel
        field, robot = np.divmod(rows, m)
        gap = np.linalg.norm(pos[field] - pos[field, robot][:, None], axis=-1)
        gap[np.arange(len(rows)), robot] = np.inf
        near = np.argmin(gap, axis=1)
        self.teammate[rows] = near < m
        self.closing[rows] = np.linalg.norm(vel[field, robot] - vel[field, near], axis=1)
        return self.manager(obs, rows=rows) if self.remembers else self.manager(obs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("manager", help="a planner's name or a run directory")
    parser.add_argument("--scenario", help="a scenario or task YAML (default: the run's own)")
    parser.add_argument("--policy", default="final", choices=("best", "final"))
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--window", type=int, default=300, help="control steps before the limit")
    parser.add_argument("--jump", type=float, default=0.45, help="m: a sub-goal move counted as a jump")
    parser.add_argument("--dither", type=int, default=50, help="jumps in the window that count as dithering")
    parser.add_argument("--near", type=float, default=0.6, help="m from a robot's target")
    args = parser.parse_args()
    if args.scenario is None and is_planner(args.manager):
        parser.error("a planner needs --scenario")
    config = task_config(args.scenario) if args.scenario else run_config(args.manager).task_config
    if config.frame_skip != 1:
        parser.error(
            f"the window counts decisions as control steps: frame skip 1 only, got {config.frame_skip}"
        )

    core = HierarchicalCore(config, args.episodes, autoreset=False)
    watched = Watched(
        load_manager(args.manager, config, args.policy), core, args.jump, config.max_steps, args.window
    )
    ends = play(core, watched, args.seed)
    arrived, hit = ends["success"], ends["collision"]
    fouled = ends["foul"] > 0 if "foul" in ends else np.zeros_like(arrived)
    late = ~arrived & ~hit & ~fouled
    fields, robots = np.nonzero(late)
    m = late.shape[1]
    where, target = core.state.pos, core.target[..., 0:2]
    away = np.linalg.norm(where[fields, robots] - target[fields, robots], axis=1)
    parked = [
        int(np.sum(arrived[f] & (np.linalg.norm(where[f, :m] - target[f, r], axis=1) < args.near)))
        for f, r in zip(fields, robots, strict=True)
    ]
    jumps = watched.jumps.reshape(late.shape)[late]
    print(
        f"robots {arrived.size} arrived {arrived.sum()} collided {hit.sum()} fouled {fouled.sum()} "
        f"timed out {late.sum()}"
    )
    if hit.any():
        met = watched.teammate.reshape(hit.shape)[hit]
        print(
            f"collided nearest a teammate {met.sum()}, another robot {(~met).sum()} at the last decision "
            f"(median relative speed {np.median(watched.closing.reshape(hit.shape)[hit]):.2f} m/s)"
        )
    if late.any():
        print(
            f"dithering {np.sum(jumps >= args.dither)} (median jumps {np.median(jumps):.0f} in the last "
            f"{args.window} steps)"
        )
        print(
            f"teammates parked within {args.near} m of the target: {np.bincount(parked).tolist()} (0, 1, ...)"
        )
        print(f"distance to the target at the end, median {np.median(away):.2f} m")


if __name__ == "__main__":
    main()
