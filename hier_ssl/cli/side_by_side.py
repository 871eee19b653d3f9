"""``hier-ssl bench compare``: hier_ssl's batched view beside VMAS's, timed in turns in one process.

Each pair has the same robots per field: ``obstacle`` (1 robot + 1 obstacle) beside VMAS ``navigation``
with 2 agents, ``formation`` (6 + 6) beside ``navigation`` with 6 (the issue's anchor; VMAS has no moving
obstacles), ``proposed`` (1 robot) beside ``simple``. Both take uniform random actions drawn beforehand;
hier_ssl resets finished episodes inside its step, VMAS (no auto-reset) runs on. Rounds alternate the
two, hier_ssl first, and each side's best round is kept. Rounds are many and short (40 of about 0.1 s by
default): on a shared machine a process's speed drifts over seconds, and a few long rounds let that drift
into the ratio (docs/guide/benchmarks.md has the runs that showed it). A control step is 0.025 s of
simulated time in hier_ssl and 0.1 s in VMAS: the ratios are given per control step and per simulated
second.

Without VMAS installed (``pip install hier_ssl[bench]``) only hier_ssl's figures are printed; the
PettingZoo view's steps per second at frame skip 1 are printed in both cases. With several counts of
``threads`` hier_ssl's view runs on each count of cores (``hier_ssl.envs.shards``; wall clock), the counts
and VMAS alternated round by round; VMAS keeps one torch thread, its best here (on two threads of this
busy 2-core machine it fell to a quarter or less: OpenMP threads waiting on each other's cores).
"""

from __future__ import annotations

import importlib.util
import json
from collections.abc import Iterator, Sequence
from typing import Any

from hier_ssl.cli.bench import Clock, VectorRun, bench_env

HIER_DT, VMAS_DT = 0.025, 0.1
# (hier_ssl task or scenario, VMAS scenario, VMAS options)
PAIRS = (
    ("obstacle", "navigation", {"n_agents": 2}),
    ("formation", "navigation", {"n_agents": 6}),
    ("proposed", "simple", {}),
)
PETTINGZOO_TASKS = ("proposed", "obstacle")
ROUND_ROBOT_STEPS = 50_000  # a round at N = 1024: 25 control steps of `obstacle`, about 0.1 s
PETTINGZOO_ROUND_STEPS = 500  # a PettingZoo round: about 25 ms


def vmas_installed() -> bool:
    return importlib.util.find_spec("vmas") is not None


class VmasRun:
    """A VMAS scenario over ``n_fields`` environments on the CPU, reset once; ``run(count)`` makes
    ``count`` steps of uniform random actions drawn beforehand and returns the seconds by ``clock``."""

    def __init__(
        self,
        scenario: str,
        n_fields: int,
        options: dict[str, Any],
        clock: Clock,
        seed: int = 0,
    ):
        # here, not at the top: VMAS is optional (the bench extra), and it loads torch
        import torch
        import vmas

        torch.set_num_threads(1)
        self.clock = clock
        self.env = vmas.make_env(
            scenario, num_envs=n_fields, device="cpu", continuous_actions=True, seed=seed, **options
        )
        self.env.reset()
        generator = torch.Generator().manual_seed(seed)
        sizes = [self.env.get_agent_action_size(agent) for agent in self.env.agents]
        self._pool = [
            [torch.rand(n_fields, size, generator=generator) * 2 - 1 for size in sizes] for _ in range(8)
        ]
        self.run(1)

    def run(self, count: int) -> float:
        start = self.clock()
        for i in range(count):
            self.env.step(self._pool[i % len(self._pool)])
        return self.clock() - start


def compare_pair(
    task: str,
    scenario: str,
    options: dict[str, Any],
    n_fields: int,
    rounds: int,
    clock: Clock,
    steps: int | None = None,
    threads: Sequence[int] = (1,),
) -> Iterator[dict[str, Any]]:
    """hier_ssl's ``task`` at frame skip 1 on each count of cores in ``threads`` and, if installed, VMAS's
    ``scenario`` over ``n_fields`` fields, ``rounds`` alternating rounds of ``steps`` control steps each
    (None: 50,000 robot-steps, about a tenth of a second): for each count, the best of each side in
    field-steps/s and simulated seconds per second, their ratios (hier_ssl over VMAS) and ``speedup``
    (over the first count)."""
    hier = {k: VectorRun(task, n_fields, 1, clock, threads=k) for k in threads}
    vmas_run = VmasRun(scenario, n_fields, options, clock) if vmas_installed() else None
    robots = hier[threads[0]].robots_per_field
    count = steps or max(5, round(ROUND_ROBOT_STEPS / (n_fields * robots)))
    best, best_vmas = dict.fromkeys(hier, 0.0), 0.0
    for _ in range(rounds):
        for k, run in hier.items():
            seconds, taken, _ = run.run(count)
            best[k] = max(best[k], n_fields * taken / seconds)
        if vmas_run is not None:
            best_vmas = max(best_vmas, n_fields * count / vmas_run.run(count))
    for run in hier.values():
        run.env.close()
    for k in hier:
        out = {
            "bench": "compare",
            "task": task,
            "n_fields": n_fields,
            "threads": k,
            "robots_per_field": robots,
            "steps_per_s": round(best[k], 1),
            "sim_s_per_s": round(best[k] * HIER_DT, 1),
            "speedup": round(best[k] / best[threads[0]], 3),
        }
        if vmas_run is not None:
            out |= {
                "vmas": scenario + "".join(f" {key}={v}" for key, v in options.items()),
                "vmas_steps_per_s": round(best_vmas, 1),
                "vmas_sim_s_per_s": round(best_vmas * VMAS_DT, 1),
                "ratio_per_step": round(best[k] / best_vmas, 3),
                "ratio_per_sim_s": round(best[k] * HIER_DT / (best_vmas * VMAS_DT), 3),
            }
        yield out


def comparisons(
    sizes: Sequence[int],
    rounds: int,
    clock: Clock,
    steps: int | None = None,
    threads: Sequence[int] = (1,),
) -> Iterator[dict[str, Any]]:
    """The PettingZoo view at frame skip 1 for ``PETTINGZOO_TASKS`` (``bench_env``, best of ``rounds``
    rounds of ``PETTINGZOO_ROUND_STEPS`` steps, or ``steps``), then every pair at every N (``compare_pair``,
    on each count of cores in ``threads``)."""
    for task in PETTINGZOO_TASKS:
        decisions = steps or PETTINGZOO_ROUND_STEPS
        result = bench_env(1, task, decisions=decisions, repeats=rounds, clock=clock)
        yield {"bench": "env", "task": task, "n_fields": 1, "steps_per_s": round(result.steps_per_s, 1)}
    for n in sizes:
        for task, scenario, options in PAIRS:
            yield from compare_pair(task, scenario, options, n, rounds, clock, steps, threads)


def describe(record: dict[str, Any]) -> str:
    """One line of text for a record of ``comparisons``."""
    line = f"  {record['task']:>9} N = {record['n_fields']:5d}: {record['steps_per_s']:12,.0f} field-steps/s"
    if "threads" in record:
        line += f" on {record['threads']} core(s) ({record['speedup']:.2f}x)"
    if "sim_s_per_s" in record:
        line += f" ({record['sim_s_per_s']:,.0f} sim s/s)"
    if "vmas" in record:
        line += (
            f" | VMAS {record['vmas']}: {record['vmas_steps_per_s']:,.0f} ({record['vmas_sim_s_per_s']:,.0f}"
            f" sim s/s) | ratio {record['ratio_per_step']:.2f} per step, {record['ratio_per_sim_s']:.2f}"
            " per simulated second"
        )
    return line


def print_comparisons(records: Iterator[dict[str, Any]], as_json: bool) -> None:
    for record in records:
        print(json.dumps(record) if as_json else describe(record), flush=True)
