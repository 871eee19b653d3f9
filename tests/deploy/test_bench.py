"""``hier-ssl bench deploy``'s rows, on a short run each: latency through 127.0.0.1 and a task row
through the wire against the same manager played directly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hier_ssl.cli import build_parser, main
from hier_ssl.deploy.bench import (
    EXPORT_FORMATS,
    GAME_TASK,
    direct_episodes,
    latency_row,
    latency_task,
    task_row,
    untrained_export,
)
from hier_ssl.deploy.field import FieldServer
from hier_ssl.deploy.loop import PRIORITY
from hier_ssl.deploy.view import DeployView, manager_task
from hier_ssl.envs import task_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.planners import make_planner
from hier_ssl.envs.play import play


def test_a_latency_row_times_frames_to_commands() -> None:
    row = latency_row("direct", "direct", 1, seconds=2.0)
    assert row["samples"] > 10  # after the first second's ticks
    assert 0 < row["p50_ms"] <= row["p99_ms"] < 1000
    assert row["scheduling"].startswith(("fifo 10", "time-shared (not permitted"))


def test_a_task_row_compares_the_wire_in_lockstep_with_the_direct_loop() -> None:
    row = task_row("direct", "direct", "proposed", episodes=1, seed=2, noise=(0.0, 0.0))
    assert row["wire_success"] == row["eval_success"] == 1.0  # nothing to hit on the Proposed task
    assert row["success_gap_points"] == row["success_gap_se_points"] == 0.0 and row["noise_mm"] == 0.0
    assert row["field_clock"] == "lockstep" and row["robot_samples"] == 1
    assert row["wire_median_length"] == row["eval_median_length"]  # one world step per command


def test_the_bench_command_takes_its_options() -> None:
    args = build_parser().parse_args(["bench", "deploy", "--json", "--episodes", "3", "--seconds", "2"])
    assert (args.json, args.episodes, args.seconds, args.run) == (True, 3, 2.0, None)
    assert (args.priority, args.noise_mm, args.noise_deg, args.rows) == (
        PRIORITY,
        2.0,
        0.5,
        "tracking,latency,task",
    )
    assert main(["bench", "deploy", "--rows", "tracking,speed"]) == 1


def test_the_direct_episodes_are_the_field_servers_episodes() -> None:
    # Episode e of the field server is a one-field core reset with seed + e; a core of many fields draws
    # other starts from the same seed.
    config = manager_task("sampling", "obstacle")
    server = FieldServer(config, vision_port=9, seed=7)
    server._reset(3)
    core = HierarchicalCore(config, num_fields=1, autoreset=False)
    core.reset(7 + 3)
    np.testing.assert_array_equal(server.core.world.state.pos, core.world.state.pos)
    batch = HierarchicalCore(config, num_fields=4, autoreset=False)
    batch.reset(7)
    assert not np.allclose(batch.world.state.pos[3], core.world.state.pos[0])
    server.close()
    policy = make_planner("sampling", config)
    success, collision, length = direct_episodes(policy, config, 2, 7)
    assert success.shape == collision.shape == length.shape == (2, 1)
    assert length[1, 0] == play(core, policy, 8)["length"][0, 0]


def test_the_latency_rows_time_the_exported_network_in_each_format_it_runs(tmp_path: Path) -> None:
    pytest.importorskip("onnxruntime")
    assert EXPORT_FORMATS == ("torchscript", "onnx")
    files = [untrained_export(tmp_path, "obstacle", fmt) for fmt in EXPORT_FORMATS]
    assert [f.suffix for f in files] == [".pt", ".onnx"]
    row = latency_row(str(files[1]), "network (untrained, onnx)", 1, seconds=3.0)
    assert row["samples"] > 0 and 0 < row["p50_ms"] <= row["p99_ms"]


def test_the_11_robot_latency_row_decides_for_all_of_them_in_one_batched_call(tmp_path: Path) -> None:
    task = latency_task(11, tmp_path)
    config = task_config(task)
    assert (config.scenario_name, config.field, config.num_agents, config.num_obstacles) == (
        "formation",
        "division_a",
        11,
        11,
    )
    view = DeployView("direct", 11, manager_task("direct", task))
    assert (view.n, view.m) == (1, 11)  # one field of 11: one call decides for all
    row = latency_row("direct", "direct", 11, seconds=2.0, task=task)
    assert row["robots"] == 11 and row["field"] == "formation" and row["samples"] > 10
    assert row["decisions"] > 0 and 0 < row["decision_p50_ms"] <= row["decision_p99_ms"] < 1000
    with pytest.raises(ValueError, match=r"latency rows of 7 robots: expected one of \[1, 6, 11\]"):
        latency_task(7, tmp_path)
    assert main(["bench", "deploy", "--rows", "latency", "--robots", "1,7"]) == 1


def test_a_row_under_the_field_servers_referee_script_counts_its_fouls_through_the_wire() -> None:
    row = task_row("direct", "direct", "crowd", episodes=1, seed=2, noise=(0.0, 0.0), script="0.5:STOP")
    assert row["bench"] == "deploy game" and row["referee_script"] == "0.5:STOP"
    assert row["robot_samples"] == 1 and row["wire_fouls"] in (0.0, 1.0) and row["eval_fouls"] is None
    assert row["wire_success"] in (0.0, 1.0) and row["eval_success"] in (0.0, 1.0)


def test_the_game_row_plays_game_stop_with_its_own_referee_through_the_wire() -> None:
    row = task_row("direct", "direct", GAME_TASK, episodes=1, seed=0, noise=(0.0, 0.0))
    assert (row["bench"], row["task"], row["robot_samples"]) == ("deploy game", "game_stop", 6)
    assert "referee_script" not in row and 0 <= row["wire_fouls"] <= 1 and 0 <= row["eval_fouls"] <= 1
    assert row["wire_success"] > 0  # its robots reach the role positions STOP gives them in mid-episode
    assert abs(row["foul_gap_points"] - 100 * (row["wire_fouls"] - row["eval_fouls"])) < 0.1
