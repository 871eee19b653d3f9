"""``hier-ssl bench game``: the game scenarios' speed, on one core.

- ``game_match`` through the PettingZoo view (one field, 11 v 11 and the ball) at frame skip 1, uniform
  random actions, the opponents' planners deciding every ``decide_every`` control steps (the scenario's
  ``options.decide_every``; 16 here): control steps per second, best and median of the rounds.
- ``game_stop``'s batched view at each N of a list (``bench.sweep``): field-steps/s and the cost per field
  against the smallest N.
- with ``--profile``: cProfile over ``PROFILE_STEPS`` PettingZoo steps of ``game_match``, the functions
  with the most time of their own, in microseconds a step (cProfile inflates them: read the shares).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import time
from collections.abc import Iterator, Sequence

from hier_ssl.cli import bench
from hier_ssl.cli.bench import BenchResult, Clock, EnvRun, bench_env, sweep
from hier_ssl.cli.common import positive_int

MATCH, STOP = "game_match", "game_stop"
DECIDE_EVERY = 16
MATCH_ROUND_STEPS = 500  # a round: about a quarter of a second at the 2,000 steps/s aimed at
PROFILE_STEPS = 1000
PROFILE_ROWS = 15


def game_results(
    sizes: Sequence[int],
    rounds: int,
    clock: Clock,
    steps: int = MATCH_ROUND_STEPS,
    frame_skip: int = 16,
    decide_every: int = DECIDE_EVERY,
) -> Iterator[BenchResult]:
    """``game_match``'s PettingZoo view at frame skip 1 (``bench_env``, the best of ``rounds`` rounds of
    ``steps`` steps), then ``game_stop``'s batched view at ``frame_skip`` for each N of ``sizes``."""
    options = {"decide_every": decide_every}
    result = bench_env(1, MATCH, decisions=steps, repeats=rounds, clock=clock, options=options)
    result.extra["decide_every"] = decide_every
    yield result
    if sizes:
        yield from sweep([STOP], sizes, frame_skip, clock)


def match_profile(
    decide_every: int = DECIDE_EVERY, steps: int = PROFILE_STEPS, rows: int = PROFILE_ROWS
) -> list[str]:
    """cProfile of ``steps`` PettingZoo steps of ``game_match`` (frame skip 1, random actions, after 100
    steps of warm-up): the ``rows`` functions with the most time of their own, as lines of text, each with
    its microseconds a step alone and with what it calls, its share and its calls a step."""
    bench = EnvRun(MATCH, 1, time.perf_counter, options={"decide_every": decide_every})
    bench.run(100)
    profiler = cProfile.Profile()
    profiler.runcall(bench.run, steps)
    stats = pstats.Stats(profiler)
    table = stats.stats  # type: ignore[attr-defined]
    total = sum(entry[2] for entry in table.values())
    lines = [f"game_match, {steps} steps under cProfile: {1e6 * total / steps:,.0f} us a step"]
    for (path, line, name), (_, calls, own, cumulative, _) in sorted(table.items(), key=lambda e: -e[1][2])[
        :rows
    ]:
        where = "/".join(path.split("/")[-2:]) + f":{line}({name})"
        lines.append(
            f"  {1e6 * own / steps:8.1f} us {100 * own / total:5.1f} %  {1e6 * cumulative / steps:8.1f} us "
            f"with callees  {calls / steps:6.1f} calls  {where}"
        )
    return lines


def add_bench_game(parser: argparse.ArgumentParser, cpu_time_help: str) -> None:
    """The options of ``hier-ssl bench game``."""
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    parser.add_argument("--cpu-time", action="store_true", help=cpu_time_help)
    parser.add_argument(
        "--sizes",
        type=positive_int,
        nargs="*",
        default=[256, 1024, 4096],
        metavar="N",
        help="game_stop's fields, at frame skip 16 (default: %(default)s; none: skip it)",
    )
    parser.add_argument(
        "--rounds", type=positive_int, default=20, help="PettingZoo rounds (default: %(default)s)"
    )
    parser.add_argument(
        "--steps", type=positive_int, default=MATCH_ROUND_STEPS, help="steps a round (default: %(default)s)"
    )
    parser.add_argument(
        "--profile", action="store_true", help="then a cProfile of game_match's steps: top costs"
    )
    parser.set_defaults(func=_bench_game)


def _bench_game(args: argparse.Namespace) -> int:
    cpu = bench.pin_to_one_core()
    if not args.json:
        print(f"game bench on {f'CPU {cpu}' if cpu is not None else 'one thread'}, best of several runs")
    clock = time.thread_time if args.cpu_time else time.perf_counter
    bench.print_results(game_results(args.sizes, args.rounds, clock, args.steps), args.json)
    if args.profile:
        print("\n".join(match_profile()), flush=True)
    return 0
