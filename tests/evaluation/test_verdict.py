from __future__ import annotations

from hier_ssl.envs import parse_config
from hier_ssl.evaluation.verdict import closing_note, paper_setup, standing


def _record(manager: str, success: float, collisions: float, length: float, cpad: float = 0.0) -> dict:
    return {
        "manager": manager,
        "success_rate": success,
        "collision_rate": collisions,
        "episode_length": {"median": length},
        "cpad": {"median": cpad},
        "cpad_public": {"median": cpad / 2},
    }


DIRECT = _record("direct", 1.0, 0.0, 100)
SAMPLING = _record("sampling", 0.99, 0.0, 131, 0.4)


def test_standing_is_decided_on_success_then_collisions_then_length() -> None:
    run = _record("run", 0.995, 0.0, 102)
    assert standing(run, DIRECT) == "behind `direct` on success (99.5 against 100.0 %)"
    assert standing(run, SAMPLING) == "ahead of `sampling` on success (99.5 against 99.0 %)"
    assert standing(_record("run", 1.0, 0.0, 98), DIRECT).startswith("ahead of `direct` on length")
    assert standing(_record("run", 0.99, 0.01, 98), SAMPLING).startswith("behind `sampling` on collisions")
    assert standing(DIRECT, DIRECT).startswith("level with `direct`")


def test_the_default_task_says_direct_is_the_bar_and_quotes_both_paper_rows() -> None:
    config = parse_config({"env": {"task": "proposed", "frame_skip": 16}, "sac": {"caps": True}})
    assert paper_setup(config) == "fscaps"
    note = closing_note(_record("run", 0.995, 0.0, 102, 0.04), [DIRECT, SAMPLING], config, others=0)
    assert "no obstacle" in note[0] and "planning has nothing to avoid" in note[0]
    assert "behind `direct` on success" in note[1] and "ahead of `sampling`" in note[1]
    assert note[2].startswith("What it learned") and "0.04 m" in note[2] and "0.02 m" in note[2]
    # The paper's Proposed FSCAPS (Table 1) and the Baseline's row it is set against.
    assert "Proposed FSCAPS, median 114 steps, CPAD 0.06 m" in note[3]
    assert "Baseline FSCAPS, median 109 steps, CPAD 0.58 m" in note[3]


def test_a_task_with_other_robots_and_a_scenario_without_a_paper_row() -> None:
    obstacle = parse_config({"env": {"task": "obstacle", "frame_skip": 1}})
    assert paper_setup(obstacle) == "vanilla"
    note = closing_note(_record("run", 0.9, 0.1, 300), [DIRECT, SAMPLING], obstacle, others=1)
    assert "1 other robot moves:" in note[0] and "Obstacle Vanilla" in note[-1] and "12.38 %" in note[-1]
    assert note[2].startswith("What it learned") and "around the others" in note[2]
    assert "from the reward alone" in note[2]
    scorer = parse_config({"env": {"task": "obstacle"}, "algo": "candidates"})
    assert paper_setup(scorer) is None
    note = closing_note(_record("run", 0.997, 0.003, 109), [DIRECT, SAMPLING], scorer, others=1)
    assert "from the `sampling` planner's choices, then the task's outcomes" in note[2]
    assert note[-1].startswith("The paper trained SAC only; its best row on this task: Obstacle FSCAPS,")
    untrained = closing_note(_record("run", 0.0, 0.0, 1200, 3.0), [DIRECT], obstacle, others=1)
    assert untrained[2].startswith("It has not learned to reach the target (0.0 % success)")
    crossing = parse_config({"scenario": {"scenario": "crossing", "num_agents": 6}})
    assert closing_note(_record("run", 1, 0, 150), [DIRECT], crossing, others=5)[-1] == (
        "The paper has no row for this task."
    )
