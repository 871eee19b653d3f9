"""Measurement, not CI: can a network that chooses among the `sampling` planner's candidate sub-goals learn
the planner's choice where a Gaussian policy over sub-goal coordinates does not?

The planner's choice is discontinuous in the observation (pass an obstacle left or right), and a Gaussian
actor fitted to it lands between the branches (README, "Learning from the planner"). Here the action is a
class: one of the planner's candidates (the target, the robot's own position, rings around each seen
obstacle, fixed points along the robot-target line, a ring around the robot), which the planner builds
from the observation alone with a few geometric operations. An MLP (``--hidden``) maps the manager
observation to one logit per candidate and is trained by DAgger: round 0 plays the planner, later rounds
play the network; every state met is labelled with the planner's scores of all candidates (a softmax over the
arrival times of the candidates in the planner's best safety tier, temperature ``--tau`` s) and the
network is refitted on everything gathered so far. The figures are the rounds' own episodes and, at the
end, ``--held-out`` episodes of seed 7 that no round played, and the time of one decision at batch 1 of
the network (the geometry in numpy, the MLP in torch, not exported) and of the planner.

Run: python benchmarks/candidate_dagger.py CONFIG [--set KEY=VALUE] [--rounds 30] [--episodes 500]
     [--epochs 8] [--hidden 256,256]   (CONFIG: a shipped config or YAML, e.g. scenarios/crowd)
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch


def planner_scores(planner, obs: np.ndarray, tau: float):
    """The scene of ``obs``, the planner's candidates (B, C) complex and its soft choice (B, C): a softmax
    of minus the arrival time over the candidates of the best tier the planner would choose from (clear of
    the growing safety distance; else of the fixed one; else, by distance kept, all)."""
    scene = planner.read(obs)
    cand = planner.candidates(scene)
    arrival, clearance, hard, near = planner.rollout(scene, cand)
    safe, close = clearance >= 0.0, hard >= 0.0
    # No candidate clear: keep farthest from the obstacles (+inf without any, as the planner's ``near``).
    score = np.where(np.isfinite(near), near, 1e3)
    score = np.where(close.any(1, keepdims=True), np.where(close, -arrival, -np.inf), score)
    score = np.where(safe.any(1, keepdims=True), np.where(safe, -arrival, -np.inf), score)
    weight = np.exp((score - score.max(1, keepdims=True)) / tau)
    return scene, cand, weight / weight.sum(1, keepdims=True)


def outcome(result: dict) -> str:
    """Success, collisions and median length of an ``evaluate`` summary, in one phrase."""
    return (
        f"success {100 * result['success_rate']:.1f} %, collisions {100 * result['collision_rate']:.1f} %, "
        f"median length {result['episode_length']['median']:.0f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--rounds", type=int, default=30)
    parser.add_argument("--episodes", type=int, default=500, help="episodes per round")
    parser.add_argument("--epochs", type=int, default=8, help="passes over all data gathered, per round")
    parser.add_argument("--tau", type=float, default=0.05, help="s: temperature of the planner's soft choice")
    parser.add_argument("--held-out", type=int, default=1000)
    parser.add_argument("--hidden", default="256,256", help="the MLP's hidden layer sizes")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--save", help="write the network's state_dict here")
    args = parser.parse_args()
    torch.set_num_threads(1)

    from hier_ssl.config import TrainConfig
    from hier_ssl.config_files import apply_overrides, load_yaml
    from hier_ssl.envs.core import HierarchicalCore
    from hier_ssl.evaluate import evaluate
    from hier_ssl.manager.planners import make_planner

    config = TrainConfig.model_validate(apply_overrides(load_yaml(args.config), args.set)).task_config
    planner = make_planner("sampling", config)
    torch.manual_seed(args.seed)
    net, opt = None, None
    gathered: list[tuple[np.ndarray, np.ndarray]] = []

    def act(scene, cand: np.ndarray, choice: np.ndarray) -> np.ndarray:
        return planner.action(scene, planner.subgoals(scene, cand[np.arange(len(cand)), choice]))

    def network_choice(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return net(torch.as_tensor(obs, dtype=torch.float32)).argmax(1).numpy()

    def gathering(expert: bool):
        def policy(obs: np.ndarray) -> np.ndarray:
            scene, cand, soft = planner_scores(planner, obs, args.tau)
            gathered.append((obs.astype(np.float32), soft.astype(np.float32)))
            return act(scene, cand, soft.argmax(1) if expert else network_choice(obs))

        return policy

    def playing(obs: np.ndarray) -> np.ndarray:
        scene = planner.read(obs)
        return act(scene, planner.candidates(scene), network_choice(obs))

    start = time.perf_counter()
    for round_ in range(args.rounds):
        result = evaluate(gathering(expert=round_ == 0), config, args.episodes, seed=100 + round_)
        x = torch.as_tensor(np.concatenate([g[0] for g in gathered]))
        p = torch.as_tensor(np.concatenate([g[1] for g in gathered]))
        if net is None:
            sizes = [x.shape[1], *map(int, args.hidden.split(","))]
            pairs = zip(sizes[:-1], sizes[1:], strict=True)
            layers = [m for a, b in pairs for m in (torch.nn.Linear(a, b), torch.nn.ReLU())]
            net = torch.nn.Sequential(*layers, torch.nn.Linear(sizes[-1], p.shape[1]))
            opt = torch.optim.Adam(net.parameters(), lr=1e-3)
        for _ in range(args.epochs):
            for rows in torch.randperm(len(x)).split(256):
                loss = -(p[rows] * torch.log_softmax(net(x[rows]), 1)).sum(1).mean()
                opt.zero_grad()
                loss.backward()
                opt.step()
        with torch.no_grad():
            agree = float((net(x).argmax(1) == p.argmax(1)).float().mean())
        print(
            f"round {round_:2d} ({'planner' if round_ == 0 else 'network'} playing): {outcome(result)}; "
            f"fitted on {len(x)} states, the planner's first choice on {100 * agree:.0f} % "
            f"[{time.perf_counter() - start:.0f} s]",
            flush=True,
        )
    result = evaluate(playing, config, args.held_out, seed=7)
    print(f"held out ({args.held_out} episodes, seed 7): {outcome(result)}")
    # Decision time at batch 1, one robot's observation of a fresh episode (median of 300 calls).
    core = HierarchicalCore(config, 1)
    obs = core.reset(7).reshape(-1, core.obs_dim)[:1]
    for name, decide in (("network", playing), ("sampling", planner)):
        times = []
        for _ in range(300):
            begin = time.perf_counter()
            decide(obs)
            times.append(time.perf_counter() - begin)
        print(f"decision time at batch 1, {name}: {1e6 * np.median(times):.0f} us")
    if args.save:
        torch.save(net.state_dict(), args.save)


if __name__ == "__main__":
    main()
