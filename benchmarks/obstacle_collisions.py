"""Measurement, not CI: when and how does a trained Obstacle manager collide?

Plays a run's policy (``--policy final|best``, ``--sample`` for the paper's sampled actions) on seeded
episodes of its own task, every control step recorded, and prints for the episodes that end in a collision
when it happens (control step quartiles, share after the robot has spent 600 steps in the field), how fast
the controlled robot and the obstacle moved over the last 4 control steps before contact, and how far the
robot was from its target. ``--still`` plays the same episodes with a worker that commands zero velocity:
the robot never moves, so every collision is the obstacle's random walk running into it. A policy that
times out parked near its target is exposed to that hazard for all 1,200 steps of an episode.

Run: python benchmarks/obstacle_collisions.py RUN_DIR [--episodes 1000] [--policy final] [--sample] [--still]
"""

from __future__ import annotations

import argparse

import numpy as np

_MOVING = 0.2  # m/s: slower than this over the last 4 steps, the robot counts as parked
_LATE = 600  # control steps


class StillWorker:
    """A worker that commands zero velocity to every robot: the controlled robot stays where it starts."""

    def __call__(self, state: object, subgoal: np.ndarray) -> np.ndarray:
        return np.zeros(subgoal.shape[:-1] + (3,))

    def reset(self, fields: np.ndarray) -> None:
        """Stateless: nothing to forget."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--policy", choices=("best", "final"), default="final")
    parser.add_argument("--sample", action="store_true")
    parser.add_argument("--still", action="store_true", help="zero-velocity worker: the robot never moves")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    from hier_ssl.evaluation.compare import load_manager, run_config
    from hier_ssl.evaluation.evaluate import evaluate

    config = run_config(args.run_dir).task_config
    policy = load_manager(args.run_dir, config, args.policy, args.sample, args.seed)
    worker = StillWorker() if args.still else None
    result = evaluate(policy, config, args.episodes, args.seed, record=range(args.episodes), worker=worker)
    per = {key: value[:, 0] for key, value in result["per_robot"].items()}
    dt = config.dt
    when, robot_speed, obstacle_speed, to_target = [], [], [], []
    for episode in result["trajectories"]:
        if not per["collision"][episode["field"]]:
            continue
        robots = episode["robots"]  # (T + 1, R, 2): robot 0 controlled, robot 1 the obstacle
        last = robots[-5:]
        speed = np.linalg.norm(np.diff(last, axis=0), axis=-1).mean(axis=0) / dt
        when.append(len(robots) - 1)
        robot_speed.append(speed[0])
        obstacle_speed.append(speed[1])
        to_target.append(np.linalg.norm(robots[-1, 0] - episode["target"][0, 0:2]))
    actions = "sampled" if args.sample else "mean"
    mode = "still robot" if args.still else f"{args.policy} policy, {actions} actions"
    print(
        f"{args.run_dir} ({mode}), {args.episodes} episodes (seed {args.seed}): success "
        f"{100 * result['success_rate']:.1f} %, collisions {100 * result['collision_rate']:.1f} %, "
        f"episodes that begin in contact {100 * result['start_contact_rate']:.1f} %"
    )
    if not when:
        return
    when, robot_speed = np.array(when), np.array(robot_speed)
    q1, q2, q3 = np.percentile(when, [25, 50, 75])
    print(
        f"  collisions at control step {q1:.0f} / {q2:.0f} / {q3:.0f} (quartiles), "
        f"{100 * np.mean(when > _LATE):.0f} % after step {_LATE}; robot parked (< {_MOVING} m/s over the "
        f"last 4 steps) in {100 * np.mean(robot_speed < _MOVING):.0f} % of them"
    )
    print(
        f"  medians at contact: robot {np.median(robot_speed):.2f} m/s, obstacle "
        f"{np.median(obstacle_speed):.2f} m/s, robot {np.median(to_target):.2f} m from its target"
    )


if __name__ == "__main__":
    main()
