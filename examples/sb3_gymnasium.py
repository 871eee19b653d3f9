"""Stable-Baselines3's SAC on a registered Gymnasium id, then a few deterministic test episodes.

    python examples/sb3_gymnasium.py --steps 20000 --episodes 20

Importing hier_ssl registers ``hier_ssl/Baseline-v0``, ``hier_ssl/Proposed-v0``, ``hier_ssl/Obstacle-v0``
and ``hier_ssl/Crowd-v0``. One step is one manager decision; the made env carries a ``TimeLimit`` of
ceil(1200 / frame_skip) decisions. A few thousand steps do not make a good manager: the defaults show the
loop, ``hier-ssl train`` trains the paper's managers.
"""

from __future__ import annotations

import argparse

import gymnasium
from stable_baselines3 import SAC
from stable_baselines3.common.monitor import Monitor

import hier_ssl  # noqa: F401  (registers the hier_ssl/... ids)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--id", default="hier_ssl/Proposed-v0")
    parser.add_argument("--steps", type=int, default=5000, help="SAC environment steps (decisions)")
    parser.add_argument("--episodes", type=int, default=5, help="test episodes after training")
    args = parser.parse_args()

    env = Monitor(gymnasium.make(args.id, frame_skip=16))
    model = SAC("MlpPolicy", env, learning_starts=min(1000, args.steps // 2), seed=0)
    model.learn(total_timesteps=args.steps)

    successes = []
    for episode in range(args.episodes):
        obs, info = env.reset(seed=1000 + episode)
        done = False
        while not done:
            action, _ = model.predict(obs, deterministic=True)
            obs, reward, terminated, truncated, info = env.step(action)
            done = terminated or truncated
        successes.append(info["task"]["success"])
        print(f"episode {episode}: {info['episode']['l']} decisions, success {info['task']['success']:.0f}")
    print(f"success rate {sum(successes) / len(successes):.2f} over {len(successes)} episodes")


if __name__ == "__main__":
    main()
