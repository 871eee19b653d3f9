"""Measurement, not CI: train one shared manager (SAC + CAPS, frame skip 16) on a multi-robot scenario
within a wall-time budget, then compare it with the scripted ``direct`` and ``sampling`` managers.

Every controlled robot of every field is one row of the vector view (parameter sharing); rows of robots
that have left hold the absorbing state (see ``MultiVectorEnv``). Every ``--eval-every`` vector steps the
deterministic actor is scored on ``--eval-episodes`` selection episodes (seed 10000) and the best one
(success rate, then fewer collisions) is kept; training stops after ``--steps`` vector steps or once
``--minutes`` of wall time (evaluations included) have passed. The kept actor and the planners are then
evaluated on held-out episodes (seed 20000) of the training scenario, of each ``--also`` scenario (name
or YAML, ``key=value`` overrides after a colon), and results go to ``OUT/results.json``.

Run: python benchmarks/shared_manager.py configs/scenarios/crowd.yaml --set num_agents=3 --minutes 28 \
        --also configs/scenarios/crowd.yaml configs/scenarios/crossing.yaml --out runs/shared-crowd
"""

from __future__ import annotations

import argparse
import copy
import json
import time
from pathlib import Path

import torch

from hier_ssl.config import apply_overrides, load_yaml
from hier_ssl.envs.multi import MultiVectorEnv
from hier_ssl.envs.scenarios import ScenarioConfig, scenario_config
from hier_ssl.evaluate_multi import evaluate_scenario, planner_policy
from hier_ssl.policies.sac import SACConfig
from hier_ssl.policies.sac_runner import SACRunner
from hier_ssl.train import sac_policy

SELECTION_SEED, EVALUATION_SEED = 10_000, 20_000


class OutOfTime(Exception):
    """The wall-time budget is spent: training stops at the evaluation that noticed."""


class Selection:
    """Evaluation hook: print the learning curve, keep the best actor, stop at the deadline."""

    def __init__(self, config: ScenarioConfig, episodes: int, deadline: float) -> None:
        self.config, self.episodes, self.deadline = config, episodes, deadline
        self.best: tuple[float, float] | None = None
        self.best_actor: dict[str, torch.Tensor] | None = None
        self.curve: list[dict[str, float]] = []

    def __call__(self, runner: SACRunner) -> dict[str, float]:
        result = evaluate_scenario(sac_policy(runner.sac.actor), self.config, self.episodes, SELECTION_SEED)
        row = {
            "step": runner.step,
            "transitions": runner.num_transitions,
            "train_time_s": round(runner.train_time_s, 1),
            "success_rate": result["success_rate"],
            "collision_rate": result["collision_rate"],
            "episode_length_median": result["episode_length"]["median"],
        }
        self.curve.append(row)
        print(json.dumps(row), flush=True)
        score = (row["success_rate"], -row["collision_rate"])
        if self.best is None or score > self.best:
            self.best, self.best_actor = score, copy.deepcopy(runner.sac.actor.state_dict())
        if time.monotonic() > self.deadline:
            raise OutOfTime
        return {k: float(v) for k, v in row.items() if k != "step"}


def _scenario(spec: str) -> ScenarioConfig:
    """``NAME_OR_YAML[:key=value,...]`` as a ScenarioConfig."""
    source, _, overrides = spec.partition(":")
    data = load_yaml(source) if source.endswith(".yaml") else {"scenario": source}
    return scenario_config(**apply_overrides(data, [o for o in overrides.split(",") if o]))


def _row(result: dict[str, object]) -> dict[str, object]:
    keys = ("robots", "success_rate", "collision_rate", "field_success_rate", "episode_length", "eval_wall_s")
    return {k: result[k] for k in keys}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", help="scenario YAML to train on")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--fields", type=int, default=16)
    parser.add_argument("--steps", type=int, default=1_000_000, help="vector steps at most")
    parser.add_argument("--minutes", type=float, default=28.0, help="wall-time budget, evaluations included")
    parser.add_argument("--eval-every", type=int, default=2000)
    parser.add_argument("--eval-episodes", type=int, default=100)
    parser.add_argument("--final-episodes", type=int, default=500)
    parser.add_argument("--also", nargs="*", default=[], help="further scenarios to evaluate on")
    parser.add_argument("--buffer", type=int, default=500_000)
    parser.add_argument("--reward-scale", type=float, default=0.1, help="SAC's critic-target reward scale")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="runs/shared-manager")
    args = parser.parse_args()
    torch.set_num_threads(1)
    start = time.monotonic()

    config = scenario_config(**apply_overrides(load_yaml(args.config), args.set))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    env = MultiVectorEnv(config, args.fields)
    sac = SACConfig(caps=True, reward_scale=args.reward_scale, buffer_size=args.buffer)
    selection = Selection(config, args.eval_episodes, start + 60 * args.minutes)
    runner = SACRunner(
        env,
        sac,
        out,
        seed=args.seed,
        eval_interval=args.eval_every,
        eval_callback=selection,
        progress=False,
        save_interval=10**9,  # checkpoints are not the point of a measurement
    )
    # Train until the step budget or the deadline, then act with the best selected actor.
    try:
        runner.learn(args.steps)
    except OutOfTime:
        pass
    runner.close()
    wall = time.monotonic() - start
    if selection.best_actor is not None:
        runner.sac.actor.load_state_dict(selection.best_actor)
    print(f"trained {runner.step} vector steps ({runner.num_transitions} transitions) in {wall:.0f} s")

    # Held-out evaluation: the trained manager beside the planners on the same episodes.
    managers = {"trained": sac_policy(runner.sac.actor)}
    results: dict[str, object] = {
        "train": {"config": config.model_dump(), "vector_steps": runner.step, "wall_s": round(wall, 1)},
        "curve": selection.curve,
    }
    for spec in [f"{args.config}:{','.join(args.set)}", *args.also]:
        scenario = _scenario(spec)
        print(f"\n{spec}: {scenario.num_agents} robots, {scenario.num_obstacles} obstacles")
        print("| manager | success % | collisions % | episode length median (Q1 - Q3) |")
        print("|---|---|---|---|")
        rows = {}
        for name in ("trained", "direct", "sampling"):
            # The planners name sub-goals in field coordinates; the episodes do not depend on the frame.
            frame = config.action_frame if name == "trained" else "field"
            acting = scenario.model_copy(update={"action_frame": frame})
            policy = managers.get(name) or planner_policy(name, acting)
            result = evaluate_scenario(policy, acting, args.final_episodes, EVALUATION_SEED)
            rows[name] = _row(result)
            length = result["episode_length"]
            print(
                f"| {name} | {100 * result['success_rate']:.1f} | {100 * result['collision_rate']:.1f} | "
                f"{length['median']:.0f} ({length['q1']:.0f} - {length['q3']:.0f}) |",
                flush=True,
            )
        results[spec] = rows
    (out / "results.json").write_text(json.dumps(results, indent=2) + "\n")
    torch.save(runner.sac.actor.state_dict(), out / "best_actor.pt")


if __name__ == "__main__":
    main()
