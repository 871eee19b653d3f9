"""Every script under benchmarks/ runs, in a tiny form: the maintained ones are these, and a script that no
test runs is an investigation to retire (docs/research-notes.md, "Retired investigation scripts")."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hier_ssl.envs import parse_config
from hier_ssl.runs.train import train

ROOT = Path(__file__).parents[1]
SCRIPTS = {
    "collect_threads.py",
    "export_latency.py",
    "front_page_gif.py",
    "planner_latency.py",
    "sac_device.py",
    "sac_update.py",
    "team_decision.py",
}


def _run(script: str, *args: str, cwd: Path) -> list[str]:
    """The script's printed lines; it must exit 0."""
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / script), *args],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


def test_benchmarks_holds_only_the_maintained_scripts() -> None:
    assert {p.name for p in (ROOT / "benchmarks").glob("*.py")} == SCRIPTS


def test_collect_threads_times_every_pair_of_core_and_torch_thread_counts(tmp_path: Path) -> None:
    args = ("--fields", "70", "--cores", "2", "--rounds", "1", "--steps", "2")
    lines = _run("collect_threads.py", *args, cwd=tmp_path)
    assert lines[0].startswith("obstacle/ppo_frame_skip: 70 fields") and len(lines) == 1 + 2 * 2
    assert all(" best " in line and line.endswith(" s") for line in lines[1:])


def test_planner_latency(tmp_path: Path) -> None:
    lines = _run("planner_latency.py", "--task", "obstacle", "--episodes", "1", "--calls", "5", cwd=tmp_path)
    assert lines[0].startswith("obstacle: ") and "5 timed at batch 1" in lines[0]
    assert [line.split()[0] for line in lines[1:]] == ["direct", "sampling", "trajectory"]


def test_sac_update_and_sac_device(tmp_path: Path) -> None:
    (line,) = _run("sac_update.py", "--updates", "3", "--repeats", "2", "--threads", "1", cwd=tmp_path)
    assert " ms per update best, " in line and "batch 256" in line
    args = ("--devices", "cpu", "cuda", "--updates", "3", "--steps", "3")
    rows = [
        line.split(" | ")[0] for line in _run("sac_device.py", *args, cwd=tmp_path) if line.startswith("| ")
    ]
    assert rows[:2] == ["| learner", "| cpu"] and len(rows) == 3  # cuda: timed, or said to be skipped


def test_export_latency_on_a_tiny_run(tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime")
    config = parse_config(
        {
            "env": {"task": "obstacle", "frame_skip": 16, "max_steps": 160},
            "num_envs": 4,
            "total_steps": 100,
            "eval_interval": 100,
            "eval_episodes": 2,
            "sac": {"hidden": [16, 16], "learning_starts": 200, "batch_size": 32},
        }
    )
    train(config, tmp_path / "run", progress=False)
    lines = _run("export_latency.py", str(tmp_path / "run"), "--calls", "5", cwd=tmp_path)
    timed = [line.split()[0] for line in lines[1:]]
    assert timed == ["torchscript", "onnxruntime", "python", "sampling"]


def test_front_page_gif_with_a_planner_in_the_runs_place(tmp_path: Path) -> None:
    out = tmp_path / "front.gif"
    (line,) = _run("front_page_gif.py", "sampling", "--episodes", "8", "--out", str(out), cwd=tmp_path)
    assert line.startswith(f"wrote {out}: episode ") and out.read_bytes()[:6] == b"GIF89a"


def test_team_decision(tmp_path: Path) -> None:
    lines = _run("team_decision.py", "--states", "1", "--warmup", "1", cwd=tmp_path)
    assert lines[0].startswith("division_a, STOP, a team of 11 per call")
    rows = [line.split()[:2] for line in lines[1:]]
    assert rows == [[p, r] for p in ("direct", "sampling", "trajectory") for r in ("none", "rules")]
