from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from hier_ssl.envs import parse_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.manager import decode_subgoal
from hier_ssl.policies.actor import load_policy
from hier_ssl.policies.learner import Checkpoint
from hier_ssl.policies.networks import SquashedGaussianActor
from hier_ssl.policies.sac_runner import MODEL_FILE, REPLAY_FILE
from hier_ssl.runs import train as train_module
from hier_ssl.runs.train import EVALUATION_SEED, Selection, train

TINY = {
    "name": "tiny",
    "env": {"task": "proposed", "frame_skip": 16},
    "num_envs": 8,
    "total_steps": 1500,
    "eval_interval": 500,
    "eval_episodes": 20,
    "threads": 1,
    "sac": {"caps": True, "hidden": [64, 64], "learning_starts": 800, "batch_size": 128, "reward_scale": 0.1},
}


def _subgoal_error(actor: SquashedGaussianActor, seed: int = 99) -> float:
    """Median distance (m) between the first sub-goal and the target over 200 fresh episodes."""
    core = HierarchicalCore(parse_config(TINY).env, 200)
    obs = core.reset(seed)[:, 0]
    with torch.no_grad():
        action = actor.deterministic(torch.as_tensor(obs)).numpy()
    subgoal = decode_subgoal(action, "pose4", core.field.half_length, core.field.half_width)
    return float(np.median(np.linalg.norm(subgoal[:, :2] - core.target[:, 0, :2], axis=1)))


def test_sac_caps_learns_to_aim_sub_goals_at_the_target(tmp_path: Path) -> None:
    config = parse_config(TINY)
    summary = train(config, tmp_path, progress=False)
    actor = SquashedGaussianActor(13, 4, (64, 64))
    untrained = _subgoal_error(actor)
    actor.load_state_dict(torch.load(tmp_path / MODEL_FILE, weights_only=True)["sac"]["actor"])
    trained = _subgoal_error(actor)
    # An untrained actor names a point near the centre, ~2 m from a random target.
    assert untrained > 1.0
    assert trained < 0.4, (untrained, trained)
    for name in ("config.yaml", "eval.json", "curve.csv", "best_actor.pt", REPLAY_FILE):
        assert (tmp_path / name).is_file(), name
    keys = {
        "success_rate",
        "episode_length_median",
        "cpad_median",
        "collision_rate",
        "episodes",
        "train_wall_s",
    }
    saved = json.loads((tmp_path / "eval.json").read_text())
    assert keys <= set(saved)
    assert summary["episodes"] == 20
    # Both policies are evaluated on the same held-out episodes and labelled: the selection's best at the
    # top level, the one training ended with under "final"; each is what its checkpoint file plays.
    assert saved["policy"] == "best" and keys - {"episodes", "train_wall_s"} <= set(saved["final"])
    for which, figures in (("best", saved), ("final", saved["final"])):
        again = evaluate(load_policy(tmp_path, which=which), config.task_config, 20, EVALUATION_SEED)
        assert figures["success_rate"] == again["success_rate"], which
        assert figures["episode_length"] == again["episode_length"], which


def _cli(*args: str, **kwargs) -> subprocess.Popen:
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, "-m", "hier_ssl.cli", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        **kwargs,
    )


def test_killed_run_resumes_to_the_same_step_with_its_replay(tmp_path: Path) -> None:
    config = tmp_path / "tiny.yaml"
    config.write_text(
        json.dumps(
            {**TINY, "total_steps": 600, "save_interval": 100, "sac": {**TINY["sac"], "learning_starts": 200}}
        )
    )
    run = tmp_path / "run"
    proc = _cli("train", str(config), "--out", str(run), "--no-progress")
    deadline = time.time() + 120
    while not (run / MODEL_FILE).is_file() and time.time() < deadline:
        time.sleep(0.2)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    killed_at = torch.load(run / MODEL_FILE, weights_only=True)["step"]
    assert 0 < killed_at < 600
    assert not (run / "eval.json").exists()

    proc = _cli("train", "--resume", str(run), "--no-progress", "--no-planners")
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    model = torch.load(run / MODEL_FILE, weights_only=True)
    replay = torch.load(run / REPLAY_FILE, weights_only=True)
    assert model["step"] == 600
    # Every transition since the start is in the buffer: the replay survived the kill.
    assert len(replay["obs"]) == 600 * TINY["num_envs"]
    assert (run / "eval.json").is_file()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--set", "env.frame_skp=4"], "env.frame_skp"),
        (["--set", "sac.actor_lr=-0.1"], "sac.actor_lr"),
        (["--set", "env.field=moon"], "moon"),
    ],
)
def test_bad_config_is_one_line_and_writes_nothing(tmp_path: Path, args: list[str], message: str) -> None:
    out = tmp_path / "run"
    proc = _cli(
        "train", "configs/proposed/fscaps.yaml", "--out", str(out), *args, cwd=Path(__file__).parents[2]
    )
    _, err = proc.communicate(timeout=120)
    assert proc.returncode != 0
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_resume_without_checkpoint_names_the_file(tmp_path: Path) -> None:
    proc = _cli("train", "--resume", str(tmp_path))
    _, err = proc.communicate(timeout=120)
    assert proc.returncode != 0 and "config.yaml" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


SCENARIO = {
    "name": "tiny-crossing",
    "scenario": {"scenario": "crossing", "num_agents": 3, "max_steps": 160, "action_frame": "target"},
    "num_envs": 2,
    "total_steps": 60,
    "eval_interval": 30,
    "eval_episodes": 4,
    "threads": 1,
    "sac": {"caps": True, "hidden": [16, 16], "learning_starts": 96, "batch_size": 32},
}


def test_a_scenario_run_trains_a_shared_manager_and_evaluates_it_per_robot(tmp_path: Path) -> None:
    run = tmp_path / "run"
    summary = train(parse_config(SCENARIO), run, progress=False)
    assert summary["task"] == "crossing" and summary["robots"] == 4 * 3 and summary["episodes"] == 4
    assert 0.0 <= summary["field_success_rate"] <= summary["success_rate"] <= 1.0
    assert (run / "best_actor.pt").is_file() and len((run / "curve.csv").read_text().splitlines()) == 3
    # The run directory is a manager for `hier-ssl eval`, beside the planners, with per-robot figures.
    proc = _cli("eval", str(run), "direct", "--episodes", "3", "--out", str(tmp_path / "eval"))
    out, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert "scenario crossing (3 robots a field)" in out and (tmp_path / "eval" / "fig3.png").is_file()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"env": {"frame_skip": 4}}, "env: not read"),
        ({"algo": "ppo"}, "shared manager with SAC"),
        ({"scenario": {"scenario": "crossing", "num_agents": 12}}, "scenario.num_agents"),
    ],
)
def test_scenario_config_errors_name_the_key(change: dict[str, object], message: str) -> None:
    from hier_ssl.config import ConfigError

    with pytest.raises(ConfigError, match=message):
        parse_config({**SCENARIO, **change})


TINY_PPO = {
    "name": "tiny-ppo",
    "env": {"task": "proposed", "frame_skip": 16},
    "algo": "ppo",
    "num_envs": 8,
    "eval_episodes": 10,
    "threads": 1,
    "ppo": {"hidden": [16, 16]},
}


def test_a_ppo_run_keeps_its_best_policy_by_the_selection_curve(tmp_path: Path) -> None:
    from hier_ssl.checkpoints.actor import load_actor

    # 4 iterations of 16 steps; a checkpoint, and a score, every 2 iterations.
    config = {**TINY_PPO, "total_steps": 64, "eval_interval": 32}
    run = tmp_path / "run"
    summary = train(parse_config(config), run, progress=False)
    rows = (run / "curve.csv").read_text().splitlines()
    steps = [int(row.split(",")[0]) for row in rows[1:]]
    assert steps == [16, 48, 64]  # after iteration 1, 3 and the last (rsl-rl saves at 0, 2 and the end)
    assert (run / "best_actor.pt").is_file() and summary["episodes"] == 10
    actor, _ = load_actor(run)
    assert actor(torch.zeros(3, 13)).shape == (3, 4)


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"env": {"success_weight": float("inf")}}, "env.success_weight: Input should be a finite number"),
        ({"env": {"worker": "nope"}}, "env.worker: unknown worker 'nope'"),
        ({"scenario": {"scenario": ["crossing"]}}, "scenario.scenario: unknown scenario"),
        ({"scenario": {"scenario": "crossing", "field": "moon"}}, "scenario.field: unknown preset 'moon'"),
    ],
)
def test_task_settings_errors_name_the_key(data: dict[str, object], message: str) -> None:
    from hier_ssl.config import ConfigError

    with pytest.raises(ConfigError) as err:
        parse_config(data)
    assert str(err.value).startswith(message)


def test_train_refuses_a_run_directory_that_is_not_empty(tmp_path: Path) -> None:
    (tmp_path / "curve.csv").write_text("step\n")
    proc = _cli(
        "train", "configs/proposed/fscaps.yaml", "--out", str(tmp_path), cwd=Path(__file__).parents[2]
    )
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1 and "is not empty: --resume" in err and "Traceback" not in err
    assert [p.name for p in tmp_path.iterdir()] == ["curve.csv"]


def test_a_resumed_ppo_run_continues_after_its_last_iteration(tmp_path: Path) -> None:
    import yaml

    from hier_ssl.runs.train import resume_config

    config = {**TINY_PPO, "total_steps": 32, "eval_interval": 16}  # 2 iterations, a checkpoint after each
    run = tmp_path / "run"
    train(parse_config(config), run, progress=False)
    second = (run / "model_1.pt").read_bytes()
    saved = yaml.safe_load((run / "config.yaml").read_text())
    (run / "config.yaml").write_text(yaml.safe_dump({**saved, "total_steps": 64}))
    train(resume_config(run), run, resume=True, progress=False)
    # Iterations 2 and 3 ran; iteration 1 was not run (and saved) again.
    assert (run / "model_1.pt").read_bytes() == second and (run / "model_3.pt").is_file()
    steps = [int(row.split(",")[0]) for row in (run / "curve.csv").read_text().splitlines()[1:]]
    assert steps == [16, 32, 48, 64]


def test_ppo_runs_with_one_seed_give_the_same_curve_and_weights(tmp_path: Path) -> None:
    import csv

    def run(name: str) -> tuple[list[dict[str, str]], dict[str, torch.Tensor]]:
        config = {**TINY_PPO, "total_steps": 32, "eval_interval": 16, "seed": 3}
        train(parse_config(config), tmp_path / name, progress=False)
        rows = list(csv.DictReader((tmp_path / name / "curve.csv").open()))
        for row in rows:
            del row["train_time_s"]  # wall time: the one column that may differ
        weights = torch.load(tmp_path / name / "model_1.pt", weights_only=True)["actor_state_dict"]
        return rows, weights

    (curve_a, weights_a), (curve_b, weights_b) = run("a"), run("b")
    assert len(curve_a) == 2 and curve_a == curve_b
    assert weights_a.keys() == weights_b.keys()
    for key, value in weights_a.items():
        assert torch.equal(value, weights_b[key]), key


# -- a first run that cannot go wrong ------------------------------------------------------------------------


SHORT = {
    **TINY,
    "num_envs": 2,
    "total_steps": 12,
    "eval_episodes": 2,
    "sac": {**TINY["sac"], "learning_starts": 8},
}


def test_a_run_shorter_than_eval_interval_scores_its_final_policy(tmp_path: Path) -> None:
    from hier_ssl.policies.export import export_manager

    assert SHORT["total_steps"] < SHORT["eval_interval"]
    summary = train(parse_config(SHORT), tmp_path, progress=False)
    rows = (tmp_path / "curve.csv").read_text().splitlines()
    assert len(rows) == 2 and rows[1].startswith("12,")  # header, and the final policy's score
    assert (tmp_path / "best_actor.pt").is_file() and summary["policy"] == "best"
    assert export_manager(tmp_path, "torchscript").is_file()
    # Resumed once finished, nothing is scored twice.
    train(parse_config(SHORT), tmp_path, resume=True, progress=False)
    assert len((tmp_path / "curve.csv").read_text().splitlines()) == 2


@pytest.mark.parametrize("window, kept", [(1, 1), (2, 4)])
def test_selection_keeps_the_checkpoint_that_ends_the_best_stretch_of_evaluations(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, window: int, kept: int
) -> None:
    rates = iter([0.9, 1.0, 0.8, 0.95, 0.96, 0.9])

    def scores(policy: object, config: object, seed: int) -> dict[str, object]:
        return {
            "success_rate": next(rates),
            "collision_rate": 0.0,
            "episode_length": {"median": 10.0},
            "cpad": {"median": 1.0},
        }

    monkeypatch.setattr(train_module, "evaluate_run", scores)
    config = parse_config({**SHORT, "selection_window": window})
    selection = Selection(config, tmp_path)
    for step in range(5):
        selection(Checkpoint(step, step, 0.0, None, lambda step=step: {"step": step}))
    assert torch.load(tmp_path / "best_actor.pt")["step"] == kept
    # Resumed from its curve, the selection ranks the next evaluation against the same windows.
    Selection(config, tmp_path)(Checkpoint(5, 5, 0.0, None, lambda: {"step": 5}))
    assert torch.load(tmp_path / "best_actor.pt")["step"] == kept


def test_a_run_shorter_than_its_warm_up_says_so(tmp_path: Path) -> None:
    config = parse_config({**SHORT, "sac": {**SHORT["sac"], "learning_starts": 25}})
    with pytest.warns(
        UserWarning, match=r"= 24 transitions, fewer than sac.learning_starts = 25.*never updates"
    ):
        train(config, tmp_path, progress=False)


@pytest.mark.filterwarnings("error:this run collects")
def test_a_scenario_runs_warm_up_counts_every_robots_row(tmp_path: Path) -> None:
    # 60 steps x 2 fields x 3 robots = 360 transitions, past a warm-up of 200 (60 x 2 fields alone is not).
    train(
        parse_config({**SCENARIO, "sac": {**SCENARIO["sac"], "learning_starts": 200}}),
        tmp_path,
        progress=False,
    )


def test_eval_and_export_fall_back_to_the_final_policy_without_a_best_one(tmp_path: Path) -> None:
    from hier_ssl.checkpoints.actor import load_actor
    from hier_ssl.policies.export import export_manager

    train(parse_config(SHORT), tmp_path, progress=False)
    # As a run killed before its first selection leaves it.
    (tmp_path / "best_actor.pt").unlink(missing_ok=True)
    with pytest.warns(UserWarning, match="no best_actor.pt yet; using the final policy, model.pt"):
        actor, _ = load_actor(tmp_path)
    final, _ = load_actor(tmp_path, which="final")
    obs = torch.zeros(1, 13)
    torch.testing.assert_close(actor(obs), final(obs))
    with pytest.warns(UserWarning, match="final policy"):
        assert export_manager(tmp_path, "torchscript").is_file()


def test_an_interrupted_run_prints_the_resume_command(tmp_path: Path) -> None:
    from hier_ssl.cli.runs import _resume_hint

    config = tmp_path / "tiny.yaml"
    config.write_text(json.dumps({**TINY, "total_steps": 100_000, "save_interval": 20}))
    run = tmp_path / "run"
    proc = _cli("train", str(config), "--out", str(run), "--no-progress")
    deadline = time.time() + 120
    while not (run / MODEL_FILE).is_file() and time.time() < deadline:
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130
    assert f"continue the run with: hier-ssl train --resume {run}" in err
    assert "nothing in" in _resume_hint(tmp_path / "empty", 5000)


def test_a_trained_manager_is_shown_beside_the_planners_on_its_held_out_episodes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from hier_ssl.cli.runs import beside_planners

    # Episodes of at most 160 control steps, so an untrained manager's are short too.
    short = {**TINY["env"], "max_steps": 160}
    config = parse_config(
        {**TINY, "env": short, "total_steps": 200, "eval_interval": 100, "eval_episodes": 6}
    )
    run = tmp_path / "run"
    summary = train(config, run, progress=False)
    capsys.readouterr()
    beside_planners(run, config.eval_episodes, config.seed, video=False)  # GIFs: tests/cli/test_eval_cli.py
    out = capsys.readouterr().out
    assert "beside two scripted managers" in out and "`sampling` is a classical" in out
    assert "On this task (proposed) there is no obstacle" in out and "The paper: Proposed" in out
    rows = [line.split(" | ") for line in out.splitlines() if line.startswith("| ") and "---" not in line]
    assert [row[0] for row in rows] == ["| manager", "| run", "| direct", "| sampling"]
    # The same held-out episodes as eval.json: the run's row repeats its success and collision rates.
    assert float(rows[1][1]) == pytest.approx(100 * summary["success_rate"], abs=0.05)
    assert float(rows[1][2]) == pytest.approx(100 * summary["collision_rate"], abs=0.05)
    assert float(rows[2][3]) <= 160  # the run's episode limit: the planners play its episodes
    written = sorted(p.name for p in (run / "beside-planners").iterdir())
    assert written == ["fig3.png", "table.csv", "table.md", "table.tex"]
