"""The game table's rows and the target check (issue 54) on hand-made figures: every way it is met or
missed, with the numbers in its sentence."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from hier_ssl.evaluation.game_table import (
    GameRow,
    best_planner,
    game_csv,
    game_figures,
    game_markdown,
    game_row,
    median_seed,
    read_game_csv,
    target_check,
)


def _row(
    success: float, fouls_collisions: float, time: float, manager: str = "m", policy: str = "-"
) -> GameRow:
    spreads = {key: (math.nan,) * 3 for key in ("collisions", "fouls", "fouls_per_minute", "cpad")}
    spreads |= {key: (v, v, v) for key, v in (("success", success), ("fouls_collisions", fouls_collisions))}
    spreads["time_to_target"] = (time, time, time)
    return GameRow("game_stop", manager, 1, policy, 0 if policy == "-" else 1, spreads)


def _record(
    success: float, collision: float, foul: float, time: float | None, name: str = "r"
) -> dict[str, Any]:
    return {
        "manager": name,
        "success_rate": success,
        "collision_rate": collision,
        "foul_rate": foul,
        "fouls_per_robot_minute": {"stop_speed": 0.25, "own_defense_area": 0.5},
        "time_to_target_s_median": time,
        "cpad": {"median": 50.0},
    }


PLANNER = _row(96.8, 1.35, 5.53, "sampling")


def test_met_by_halving_the_fouls_at_no_longer_time() -> None:
    verdict = target_check(PLANNER, _row(96.4, 0.60, 5.53), "`game/x` best")
    assert verdict.met
    assert verdict.sentence.startswith("`game/x` best: 96.4 % success, 0.60 % fouls + collisions")
    assert (
        "against the planner's 96.8, 1.35, 5.53: met (success at least 96.3; at most half" in verdict.sentence
    )
    assert "0.68" in verdict.sentence
    # One second longer breaks it: the halving way asks for a time no longer than the planner's.
    assert not target_check(PLANNER, _row(96.4, 0.60, 5.54), "x").met


def test_met_by_the_ten_percent_shorter_way_where_the_planner_barely_fouls() -> None:
    planner = _row(99.0, 0.40, 6.00)
    verdict = target_check(planner, _row(98.6, 0.40, 5.40), "x")
    assert verdict.met and "no more of them, and at most 5.40 s, 10 % shorter" in verdict.sentence
    # The same fouls, a time 9 % shorter: not enough.
    slower = target_check(planner, _row(98.6, 0.40, 5.46), "x")
    assert not slower.met and "a time over 5.40 s, 10 % shorter" in slower.sentence
    # That way is closed where the planner fouls 0.5 % of robots or more.
    assert not target_check(_row(99.0, 0.50, 6.00), _row(98.6, 0.40, 5.0), "x").met


def test_not_met_on_success() -> None:
    verdict = target_check(PLANNER, _row(96.2, 0.0, 4.0), "x")
    assert not verdict.met
    assert verdict.sentence.endswith("not met (success under 96.3 (the planner's minus 0.5 point)).")


def test_not_met_on_fouls() -> None:
    verdict = target_check(PLANNER, _row(96.8, 0.70, 5.0), "x")
    assert not verdict.met
    assert "not met (fouls + collisions above half the planner's, 0.68)" in verdict.sentence
    both = target_check(PLANNER, _row(95.3, 2.62, 5.60), "x").sentence
    assert "success under 96.3" in both and "above half the planner's, 0.68 and a longer median time" in both


def test_no_success_is_not_met() -> None:
    assert not target_check(_row(10.0, 0.0, 6.0), _row(10.0, 0.0, math.nan), "x").met


def test_the_best_planner_has_the_highest_success_then_fewer_fouls_then_the_shorter_time() -> None:
    rows = [_row(96.0, 0.1, 5.0, "a"), _row(97.0, 2.0, 6.0, "b"), _row(97.0, 1.0, 6.5, "c")]
    assert best_planner(rows).manager == "c"
    assert best_planner([*rows, _row(97.0, 1.0, 6.0, "d")]).manager == "d"
    with pytest.raises(ValueError, match="no planner row"):
        best_planner([])


def test_figures_and_rows_come_from_the_evaluation_records() -> None:
    record = _record(0.95, 0.012, 0.003, 5.6)
    figures = game_figures(record)
    assert figures["success"] == pytest.approx(95.0) and figures["fouls_collisions"] == pytest.approx(1.5)
    assert figures["fouls_per_minute"] == pytest.approx(0.75) and figures["time_to_target"] == 5.6
    assert math.isnan(game_figures(_record(0.0, 0.5, 0.5, None))["time_to_target"])
    seeds = [_record(0.90, 0.02, 0.0, 6.0, "s0"), _record(0.95, 0.01, 0.0, 5.0, "s1")]
    seeds.append(_record(0.93, 0.01, 0.01, 5.5, "s2"))
    row = game_row("game_stop", "game/x", 1, "best", seeds)
    assert row.seeds == 3 and row.spreads["success"] == (93.0, 90.0, 95.0)
    assert median_seed(seeds)["manager"] == "s2" and median_seed(seeds[:2])["manager"] == "s0"
    text = game_markdown([game_row("game_stop", "sampling", 16, "-", seeds[:1]), row])
    assert "| `sampling` | 16 | - | - | 90.0 | 2.00 | 0.00 | 2.00 | 0.750 | 6.00 | 50.0 |" in text
    assert "| `game/x` | 1 | best | 3 | 93.0 (90.0 - 95.0) | 1.00 (1.00 - 2.00) |" in text
    assert game_csv([row]).splitlines()[1].startswith("game_stop,game/x,1,best,3,93.0,90.0,95.0,1.0,1.0,2.0")


def test_the_game_csv_reads_back_as_it_was_written() -> None:
    text = (Path(__file__).parents[2] / "results" / "game-table.csv").read_text()
    rows = read_game_csv(text)
    assert game_csv(rows) == text and {r.scenario for r in rows} >= {"game_stop", "game_match"}
    with pytest.raises(ValueError, match="line 2: 3 cells"):
        read_game_csv(text.splitlines()[0] + "\na,b,c\n")
    with pytest.raises(ValueError, match="not a game-table CSV"):
        read_game_csv("scenario,manager\n")
