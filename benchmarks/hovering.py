"""Measurement, not CI: does a trained manager hover inside the thresholds instead of finishing?

Plays a run's policy (``--policy final|best``, ``--sample`` for the paper's sampled actions) on seeded
episodes of its own task and prints, over the episodes that time out, the share of control steps in which
the held sub-goal is within D_th and theta_th of the target (the in-threshold bonus is paid) and the robot
within 2 D_th of it, and where the robot and the sub-goal end. A policy whose optimum hovers (the paper's
reward at gamma 0.99, ``hier_ssl.manager.optimum``) times out with its sub-goal on the target and the robot
parked next to it.

Run: python benchmarks/hovering.py RUN_DIR [--episodes 200] [--policy final] [--sample]
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--policy", choices=("best", "final"), default="final")
    parser.add_argument("--sample", action="store_true")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from hier_ssl.evaluation.compare import load_manager, run_config
    from hier_ssl.evaluation.evaluate import evaluate
    from hier_ssl.manager import pose_errors

    config = run_config(args.run_dir).task_config
    policy = load_manager(args.run_dir, config, args.policy, args.sample, args.seed)
    result = evaluate(policy, config, args.episodes, args.seed, record=range(args.episodes))
    per = {key: value[:, 0] for key, value in result["per_robot"].items()}
    timeout = ~per["success"] & ~per["collision"]
    theta_th = np.deg2rad(config.theta_th_deg)
    inside, robot_near, sub_end, robot_end = [], [], [], []
    for episode in result["trajectories"]:
        if not timeout[episode["field"]]:
            continue
        target = episode["target"][0]
        subgoal = episode["subgoal"][:, 0]
        d_sub, a_sub = pose_errors(subgoal, np.broadcast_to(target, subgoal.shape))
        robot = episode["robots"][1:, 0]
        d_robot = np.linalg.norm(robot - target[0:2], axis=1)
        inside.append(np.mean((d_sub < config.d_th) & (a_sub < theta_th)))
        robot_near.append(np.mean(d_robot < 2 * config.d_th))
        sub_end.append(d_sub[-1])
        robot_end.append(d_robot[-1])
    print(
        f"{args.run_dir} ({args.policy} policy, {'sampled' if args.sample else 'mean'} actions), "
        f"{args.episodes} episodes: success {100 * result['success_rate']:.1f} %, collisions "
        f"{100 * result['collision_rate']:.1f} %, timeouts {100 * timeout.mean():.1f} %"
    )
    if inside:
        print(
            f"  timeouts: sub-goal inside the thresholds in {100 * np.median(inside):.0f} % of their control "
            f"steps (median over episodes), robot within {2 * config.d_th:.2f} m of the target in "
            f"{100 * np.median(robot_near):.0f} %; at the end the sub-goal is {np.median(sub_end):.3f} m and "
            f"the robot {np.median(robot_end):.3f} m from the target (medians)"
        )


if __name__ == "__main__":
    main()
