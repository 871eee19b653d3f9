"""What keeps a core whole when a step fails part-way: a worker runs user code, and what it raises (a
``WorkerError`` for a bad command, or its own exception) must not leave a decision half made.

The core calls the worker first in every control step, before the obstacles, the world or any count
moves. So a failure at a decision's first control step is undone whole: ``abandon`` puts back the
sub-goals, decision counts and CPAD that the decision had set, and the fields are as before the step. A
failure later in the decision (frame_skip > 1) comes after the world has moved; the fields cannot be put
back, so the core is marked ``interrupted`` and refuses to step until ``reset()``.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

# What a decision changes before its first control step, and the world step count when it began.
Snapshot = tuple[np.ndarray, np.ndarray, np.ndarray, int]


class Guarded(Protocol):
    """What of a core (``hier_ssl.envs.core.HierarchicalCore``) a guard reads and puts back; the core
    imports this module, so it is named by what it has, not by its class."""

    interrupted: bool
    subgoal: np.ndarray
    decisions: np.ndarray
    ep_cpad: np.ndarray
    control_steps: int


def snapshot(core: Guarded) -> Snapshot:
    """What a decision changes before its first control step (sub-goals, decisions, CPAD) and the world
    step count; a RuntimeError if an earlier step stopped part-way."""
    if core.interrupted:
        raise RuntimeError(
            "an exception stopped an earlier step() part-way through a decision: call reset() first"
        )
    return core.subgoal.copy(), core.decisions.copy(), core.ep_cpad.copy(), core.control_steps


def abandon(core: Guarded, kept: Snapshot) -> None:
    """After an exception inside a step: put back the ``snapshot`` ``kept`` if no control step ran since,
    else mark ``core`` interrupted."""
    subgoal, decisions, cpad, control_steps = kept
    if core.control_steps != control_steps:
        core.interrupted = True
        return
    core.subgoal[...], core.decisions[...], core.ep_cpad[...] = subgoal, decisions, cpad


__all__ = ["Guarded", "Snapshot", "abandon", "snapshot"]
