from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.image import imread

from hier_ssl import cli
from hier_ssl.cli import bench
from hier_ssl.cli.demo import run_demo


def test_demo_writes_a_png_of_the_paths(tmp_path: object) -> None:
    result = run_demo(tmp_path / "figs" / "demo.png", seed=1, worker="bangbang", targets=2, size=(330, 230))
    assert result.path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    image = imread(result.path)
    assert image.shape[:2] == (230, 330) and np.ptp(image) > 0
    assert result.reached == 2 and result.targets == 2 and 0 < result.steps <= 2 * 400


def test_demo_command_prints_where_it_wrote(tmp_path: object, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "demo.png"
    assert cli.main(["demo", "--out", str(out), "--targets", "1", "--worker", "paper"]) == 0
    assert out.is_file()
    assert capsys.readouterr().out.startswith(f"wrote {out} (paper worker: 1/1 targets reached")


def test_bench_world_json_lines_parse(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # Pinning would tie the rest of the test session to one core.
    monkeypatch.setattr(bench, "pin_to_one_core", lambda: None)
    assert cli.main(["bench", "world", "--json", "--steps", "2"]) == 0
    lines = capsys.readouterr().out.splitlines()
    records = [json.loads(line) for line in lines]
    assert [r["n_fields"] for r in records] == list(bench.WORLD_SIZES)
    for record in records:
        assert set(record) == {"bench", "n_fields", "robots_per_field", "steps_per_s"}
        assert record["bench"] == "world" and record["robots_per_field"] == 2 and record["steps_per_s"] > 0


def test_bench_world_text_output(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(bench, "WORLD_SIZES", (1, 4))
    monkeypatch.setattr(bench, "pin_to_one_core", lambda: None)
    assert cli.main(["bench", "world", "--steps", "3", "--cpu-time"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert len(lines) == 3 and "field-steps/s" in lines[1] and "N =     4" in lines[2]


def test_errors_are_one_line_without_traceback(tmp_path: object, capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["demo", "--out", str(tmp_path / "demo.txt")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "error: out must be a .png path" in err and "Traceback" not in err

    for argv in (["bench", "fields"], ["demo", "--worker", "pid"], ["demo", "--targets", "0"], []):
        with pytest.raises(SystemExit) as exit_info:
            cli.main(argv)
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "error:" in err, argv


def test_bench_env_and_vector_json_lines_parse(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setattr(bench, "pin_to_one_core", lambda: None)
    # Short runs; build_s is measured in a fresh interpreter as in the real command.
    env, vector = bench.bench_env, bench.bench_vector
    monkeypatch.setattr(bench, "bench_env", lambda fs, clock: env(fs, decisions=3, repeats=1, clock=clock))
    monkeypatch.setattr(
        bench, "bench_vector", lambda task, n, clock: vector(task, 2, decisions=2, repeats=1, clock=clock)
    )
    monkeypatch.setattr(bench, "build_seconds", lambda task, frame_skip: 0.5)
    assert cli.main(["bench", "env", "--json"]) == 0
    assert cli.main(["bench", "vector", "--json", "--cpu-time"]) == 0
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["bench"], r["task"], r["frame_skip"]) for r in records] == [
        ("env", "proposed", 1),
        ("env", "proposed", 16),
        ("vector", "proposed", 16),
        ("vector", "formation", 16),
    ]
    common = {"bench", "n_fields", "robots_per_field", "steps_per_s", "task", "frame_skip", "decisions_per_s"}
    for record in records:
        vector = {"physics_share", "memory_kb_per_field"}
        assert set(record) == common | ({"build_s"} if record["bench"] == "env" else vector)
        assert record["steps_per_s"] > 0 and record["decisions_per_s"] > 0
    assert [r["robots_per_field"] for r in records] == [1, 1, 1, 12]
    # At frame skip 1 a decision is one control step.
    assert records[0]["steps_per_s"] == records[0]["decisions_per_s"]
    assert 0 < records[3]["physics_share"] < 1


def test_build_seconds_times_a_fresh_interpreter() -> None:
    seconds = bench.build_seconds("proposed", 1, repeats=1)
    assert 0 < seconds < 60


def test_bench_rejects_bad_sizes() -> None:
    with pytest.raises(ValueError, match="n_fields must be an integer >= 1, got 0"):
        bench.bench_world(0)
    with pytest.raises(ValueError, match="steps must be an integer >= 1, got 0"):
        bench.bench_world(1, steps=0)


def test_render_draws_one_scenario_episode_and_names_a_bad_file_type(
    tmp_path: object, capsys: pytest.CaptureFixture[str]
) -> None:
    gif = tmp_path / "crossing.gif"
    assert cli.main(["render", "crossing", "--set", "num_agents=2", "--out", str(gif)]) == 0
    assert gif.read_bytes()[:6] == b"GIF89a" and capsys.readouterr().out.startswith(f"wrote {gif}: sampling")
    png = tmp_path / "obstacle.png"  # a paper task renders through the same loop
    assert cli.main(["render", "obstacle", "--manager", "direct", "--out", str(png)]) == 0
    assert png.read_bytes()[:4] == b"\x89PNG" and capsys.readouterr().out.startswith(f"wrote {png}: direct")
    assert cli.main(["render", "crossing", "--out", str(tmp_path / "crossing.mp4")]) == 1
    assert "crossing.mp4" in capsys.readouterr().err and not (tmp_path / "crossing.mp4").exists()
    assert cli.main(["render", "crosing", "--out", str(gif)]) == 1
    known = "known: ['crossing', 'crowd', 'formation', 'game_ball_placement', 'game_free_kick', 'game_match'"
    assert f"unknown scenario 'crosing'; {known}" in capsys.readouterr().err
    assert cli.main(["eval", "direct", "--scenario", "crossing", "--set", "config=3"]) == 1
    assert "scenario.config: Extra inputs are not permitted" in capsys.readouterr().err
