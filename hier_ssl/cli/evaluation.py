"""``hier-ssl eval`` and ``export``: trained managers side by side, and as files for robot software."""

from __future__ import annotations

import argparse
from pathlib import Path

from hier_ssl.cli.common import WORKER_HELP, positive_int, worker_spec
from hier_ssl.config import ConfigError, ScenarioConfig
from hier_ssl.envs import task_config
from hier_ssl.evaluation.compare import compare, is_planner, run_config
from hier_ssl.evaluation.paper_tables import TASKS
from hier_ssl.evaluation.report import markdown_table, write_evaluation
from hier_ssl.manager.planners import PLANNERS

# -- eval ----------------------------------------------------------------------------------------------------


def add_eval(subparsers: argparse._SubParsersAction) -> None:
    ev = subparsers.add_parser(
        "eval",
        help="evaluate managers (run directories or planners) on the same seeded episodes: tables, Fig. 3",
    )
    ev.add_argument(
        "managers",
        nargs="+",
        metavar="RUN_DIR_OR_PLANNER",
        help=f"a run directory or a planner {PLANNERS}, optionally with settings: sampling+trapped=brake",
    )
    ev.add_argument("--task", choices=TASKS, default=None, help="task (default: a run's own, else proposed)")
    ev.add_argument(
        "--scenario",
        default=None,
        metavar="NAME_OR_YAML",
        help="a multi-robot scenario, or a YAML of any task, instead of --task (default for runs trained on "
        "a scenario: their own); figures are per robot",
    )
    ev.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a key of the task or scenario, spelt as train takes it (env.frame_skip=4, "
        "scenario.num_agents=4) or alone (frame_skip=4); repeatable; a run still acts with its own "
        "action_form, action_frame, observation and neighbours",
    )
    ev.add_argument("--episodes", type=positive_int, default=1000, help="episodes (default: %(default)s)")
    ev.add_argument(
        "--worker",
        action="append",
        type=worker_spec,
        default=None,
        metavar="WORKER",
        help=f"{WORKER_HELP} (keys: hier_ssl.worker.perturbed); repeatable; default: the run's own",
    )
    ev.add_argument("--seed", type=int, default=0, help="episode seed (default: %(default)s)")
    ev.add_argument(
        "--frame-skip", type=positive_int, default=None, help="decision period (default: a run's own, 16)"
    )
    ev.add_argument("--json", default=None, metavar="PATH", help="write one JSON record per evaluation")
    ev.add_argument(
        "--out", default=None, metavar="DIR", help="tables and figure (default: runs/eval/TASK-sSEED)"
    )
    ev.add_argument("--video", action="store_true", help="also write an animated GIF of the figure's episode")
    ev.add_argument(
        "--policy",
        choices=("best", "final"),
        default="best",
        help="a run's checkpoint: the one model selection kept, or the one training ended with "
        "(default: %(default)s)",
    )
    ev.add_argument(
        "--sample",
        action="store_true",
        help="runs sample their actions (the paper's test script) instead of the mean",
    )
    ev.add_argument("--no-progress", action="store_true", help="no progress bars")
    ev.set_defaults(func=_eval)


def _eval(args: argparse.Namespace) -> int:
    if args.task is not None and args.scenario is not None:
        raise ConfigError("--task names a paper task and --scenario a scenario: give one of them")
    record = range(min(16, args.episodes))
    runs = [spec for spec in args.managers if not is_planner(spec)]
    config = None  # every manager acts in the one task given; else each run in its own (compare)
    if args.scenario is not None or args.set:
        base = args.scenario or args.task or (run_config(runs[0]).task_config if runs else None)
        config = task_config(base, args.set)
    evaluations = compare(
        args.managers,
        config,
        task=args.task if config is None else None,
        workers=args.worker or [None],
        episodes=args.episodes,
        seed=args.seed,
        frame_skip=args.frame_skip,
        record=record,
        which=args.policy,
        sample=args.sample,
        progress=not args.no_progress,
    )
    first = evaluations[0]
    task = first.env.scenario_name
    what = f"task {task}"
    if isinstance(first.env, ScenarioConfig):
        what = f"scenario {task} ({first.record['robots'] // args.episodes} robots a field)"
    out = Path(args.out) if args.out else Path("runs") / "eval" / f"{task}-s{args.seed}"
    acting = f"runs act with their {args.policy} checkpoint, {'sampled' if args.sample else 'mean'} actions"
    print(f"{what}, {args.episodes} episodes, seed {args.seed}; {acting}; lengths in 25 ms control steps\n")
    print(markdown_table([e.record for e in evaluations]))
    for e in evaluations:
        where = f"{e.env.worker} worker, frame skip {e.env.frame_skip}"
        print(f"eval wall time {e.name} ({where}): {e.record['eval_wall_s']:.1f} s")
    paths = write_evaluation(
        evaluations, out, json_path=args.json, video=args.video, title=task, progress=not args.no_progress
    )
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


# -- export --------------------------------------------------------------------------------------------------


def add_export(subparsers: argparse._SubParsersAction) -> None:
    export = subparsers.add_parser(
        "export", help="write a trained manager as one TorchScript or ONNX file: raw state in, sub-goal out"
    )
    export.add_argument("run_dir", metavar="RUN_DIR", help="run directory of a trained manager")
    export.add_argument("--format", choices=("torchscript", "onnx"), default="torchscript", dest="fmt")
    export.add_argument("--out", default=None, help="file to write (default: RUN_DIR/manager.pt or .onnx)")
    export.set_defaults(func=_export)


def _export(args: argparse.Namespace) -> int:
    # here, not at the top: torch, for this command alone
    from hier_ssl.policies.export import export_manager

    path = export_manager(args.run_dir, args.fmt, args.out, progress=True)
    print(
        f"wrote {path} ({path.stat().st_size:,} bytes, {args.fmt}); input/output layout: docs/guide/export.md"
    )
    return 0
