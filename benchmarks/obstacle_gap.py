"""Measurement, not CI: why the paper family's Obstacle FSCAPS does not learn here, and why its Obstacle
CAPS collides more than the paper's (docs/results.md).

Two sides, seed 0, of the Obstacle ``--setup`` (fscaps or caps). From our default
(configs/obstacle/SETUP.yaml), each ``no-*`` run puts one group of keys back to the public code's value
(configs/paper/obstacle/SETUP.yaml). From the public code's config, ``paper`` as it is and
``paper-with-interface`` with our obstacle interface alone, both cut to ``--paper-steps``. Trains what is
missing (resuming killed runs, ``hier_ssl.runs.launch``), plays every run's best and final policy (mean
action) on the same 1000 episodes of the paper family's Obstacle task (``hier-ssl reproduce``'s), prints a
markdown table (also ``OUT/table.md``) and writes the selection curves (``OUT/curves.png``).

Run: python benchmarks/obstacle_gap.py [--setup fscaps] [--out runs/obstacle-gap] [--paper-steps 40000]
     [--only no-interface paper ...] [--no-train]   (--out: runs/obstacle-gap-caps with --setup caps)
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

GROUPS = {
    "defaults": [],
    "no-reward": [
        "env.frame_skip_reward=last",
        "env.success_mode=replace",
        "env.hit_mode=replace",
        "env.success_weight=1",
        "env.hit_weight=1",
    ],
    "no-interface": ["env.observation=paper", "env.action_frame=field"],
    "no-learner": [
        "sac.gamma=0.99",
        "sac.reward_scale=1",
        "sac.actor_schedule=delayed",
        "sac.caps_actions=sampled",
    ],
    "no-gamma": ["sac.gamma=0.99"],
    "no-scale": ["sac.reward_scale=1"],
    "no-schedule": ["sac.actor_schedule=delayed", "sac.caps_actions=sampled"],
    "no-start": ["env.obstacle_from=robot", "env.min_start_distance=0.2", "env.allow_start_contact=true"],
}
PAPER_SIDE = {
    "paper": [],
    "paper-with-interface": ["env.observation=neighbours", "env.neighbours=1", "env.action_frame=target"],
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setup", choices=["fscaps", "caps"], default="fscaps")
    parser.add_argument("--out", type=Path)
    parser.add_argument("--only", nargs="+", choices=[*GROUPS, *PAPER_SIDE], default=[*GROUPS, *PAPER_SIDE])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--paper-steps", type=int, default=40000)
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--no-train", action="store_true")
    args = parser.parse_args()
    out = args.out or Path("runs/obstacle-gap" + ("" if args.setup == "fscaps" else f"-{args.setup}"))

    from hier_ssl.config.files import apply_overrides, config_dir, load_yaml
    from hier_ssl.envs import parse_config
    from hier_ssl.runs.launch import Job, launch, run_state
    from hier_ssl.runs.reproduce import Planned, episodes_of, evaluate_run, plot_curves

    runs = []
    for name in args.only:
        family = "paper" if name in PAPER_SIDE else "defaults"
        sets = PAPER_SIDE[name] + [f"total_steps={args.paper_steps}"] if family == "paper" else GROUPS[name]
        path = config_dir() / ("paper/" if family == "paper" else "") / f"obstacle/{args.setup}.yaml"
        config = parse_config({**apply_overrides(load_yaml(path), sets), "seed": args.seed})
        runs.append((name, sets, Planned(family, "obstacle", args.setup, config, out / name)))
    # With --no-train only finished runs go to launch, which checks them against their config.yaml.
    jobs = [Job(run.config, run.run_dir) for _, _, run in runs]
    launch([job for job in jobs if not args.no_train or run_state(job.run_dir) == "finished"], progress=False)
    done = [(name, sets, run) for name, sets, run in runs if run_state(run.run_dir) == "finished"]
    episodes = episodes_of("obstacle")
    header = "| run | keys changed | policy | success % | collision % | median length | train s |"
    lines = [header, "|" + "---|" * 7]
    for name, sets, run in done:
        for which in ("best", "final"):
            r = evaluate_run(run, which, False, episodes, args.episodes, 0, out / "evals")
            length = r["episode_length"]["median"]
            figures = f"{100 * r['success_rate']:.1f} | {100 * r['collision_rate']:.1f} | {length:.0f}"
            wall = json.loads((run.run_dir / "eval.json").read_text())["train_wall_s"]
            keys = ", ".join(f"`{s}`" for s in sets) or "-"
            lines.append(f"| {name} | {keys} | {which} | {figures} | {wall:.0f} |")
    print("\n".join(lines))
    (out / "table.md").write_text("\n".join(lines) + "\n")
    series = [(name, "-" if run.family == "paper" else "--", run.run_dir) for name, _, run in done]
    if series:
        print("curves:", plot_curves(series, f"Obstacle {args.setup.upper()}", out / "curves.png"))


if __name__ == "__main__":
    main()
