"""Measurement, not CI: whom do the robots of a multi-robot scenario collide with, and when?

Plays managers (run directories or planner names) on the same seeded episodes of a run's scenario, every
control step recorded, and sorts each robot that ended in a collision by its partner, the nearest other
robot at that step: a teammate still driving, a teammate parked (it had already reached its slot and holds
still there), or an obstacle. Per kind: the share of all robots, the control step quartiles of the contact,
and the robot's distance to its own target then. A manager that loses to the planner on collisions shows
here which encounters it handles worse.

Run: python benchmarks/scenario_collisions.py RUN_DIR [MANAGER ...] [--episodes 1000] [--seed 7]
     [--policy best|final]   (MANAGER: run directories or planner names; default: RUN_DIR and sampling)
"""

from __future__ import annotations

import argparse

import numpy as np

KINDS = ("teammate driving", "teammate parked", "obstacle")


def partners(result: dict) -> list[tuple[str, int, float]]:
    """(kind, control step, distance to own target) of every robot of ``result`` (an ``evaluate`` summary
    with every episode recorded) that ended in a collision."""
    per = result["per_robot"]
    found = []
    for episode in result["trajectories"]:
        f, m = episode["field"], episode["controlled"]
        robots = episode["robots"]  # (T + 1, R, 2)
        for i in np.flatnonzero(per["collision"][f]):
            step = int(per["length"][f, i])
            here = robots[min(step, len(robots) - 1)]
            gap = np.linalg.norm(here - here[i], axis=-1)
            gap[i] = np.inf
            j = int(np.argmin(gap))
            if j >= m:
                kind = "obstacle"
            elif per["success"][f, j] and per["length"][f, j] < step:
                kind = "teammate parked"
            else:
                kind = "teammate driving"
            found.append((kind, step, float(np.linalg.norm(here[i] - episode["target"][i, 0:2]))))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("managers", nargs="*")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--policy", choices=("best", "final"), default="best")
    args = parser.parse_args()

    from hier_ssl.evaluation.compare import load_manager, run_config
    from hier_ssl.evaluation.evaluate import evaluate

    config = run_config(args.run_dir).task_config
    for spec in args.managers or [args.run_dir, "sampling"]:
        policy = load_manager(spec, config, args.policy)
        result = evaluate(policy, config, args.episodes, args.seed, record=range(args.episodes))
        robots = result["robots"]
        print(
            f"{spec}: {robots} robots, success {100 * result['success_rate']:.1f} %, "
            f"collisions {100 * result['collision_rate']:.1f} %"
        )
        found = partners(result)
        for kind in KINDS:
            steps = np.array([s for k, s, _ in found if k == kind])
            to_target = np.array([d for k, _, d in found if k == kind])
            if not len(steps):
                print(f"  {kind:17s}  0.0 %")
                continue
            q1, q2, q3 = np.percentile(steps, [25, 50, 75])
            share = 100 * len(steps) / robots
            print(
                f"  {kind:17s} {share:4.1f} % of robots, control step {q1:.0f} / {q2:.0f} / {q3:.0f}, "
                f"{np.median(to_target):.2f} m from its target (median)"
            )


if __name__ == "__main__":
    main()
