"""``hier-ssl reproduce --family game``: train the learned game configs, evaluate them beside the scripted
planners on each SSL game scenario's held-out episodes, and write ``results/game-table.md`` and ``.csv``.

The scenarios are ``GAME_SCENARIOS``, each defined by ``configs/game/<scenario>.yaml`` (its scenario
section: the episodes every manager of the scenario plays). The learned game configs are the other files
of ``configs/game/`` (``stop_residual.yaml``, ``match_residual.yaml``, ...), each on the scenario it names.
Runs train as the other families' do (``hier_ssl.runs.reproduce.train_runs``: in ``OUT/runs/<name>-s<seed>``,
finished ones skipped, killed ones resumed) and their evaluations are cached in ``OUT/evals/`` beside
theirs, the planners' too (a planner at frame skip 1 costs minutes a scenario).

Every manager of a scenario plays the same ``episodes`` episodes of seed ``eval_seed`` (7, the seed of
docs/results.md's game tables, so a rebuilt row compares with them figure for figure: none of model
selection's seeds, 10,000 + the run's, ``train``'s held-out ones, 20,000 + it, or the
candidates learner's training episodes, from 1,000,000 up),
acting as ``hier-ssl eval --scenario`` has it act (``hier_ssl.evaluation.compare.compare``): the planners
at frame skip 1 and 16 in the field frame, a run with its own interface and frame skip.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hier_ssl.config import TaskConfig
from hier_ssl.config.files import apply_overrides, load_yaml
from hier_ssl.config.files import config_dir as shipped_configs
from hier_ssl.config.launch_options import LaunchOptions
from hier_ssl.envs import parse_config, task_config
from hier_ssl.evaluation.compare import compare
from hier_ssl.evaluation.game_table import (
    BEST_PLANNER_RULE,
    GameRow,
    best_planner,
    game_csv,
    game_markdown,
    game_row,
    median_seed,
    read_game_csv,
    target_check,
)
from hier_ssl.evaluation.paper_tables import header_episodes
from hier_ssl.runs.eval_cache import cached_record, config_digest
from hier_ssl.runs.reproduce import PLANNER_ROWS, Planned, train_runs
from hier_ssl.runs.train import EVAL_FILE

GAME_SCENARIOS = ("game_stop", "game_free_kick", "game_ball_placement", "game_match")
PLANNER_RATES = (1, 16)  # every control step, as SSL teams run them; the paper's FSCAPS period
# The paper tables' planners and `sampling` stopping where it is trapped, the best of them on the ball
# placement (docs/results.md, "Their ball placement: a robot trapped brakes").
GAME_PLANNERS = (*PLANNER_ROWS, "sampling+trapped=brake")
CHECKPOINTS = ("best", "final")
GAME_SEEDS = 3


def learned_configs(config_dir: str | Path | None = None) -> dict[str, Path]:
    """The learned game configs by name ("stop_residual"): every file of ``configs/game/`` but the
    scenarios' own."""
    root = (Path(config_dir) if config_dir is not None else shipped_configs()) / "game"
    scenarios = {f"{s}.yaml" for s in GAME_SCENARIOS}
    return {path.stem: path for path in sorted(root.glob("*.yaml")) if path.name not in scenarios}


def _scenario_of(path: Path) -> str:
    return str(load_yaml(path)["scenario"]["scenario"])


def select_game(
    only: Sequence[str] = (), config_dir: str | Path | None = None
) -> tuple[list[str], dict[str, Path]]:
    """The scenarios (``GAME_SCENARIOS``' order) and learned configs that ``only`` names: a scenario
    brings all its configs, a config ("stop_residual") its scenario; everything when ``only`` is empty."""
    configs = learned_configs(config_dir)
    if not only:
        return list(GAME_SCENARIOS), configs
    scenarios, chosen = set(), {}
    for name in only:
        if name in GAME_SCENARIOS:
            scenarios.add(name)
            chosen |= {c: p for c, p in configs.items() if _scenario_of(p) == name}
        elif name.removeprefix("game/") in configs:
            stem = name.removeprefix("game/")
            chosen[stem] = configs[stem]
            scenarios.add(_scenario_of(configs[stem]))
        else:
            known = ", ".join([*GAME_SCENARIOS, *configs])
            raise ValueError(f"--only {name!r}: not a game scenario or learned game config; known: {known}")
    return [s for s in GAME_SCENARIOS if s in scenarios], {c: p for c, p in configs.items() if c in chosen}


def plan_game(
    configs: dict[str, Path],
    seeds: int | None = None,
    out: Path = Path("runs/reproduce"),
    overrides: Sequence[str] = (),
) -> list[Planned]:
    """The runs of ``configs`` (``seeds`` each, default ``GAME_SEEDS``, counting up from each config's
    own seed), every config validated before anything trains; ``task`` is the scenario, ``setup`` the
    config's name."""
    runs = []
    for stem, path in configs.items():
        data = apply_overrides(load_yaml(path), list(overrides))
        base = int(data.get("seed", 0))
        for k in range(seeds or GAME_SEEDS):
            config = parse_config({**data, "seed": base + k})
            run_dir = out / "runs" / f"{config.name}-s{config.seed}"
            runs.append(Planned("game", config.task_config.scenario_name, stem, config, run_dir))
    return runs


def scenario_episodes(scenario: str, config_dir: str | Path | None = None) -> TaskConfig:
    """The scenario section of ``configs/game/<scenario>.yaml``: whose episodes its managers play."""
    root = Path(config_dir) if config_dir is not None else shipped_configs()
    return task_config(root / "game" / f"{scenario}.yaml")


def evaluate_cached(
    spec: str | Path,
    episodes: TaskConfig,
    frame_skip: int,
    which: str,
    count: int,
    seed: int,
    cache: Path,
    newer_than: float | None = None,
) -> dict[str, Any]:
    """``hier-ssl eval``'s record of the manager ``spec`` (a planner's name, or a run directory acting with
    its ``which`` checkpoint and mean actions) on ``count`` episodes of ``episodes`` at ``frame_skip``, from
    ``cache`` when it was evaluated so before (for a run: at or after ``newer_than``, its eval.json's time).
    The file's name carries a digest of the scenario's settings, so a changed YAML is evaluated again."""
    planner = isinstance(spec, str)
    name = f"{spec}-{episodes.scenario_name}" if planner else f"{Path(spec).name}-{which}"
    digest = config_digest(episodes.model_copy(update={"frame_skip": frame_skip}))
    path = cache / f"{name}-fs{frame_skip}-e{count}-s{seed}-{digest}.json"

    def compute() -> dict[str, Any]:
        evaluations = compare([spec], episodes, episodes=count, seed=seed, frame_skip=frame_skip, which=which)
        return evaluations[0].record

    return cached_record(path, compute, newer_than)


def planner_game_rows(
    scenario: str, episodes: TaskConfig, count: int, seed: int, cache: Path, progress: bool
) -> list[GameRow]:
    """The planners' rows of one scenario, ``GAME_PLANNERS`` at every rate of ``PLANNER_RATES``."""
    rows = []
    for rate in PLANNER_RATES:
        for name in GAME_PLANNERS:
            record = evaluate_cached(name, episodes, rate, "best", count, seed, cache)
            rows.append(game_row(scenario, name, rate, "-", [record]))
            if progress:
                print(f"  {scenario}: {name} at frame skip {rate}", flush=True)
    return rows


def learned_game_rows(
    scenario: str, runs: Sequence[Planned], episodes: TaskConfig, count: int, seed: int, cache: Path
) -> tuple[list[GameRow], list[tuple[str, GameRow]]]:
    """The rows of the finished runs of ``runs`` on ``scenario`` (best and final of each config, at the
    runs' own frame skip), and for the target check each such row's median seed as (label, row)."""
    rows, medians = [], []
    for stem in dict.fromkeys(r.setup for r in runs if r.task == scenario):
        done = [r for r in runs if (r.task, r.setup) == (scenario, stem)]
        done = [r for r in done if (r.run_dir / EVAL_FILE).is_file()]
        for which in CHECKPOINTS if done else ():
            records = []
            for run in done:
                finished = (run.run_dir / EVAL_FILE).stat().st_mtime
                rate = run.config.task_config.frame_skip
                records.append(
                    evaluate_cached(run.run_dir, episodes, rate, which, count, seed, cache, finished)
                )
            manager, rate = f"game/{stem}", done[0].config.task_config.frame_skip
            rows.append(game_row(scenario, manager, rate, which, records))
            middle = median_seed(records)
            label = f"`{manager}` {which} (median seed {middle['manager']} of {len(records)})"
            medians.append((label, game_row(scenario, manager, rate, which, [middle])))
    return rows, medians


def target_lines(scenario: str, planners: Sequence[GameRow], medians: Sequence[tuple[str, GameRow]]) -> str:
    """The Markdown paragraph of one scenario's target check."""
    best = best_planner(planners)
    head = (
        f"**Target check, {scenario}**: the best planner is `{best.manager}` at frame skip {best.frame_skip} "
        f"({best.median('success'):.1f} % success, {best.median('fouls_collisions'):.2f} % fouls + "
        f"collisions, median time to target {best.median('time_to_target'):.2f} s)."
    )
    if not medians:
        return head + " No learned config of this scenario has a finished run.\n"
    checks = [target_check(best, row, label) for label, row in medians]
    return head + "\n\n" + "\n".join(f"- {check.sentence}" for check in checks) + "\n"


def game_header(episodes: int, seed: int) -> str:
    """The Markdown's text above the tables."""
    return (
        "# The SSL game scenarios: planners and learned managers\n\n"
        "Written by `hier-ssl reproduce --family game` (hier_ssl/runs/reproduce_game.py). Every manager of "
        f"a scenario plays the same {episodes} episodes (seed {seed}) of its configs/game/<scenario>.yaml, "
        "paper worker, per robot. The planners decide every control step (frame skip 1) or every 16; a "
        "learned config's runs act at their own frame skip with mean actions, *best* the checkpoint model "
        "selection kept, *final* the one training ended with. Learned cells: the median over training "
        "seeds, with their min - max. Collisions: contacts alone; left for a foul: robots whose episode "
        "ended in a foul (a robot leaves one way); fouls / robot-min: every foul committed over the time "
        "the robots played; time to target: median over the robots that succeeded.\n\n"
        f"Target check (issue 54): {BEST_PLANNER_RULE} against the median seed of each learned config's "
        "best and final (seeds ranked by success, then fewer fouls + collisions; of two, the worse): "
        "success at least the planner's minus 0.5 point, and either fouls + collisions at most half the "
        "planner's with a median time to target no longer, or, where the planner's fouls + collisions are "
        "under 0.5 % of robots, no more of them and a median time to target at least 10 % shorter.\n\n"
    )


def earlier_scenarios(
    results: Path, scenarios: Sequence[str], episodes: int, seed: int
) -> tuple[list[GameRow], dict[str, str]]:
    """The rows and target-check paragraphs of ``scenarios`` in an earlier ``results``/game-table.md and
    .csv, if any, checked to be of the same episodes as these: a rebuild of some scenarios keeps the
    others' sections as they were."""
    table, report = results / "game-table.csv", results / "game-table.md"
    if not (table.is_file() and report.is_file()):
        return [], {}
    text = report.read_text()
    played = header_episodes(text)
    if played not in (None, (episodes, seed)):
        raise ValueError(
            f"{report}: its rows played {played[0]} episodes (seed {played[1]}), not {episodes} (seed "
            f"{seed}); evaluate alike or write to another --results folder"
        )
    rows = [row for row in read_game_csv(table.read_text()) if row.scenario in scenarios]
    checks = {}
    for part in re.split(r"(?=\*\*Target check, )", text)[1:]:
        scenario = part.removeprefix("**Target check, ").split("**", 1)[0]
        if scenario in scenarios:
            checks[scenario] = part.rstrip("\n") + "\n"
    return rows, checks


def reproduce_game(
    only: Sequence[str] = (),
    seeds: int | None = None,
    out: str | Path = "runs/reproduce",
    results: str | Path = "results",
    episodes: int = 1000,
    config_dir: str | Path | None = None,
    overrides: Sequence[str] = (),
    eval_seed: int = 7,
    progress: bool = True,
    launch_options: LaunchOptions | None = None,
    train: bool = True,
) -> Path:
    """Train what is missing of the selected learned game configs (unless ``train`` is False), evaluate the
    planners and every finished run on the selected scenarios, write ``results``/game-table.md and .csv
    (the other scenarios' sections kept from the earlier table there, ``earlier_scenarios``, read before
    anything trains); returns the Markdown file's path. ``overrides`` change every learned config, not
    the scenarios' episodes."""
    out, results = Path(out), Path(results)
    scenarios, configs = select_game(only, config_dir)
    runs = plan_game(configs, seeds, out, overrides)
    others = [s for s in GAME_SCENARIOS if s not in scenarios]
    rows, checks = earlier_scenarios(results, others, episodes, eval_seed)
    if train and runs:
        train_runs(runs, out, launch_options, progress)
    if progress:
        print(f"evaluating on {episodes} episodes per scenario (seed {eval_seed})", flush=True)
    cache = out / "evals"
    for scenario in scenarios:
        played = scenario_episodes(scenario, config_dir)
        planners = planner_game_rows(scenario, played, episodes, eval_seed, cache, progress)
        learned, medians = learned_game_rows(scenario, runs, played, episodes, eval_seed, cache)
        for row in learned if progress else ():
            print(f"  {scenario}: {row.manager} {row.policy}, {row.seeds} run(s)", flush=True)
        rows += [*planners, *learned]
        checks[scenario] = target_lines(scenario, planners, medians)
    rows.sort(key=lambda row: GAME_SCENARIOS.index(row.scenario))  # stable: each scenario's order kept
    ordered = [checks[s] for s in GAME_SCENARIOS if s in checks]
    results.mkdir(parents=True, exist_ok=True)
    (results / "game-table.csv").write_text(game_csv(rows))
    path = results / "game-table.md"
    path.write_text(game_header(episodes, eval_seed) + game_markdown(rows) + "\n" + "\n".join(ordered))
    return path


__all__ = [
    "CHECKPOINTS",
    "GAME_SCENARIOS",
    "GAME_SEEDS",
    "GAME_PLANNERS",
    "PLANNER_RATES",
    "earlier_scenarios",
    "learned_configs",
    "plan_game",
    "reproduce_game",
    "scenario_episodes",
    "select_game",
]
