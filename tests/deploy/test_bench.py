"""``hier-ssl bench deploy``'s rows, on a short run each: latency through 127.0.0.1 and a task row
through the wire against the same manager played directly."""

from __future__ import annotations

from hier_ssl.cli import build_parser
from hier_ssl.deploy.bench import latency_row, task_row
from hier_ssl.deploy.loop import PRIORITY


def test_a_latency_row_times_frames_to_commands() -> None:
    row = latency_row("direct", "direct", 1, seconds=2.0)
    assert row["samples"] > 10  # after the first second's ticks
    assert 0 < row["p50_ms"] <= row["p99_ms"] < 1000
    assert row["scheduling"].startswith(("fifo 10", "time-shared (not permitted"))


def test_a_task_row_compares_the_wire_with_the_direct_loop() -> None:
    row = task_row("direct", "direct", "proposed", episodes=1, seed=2)
    assert row["wire_success"] == row["eval_success"] == 1.0  # nothing to hit on the Proposed task
    assert row["success_gap_points"] == 0.0
    assert abs(row["wire_median_length"] - row["eval_median_length"]) < 0.5 * row["eval_median_length"]


def test_the_bench_command_takes_its_options() -> None:
    args = build_parser().parse_args(["bench", "deploy", "--json", "--episodes", "3", "--seconds", "2"])
    assert (args.json, args.episodes, args.seconds, args.run) == (True, 3, 2.0, None)
    assert args.priority == PRIORITY
