"""The ``hier-ssl`` command: one small function per subcommand, registered in ``COMMANDS``.

Heavy imports happen inside the subcommands, so ``hier-ssl --help`` stays fast. Errors end the command
with one line on stderr and a non-zero exit status, not a traceback.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable, Sequence

from hier_ssl import __version__


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line instead of usage + message
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


WORKER_HELP = "paper|bangbang|RUN_DIR|package.module:Name, optionally perturbed: paper+latency=2+noise=0.2"


def _worker_spec(text: str) -> str:
    """A ``make_worker`` spec whose name part is a known worker, an importable class or factory, or an
    existing directory."""

    from hier_ssl.worker import check_worker_spec

    try:
        return check_worker_spec(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


# -- bench ------------------------------------------------------------------------------------------------


CPU_TIME_HELP = "time with this thread's CPU time, not wall-clock time (steadier on a shared machine)"


def _clock(args: argparse.Namespace) -> Callable[[], float]:
    import time

    return time.thread_time if args.cpu_time else time.perf_counter


def _add_bench(subparsers: argparse._SubParsersAction) -> None:
    bench = subparsers.add_parser("bench", help="throughput benchmarks, pinned to one core")
    targets = bench.add_subparsers(dest="target", required=True, metavar="TARGET")
    world = targets.add_parser(
        "world",
        help="field-steps/s of the world with the paper worker, 1 robot + 1 random-walk obstacle per field",
    )
    world.add_argument("--json", action="store_true", help="one JSON object per line")
    world.add_argument("--cpu-time", action="store_true", help=CPU_TIME_HELP)
    world.add_argument(
        "--steps",
        type=_positive_int,
        default=None,
        help="control steps per timed run (default: 4000 / sqrt(N), at least 20)",
    )
    world.set_defaults(func=_bench_world)
    views = {
        "env": "PettingZoo view, one field, frame skip 1 and 16: steps and decisions/s, build seconds",
        "vector": "batched view at frame skip 16: proposed at N = 1024, formation at N = 256",
    }
    for name, text in views.items():
        view = targets.add_parser(name, help=text)
        view.add_argument("--json", action="store_true", help="one JSON object per line")
        view.add_argument("--cpu-time", action="store_true", help=CPU_TIME_HELP)
        view.set_defaults(func=_bench_view)


def _bench_view(args: argparse.Namespace) -> int:
    from hier_ssl import bench

    cpu = bench.pin_to_one_core()
    if not args.json:
        where = f"CPU {cpu}" if cpu is not None else "one thread"
        print(f"{args.target} bench on {where}, best of several runs")
    bench.print_results(bench.views(args.target, _clock(args)), args.json)
    return 0


def _bench_world(args: argparse.Namespace) -> int:
    from hier_ssl.bench import WORLD_SIZES, bench_world, default_steps, pin_to_one_core

    cpu = pin_to_one_core()
    if not args.json:
        where = f"CPU {cpu}" if cpu is not None else "one thread (affinity not settable here)"
        print(f"world bench on {where}: best of 5 runs per N, paper worker + random-walk obstacle")
    for n in WORLD_SIZES:
        result = bench_world(n, args.steps, clock=_clock(args))
        if args.json:
            print(json.dumps(result.as_dict()), flush=True)
        else:
            steps = args.steps or default_steps(n)
            print(
                f"  N = {n:5d} fields x {result.robots_per_field} robots: "
                f"{result.steps_per_s:12,.0f} field-steps/s  ({steps} steps per run)",
                flush=True,
            )
    return 0


# -- demo -------------------------------------------------------------------------------------------------


def _add_demo(subparsers: argparse._SubParsersAction) -> None:
    demo = subparsers.add_parser("demo", help="drive a robot to random targets past an obstacle, write a PNG")
    demo.add_argument("--out", default="runs/demo.png", help="PNG to write (default: %(default)s)")
    demo.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    demo.add_argument(
        "--worker",
        type=_worker_spec,
        default="paper",
        help=f"{WORKER_HELP} (default: %(default)s)",
    )
    demo.add_argument(
        "--targets", type=_positive_int, default=4, help="targets to visit (default: %(default)s)"
    )
    demo.set_defaults(func=_demo)


def _demo(args: argparse.Namespace) -> int:
    from hier_ssl.demo import run_demo

    result = run_demo(args.out, seed=args.seed, worker=args.worker, targets=args.targets)
    print(
        f"wrote {result.path} ({args.worker} worker: {result.reached}/{result.targets} targets reached in "
        f"{result.steps} steps, {result.contact_steps} steps in contact with the obstacle)"
    )
    return 0


# -- render -----------------------------------------------------------------------------------------------


def _add_render(subparsers: argparse._SubParsersAction) -> None:
    from hier_ssl.manager.planners import PLANNERS

    render = subparsers.add_parser(
        "render", help="one episode of a task or scenario under a manager: GIF or PNG"
    )
    render.add_argument("scenario", metavar="SCENARIO", help="a task or scenario name, or a YAML (configs/)")
    render.add_argument(
        "--manager",
        default="sampling",
        help=f"a planner {PLANNERS} or a run directory (default: %(default)s)",
    )
    render.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override a task key (repeatable)"
    )
    render.add_argument("--seed", type=int, default=0, help="episode seed (default: %(default)s)")
    render.add_argument(
        "--out", default="runs/render.gif", help="a .gif (animated) or .png (default: %(default)s)"
    )
    render.set_defaults(func=_render)


def _render(args: argparse.Namespace) -> int:
    from pathlib import Path

    from hier_ssl.compare import compare
    from hier_ssl.config import ConfigError
    from hier_ssl.envs import TASKS, task_config
    from hier_ssl.report import episode_video, figure3, panel_title
    from hier_ssl.world.field import get_field

    out = Path(args.out)
    if out.suffix.lower() not in (".gif", ".png"):
        raise ConfigError(f"--out {str(out)!r}: expected a .gif or .png file")
    # A paper task by name is evaluated as `eval --task` would (a planner deciding every 16 steps).
    by_name = args.scenario in TASKS and not args.set
    config = None if by_name else task_config(args.scenario, args.set)
    task = args.scenario if by_name else None
    (evaluation,) = compare([args.manager], config, task=task, episodes=1, seed=args.seed, record=[0])
    panels = [(evaluation.name, evaluation.result["trajectories"][0])]
    draw = episode_video if out.suffix.lower() == ".gif" else figure3
    path = draw(panels, get_field(evaluation.env.field), out)
    print(f"wrote {path}: {panel_title(*panels[0]).replace(chr(10), ': ')}")
    return 0


# -- train ------------------------------------------------------------------------------------------------

DEFAULT_CONFIG = "proposed/fscaps"


def _add_train(subparsers: argparse._SubParsersAction) -> None:
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
    train.set_defaults(func=_train)


def _train(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    from hier_ssl.config import ConfigError, apply_overrides, load_yaml
    from hier_ssl.envs import parse_config
    from hier_ssl.train import print_summary, resume_config, train

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
    summary = train(config, run_dir, resume=bool(args.resume), progress=not args.no_progress)
    print_summary(summary)
    print(f"wrote {run_dir / 'eval.json'}")
    return 0


# -- export -----------------------------------------------------------------------------------------------


def _add_export(subparsers: argparse._SubParsersAction) -> None:
    export = subparsers.add_parser(
        "export", help="write a trained manager as one TorchScript or ONNX file: raw state in, sub-goal out"
    )
    export.add_argument("run_dir", metavar="RUN_DIR", help="run directory of a trained manager")
    export.add_argument("--format", choices=("torchscript", "onnx"), default="torchscript", dest="fmt")
    export.add_argument("--out", default=None, help="file to write (default: RUN_DIR/manager.pt or .onnx)")
    export.set_defaults(func=_export)


def _export(args: argparse.Namespace) -> int:
    from hier_ssl.policies.export import export_manager

    path = export_manager(args.run_dir, args.fmt, args.out)
    print(
        f"wrote {path} ({path.stat().st_size:,} bytes, {args.fmt}); input/output layout: README.md, "
        "'Deploying a manager'"
    )
    return 0


# -- eval -------------------------------------------------------------------------------------------------


def _add_eval(subparsers: argparse._SubParsersAction) -> None:
    from hier_ssl.manager.planners import PLANNERS
    from hier_ssl.report import TASKS

    ev = subparsers.add_parser(
        "eval",
        help="evaluate managers (run directories or planners) on the same seeded episodes: tables, Fig. 3",
    )
    ev.add_argument(
        "managers", nargs="+", metavar="RUN_DIR_OR_PLANNER", help=f"a run directory or a planner {PLANNERS}"
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
        help="override a key of the task or scenario (repeatable); a run still acts with its own "
        "action_form, action_frame, observation and neighbours",
    )
    ev.add_argument("--episodes", type=_positive_int, default=1000, help="episodes (default: %(default)s)")
    ev.add_argument(
        "--worker",
        action="append",
        type=_worker_spec,
        default=None,
        metavar="WORKER",
        help=f"{WORKER_HELP} (keys: hier_ssl.worker.perturbed); repeatable; default: the run's own",
    )
    ev.add_argument("--seed", type=int, default=0, help="episode seed (default: %(default)s)")
    ev.add_argument(
        "--frame-skip", type=_positive_int, default=None, help="decision period (default: a run's own, 16)"
    )
    ev.add_argument("--json", default=None, metavar="PATH", help="write one JSON record per evaluation")
    ev.add_argument(
        "--out", default=None, metavar="DIR", help="tables and figure (default: runs/eval/TASK-sSEED)"
    )
    ev.add_argument("--video", action="store_true", help="also write an animated GIF of the figure's episode")
    ev.set_defaults(func=_eval)


def _eval(args: argparse.Namespace) -> int:
    from pathlib import Path

    from hier_ssl.compare import compare, is_planner, run_config
    from hier_ssl.config import ConfigError, ScenarioConfig
    from hier_ssl.envs import task_config
    from hier_ssl.report import markdown_table, write_evaluation

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
    )
    first = evaluations[0]
    task = first.env.scenario_name
    what = f"task {task}"
    if isinstance(first.env, ScenarioConfig):
        what = f"scenario {task} ({first.record['robots'] // args.episodes} robots a field)"
    out = Path(args.out) if args.out else Path("runs") / "eval" / f"{task}-s{args.seed}"
    print(f"{what}, {args.episodes} episodes, seed {args.seed}; lengths in 25 ms control steps\n")
    print(markdown_table([e.record for e in evaluations]))
    for e in evaluations:
        where = f"{e.env.worker} worker, frame skip {e.env.frame_skip}"
        print(f"eval wall time {e.name} ({where}): {e.record['eval_wall_s']:.1f} s")
    paths = write_evaluation(evaluations, out, json_path=args.json, video=args.video, title=task)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


# -- reproduce --------------------------------------------------------------------------------------------


def _add_reproduce(subparsers: argparse._SubParsersAction) -> None:
    from hier_ssl.launch_options import add_launch_flags

    rep = subparsers.add_parser(
        "reproduce", help="train and evaluate the paper's 12 configurations, write report.md (resumable)"
    )
    rep.add_argument(
        "--only", nargs="+", default=[], metavar="NAME", help="e.g. proposed/fscaps, obstacle (default: all)"
    )
    rep.add_argument("--seeds", type=_positive_int, default=1, help="training seeds per config (default: 1)")
    rep.add_argument("--out", default="runs/reproduce", metavar="DIR", help="(default: %(default)s)")
    rep.add_argument(
        "--episodes", type=_positive_int, default=1000, help="evaluation episodes (default: 1000)"
    )
    rep.add_argument("--config-dir", default=None, metavar="DIR", help="(default: the shipped configs)")
    rep.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override a key of every config"
    )
    rep.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_launch_flags(rep)
    rep.set_defaults(func=_reproduce)


def _reproduce(args: argparse.Namespace) -> int:
    from hier_ssl.launch_options import LaunchOptions
    from hier_ssl.reproduce import reproduce

    report = reproduce(
        only=args.only,
        seeds=args.seeds,
        out=args.out,
        episodes=args.episodes,
        config_dir=args.config_dir,
        overrides=args.set,
        progress=not args.no_progress,
        launch_options=LaunchOptions.from_args(args),
    )
    print(f"wrote {report}")
    return 0


# -- configs ----------------------------------------------------------------------------------------------


def _add_configs(subparsers: argparse._SubParsersAction) -> None:
    configs = subparsers.add_parser(
        "configs", help="list the shipped configs, by the names train, eval and render accept"
    )
    configs.add_argument("--dir", action="store_true", help="print the directory holding them instead")
    configs.set_defaults(func=_configs)


def _configs(args: argparse.Namespace) -> int:
    from hier_ssl.config import config_dir, config_names

    print(config_dir() if args.dir else "\n".join(config_names()))
    return 0


# -- sweep ------------------------------------------------------------------------------------------------


def _add_sweep(subparsers: argparse._SubParsersAction) -> None:
    from hier_ssl.launch_options import add_launch_flags

    sweep = subparsers.add_parser(
        "sweep", help="train one config over a grid of key values and seeds, tabulate eval.json (resumable)"
    )
    sweep.add_argument("config", metavar="CONFIG", help="YAML config")
    sweep.add_argument(
        "--grid", action="append", default=[], metavar="KEY=V1,V2", help="values of a key (repeatable)"
    )
    sweep.add_argument("--seeds", type=_positive_int, default=1, help="training seeds per point (default: 1)")
    sweep.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="override a key of every run"
    )
    sweep.add_argument("--out", default=None, metavar="DIR", help="(default: runs/sweep/NAME)")
    sweep.add_argument("--asha", action="store_true", help="with --ray: stop weak trials early (ASHA)")
    sweep.add_argument("--no-progress", action="store_true", help="no progress bars")
    add_launch_flags(sweep)
    sweep.set_defaults(func=_sweep)


def _sweep(args: argparse.Namespace) -> int:
    from hier_ssl.launch_options import LaunchOptions
    from hier_ssl.sweep import parse_grid, sweep

    options, progress = LaunchOptions.from_args(args), not args.no_progress
    paths = sweep(args.config, parse_grid(args.grid), args.seeds, args.set, args.out, options, progress)
    print("wrote " + ", ".join(str(p) for p in paths))
    return 0


# -- entry point ------------------------------------------------------------------------------------------

COMMANDS: tuple[Callable[[argparse._SubParsersAction], None], ...] = (
    _add_bench,
    _add_configs,
    _add_demo,
    _add_render,
    _add_train,
    _add_export,
    _add_eval,
    _add_reproduce,
    _add_sweep,
)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="hier-ssl", description="Hierarchical RL path planning for RoboCup SSL.")
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for add in COMMANDS:
        add(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``hier-ssl`` with ``argv`` (default: the process arguments); returns the exit status."""
    # A worker named package.module:Name may live in the current directory, which a console script does
    # not search (``python -m`` does). Appended, so a local file never shadows an installed module.
    if os.getcwd() not in sys.path:
        sys.path.append(os.getcwd())
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except KeyboardInterrupt:
        print("hier-ssl: interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError) as err:  # bad input: one line naming it; bugs keep their traceback
        print(f"hier-ssl {args.command}: error: {err}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
