"""Measurement, not CI: where a manager's episodes spend their time, decision by decision.

Plays managers (run directories or planners) on the same seeded episodes of the first run's task and
prints, for each of the first decisions, medians over the episodes still running: the robot's distance to
the target after the decision, the held sub-goal's distance to the target and to the robot, and the share
of episodes that have ended. A manager that detours shows sub-goals far from the target early and a robot
that closes in late.

Run: python benchmarks/decision_trace.py RUN_DIR [MANAGER ...] [--episodes 200] [--seed 11] [--decisions 12]
(default managers: the run and ``sampling``; one controlled robot, the first, is traced).
"""

from __future__ import annotations

import argparse

import numpy as np


def trace(episodes: list[dict], frame_skip: int, decisions: int) -> dict[str, list[float]]:
    """Per decision k (after its frame_skip control steps): medians over the episodes still running."""
    rows: dict[str, list[float]] = {
        "robot-target m": [],
        "subgoal-target m": [],
        "subgoal-robot m": [],
        "ended %": [],
    }
    for k in range(decisions):
        step = k * frame_skip  # the control step that starts decision k
        running = [e for e in episodes if len(e["subgoal"]) > step]
        ended = 100.0 * (1 - len(running) / len(episodes))
        robot = np.array([e["robots"][min(step + frame_skip, len(e["subgoal"])), 0] for e in running])
        subgoal = np.array([e["subgoal"][step, 0, 0:2] for e in running])
        target = np.array([e["target"][0, 0:2] for e in running])
        values = [robot - target, subgoal - target, subgoal - robot] if running else [np.zeros((0, 2))] * 3
        for key, delta in zip(list(rows)[:3], values, strict=True):
            rows[key].append(float(np.median(np.linalg.norm(delta, axis=1))) if len(delta) else float("nan"))
        rows["ended %"].append(ended)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("managers", nargs="*", default=["sampling"])
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--decisions", type=int, default=12)
    parser.add_argument("--policy", choices=("best", "final"), default="best")
    args = parser.parse_args()

    from hier_ssl.evaluation.compare import load_manager, run_config
    from hier_ssl.evaluation.evaluate import evaluate

    config = run_config(args.run_dir).task_config
    for spec in [args.run_dir, *args.managers]:
        policy = load_manager(spec, config, args.policy)
        result = evaluate(policy, config, args.episodes, args.seed, record=range(args.episodes))
        rows = trace(result["trajectories"], config.frame_skip, args.decisions)
        print(f"{spec} ({args.policy} policy for runs), {args.episodes} episodes, seed {args.seed}:")
        for key, values in rows.items():
            print(f"  {key:17s}" + " ".join(f"{v:6.2f}" for v in values))


if __name__ == "__main__":
    main()
