"""Your own goToPoint controller as the worker, compared with the paper's under the same planners.

    python examples/custom_worker.py --episodes 100

A worker is any object with ``__call__(state, subgoal) -> commands`` and ``reset(fields)``, batched over
N fields and R controlled robots; hier_ssl drives the robots with it every 25 ms control step.
"""

from __future__ import annotations

import argparse

import numpy as np

from hier_ssl.evaluation.compare import compare
from hier_ssl.world import RobotSpec, RobotState


class Proportional:
    """Velocity proportional to the distance left to the sub-goal, capped; turns onto its heading."""

    def __init__(self, robot: RobotSpec, gain: float = 2.0, turn_gain: float = 4.0) -> None:
        self.max_speed = 0.6 * robot.max_speed  # m/s; the sampling planner predicts with it
        self.max_ang_speed = robot.max_ang_speed
        self.gain, self.turn_gain = gain, turn_gain

    def reset(self, fields: np.ndarray) -> None:
        """Nothing is remembered between steps, so nothing to forget when episodes restart."""

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        """Commands (N, R, 3): (vx, vy, w) in each robot's frame; ``subgoal`` (N, R, 5) field frame."""
        vel = self.gain * (subgoal[..., 0:2] - state.pos)
        speed = np.linalg.norm(vel, axis=-1, keepdims=True)
        vel *= np.minimum(1.0, self.max_speed / np.maximum(speed, 1e-9))
        cos, sin = np.cos(state.angle), np.sin(state.angle)  # the field frame turned into the robot's
        forward = cos * vel[..., 0] + sin * vel[..., 1]
        left = cos * vel[..., 1] - sin * vel[..., 0]
        turn = (subgoal[..., 2] - state.angle + np.pi) % (2 * np.pi) - np.pi
        w = np.clip(self.turn_gain * turn, -self.max_ang_speed, self.max_ang_speed)
        return np.stack([forward, left, w], axis=-1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    args = parser.parse_args()

    mine = Proportional(RobotSpec())
    # The same seeded episodes for every (manager, worker) pair; "+latency=4" delays the paper's commands.
    workers = [mine, "paper", "paper+latency=4"]
    for e in compare(["direct", "sampling"], task="obstacle", workers=workers, episodes=args.episodes):
        record = e.record
        print(
            f"{e.name:8} {e.worker:26} success {record['success_rate']:.2f} "
            f"collisions {record['collision_rate']:.2f} median length {record['episode_length']['median']}"
        )


if __name__ == "__main__":
    main()
