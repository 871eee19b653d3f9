"""``hier-ssl bench``, ``demo``, ``render`` and ``configs``: measure, draw and list; nothing is trained."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path

from hier_ssl.cli import bench, side_by_side
from hier_ssl.cli.common import WORKER_HELP, positive_int, worker_spec
from hier_ssl.cli.demo import run_demo
from hier_ssl.cli.deploy import add_bench_deploy
from hier_ssl.config import ConfigError
from hier_ssl.config.files import config_dir, config_names, load_yaml
from hier_ssl.envs import TASKS, task_config
from hier_ssl.envs.shards import resolve_threads
from hier_ssl.evaluation.compare import compare
from hier_ssl.evaluation.figures import episode_video, figure3, panel_title
from hier_ssl.manager.planners import PLANNERS
from hier_ssl.world.field import get_field

# -- bench ---------------------------------------------------------------------------------------------------


CPU_TIME_HELP = "time with this thread's CPU time, not wall-clock time (steadier on a shared machine)"


def _clock(args: argparse.Namespace) -> Callable[[], float]:
    return time.thread_time if args.cpu_time else time.perf_counter


def add_bench(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("bench", help="throughput benchmarks, pinned to one core")
    targets = parser.add_subparsers(dest="target", required=True, metavar="TARGET")
    world = targets.add_parser(
        "world",
        help="field-steps/s of the world with the paper worker, 1 robot + 1 random-walk obstacle per field",
    )
    world.add_argument("--json", action="store_true", help="one JSON object per line")
    world.add_argument("--cpu-time", action="store_true", help=CPU_TIME_HELP)
    world.add_argument(
        "--steps",
        type=positive_int,
        default=None,
        help="control steps per timed run (default: 4000 / sqrt(N), at least 20)",
    )
    world.set_defaults(func=_bench_world)
    views = {
        "env": "PettingZoo view, one field, frame skip 1 and 16: steps and decisions/s, build seconds",
        "vector": "batched view at frame skip 16: proposed at N = 1024, formation at N = 256",
    }
    parsers = {name: targets.add_parser(name, help=text) for name, text in views.items()}
    for view in parsers.values():
        view.add_argument("--json", action="store_true", help="one JSON object per line")
        view.add_argument("--cpu-time", action="store_true", help=CPU_TIME_HELP)
        view.set_defaults(func=_bench_view)
    vector = parsers["vector"]
    vector.add_argument(
        "--sizes",
        type=positive_int,
        nargs="+",
        metavar="N",
        help="sweep these numbers of fields instead (e.g. 256 1024 4096), for each of --tasks",
    )
    vector.add_argument(
        "--tasks",
        nargs="+",
        default=["obstacle", "formation"],
        help="tasks of the sweep (default: %(default)s)",
    )
    vector.add_argument(
        "--frame-skip", type=positive_int, default=16, help="of the sweep (default: %(default)s)"
    )
    vector.add_argument(
        "--threads",
        type=positive_int,
        nargs="*",
        metavar="K",
        help="the scaling curve instead: each of --tasks at each of --sizes (default: 1024) on K cores for "
        "each K given (none given: 1 up to the cores this process may use), alternated in one run, wall "
        "clock, unpinned",
    )
    vector.add_argument(
        "--rounds", type=positive_int, default=20, help="alternations of --threads (default: %(default)s)"
    )
    versus = targets.add_parser(
        "compare", help="vector view beside VMAS (if installed), alternating; PettingZoo at frame skip 1"
    )
    versus.add_argument("--json", action="store_true", help="one JSON object per line")
    versus.add_argument("--cpu-time", action="store_true", help=CPU_TIME_HELP)
    versus.add_argument(
        "--sizes", type=positive_int, nargs="+", default=[1024], metavar="N", help="fields (default: 1024)"
    )
    versus.add_argument("--rounds", type=positive_int, default=40, help="alternations (default: %(default)s)")
    versus.add_argument(
        "--steps", type=positive_int, default=None, help="control steps a round (default: about 0.1 s)"
    )
    versus.add_argument(
        "--threads",
        type=positive_int,
        nargs="+",
        default=[1],
        metavar="K",
        help="hier_ssl on K cores for each K given, alternated with each other and VMAS (on one torch "
        "thread): wall clock, unpinned above 1 (default: 1, pinned to one core)",
    )
    versus.set_defaults(func=_bench_compare)
    add_bench_deploy(
        targets.add_parser("deploy", help="deploy chain over 127.0.0.1: tracker error, latency, task success")
    )


def _thread_counts(args: argparse.Namespace) -> list[int]:
    """``--threads`` as counts (none given: 1 up to this process's cores); SystemExit with --cpu-time."""
    counts = args.threads or list(range(1, resolve_threads("auto") + 1))
    if max(counts) > 1 and args.cpu_time:
        raise SystemExit("--cpu-time counts this thread alone: use the wall clock with --threads above 1")
    return counts


def _bench_view(args: argparse.Namespace) -> int:
    if getattr(args, "threads", None) is not None:
        return _bench_scaling(args)
    cpu = bench.pin_to_one_core()
    if not args.json:
        where = f"CPU {cpu}" if cpu is not None else "one thread"
        print(f"{args.target} bench on {where}, best of several runs")
    sizes = getattr(args, "sizes", None)
    results = bench.sweep(args.tasks, sizes, args.frame_skip, _clock(args)) if sizes else None
    bench.print_results(results or bench.views(args.target, _clock(args)), args.json)
    return 0


def _bench_scaling(args: argparse.Namespace) -> int:
    counts = _thread_counts(args)
    if not args.json:
        print(
            f"vector bench on {counts} cores, unpinned, {args.rounds} alternating rounds, best of each "
            f"(this process may use {resolve_threads('auto')} cores)"
        )
    sizes = args.sizes or [1024]
    results = bench.scaling(args.tasks, sizes, counts, args.frame_skip, args.rounds, _clock(args))
    bench.print_results(results, args.json)
    return 0


def _bench_compare(args: argparse.Namespace) -> int:
    counts = _thread_counts(args)
    cpu = bench.pin_to_one_core() if counts == [1] else None
    if not args.json:
        where = f"CPU {cpu}" if cpu is not None else f"{counts} cores, unpinned"
        vmas = "beside VMAS" if side_by_side.vmas_installed() else "(VMAS not installed: hier_ssl alone)"
        print(f"compare on {where}, {args.rounds} alternating rounds, best of each, {vmas}")
    records = side_by_side.comparisons(args.sizes, args.rounds, _clock(args), args.steps, counts)
    side_by_side.print_comparisons(records, args.json)
    return 0


def _bench_world(args: argparse.Namespace) -> int:
    cpu = bench.pin_to_one_core()
    if not args.json:
        where = f"CPU {cpu}" if cpu is not None else "one thread (affinity not settable here)"
        print(f"world bench on {where}: best of 5 runs per N, paper worker + random-walk obstacle")
    for n in bench.WORLD_SIZES:
        result = bench.bench_world(n, args.steps, clock=_clock(args))
        if args.json:
            print(json.dumps(result.as_dict()), flush=True)
        else:
            steps = args.steps or bench.default_steps(n)
            print(
                f"  N = {n:5d} fields x {result.robots_per_field} robots: "
                f"{result.steps_per_s:12,.0f} field-steps/s  ({steps} steps per run)",
                flush=True,
            )
    return 0


# -- demo ----------------------------------------------------------------------------------------------------


def add_demo(subparsers: argparse._SubParsersAction) -> None:
    demo = subparsers.add_parser("demo", help="drive a robot to random targets past an obstacle, write a PNG")
    demo.add_argument("--out", default="runs/demo.png", help="PNG to write (default: %(default)s)")
    demo.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    demo.add_argument(
        "--worker",
        type=worker_spec,
        default="paper",
        help=f"{WORKER_HELP} (default: %(default)s)",
    )
    demo.add_argument(
        "--targets", type=positive_int, default=4, help="targets to visit (default: %(default)s)"
    )
    demo.set_defaults(func=_demo)


def _demo(args: argparse.Namespace) -> int:
    result = run_demo(args.out, seed=args.seed, worker=args.worker, targets=args.targets)
    print(
        f"wrote {result.path} ({args.worker} worker: {result.reached}/{result.targets} targets reached in "
        f"{result.steps} steps, {result.contact_steps} steps in contact with the obstacle)"
    )
    return 0


# -- render --------------------------------------------------------------------------------------------------


def add_render(subparsers: argparse._SubParsersAction) -> None:
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
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a task key: env.frame_skip=4 as train takes it, or frame_skip=4 (repeatable)",
    )
    render.add_argument("--seed", type=int, default=0, help="episode seed (default: %(default)s)")
    render.add_argument(
        "--out", default="runs/render.gif", help="a .gif (animated) or .png (default: %(default)s)"
    )
    render.set_defaults(func=_render)


def _render(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.suffix.lower() not in (".gif", ".png"):
        raise ConfigError(f"--out {str(out)!r}: expected a .gif or .png file")
    # A paper task by name is evaluated as `eval --task` would (a planner deciding every 16 steps).
    by_name = args.scenario in TASKS and not args.set
    config = None if by_name else task_config(args.scenario, args.set)
    task = args.scenario if by_name else None
    (evaluation,) = compare(
        [args.manager], config, task=task, episodes=1, seed=args.seed, record=[0], progress=True
    )
    panels = [(evaluation.name, evaluation.result["trajectories"][0])]
    field = get_field(evaluation.env.field)
    if out.suffix.lower() == ".gif":
        path = episode_video(panels, field, out, progress=True)
    else:
        path = figure3(panels, field, out)
    print(f"wrote {path}: {panel_title(*panels[0]).replace(chr(10), ': ')}")
    return 0


# -- configs -------------------------------------------------------------------------------------------------


def add_configs(subparsers: argparse._SubParsersAction) -> None:
    configs = subparsers.add_parser(
        "configs", help="list the shipped configs, by the names train, eval and render accept"
    )
    configs.add_argument("--dir", action="store_true", help="print the directory holding them instead")
    configs.set_defaults(func=_configs)


def _configs(args: argparse.Namespace) -> int:
    if args.dir:
        print(config_dir())
        return 0
    names = config_names()
    width = max(map(len, names))
    for name in names:
        print(f"{name:<{width}}  {load_yaml(name).get('description', '')}".rstrip())
    return 0
