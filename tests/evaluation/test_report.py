from __future__ import annotations

import json
from pathlib import Path

import imageio.v3
import numpy as np
import pytest
from matplotlib.image import imread

from hier_ssl.envs import env_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.evaluation.compare import compare
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.evaluation.figures import (
    collisions,
    episode_video,
    figure3,
    frame_labels,
    legend_columns,
    legend_entries,
    panel_title,
    path_spread,
    pick_episode,
)
from hier_ssl.evaluation.paper_tables import (
    PAPER_RESULTS,
    csv_text,
    markdown,
    paper_record,
    read_csv,
    summarise,
)
from hier_ssl.evaluation.report import csv_table, latex_table, markdown_table, table_cells
from hier_ssl.manager import cpad, min_time_to_pose
from hier_ssl.runs import jobs as launch_module
from hier_ssl.runs import reproduce as reproduce_module
from hier_ssl.world.field import get_field

# The paper's Proposed FSCAPS row (Table 1) as a record, plus made-up collision, success and ratio.
RECORD = {
    "manager": "proposed_fscaps",
    "worker": "paper",
    "task": "proposed",
    "frame_skip": 16,
    "episodes": 1000,
    "episode_length": PAPER_RESULTS[("proposed", "fscaps")]["episode_length"],
    "cpad": PAPER_RESULTS[("proposed", "fscaps")]["cpad"],
    "collision_rate": 0.0061,
    "success_rate": 0.995,
    "optimal_ratio_median": 1.3344,
    "eval_wall_s": 1.23,
}


def test_table_cells_are_the_papers_format() -> None:
    assert table_cells(RECORD) == [
        "proposed_fscaps",
        "paper",
        "114 (92 - 137)",
        "193",
        "31",
        "0.06 (0.05 - 0.08)",
        "0.16",
        "0.00",
        "0.61 %",
        "99.5 %",
        "1.33",
    ]
    half = {**RECORD, "episode_length": {**RECORD["episode_length"], "median": 114.5}}
    assert table_cells(half)[2] == "114.5 (92 - 137)"


def test_markdown_csv_and_latex_hold_the_same_row() -> None:
    md = markdown_table([RECORD]).splitlines()
    assert len(md) == 3 and md[2].startswith("| proposed_fscaps | paper | 114 (92 - 137) |")
    rows = csv_table([RECORD]).splitlines()
    assert rows[0].startswith("manager,worker,task,frame_skip,episodes,episode_length_median")
    assert rows[1].split(",")[:7] == ["proposed_fscaps", "paper", "proposed", "16", "1000", "114", "92"]
    tex = latex_table([RECORD], caption="1000 episodes")
    assert r"proposed\_fscaps & paper & 114 (92 - 137) & 193 & 31 & 0.06 (0.05 - 0.08)" in tex
    assert r"0.61 \% & 99.5 \%" in tex and tex.count(r"\begin{tabular}") == 1
    assert "eval_wall" not in md[0] + rows[0] + tex  # tables are reproducible: no wall times


def test_paper_tables_put_the_papers_numbers_beside_the_median_and_spread_over_seeds() -> None:
    seeds = [
        {**RECORD, "success_rate": s, "collision_rate": c, "train_wall_s": w}
        for s, c, w in ((0.99, 0.01, 600.0), (0.95, 0.03, 660.0), (0.97, 0.0, 540.0))
    ]
    rows = [
        summarise("obstacle", "fscaps", "paper", "final", "sampled", [paper_record("obstacle", "fscaps")]),
        summarise("obstacle", "fscaps", "defaults", "best", "mean", seeds),
    ]
    lines = markdown(rows).splitlines()
    # The paper's CPAD column is its public code's: it stands under that column, ours under both.
    assert lines[4] == "| FSCAPS | paper | final, sampled | - | - | 0.6 | 115 | - | 1.27 | - | - |"
    assert lines[5] == (
        "| FSCAPS | defaults | best, mean | 3 | 97.0 (95.0 - 99.0) | 1.0 (0.0 - 3.0) | 114 | 0.06 | - "
        "| 1.33 | 10.0 (9.0 - 11.0) |"
    )
    table = csv_text(rows).splitlines()
    assert table[2].startswith("obstacle,fscaps,defaults,best,mean,3,97.0,95.0,99.0,1.0,0.0,3.0,114.0,114.0")


def test_paper_tables_read_back_from_the_csv_print_the_same() -> None:
    # Figures 5e-5 either side of the CSV's rounding: a row printed unrounded would show a spread here.
    seeds = [{**RECORD, "optimal_ratio_median": r, "train_wall_s": 61.23456} for r in (1.15497, 1.15503)]
    planner = {k: v for k, v in RECORD.items() if k != "optimal_ratio_median"}
    rows = [
        summarise("proposed", "fscaps", "paper", "final", "sampled", [paper_record("proposed", "fscaps")]),
        summarise("proposed", "fscaps", "paper family", "best", "mean", seeds),
        summarise("proposed", "-", "planner", "direct", "-", [planner]),
    ]
    text = csv_text(rows)
    again = read_csv(text)
    assert [r.key for r in again] == [r.key for r in rows] and [r.seeds for r in again] == [0, 2, 0]
    assert csv_text(again) == text and markdown(again) == markdown(rows)
    assert (
        "| FSCAPS | paper family | best, mean | 2 | 99.5 | 0.6 | 114 | 0.06 | - | 1.16 | 1.0 |"
        in markdown(again)
    )
    with pytest.raises(ValueError, match="not a paper-tables CSV"):
        read_csv(text.replace("seeds", "runs", 1))
    with pytest.raises(ValueError, match="line 3: 5 cells"):
        read_csv(text.replace(text.splitlines()[2], "proposed,fscaps,paper family,best,mean"))


def test_recorded_episode_matches_the_metrics() -> None:
    config = env_config(task="proposed", frame_skip=16)
    result = evaluate(make_planner("direct", config), config, 6, seed=2, record=[0, 5])
    per = {key: value[:, 0] for key, value in result["per_robot"].items()}
    for episode in result["trajectories"]:
        i, length = episode["field"], int(per["length"][episode["field"]])
        robot, target = episode["robots"][:, 0], episode["target"][0]
        assert episode["controlled"] == 1 and episode["robots"].shape == (length + 1, 1, 2)
        assert episode["subgoal"].shape == (length, 1, 5) and episode["angles"].shape == (length + 1, 1)
        # The paper's CPAD of the sub-goal in force at each control step is the env's running CPAD.
        assert cpad(episode["subgoal"][:, 0, :2]) == pytest.approx(per["cpad"][i])
        assert per["success"][i] and np.linalg.norm(robot[-1] - target[:2]) < 0.05
        assert per["distance"][i] == pytest.approx(np.linalg.norm(robot[0] - target[:2]))
    # Ratio to the time-optimal bound, recomputed by hand from the per-episode arrays.
    bound = min_time_to_pose(per["distance"], 2.5, 3.0)
    assert result["optimal_ratio_median"] == pytest.approx(np.median(per["length"] * 0.025 / bound))
    with pytest.raises(ValueError, match="record"):
        evaluate(make_planner("direct", config), config, 6, record=[6])


def test_both_cpads_of_a_recorded_episode_match_the_metric_functions() -> None:
    config = env_config(task="obstacle", frame_skip=16)
    result = evaluate(make_planner("sampling", config), config, 8, seed=1, record=range(8))
    per = {key: value[:, 0] for key, value in result["per_robot"].items()}
    moved = 0
    for episode in result["trajectories"]:
        subgoals = episode["subgoal"][:, 0, :2]
        assert cpad(subgoals) == pytest.approx(per["cpad"][episode["field"]])
        assert cpad(subgoals, "public_code") == pytest.approx(per["cpad_public"][episode["field"]])
        moved += per["cpad_public"][episode["field"]] < per["cpad"][episode["field"]]
    assert moved > 0  # detours of several moves, where the two definitions differ
    assert result["cpad_public"]["median"] <= result["cpad"]["median"]


def test_an_evaluation_shows_its_progress_only_when_asked(capsys: pytest.CaptureFixture[str]) -> None:
    config = env_config(task="obstacle", frame_skip=16)
    evaluate(make_planner("direct", config), config, 4, seed=0)
    assert capsys.readouterr().err == ""
    evaluate(make_planner("direct", config), config, 4, seed=0, progress="held-out")
    # Control steps against the episode limit: an evaluation's time grows with them.
    err = capsys.readouterr().err
    assert "held-out:" in err and "/1200 [" in err


def test_same_manager_same_seed_gives_identical_tables() -> None:
    first, second = (compare(["sampling", "direct"], task="obstacle", episodes=40, seed=5) for _ in range(2))
    assert markdown_table([e.record for e in first]) == markdown_table([e.record for e in second])
    assert csv_table([e.record for e in first]) == csv_table([e.record for e in second])
    other = compare(["sampling"], task="obstacle", episodes=40, seed=6)
    assert csv_table([other[0].record]) != csv_table([first[0].record])


def test_figure_and_video_of_one_episode(tmp_path: Path) -> None:
    evaluations = compare(["direct", "sampling"], task="obstacle", episodes=4, seed=0, record=range(4))
    j = pick_episode([e.result["trajectories"] for e in evaluations])
    panels = [(e.name, e.result["trajectories"][j]) for e in evaluations]
    png = figure3(panels, get_field("hardware_challenge"), tmp_path / "fig" / "fig3.png", size=(220, 150))
    image = imread(png)
    assert image.shape[1] > 400 and image.std() > 0.05  # two panels side by side, not blank
    assert (image[-25:, :, :3] < 0.3).all(axis=-1).sum() > 50  # the legend's dark text along the bottom
    gif = episode_video(
        panels, get_field("hardware_challenge"), tmp_path / "ep.gif", max_frames=5, size=(110, 75)
    )
    assert gif.read_bytes()[:6] == b"GIF89a"
    # The outcome is said from the frame the episode ended, not before.
    end = len(panels[0][1]["robots"]) - 1
    assert frame_labels(panels[:1], 0) == ("direct",)
    assert frame_labels(panels[:1], end) == (f"direct: {panels[0][1]['outcome'][0]}",)
    frames = imageio.v3.imread(gif, index=None)
    assert not np.array_equal(frames[0][:20], frames[-1][:20])  # the strip's words changed
    with pytest.raises(ValueError, match=".gif"):
        episode_video(panels, get_field("hardware_challenge"), tmp_path / "ep.mp4")


def test_a_one_panel_video_keeps_its_legend_whole(tmp_path: Path) -> None:
    (evaluation,) = compare(["sampling"], task="obstacle", episodes=1, seed=0, record=[0])
    panels = [(evaluation.name, evaluation.result["trajectories"][0])]
    assert legend_columns(4.4) < len(legend_entries()) <= legend_columns(13.2)
    gif = episode_video(panels, get_field("hardware_challenge"), tmp_path / "one.gif", max_frames=3)
    first = imageio.v3.imread(gif, index=0)[..., :3]
    strip = first[: first.shape[0] - 300]  # above the 300-pixel panel
    # Nothing drawn at the strip's left or right edge: no legend entry runs off the picture.
    for edge in (strip[:, :2], strip[:, -2:]):
        assert (edge > 240).all()
    assert (strip < 100).all(axis=-1).sum() > 200  # and the legend's dark text is there


def _episodes(outcomes: list[list[str]]) -> list[list[dict]]:
    """Recorded episodes with these outcomes, every path the same (one robot standing still)."""
    still, target = np.zeros((3, 1, 2)), np.array([[1.0, 0.0, 0.0, 0.0, 0.0]])
    return [
        [{"controlled": 1, "robots": still, "target": target, "outcome": [o]} for o in row]
        for row in outcomes
    ]


def test_pick_episode_prefers_episodes_most_managers_solve() -> None:
    assert (
        pick_episode(_episodes([["timeout", "success", "success"], ["collision", "timeout", "success"]])) == 2
    )
    assert pick_episode(_episodes([["timeout", "timeout"], ["collision", "timeout"]])) == 0
    # With several robots a manager counts for the share of its robots that succeeded.
    two = {"controlled": 2, "robots": np.zeros((3, 2, 2)), "target": np.ones((2, 5))}
    half = [{**two, "outcome": ["success", "timeout"]}]
    both = [{**two, "outcome": ["success", "success"]}]
    assert pick_episode([half + both]) == 1


def _fake_training(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """Training replaced by writing a finished run of an untrained tiny actor; returns the runs trained."""
    import torch

    from hier_ssl.config import dump_config
    from hier_ssl.policies.networks import SquashedGaussianActor

    trained = []

    def fake_train(config: object, run_dir: Path, resume: bool = False, progress: bool = True, **_) -> None:
        trained.append(run_dir.name)
        run_dir.mkdir(parents=True)
        (run_dir / "config.yaml").write_text(dump_config(config))
        actor = SquashedGaussianActor(13, 4, config.sac.hidden).state_dict()
        torch.save({"actor": actor}, run_dir / "best_actor.pt")
        torch.save({"sac": {"actor": actor}}, run_dir / "model.pt")
        (run_dir / "eval.json").write_text(json.dumps({"train_wall_s": 60.0}))

    monkeypatch.setattr(launch_module, "train", fake_train)
    return trained


def test_reproduce_trains_missing_runs_once_and_writes_the_tables(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    trained = _fake_training(monkeypatch)
    args = {"only": ["proposed/fscaps"], "out": tmp_path / "runs", "results": tmp_path / "results"}
    args |= {"episodes": 3, "overrides": ["sac.hidden=[8, 8]"], "seeds": 1, "progress": False}
    report = reproduce_module.reproduce(**args)
    text = report.read_text()
    assert sorted(trained) == ["paper-proposed-fscaps-s0", "proposed-fscaps-s0"]
    assert "| FSCAPS | paper | final, sampled | - | - | - | 114 | - | 0.06 | - | - |" in text
    for source, policy in (("paper family", "final, sampled"), ("paper family", "best, mean")):
        assert f"| FSCAPS | {source} | {policy} | 1 |" in text
    assert "| FSCAPS | defaults | final, mean | 1 |" in text and "| - | planner | sampling | - |" in text
    assert "| - | planner | trajectory | - |" in text
    assert (tmp_path / "results" / "paper-tables.csv").is_file()
    assert (tmp_path / "results" / "fig3-proposed.png").is_file() and "fig3-proposed.png" in text
    cached = sorted(p.name for p in (tmp_path / "runs" / "evals").iterdir())
    assert len(cached) == 5 and "proposed-fscaps-s0-best-mean-e3-s0.json" in cached
    reproduce_module.reproduce(**args)
    assert len(trained) == 2  # finished runs are skipped
    with pytest.raises(ValueError, match="not a paper configuration"):
        reproduce_module.reproduce(only=["proposed/sac"], out=tmp_path)


def test_reproduce_keeps_the_rows_it_does_not_evaluate(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _fake_training(monkeypatch)
    results = tmp_path / "results"
    results.mkdir()
    made_up = {**RECORD, "train_wall_s": 600.0}
    earlier = [
        summarise("proposed", "fscaps", "defaults", "best", "mean", [made_up] * 3),
        summarise("baseline", "caps", "paper family", "final", "sampled", [made_up]),
        summarise("proposed", "frame_skip", "defaults", "final", "mean", [made_up, RECORD]),
    ]
    (results / "paper-tables.csv").write_text(csv_text(earlier))
    for name in ("fig3-baseline.png", "fig3-obstacle.png"):
        (results / name).write_bytes(b"")  # an earlier figure of a task in the tables, one of a task not
    args = {"families": ["defaults"], "only": ["proposed/fscaps"], "out": tmp_path / "runs"}
    args |= {"results": results, "episodes": 3, "overrides": ["sac.hidden=[8, 8]"], "seeds": 1}
    text = reproduce_module.reproduce(**args, progress=False).read_text()
    rows = read_csv((results / "paper-tables.csv").read_text())
    assert [r.key[:4] for r in rows] == [
        ("baseline", "caps", "paper", "final"),
        ("baseline", "caps", "paper family", "final"),
        ("baseline", "-", "planner", "direct"),
        ("baseline", "-", "planner", "sampling"),
        ("baseline", "-", "planner", "trajectory"),
        ("proposed", "frame_skip", "paper", "final"),
        ("proposed", "frame_skip", "defaults", "final"),
        ("proposed", "fscaps", "paper", "final"),
        ("proposed", "fscaps", "defaults", "best"),
        ("proposed", "fscaps", "defaults", "final"),
        ("proposed", "-", "planner", "direct"),
        ("proposed", "-", "planner", "sampling"),
        ("proposed", "-", "planner", "trajectory"),
    ]
    assert csv_text([rows[1], rows[6]]) == csv_text(earlier[1:])  # kept as they were
    assert rows[8].seeds == 1 and rows[8].spreads["train_wall_s"] == (1.0, 1.0, 1.0)  # the new run's
    kept = markdown(earlier[1:]).splitlines()[4::6]
    assert len(kept) == 2 and all(f"\n{line}\n" in text for line in kept)
    assert "end as collisions for every manager: baseline 0.0 %, proposed 0.0 %." in text
    assert text.endswith("![fig3-baseline](fig3-baseline.png)\n![fig3-proposed](fig3-proposed.png)\n")
    with pytest.raises(ValueError, match="played 3 episodes \\(seed 0\\), not 4"):
        reproduce_module.reproduce(**{**args, "episodes": 4}, train=False, progress=False)


def test_pick_episode_shows_where_the_paths_differ_most() -> None:
    line = np.linspace([0.0, 0.0], [2.0, 0.0], 11)[:, None]  # (T + 1, robots, 2): one robot on a line
    detour = line + np.array([0.0, 0.5]) * np.sin(np.linspace(0, np.pi, 11))[:, None, None]
    target = np.array([[2.0, 0.0, 0.0, 0.0, 0.0]])
    same = [
        {"controlled": 1, "robots": line, "target": target},
        {"controlled": 1, "robots": line[:6], "target": target},
    ]
    apart = [
        {"controlled": 1, "robots": line, "target": target},
        {"controlled": 1, "robots": detour, "target": target},
    ]
    assert path_spread([same[0], same[0]]) == 0.0
    # The shorter episode is held at its end: 1 m behind at the last step.
    assert path_spread(same) == pytest.approx(np.mean(np.r_[np.zeros(6), 0.2, 0.4, 0.6, 0.8, 1.0]))
    assert path_spread(apart) == pytest.approx(np.mean(0.5 * np.sin(np.linspace(0, np.pi, 11))))
    far = [
        {"controlled": 1, "robots": line, "target": target},
        {"controlled": 1, "robots": line + 9.0, "target": target},
    ]
    recorded = [[same[m], apart[m], far[m]] for m in range(2)]
    for m, outcomes in enumerate((["success"] * 3, ["success", "success", "timeout"])):
        for episode, o in zip(recorded[m], outcomes, strict=True):
            episode["outcome"] = [o]
    # Episode 2's paths differ most but fewer managers solve it; of episodes 0 and 1, 1 differs more.
    assert pick_episode(recorded) == 1


def _from(distance: float, outcome: str = "success", detour: float = 0.0) -> dict:
    """One robot driving 10 steps to a target at the origin from ``distance`` m along +x, bulging
    ``detour`` m sideways on the way."""
    x = np.linspace(distance, 0.0, 11)
    y = detour * np.sin(np.linspace(0, np.pi, 11))
    robots = np.stack([x, y], axis=-1)[:, None]
    return {"controlled": 1, "robots": robots, "target": np.zeros((1, 5)), "outcome": [outcome]}


def test_pick_episode_shows_a_typical_episode_not_a_short_one() -> None:
    distances = [0.3, 1.5, 2.0, 2.6, 4.0]
    # One manager: no paths to compare, so the episode whose start distance is the median.
    assert pick_episode([[_from(d) for d in distances]]) == 2
    # Two managers whose paths differ most on the 0.3 m episode: a start that short is not typical.
    detours = [0.9, 0.0, 0.1, 0.4, 2.0]
    recorded = [
        [_from(d) for d in distances],
        [_from(d, detour=b) for d, b in zip(distances, detours, strict=True)],
    ]
    assert pick_episode(recorded) == 3
    # Solved by more managers still comes first: only the 0.3 m episode is solved by both.
    for j in range(1, 5):
        recorded[1][j]["outcome"] = ["timeout"]
    assert pick_episode(recorded) == 0


def test_collisions_are_found_where_and_when_the_robots_met() -> None:
    robots = np.zeros((11, 3, 2))
    robots[:, 0, 0] = np.linspace(0.0, 1.0, 11)  # robot 0 drives along +x at 0.1 m a step
    robots[:, 1] = [3.0, 3.0]  # robot 1, controlled too, far away
    robots[:, 2] = [0.75, 0.05]  # an obstacle on robot 0's way
    episode = {"controlled": 2, "robots": robots, "outcome": ["collision", "success"]}
    ((i, t, point),) = collisions(episode)
    # First within 0.2 m at step 6: robot 0 at (0.6, 0), 0.158 m from the obstacle; the point between them.
    assert (i, t) == (0, 6) and point == pytest.approx([0.675, 0.025])
    # Never within the distance (a run with a larger collision distance): the closest approach.
    ((_, t, _),) = collisions(episode, distance=0.01)
    assert t == 7 or t == 8  # x = 0.7 and 0.8 are both 0.05 m from 0.75 along x
    assert collisions({**episode, "outcome": ["success", "timeout"]}) == []


def test_multi_robot_titles_name_the_robots_that_collided() -> None:
    episode = {"robots": np.zeros((58, 4, 2)), "outcome": ["collision", "success", "collision", "timeout"]}
    assert panel_title("direct", episode) == "direct\n1/4 reached, 2 collided (robots 0, 2), 57 steps"
    episode["outcome"] = ["success", "success", "collision", "success"]
    assert panel_title("direct", episode) == "direct\n3/4 reached, 1 collided (robot 2), 57 steps"
    assert [label for label, _ in legend_entries()] == [
        "target",
        "sub-goals",
        "robot, path",
        "obstacle, path",
        "collision",
    ]
