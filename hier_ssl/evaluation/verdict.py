"""What a trained manager's row beside the scripted planners shows, in words: ``hier-ssl train``'s closing
note. Every sentence is computed from the records and the task; the paper's figures come from its tables
(``hier_ssl.evaluation.paper_tables.PAPER_RESULTS``).

On a task without obstacles driving straight at the target (``direct``) already succeeds, so a manager
has nothing to avoid; what the paper showed on such a task is how steady the sub-goals are (CPAD), the
Proposed environment's against the Baseline's. The note says which of these the task is before it says
who is ahead.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from hier_ssl.config import TrainConfig
from hier_ssl.evaluation.paper_tables import PAPER_RESULTS, SETUP_TITLES, TASKS


def paper_setup(config: TrainConfig) -> str | None:
    """The paper's setup a SAC run is: FSCAPS, Frame Skip, CAPS or Vanilla by its decision period and its
    smoothness terms; None for another learner, which the paper did not train."""
    if config.algo != "sac":
        return None
    skips, caps = config.task_config.frame_skip > 1, config.sac.caps
    return ("fscaps" if caps else "frame_skip") if skips else ("caps" if caps else "vanilla")


def _taught_by(config: TrainConfig) -> str:
    """Where the manager's behaviour came from, for "What it learned, ...": the reward, or a planner first."""
    if config.algo == "candidates":
        return "from the `sampling` planner's choices, then the task's outcomes"
    if config.algo == "sac" and config.sac.teacher is not None:
        return "taught by a scripted planner, then from the reward"
    return "from the reward alone"


def _rates(record: dict[str, Any]) -> tuple[float, float, float]:
    return 100 * record["success_rate"], 100 * record["collision_rate"], record["episode_length"]["median"]


def standing(run: dict[str, Any], planner: dict[str, Any]) -> str:
    """How the ``run``'s record stands against the ``planner``'s, first on success, then collisions, then
    median length: "ahead of", "level with" or "behind", and on which figure it is decided."""
    (s, c, n), (ps, pc, pn) = _rates(run), _rates(planner)
    name = f"`{planner['manager']}`"
    if s != ps:
        return f"{'ahead of' if s > ps else 'behind'} {name} on success ({s:.1f} against {ps:.1f} %)"
    if c != pc:
        return f"{'ahead of' if c < pc else 'behind'} {name} on collisions ({c:.1f} against {pc:.1f} %)"
    if n != pn:
        where = "ahead of" if n < pn else "behind"
        return f"{where} {name} on length at the same success ({n:.0f} against {pn:.0f} steps)"
    return f"level with {name} (success, collisions and median length)"


def closing_note(
    run: dict[str, Any], planners: Sequence[dict[str, Any]], config: TrainConfig, others: int
) -> list[str]:
    """The lines that say what the run's record beside the ``planners``' records (``direct`` and
    ``sampling`` on the same episodes) shows on a task with ``others`` other moving robots, what the
    manager learned, and the paper's corresponding row where it has one."""
    task = config.task_config.scenario_name
    if others == 0:
        lines = [
            f"On this task ({task}) there is no obstacle and no other robot: driving straight at the target, "
            "as `direct` does, already succeeds, so planning has nothing to avoid; what differs is the time "
            "and how steady the sub-goals are.",
        ]
    else:
        lines = [
            f"On this task ({task}) {others} other robot{'s move' if others > 1 else ' moves'}: `direct` "
            "drives through them (its collisions), `sampling` plans around them.",
        ]
    lines.append("The trained manager is " + "; ".join(standing(run, p) for p in planners) + ".")
    success, cpad, public = 100 * run["success_rate"], run["cpad"]["median"], run["cpad_public"]["median"]
    moved = (
        f"sub-goals that move {cpad:.2f} m in a median episode (CPAD; {public:.2f} m by the paper's public "
        "code's formula)"
    )
    if success >= 50:
        avoiding = (
            "where `direct` keeps the target itself as its sub-goal" if others == 0 else "around the others"
        )
        learned = f"to reach the target ({success:.1f} %) with {moved}, {avoiding}"
        lines.append(f"What it learned, {_taught_by(config)}: {learned}.")
    else:
        lines.append(f"It has not learned to reach the target ({success:.1f} % success); its {moved}.")
    if task not in TASKS:
        return [*lines, "The paper has no row for this task."]
    setup = paper_setup(config)
    if setup is None:
        # Not the paper's learner: its best row on the task is what a manager here would be held against.
        best = _paper_row(task, "fscaps", PAPER_RESULTS[(task, "fscaps")])
        return [*lines, f"The paper trained SAC only; its best row on this task: {best}."]
    row = _paper_row(task, setup, PAPER_RESULTS[(task, setup)])
    if task == "proposed":
        baseline = _paper_row("baseline", setup, PAPER_RESULTS[("baseline", setup)])
        row += (
            f"; its Baseline row, the same setup without the Proposed environment: {baseline}. The paper's "
            "point here is that difference in steadiness, not a gain over driving straight"
        )
    return [*lines, f"The paper: {row}."]


def _paper_row(task: str, setup: str, paper: dict[str, Any]) -> str:
    collisions = paper.get("collision_rate")
    hits = "" if collisions is None else f", {100 * collisions:.2f} % collisions"
    length, cpad = paper["episode_length"]["median"], paper["cpad"]["median"]
    title = f"{task.capitalize()} {SETUP_TITLES[setup]}"
    return f"{title}, median {length:.0f} steps{hits}, CPAD {cpad:.2f} m (public code's formula)"


__all__ = ["closing_note", "paper_setup", "standing"]
