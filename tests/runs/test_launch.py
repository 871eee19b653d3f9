"""hier_ssl.runs.launch, hier_ssl.runs.sweep and hier_ssl.runs.ray_tune: runs in turn, as processes, and as
Ray Tune trials on a real Ray instance started here (2 CPUs, loopback only)."""

from __future__ import annotations

import csv
import json
import os
import sys
from pathlib import Path

import pytest
import torch
import yaml

# Before anything imports ray: a Ray started here keeps every address on 127.0.0.1.
os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"

from hier_ssl.cli import main  # noqa: E402
from hier_ssl.config import ConfigError  # noqa: E402
from hier_ssl.config.launch_options import LaunchOptions  # noqa: E402
from hier_ssl.envs import parse_config  # noqa: E402
from hier_ssl.policies.sac_runner import MODEL_FILE, REPLAY_FILE  # noqa: E402
from hier_ssl.runs.jobs import EXIT_MARKER, EXIT_ONCE_ENV, Job, run_state  # noqa: E402
from hier_ssl.runs.launch import RunFailed, launch  # noqa: E402
from hier_ssl.runs.ray_tune import LOOPBACK, LOOPBACK_ENV, connect, import_ray  # noqa: E402
from hier_ssl.runs.sweep import parse_grid, sweep  # noqa: E402
from hier_ssl.runs.train import train  # noqa: E402

TINY = {
    "name": "tiny",
    "env": {"task": "proposed", "frame_skip": 16},
    "num_envs": 4,
    "total_steps": 60,
    "eval_interval": 20,
    "save_interval": 20,
    "eval_episodes": 4,
    "sac": {"caps": True, "hidden": [16, 16], "learning_starts": 64, "batch_size": 32},
}
KILLED = "killed-s0"  # the run whose process the Ray instance's workers hard-exit once, at step 40


def _steps(run_dir: Path) -> list[int]:
    return [int(row["step"]) for row in csv.DictReader((run_dir / "curve.csv").open())]


def _without_times(run_dir: Path) -> tuple[str, list[dict]]:
    """eval.json and curve.csv with the wall-time figures removed (as text: NaN == NaN)."""
    summary = json.loads((run_dir / "eval.json").read_text())
    del summary["train_wall_s"]
    curve = [
        {k: v for k, v in row.items() if k != "train_time_s"}
        for row in csv.DictReader(open(run_dir / "curve.csv"))
    ]
    return json.dumps(summary, sort_keys=True), curve


def test_grid_values_split_on_top_level_commas_only() -> None:
    grid = parse_grid(["sac.gamma=0.9,0.95", "sac.hidden=[8, 8],[16,16]"])
    assert grid == {"sac.gamma": ["0.9", "0.95"], "sac.hidden": ["[8, 8]", "[16,16]"]}
    for bad in ("sac.gamma", "sac.gamma=0.9,", "=1"):
        with pytest.raises(ConfigError, match="--grid"):
            parse_grid([bad])


def test_processes_run_at_once_and_a_dead_one_resumes_on_the_next_launch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    jobs = [Job(parse_config({**TINY, "name": name}), tmp_path / name) for name in ("a-s0", KILLED)]
    monkeypatch.setenv(EXIT_ONCE_ENV, f"{KILLED}@40")  # the spawned processes inherit it
    with pytest.raises(RunFailed, match=f"1 of 2 runs failed: {KILLED}: its process exited with status 17"):
        launch(jobs, LaunchOptions(jobs=2), progress=False)
    killed = tmp_path / KILLED
    assert run_state(tmp_path / "a-s0") == "finished" and run_state(killed) == "resumable"
    assert torch.load(killed / MODEL_FILE, weights_only=True)["step"] == 20  # saved after the step-20 row

    launch(jobs, LaunchOptions(jobs=2), progress=False)
    assert run_state(killed) == "finished" and (killed / EXIT_MARKER).is_file()
    assert torch.load(killed / MODEL_FILE, weights_only=True)["step"] == 60
    assert len(torch.load(killed / REPLAY_FILE, weights_only=True)["obs"]) == 60 * TINY["num_envs"]
    # Resumed from step 20: the row of step 40 was written before the exit and again after the resume.
    assert _steps(killed) == [20, 40, 40, 60]


def test_a_run_directory_of_another_config_is_refused(tmp_path: Path) -> None:
    run = tmp_path / "tiny-s0"
    run.mkdir()
    (run / "config.yaml").write_text(yaml.safe_dump({**TINY, "total_steps": 40}))
    with pytest.raises(ConfigError, match="total_steps=40, this command asks for 60"):
        launch([Job(parse_config(TINY), run)], progress=False)
    assert sorted(p.name for p in run.iterdir()) == ["config.yaml"]


def test_ray_flag_without_ray_installed_is_one_line_naming_the_extra(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump(TINY))
    monkeypatch.setitem(sys.modules, "ray", None)  # what `import ray` meets where it is not installed
    out = tmp_path / "sweep"
    assert main(["sweep", str(config), "--grid", "seed=0,1", "--out", str(out), "--ray"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and 'pip install -e ".[ray]"' in err
    assert not (out / "runs").exists()


def test_a_local_ray_is_started_on_loopback_only(monkeypatch: pytest.MonkeyPatch) -> None:
    started: list[dict] = []
    fake = type(sys)("ray")
    fake.is_initialized = lambda: False
    fake.init = lambda **kwargs: started.append(kwargs)
    monkeypatch.setitem(sys.modules, "ray", fake)
    monkeypatch.setitem(sys.modules, "ray.tune", type(sys)("ray.tune"))
    monkeypatch.setenv(LOOPBACK_ENV, "1")
    assert connect(import_ray("local"), "local")
    assert started[0]["_node_ip_address"] == "127.0.0.1" and os.environ[LOOPBACK_ENV] == "0"


def test_asha_needs_ray() -> None:
    with pytest.raises(ValueError, match="--asha"):
        LaunchOptions(asha=True)


# -- on a real Ray instance -------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def ray_instance():
    ray = pytest.importorskip("ray", reason='Ray is not installed (pip install -e ".[ray]")')
    pytest.importorskip("ray.tune", reason='Ray Tune is not installed (pip install -e ".[ray]")')
    ray.init(
        num_cpus=2,
        _node_ip_address=LOOPBACK,
        include_dashboard=False,
        object_store_memory=100 * 2**20,
        runtime_env={"env_vars": {EXIT_ONCE_ENV: f"{KILLED}@40"}},
    )
    try:
        yield ray
    finally:
        ray.shutdown()


def test_ray_listens_on_loopback_only(ray_instance) -> None:
    nodes = ray_instance.nodes()
    assert nodes and all(node["NodeManagerAddress"] == "127.0.0.1" for node in nodes)


def test_a_sweep_on_ray_writes_its_table_with_the_figures_of_a_local_run(
    ray_instance, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config, out = tmp_path / "tiny.yaml", tmp_path / "sweep"
    config.write_text(yaml.safe_dump(TINY))
    args = ["sweep", str(config), "--grid", "sac.gamma=0.9,0.95", "--out", str(out), "--no-progress"]
    assert main([*args, "--ray", "auto"]) == 0, capsys.readouterr().err
    rows = list(csv.DictReader((out / "sweep.csv").open()))
    assert [(r["run"], r["status"]) for r in rows] == [
        ("tiny-sac.gamma=0.9-s0", "finished"),
        ("tiny-sac.gamma=0.95-s0", "finished"),
    ]
    assert all(r["success %"] != "" and r["CPAD median m"] != "" for r in rows)
    assert "| tiny-sac.gamma=0.9-s0 | 0.9 | 0 | finished |" in (out / "sweep.md").read_text()

    # The same config and seed trained here, in this process, gives the same numbers to the last digit.
    local = tmp_path / "local"
    train(parse_config({**TINY, "sac": {**TINY["sac"], "gamma": 0.9}}), local, progress=False)
    on_ray = out / "runs" / "tiny-sac.gamma=0.9-s0"
    assert _without_times(on_ray) == _without_times(local)
    actors = [torch.load(d / MODEL_FILE, weights_only=True)["sac"]["actor"] for d in (on_ray, local)]
    assert all(torch.equal(actors[0][k], actors[1][k]) for k in actors[0])


def test_asha_stops_the_weaker_trial_and_reruns_skip_it(ray_instance, tmp_path: Path) -> None:
    # A 10 m success radius (any heading, any speed) succeeds at once; 5 cm does not within 20 steps.
    config = tmp_path / "tiny.yaml"
    config.write_text(yaml.safe_dump({**TINY, "env": {**TINY["env"], "theta_th_deg": 180, "speed_th": 10}}))
    grid = parse_grid(["env.d_th=10,0.05"])
    options = LaunchOptions(ray="auto", jobs=1, asha=True)  # one at a time: the strong trial sets the bar
    sweep(config, grid, out=tmp_path, launch_options=options, progress=False)
    weak = tmp_path / "runs" / "tiny-env.d_th=0.05-s0"
    assert run_state(tmp_path / "runs" / "tiny-env.d_th=10-s0") == "finished"
    assert run_state(weak) == "stopped" and _steps(weak) == [20]
    rows = list(csv.DictReader((tmp_path / "sweep.csv").open()))
    assert (
        rows[1]["status"].startswith("stopped at step 20 (selection success") and rows[1]["success %"] == ""
    )
    sweep(config, grid, out=tmp_path, launch_options=options, progress=False)
    assert _steps(weak) == [20]


def test_a_trial_whose_process_dies_is_retried_by_tune_and_resumes(ray_instance, tmp_path: Path) -> None:
    run = tmp_path / "runs" / KILLED
    launch(
        [Job(parse_config(TINY), run)], LaunchOptions(ray="auto"), progress=False, tune_dir=tmp_path / "tune"
    )
    assert (run / EXIT_MARKER).is_file()  # the first attempt did die
    assert torch.load(run / MODEL_FILE, weights_only=True)["step"] == 60
    assert len(torch.load(run / REPLAY_FILE, weights_only=True)["obs"]) == 60 * TINY["num_envs"]
    # The retry resumed from the step-20 checkpoint (a fresh start would have rewritten rows 20 and 40).
    assert _steps(run) == [20, 40, 40, 60]
    assert run_state(run) == "finished"


def test_a_run_started_under_another_description_is_the_same_run(tmp_path: Path) -> None:
    from hier_ssl.config import dump_config
    from hier_ssl.runs.launch import _check_same_config

    run = tmp_path / "run"
    run.mkdir()
    (run / "config.yaml").write_text(dump_config(parse_config(TINY)))
    _check_same_config(Job(parse_config({**TINY, "description": "now says what it trains"}), run))
    with pytest.raises(ConfigError, match="was started with seed=0"):
        _check_same_config(Job(parse_config({**TINY, "seed": 1}), run))
