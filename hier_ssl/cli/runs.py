"""``hier-ssl train``, ``reproduce`` and ``sweep``: training runs, one or many."""

from __future__ import annotations

import argparse
import functools
import shlex
import sys
import textwrap
import time
from pathlib import Path

from hier_ssl.cli.common import positive_int
from hier_ssl.config import ConfigError
from hier_ssl.config.files import apply_overrides, load_yaml
from hier_ssl.config.launch_options import LaunchOptions, add_launch_flags
from hier_ssl.envs import parse_config

# -- train ---------------------------------------------------------------------------------------------------


DEFAULT_CONFIG = "proposed/fscaps"


def add_train(subparsers: argparse._SubParsersAction) -> None:
    train = subparsers.add_parser("train", help="train a manager, then evaluate it and write eval.json")
    train.add_argument(
        "config",
        nargs="?",
        default=DEFAULT_CONFIG,
        help="a YAML file, or a shipped config's name (hier-ssl configs) (default: %(default)s)",
    )
    train.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override a config key"
    )
    train.add_argument("--seed", type=int, default=None, help="random seed (overrides the config's)")
    train.add_argument("--out", default=None, help="run directory (default: runs/NAME-sSEED-TIME)")
    train.add_argument("--resume", default=None, metavar="RUN_DIR", help="continue a killed run")
    train.add_argument("--no-progress", action="store_true", help="no progress bar")
    train.add_argument(
        "--no-planners",
        action="store_true",
        help="skip the end's comparison with the direct and sampling planners (and its Fig. 3 and GIF)",
    )
    train.set_defaults(func=_train)


def _train(args: argparse.Namespace) -> int:
    # here, not at the top: torch, for this command alone
    from hier_ssl.runs.train import print_summary, resume_config, train

    # Everything is validated before the run directory is created, so a bad config writes nothing.
    if args.resume:
        run_dir = Path(args.resume)
        config = resume_config(run_dir)
    else:
        data = apply_overrides(load_yaml(args.config), args.set)
        if args.seed is not None:
            data["seed"] = args.seed
        config = parse_config(data)
        stamp = time.strftime("%Y%m%d-%H%M%S")
        run_dir = Path(args.out) if args.out else Path("runs") / f"{config.name}-s{config.seed}-{stamp}"
        if run_dir.exists() and any(run_dir.iterdir()):  # its curve and best actor would mix with ours
            raise ConfigError(f"run directory {run_dir} is not empty: --resume {run_dir}, or another --out")
    print(f"run directory: {run_dir}", flush=True)
    try:
        summary = train(config, run_dir, resume=bool(args.resume), progress=not args.no_progress)
    except KeyboardInterrupt:
        print(_resume_hint(run_dir, config.save_interval), file=sys.stderr)
        raise
    print_summary(summary)
    print(f"wrote {run_dir / 'eval.json'}")
    if config.kind == "manager" and not args.no_planners:
        beside_planners(run_dir, config.eval_episodes, config.seed, progress=not args.no_progress)
    return 0


def _resume_hint(run_dir: Path, save_interval: int) -> str:
    """What to run after an interrupted ``train``: the ``--resume`` command, or why there is none."""
    from hier_ssl.runs.jobs import run_state

    if run_state(run_dir) == "resumable":
        return f"interrupted; continue the run with: hier-ssl train --resume {shlex.quote(str(run_dir))}"
    return (
        f"interrupted before the first checkpoint (one every {save_interval} steps): nothing in {run_dir} "
        "to resume; start the run again"
    )


PLANNERS_SAID = (
    "The trained manager beside two scripted managers on the same {episodes} held-out episodes.\n"
    "`direct` names the target as the sub-goal (no planning at all); `sampling` is a classical\n"
    "planner that samples sub-goals and predicts the obstacles at every decision. Success: the robot\n"
    "reached the target pose and stopped; collisions: it touched another robot; length: 25 ms control\n"
    "steps to the end of the episode; CPAD: how far the sub-goal moved in all (m), lower is steadier.\n"
)


def beside_planners(
    run_dir: Path, episodes: int, seed: int, video: bool = True, progress: bool = False
) -> None:
    """Print a trained manager beside the ``direct`` and ``sampling`` planners on its held-out episodes
    (eval.json's: the same seed, so its row repeats the summary's) and write Fig. 3 and a GIF of one of
    them (the GIF with ``video``) under ``run_dir/beside-planners/``."""
    # here, not at the top: torch and matplotlib, for this command alone
    from hier_ssl.envs import make_scenario
    from hier_ssl.evaluation.compare import compare, run_config
    from hier_ssl.evaluation.report import write_evaluation
    from hier_ssl.evaluation.verdict import closing_note
    from hier_ssl.runs.train import EVALUATION_SEED

    evaluations = compare(
        [run_dir, "direct", "sampling"],
        episodes=episodes,
        seed=EVALUATION_SEED + seed,
        record=range(min(16, episodes)),
        progress=progress,
    )
    print("\n" + PLANNERS_SAID.format(episodes=episodes))
    print("| manager | success % | collisions % | median length | median CPAD m |\n|---|---|---|---|---|")
    for e in evaluations:
        r = e.record
        cells = (
            100 * r["success_rate"],
            100 * r["collision_rate"],
            r["episode_length"]["median"],
            r["cpad"]["median"],
        )
        print(f"| {e.name} | {cells[0]:.1f} | {cells[1]:.1f} | {cells[2]:.0f} | {cells[3]:.2f} |")
    run, *planners = (e.record for e in evaluations)
    scene = make_scenario(evaluations[0].env)
    print()
    for line in closing_note(run, planners, run_config(run_dir), scene.num_agents - 1 + scene.num_obstacles):
        print(textwrap.fill(line, width=110, break_on_hyphens=False))
    paths = write_evaluation(
        evaluations,
        run_dir / "beside-planners",
        video=video,
        title=evaluations[0].env.scenario_name,
        progress=progress,
    )
    print("wrote " + ", ".join(str(path) for path in paths))


# -- reproduce -----------------------------------------------------------------------------------------------


def add_reproduce(subparsers: argparse._SubParsersAction) -> None:
    rep = subparsers.add_parser(
        "reproduce",
        help="train the paper's 12 configurations in both families (resumable), evaluate them beside the "
        "planners, write results/paper-tables.md and .csv; --family game: the SSL game scenarios' learned "
        "configs, results/game-table.md and .csv",
    )
    rep.add_argument(
        "--family",
        action="append",
        choices=("paper", "defaults", "game"),
        default=None,
        help="configuration family: the public code's settings or ours (repeatable; default: both), or "
        "game (configs/game/, alone)",
    )
    rep.add_argument(
        "--only",
        nargs="+",
        default=[],
        metavar="NAME",
        help="e.g. proposed/fscaps, obstacle (default: all); the rows of an existing "
        "RESULTS/paper-tables.csv that these runs do not evaluate are kept, those they do are replaced, the "
        "planners re-evaluated; with --family game a scenario (game_stop) or a learned game config "
        "(stop_residual), the other scenarios' sections of RESULTS/game-table.md kept",
    )
    rep.add_argument(
        "--seeds",
        type=positive_int,
        default=None,
        help="training seeds per config (default: 3, and 1 for the paper family's non-FSCAPS rows)",
    )
    rep.add_argument("--out", default="runs/reproduce", metavar="DIR", help="runs (default: %(default)s)")
    rep.add_argument("--results", default="results", metavar="DIR", help="tables (default: %(default)s)")
    rep.add_argument(
        "--episodes", type=positive_int, default=1000, help="evaluation episodes (default: 1000)"
    )
    rep.add_argument("--config-dir", default=None, metavar="DIR", help="(default: the shipped configs)")
    rep.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override a key of every config"
    )
    rep.add_argument("--no-train", action="store_true", help="only evaluate the runs that have finished")
    rep.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_launch_flags(rep)
    rep.set_defaults(func=_reproduce)


def _reproduce(args: argparse.Namespace) -> int:
    # here, not at the top: torch, for this command alone
    from hier_ssl.runs.reproduce import FAMILIES, reproduce
    from hier_ssl.runs.reproduce_game import reproduce_game

    families = args.family or tuple(FAMILIES)
    if "game" in families and set(families) != {"game"}:
        raise ConfigError("--family game runs alone: its --only names game scenarios, not paper rows")
    write = reproduce_game if "game" in families else functools.partial(reproduce, families=families)
    report = write(
        only=args.only,
        seeds=args.seeds,
        out=args.out,
        results=args.results,
        episodes=args.episodes,
        config_dir=args.config_dir,
        overrides=args.set,
        progress=not args.no_progress,
        launch_options=LaunchOptions.from_args(args),
        train=not args.no_train,
    )
    print(f"wrote {report}")
    return 0


# -- sweep ---------------------------------------------------------------------------------------------------


def add_sweep(subparsers: argparse._SubParsersAction) -> None:
    sweep = subparsers.add_parser(
        "sweep", help="train one config over a grid of key values and seeds, tabulate eval.json (resumable)"
    )
    sweep.add_argument("config", metavar="CONFIG", help="YAML config")
    sweep.add_argument(
        "--grid", action="append", default=[], metavar="KEY=V1,V2", help="values of a key (repeatable)"
    )
    sweep.add_argument("--seeds", type=positive_int, default=1, help="training seeds per point (default: 1)")
    sweep.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override a key of every run"
    )
    sweep.add_argument("--out", default=None, metavar="DIR", help="(default: runs/sweep/NAME)")
    sweep.add_argument("--asha", action="store_true", help="with --ray: stop weak trials early (ASHA)")
    sweep.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_launch_flags(sweep)
    sweep.set_defaults(func=_sweep)


def _sweep(args: argparse.Namespace) -> int:
    # here, not at the top: torch, for this command alone
    from hier_ssl.runs.sweep import parse_grid, sweep

    options, progress = LaunchOptions.from_args(args), not args.no_progress
    paths = sweep(args.config, parse_grid(args.grid), args.seeds, args.set, args.out, options, progress)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0
