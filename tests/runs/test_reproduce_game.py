"""``hier-ssl reproduce --family game``: which configs and scenarios it takes, and one tiny run end to end on
game_stop (a residual trained for two PPO iterations, one episode a row) through the CLI."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from hier_ssl import cli
from hier_ssl.config.files import config_dir, load_yaml
from hier_ssl.evaluation.compare import compare
from hier_ssl.runs import reproduce_game
from hier_ssl.runs.reproduce_game import GAME_SCENARIOS, learned_configs, plan_game, select_game

TINY = [
    "candidates.ppo.iterations=2",
    "candidates.ppo.fields=2",
    "candidates.ppo.horizon=8",
    "candidates.ppo.eval_interval=1",
    "candidates.hidden=[8, 8]",
    "eval_episodes=1",
]


def test_the_learned_game_configs_and_what_only_selects() -> None:
    assert set(learned_configs()) >= {"stop_residual", "stop_candidates"}
    assert not set(learned_configs()) & set(GAME_SCENARIOS)
    for scenario in GAME_SCENARIOS:  # issue 54, item 1: a learned manager on each, deciding every step
        rates = [load_yaml(path)["scenario"]["frame_skip"] for path in select_game([scenario])[1].values()]
        assert 1 in rates, scenario
    scenarios, configs = select_game()
    assert scenarios == list(GAME_SCENARIOS) and configs == learned_configs()
    scenarios, configs = select_game(["game_stop"])
    assert scenarios == ["game_stop"] and {"stop_residual", "stop_candidates"} <= set(configs)
    assert select_game(["game/stop_residual", "game_match"]) == (
        ["game_stop", "game_match"],
        {name: config_dir() / "game" / f"{name}.yaml" for name in ("match_residual", "stop_residual")},
    )
    with pytest.raises(ValueError, match="--only 'game_stp': not a game scenario.*known: game_stop"):
        select_game(["game_stp"])


def test_three_seeds_a_config_counting_up_from_its_own() -> None:
    runs = plan_game({"stop_residual": config_dir() / "game" / "stop_residual.yaml"}, out=Path("o"))
    assert [r.run_dir for r in runs] == [Path(f"o/runs/game_stop-residual-s{k}") for k in range(3)]
    assert {(r.family, r.task, r.setup) for r in runs} == {("game", "game_stop", "stop_residual")}


def test_reproduce_game_trains_evaluates_and_writes_the_table(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    configs = tmp_path / "configs" / "game"
    configs.mkdir(parents=True)
    for name in ("game_stop.yaml", "stop_residual.yaml"):  # the candidates classifier needs DAgger rounds
        shutil.copy(config_dir() / "game" / name, configs)
    out, results = tmp_path / "out", tmp_path / "results"
    argv = ["reproduce", "--family", "game", "--only", "game_stop", "--seeds", "1", "--episodes", "1"]
    argv += ["--config-dir", str(configs.parent), "--out", str(out), "--results", str(results)]
    argv += ["--no-progress", *(a for item in TINY for a in ("--set", item))]
    assert cli.main(argv) == 0
    text = (results / "game-table.md").read_text()
    assert "the same 1 episodes (seed 7)" in text
    for rate in (1, 16):
        for planner in ("direct", "sampling", "trajectory", "sampling+trapped=brake"):
            assert f"| `{planner}` | {rate} | - | - |" in text
    assert (
        "| `game/stop_residual` | 1 | best | 1 |" in text
        and "| `game/stop_residual` | 1 | final | 1 |" in text
    )
    assert "**Target check, game_stop**: the best planner is `" in text
    checks = [line for line in text.splitlines() if line.startswith("- `game/stop_residual` ")]
    assert len(checks) == 2 and all(": met (" in c or ": not met (" in c for c in checks)
    assert "(median seed game_stop-residual-s0 of 1)" in checks[0]
    csv_lines = (results / "game-table.csv").read_text().splitlines()
    assert len(csv_lines) == 1 + 8 + 2 and csv_lines[-1].startswith("game_stop,game/stop_residual,1,final,1,")
    cached = sorted(p.name for p in (out / "evals").iterdir())
    assert len(cached) == 10 and any(n.startswith("game_stop-residual-s0-best-fs1-e1-s7-") for n in cached)

    # Again without training: everything comes from the cache; a removed record alone is evaluated again.
    calls = []

    def counting(specs: list, *args: object, **kwargs: object) -> list:
        calls.append(str(specs[0]))
        return compare(specs, *args, **kwargs)

    monkeypatch.setattr(reproduce_game, "compare", counting)
    (out / "evals" / next(n for n in cached if n.startswith("sampling-game_stop-fs16-"))).unlink()
    capsys.readouterr()
    assert cli.main([*argv, "--no-train"]) == 0
    assert calls == ["sampling"] and "training" not in capsys.readouterr().out
    assert (results / "game-table.md").read_text() == text

    # An earlier table's other scenarios (here game_match's, from the shipped one) are kept, in order.
    shipped = Path(__file__).parents[2] / "results"
    match_rows = [
        line for line in (shipped / "game-table.csv").read_text().splitlines() if "game_match," in line
    ]
    match_check = (
        "**Target check, game_match**"
        + (shipped / "game-table.md").read_text().split("**Target check, game_match**")[1]
    )
    with (results / "game-table.csv").open("a") as table:
        table.write("\n".join(match_rows) + "\n")
    (results / "game-table.md").write_text(text + "\n" + match_check)
    assert cli.main([*argv, "--no-train"]) == 0
    again = (results / "game-table.md").read_text()
    assert again.index("### game_stop") < again.index("### game_match") < again.index("**Target check")
    assert again.endswith("\n" + match_check) and again.count("**Target check, game_stop**") == 1
    assert (results / "game-table.csv").read_text().splitlines()[-len(match_rows) :] == match_rows
    with pytest.raises(ValueError, match="its rows played 1 episodes .seed 7., not 1000"):
        reproduce_game.earlier_scenarios(results, ["game_match"], 1000, 7)


def test_bad_only_and_mixed_families_say_what_is_wrong(capsys: pytest.CaptureFixture[str]) -> None:
    assert cli.main(["reproduce", "--family", "game", "--only", "game_kickoff", "--no-train"]) == 1
    assert "--only 'game_kickoff': not a game scenario or learned game config" in capsys.readouterr().err
    assert cli.main(["reproduce", "--family", "game", "--family", "paper", "--no-train"]) == 1
    assert "--family game runs alone" in capsys.readouterr().err
