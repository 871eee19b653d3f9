"""Measurement, not CI: wall time for rsl-rl PPO to reach a success rate on Proposed with frame skip 16.

Trains in chunks of ``--eval-every`` PPO iterations on one torch thread and after each chunk evaluates
the deterministic policy on 200 seeded episodes (``evaluate(..., seed=123)``). Prints one line per
evaluation: training wall time (evaluations excluded), total wall time, environment decisions,
success rate, median episode length, median CPAD, the mean action std and the (KL-adapted) learning
rate. Stops at ``--target``
success or after ``--max-minutes`` of total wall time.

Run: python benchmarks/ppo_proposed.py [--num-envs 512] [--max-minutes 20] [--target 0.9] ...
"""

from __future__ import annotations

import argparse
import json
import time

import torch

import hier_ssl
from hier_ssl.config.learners import PPOConfig
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.policies.ppo import make_ppo_runner, ppo_policy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--num-envs", type=int, default=512)
    parser.add_argument("--steps", type=int, default=16, help="num_steps_per_env (decisions per iteration)")
    parser.add_argument("--lr", type=float, default=1e-3)
    parser.add_argument("--epochs", type=int, default=5)
    parser.add_argument("--minibatches", type=int, default=4)
    parser.add_argument("--gamma", type=float, default=0.95)
    parser.add_argument("--lam", type=float, default=0.95)
    parser.add_argument("--entropy", type=float, default=0.0)
    parser.add_argument("--noise-std", type=float, default=0.5)
    parser.add_argument("--hidden", type=int, nargs="+", default=[128, 128])
    parser.add_argument("--activation", default="elu")
    parser.add_argument("--schedule", default="adaptive", choices=["adaptive", "fixed"])
    parser.add_argument("--desired-kl", type=float, default=0.01)
    parser.add_argument("--no-clip-value-loss", action="store_true")
    parser.add_argument("--eval-every", type=int, default=10, help="PPO iterations between evaluations")
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--target", type=float, default=0.9)
    parser.add_argument("--max-minutes", type=float, default=20.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)

    cfg = PPOConfig(
        num_steps_per_env=args.steps,
        learning_rate=args.lr,
        num_learning_epochs=args.epochs,
        num_mini_batches=args.minibatches,
        gamma=args.gamma,
        lam=args.lam,
        entropy_coef=args.entropy,
        hidden=tuple(args.hidden),
        init_noise_std=args.noise_std,
    )
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=args.num_envs)
    env.reset(seed=args.seed)
    runner = make_ppo_runner(
        env,
        cfg,
        log_dir=None,
        activation=args.activation,
        schedule=args.schedule,
        desired_kl=args.desired_kl,
        clip_value_loss=not args.no_clip_value_loss,
    )
    policy = ppo_policy(runner)
    print("settings", json.dumps({**vars(args), "ppo": cfg.model_dump(mode="json")}), flush=True)
    print(
        f"{'iter':>5} {'train_s':>8} {'wall_s':>8} {'decisions':>10} {'success':>7} {'len_med':>7} "
        f"{'cpad_med':>8} {'std':>6} {'lr':>8}",
        flush=True,
    )

    # Train in chunks; only runner.learn counts as training time, evaluations are timed apart.
    start, train_s, iters = time.perf_counter(), 0.0, 0
    reached = None
    while True:
        t0 = time.perf_counter()
        runner.learn(args.eval_every)
        train_s += time.perf_counter() - t0
        iters += args.eval_every
        result = evaluate(policy, env.config, args.episodes, seed=123)
        wall = time.perf_counter() - start
        std = runner.alg.get_policy().distribution.std_param.mean().item()
        print(
            f"{iters:5d} {train_s:8.1f} {wall:8.1f} {iters * args.steps * args.num_envs:10d} "
            f"{result['success_rate']:7.3f} {result['episode_length']['median']:7.0f} "
            f"{result['cpad']['median']:8.3f} {std:6.3f} {runner.alg.learning_rate:8.1e}",
            flush=True,
        )
        if result["success_rate"] >= args.target and reached is None:
            reached = (train_s, wall, iters)
            break
        if wall > args.max_minutes * 60:
            break
    if reached:
        print(
            f"reached {args.target:.0%} success after {reached[2]} iterations: "
            f"{reached[0]:.1f} s training, {reached[1]:.1f} s wall including evaluations"
        )
    else:
        print(f"did not reach {args.target:.0%} within {args.max_minutes} min")


if __name__ == "__main__":
    main()
