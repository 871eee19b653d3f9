from __future__ import annotations

import json
import time

import pytest

from hier_ssl import cli
from hier_ssl.cli import bench, game_bench, look, side_by_side
from hier_ssl.envs import shards


@pytest.fixture(autouse=True)
def _quick(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bench, "pin_to_one_core", lambda: None)
    monkeypatch.setattr(bench, "build_seconds", lambda task, frame_skip, **settings: 0.5)


def test_vector_sweep_gives_each_task_at_each_size_against_the_smallest(
    capsys: pytest.CaptureFixture[str],
) -> None:
    argv = ["bench", "vector", "--json", "--sizes", "3", "2", "--tasks", "obstacle", "crossing"]
    assert cli.main([*argv, "--frame-skip", "2"]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["task"], r["n_fields"], r["frame_skip"]) for r in records] == [
        ("obstacle", 2, 2),
        ("obstacle", 3, 2),
        ("crossing", 2, 2),
        ("crossing", 3, 2),
    ]
    assert [r["per_field_vs_smallest"] for r in records[::2]] == [1.0, 1.0]
    for record in records:
        assert record["steps_per_s"] > 0 and record["per_field_vs_smallest"] > 0
        assert record["memory_kb_per_field"] is None or record["memory_kb_per_field"] >= 0


def test_resident_bytes_grow_with_what_the_process_holds() -> None:
    before = bench.resident_bytes()
    if before is None:
        pytest.skip("no /proc here")
    held = bytearray(64 << 20)
    held[::4096] = b"\1" * len(held[::4096])  # touch every page
    assert bench.resident_bytes() - before >= 60 << 20


def test_compare_without_vmas_prints_hier_ssl_alone(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(side_by_side, "vmas_installed", lambda: False)
    assert cli.main(["bench", "compare", "--sizes", "2", "--rounds", "1", "--steps", "3"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "VMAS not installed" in lines[0] and len(lines) == 1 + 2 + len(side_by_side.PAIRS)
    assert not any("VMAS " in line for line in lines[1:])
    assert cli.main(["bench", "compare", "--json", "--sizes", "2", "--rounds", "1", "--steps", "3"]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["bench"], r["task"]) for r in records] == [("env", "proposed"), ("env", "obstacle")] + [
        ("compare", task) for task, _, _ in side_by_side.PAIRS
    ]
    for record in records[2:]:
        assert record["sim_s_per_s"] == pytest.approx(record["steps_per_s"] * side_by_side.HIER_DT, abs=0.1)
        assert "vmas_steps_per_s" not in record


def test_compare_on_several_core_counts_alternates_them_on_the_wall_clock(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(side_by_side, "vmas_installed", lambda: False)
    monkeypatch.setattr(side_by_side, "PAIRS", side_by_side.PAIRS[:1])
    monkeypatch.setattr(shards, "SHARD_BLOCKS", 1)  # 70 fields: two shards of a block, so two cores
    cores = []

    class Counted(bench.VectorRun):
        def __post_init__(self) -> None:
            super().__post_init__()
            cores.append(self.core.threads)

    monkeypatch.setattr(side_by_side, "VectorRun", Counted)
    argv = [
        "bench",
        "compare",
        "--json",
        "--sizes",
        "70",
        "--rounds",
        "1",
        "--steps",
        "3",
        "--threads",
        "1",
        "2",
    ]
    assert cli.main(argv) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()][-2:]
    assert [(r["task"], r["threads"]) for r in records] == [("obstacle", 1), ("obstacle", 2)]
    assert cores == [1, 2] and records[0]["speedup"] == 1.0 and records[1]["speedup"] > 0
    with pytest.raises(SystemExit, match="--cpu-time counts this thread alone"):
        cli.main([*argv, "--cpu-time"])


def test_vector_scaling_runs_each_core_count_up_to_this_process_cores(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(look, "resolve_threads", lambda threads: 2)
    argv = ["bench", "vector", "--json", "--sizes", "70", "--tasks", "obstacle", "--frame-skip", "2"]
    assert cli.main([*argv, "--rounds", "1", "--threads"]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["task"], r["n_fields"], r["threads"]) for r in records] == [
        ("obstacle", 70, 1),
        ("obstacle", 70, 2),
    ]
    assert records[0]["speedup"] == 1.0 and all(r["steps_per_s"] > 0 for r in records)


def test_compare_beside_vmas_gives_both_sides_and_their_ratios() -> None:
    pytest.importorskip("vmas")
    (record,) = side_by_side.compare_pair(
        "obstacle", "navigation", {"n_agents": 2}, 2, 2, time.perf_counter, 3
    )
    assert record["vmas"] == "navigation n_agents=2" and record["robots_per_field"] == 2
    ratio = record["steps_per_s"] / record["vmas_steps_per_s"]
    assert record["ratio_per_step"] == pytest.approx(ratio, rel=1e-2)
    assert record["ratio_per_sim_s"] == pytest.approx(ratio * 0.25, rel=1e-2)
    line = side_by_side.describe(record)
    assert "VMAS navigation n_agents=2" in line and "per simulated second" in line


def test_compare_times_the_game_pair_by_name(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(side_by_side, "vmas_installed", lambda: False)
    argv = ["bench", "compare", "--json", "--sizes", "2", "--rounds", "1", "--steps", "3"]
    assert cli.main([*argv, "--tasks", "game_stop"]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["bench"], r["task"]) for r in records[2:]] == [("compare", "game_stop")]
    assert records[2]["robots_per_field"] == 12
    assert cli.main([*argv, "--tasks", "crowd"]) == 1
    assert "no VMAS pair for ['crowd']" in capsys.readouterr().err


def test_bench_game_gives_the_match_then_game_stop_per_field(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["bench", "game", "--json", "--sizes", "2", "1", "--rounds", "2", "--steps", "3"]
    assert cli.main(argv) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    match = records[0]
    assert (match["task"], match["frame_skip"], match["decide_every"], match["robots_per_field"]) == (
        "game_match",
        1,
        16,
        22,
    )
    assert match["steps_per_s"] >= match["median_steps_per_s"] > 0
    assert [(r["task"], r["n_fields"]) for r in records[1:]] == [("game_stop", 1), ("game_stop", 2)]
    lines = game_bench.match_profile(steps=4, rows=3)
    assert lines[0].startswith("game_match, 4 steps under cProfile: ") and len(lines) == 4
    assert all(" us " in line and " calls " in line for line in lines[1:])
