"""A tiny game-scenario training run learns something: the shipped STOP manager's config, cut to seconds."""

from __future__ import annotations

from pathlib import Path

import pytest

from hier_ssl.config.files import config_dir, load_yaml
from hier_ssl.envs import parse_config
from hier_ssl.runs.train import train


# 300 steps x 24 rows pass the warm-up of 3,600 transitions: the runner's check counts every robot's row.
@pytest.mark.filterwarnings("error:this run collects")
def test_a_tiny_stop_run_taught_by_sampling_learns_to_reach_role_positions(tmp_path: Path) -> None:
    data = load_yaml(config_dir() / "game" / "stop_teacher.yaml")
    # 4 fields (24 rows), 150 vector steps acted by the planner, 300 pretraining steps, then 150 SAC + CAPS
    # updates under the imitation term: the update path runs.
    sac = {**data["sac"], "learning_starts": 3600, "teacher_pretrain": 300, "teacher_steps": 300}
    config = {**data, "num_envs": 4, "total_steps": 300, "eval_interval": 300, "eval_episodes": 10}
    config["sac"] = {**sac, "batch_size": 128, "hidden": [64, 64]}
    summary = train(parse_config({**config, "seed": 0}), tmp_path / "run", progress=False)
    # 50 % on these 10 selection episodes (seed 1: 43 %); untaught, SAC + CAPS on game_stop reached 1.7 %
    # after 1,000 vector steps of 8 fields.
    assert summary["final"]["success_rate"] >= 0.2, summary["final"]
