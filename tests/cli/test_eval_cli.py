from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from matplotlib.image import imread

from hier_ssl import cli
from hier_ssl.config import EnvConfig, ObstacleConfig, TrainConfig, dump_config
from hier_ssl.envs import HierarchicalCore, task_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.evaluation.compare import compare, load_manager, manager_env
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.evaluation.report import RECORD_KEYS
from hier_ssl.policies.networks import SquashedGaussianActor
from hier_ssl.policies.sac import SACConfig

STATS = {"median", "q1", "q3", "min", "max"}


def _sac_run(run_dir: Path, **env: object) -> Path:
    """A run directory as ``hier-ssl train`` leaves it, with a tiny untrained actor."""
    config = TrainConfig(name="tiny", env=EnvConfig(**env), sac=SACConfig(hidden=(8, 8)))
    run_dir.mkdir(parents=True)
    (run_dir / "config.yaml").write_text(dump_config(config))
    obs_dim = 13 + 5 * len(config.env.obstacles)
    actor = SquashedGaussianActor(obs_dim, 4, (8, 8))
    torch.save({"actor": actor.state_dict(), "step": 0}, run_dir / "best_actor.pt")
    return run_dir


def test_eval_writes_json_tables_and_figure(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out, report = tmp_path / "eval", tmp_path / "records.json"
    argv = ["eval", "direct", "sampling", "--task", "obstacle", "--episodes", "20", "--seed", "3"]
    assert cli.main([*argv, "--json", str(report), "--out", str(out)]) == 0
    records = json.loads(report.read_text())
    assert [r["manager"] for r in records] == ["direct", "sampling"]
    for record in records:
        assert set(RECORD_KEYS) <= set(record)
        assert record["task"] == "obstacle" and record["worker"] == "paper" and record["episodes"] == 20
        assert set(record["episode_length"]) == STATS and set(record["cpad"]) == STATS
        assert 0 <= record["collision_rate"] <= 1 and record["eval_wall_s"] > 0
    assert records[0]["collision_rate"] > records[1]["collision_rate"]
    printed = capsys.readouterr().out
    assert (
        "| direct | paper |" in printed and "eval wall time sampling (paper worker, frame skip 16)" in printed
    )
    for name in ("table.md", "table.csv", "table.tex"):
        assert (out / name).is_file()
    image = imread(out / "fig3.png")
    assert image.ndim == 3 and image.std() > 0.05  # not blank


def test_eval_of_a_run_directory_with_two_workers(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = _sac_run(tmp_path / "tiny-run", task="proposed", frame_skip=16)
    argv = ["eval", str(run), "direct", "--episodes", "3", "--worker", "paper", "--worker", "bangbang"]
    assert cli.main([*argv, "--out", str(tmp_path / "eval"), "--json", str(tmp_path / "r.json")]) == 0
    printed = capsys.readouterr().out
    assert "| tiny-run | paper |" in printed and "| direct | bangbang |" in printed
    records = json.loads((tmp_path / "r.json").read_text(), parse_constant=lambda c: pytest.fail(c))
    assert [(r["manager"], r["worker"]) for r in records][1:3] == [
        ("tiny-run", "bangbang"),
        ("direct", "paper"),
    ]
    untrained = records[0]
    assert untrained["success_rate"] > 0 or untrained["optimal_ratio_median"] is None  # NaN as null


def test_eval_video(tmp_path: Path) -> None:
    assert cli.main(["eval", "direct", "--episodes", "2", "--out", str(tmp_path), "--video"]) == 0
    assert (tmp_path / "episode.gif").read_bytes()[:6] == b"GIF89a"


def test_manager_env_keeps_a_runs_settings_unless_overridden(tmp_path: Path) -> None:
    run = _sac_run(tmp_path / "run", task="proposed", frame_skip=4, worker="bangbang")
    assert (manager_env(run).frame_skip, manager_env(run).worker) == (4, "bangbang")
    assert manager_env(run, frame_skip=16, worker="paper").frame_skip == 16
    planner_env = manager_env("sampling", task="obstacle")
    assert planner_env.frame_skip == 16 and len(planner_env.obstacles) == 1
    policy = load_manager(run, manager_env(run))
    assert policy(torch.zeros(5, 13).numpy()).shape == (5, 4)


def test_eval_takes_a_planner_with_settings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["eval", "sampling+trapped=brake", "--task", "obstacle", "--episodes", "4", "--no-progress"]
    assert cli.main([*argv, "--out", str(tmp_path / "out")]) == 0
    assert "| sampling+trapped=brake | paper |" in capsys.readouterr().out


def test_eval_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    run = _sac_run(tmp_path / "run", task="proposed")
    cases = [
        (["eval", "astar"], "neither a planner (direct, sampling, trajectory) nor a run directory"),
        (["eval", str(run), "--task", "obstacle"], "trained with observations/actions of size (13, 4)"),
        (["eval", str(tmp_path)], "no config.yaml"),
        (["eval", "sampling+brake=1"], "planner 'sampling+brake=1': sampling has no setting 'brake'"),
    ]
    for argv, message in cases:
        assert cli.main([*argv, "--episodes", "2", "--out", str(tmp_path / "out")]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and message in err and "Traceback" not in err, err
    with pytest.raises(SystemExit):
        cli.main(["eval", "direct", "--worker", "pid"])


def test_planners_play_the_episodes_of_the_run_they_are_compared_with(tmp_path: Path) -> None:
    """A paper-family Obstacle run (starts 0.2 m from the target, not the task default's 0.6): without
    --scenario or --set, the planners beside it meet its starts, targets and obstacle draws."""
    obstacles = [ObstacleConfig(behaviour="public_code", placement="midpoint")]
    run = _sac_run(
        tmp_path / "paper-obstacle",
        task="obstacle",
        obstacles=obstacles,
        min_start_distance=0.2,
        allow_start_contact=True,
        frame_skip=16,
    )
    evaluations = compare([run, "sampling", "direct"], episodes=2, seed=1)
    cores = [HierarchicalCore(e.env, 1000, autoreset=False) for e in evaluations]
    for core in cores:
        core.reset(seed=1)
        for _ in range(5):  # robots hold still at their starts; obstacles move by their draws
            core.control_step(core.active.copy())
    for core in cores[1:]:
        assert core.config.min_start_distance == 0.2
        np.testing.assert_array_equal(core.target, cores[0].target)
        np.testing.assert_array_equal(core.state.pos, cores[0].state.pos)
        assert core.rng.bit_generator.state == cores[0].rng.bit_generator.state


def test_a_planner_beside_a_target_frame_task_acts_in_the_field_frame() -> None:
    """The target frame's sub-goals reach half the field's length from the target: a planner acting in it
    had its far sub-goals clipped (crowd, 1000 episodes: `sampling` 97.4 % against 99.0 %)."""
    target = task_config("crowd", frame_skip=16).model_copy(update={"action_frame": "target"})
    field = target.model_copy(update={"action_frame": "field"})
    (compared,) = compare(["sampling"], target, episodes=12, seed=7)
    assert compared.env.action_frame == "field"
    played = {
        frame: evaluate(make_planner("sampling", config), config, 12, seed=7)["per_robot"]["length"]
        for frame, config in (("field", field), ("target", target))
    }
    np.testing.assert_array_equal(compared.result["per_robot"]["length"], played["field"])
    assert not np.array_equal(played["field"], played["target"])  # the clip changes the paths
