"""A manager decision's per-robot book-keeping in the core, each part one compiled loop over the robots (at
one field numpy's per-call overhead, not the arithmetic, is the cost of the equivalent array operations):
the sub-goals taken, the decisions counted, the CPAD grown and the action values clipped
(``take_decisions``); each control step's reward, departures and time counted into a ``Period``
(``tally_control_step``)."""

from __future__ import annotations

import numba
import numpy as np

from hier_ssl.manager.rewards import pose_error


@numba.njit(cache=True)
def take_decisions(
    action: np.ndarray,
    decoded: np.ndarray,
    live: np.ndarray,
    subgoal: np.ndarray,
    decisions: np.ndarray,
    cpad: np.ndarray,
    clipped: np.ndarray,
) -> None:
    """The ``live`` (N, M) robots take their ``decoded`` sub-goals (N, M, 5) in place of ``subgoal``: their
    ``decisions`` count one more, ``cpad`` grows by the sub-goal's move (``cpad_increment``; not at a
    robot's first decision, whose held sub-goal was its own start pose) and ``clipped`` (N, M) counts the
    values of ``action`` (N, M, A) outside [-1, 1] (0 where not live). One compiled loop over the robots."""
    for f in range(live.shape[0]):
        for i in range(live.shape[1]):
            clipped[f, i] = 0
            if not live[f, i]:
                continue
            for value in action[f, i]:
                clipped[f, i] += abs(value) > 1.0
            if decisions[f, i] > 0:
                cpad[f, i] += pose_error(decoded[f, i], subgoal[f, i])[0]
            subgoal[f, i] = decoded[f, i]
            decisions[f, i] += 1


@numba.njit(cache=True)
def tally_control_step(
    step_reward: np.ndarray,
    succ: np.ndarray,
    hit: np.ndarray,
    steps: np.ndarray,
    max_steps: int,
    add: bool,
    count: bool,
    start: np.ndarray,
    live: np.ndarray,
    reward: np.ndarray,
    success: np.ndarray,
    collision: np.ndarray,
    elapsed: np.ndarray,
    timeout: np.ndarray,
) -> int:
    """One control step of a decision into its running per-robot values (N, M), in place; returns how many
    robots are still ``live``.

    Each ``live`` robot takes ``step_reward`` into ``reward`` (added if ``add``, else set), and leaves
    with ``success`` or ``collision`` where ``succ`` or ``hit`` say so, or when its field's ``steps``
    (N,) reach ``max_steps``; one still live counts the step in ``elapsed`` if ``count``. ``timeout``: the
    robots of ``start`` that left without success or collision (so far)."""
    remaining = 0
    for f in range(live.shape[0]):
        out_of_time = steps[f] >= max_steps
        for i in range(live.shape[1]):
            if live[f, i]:
                reward[f, i] = reward[f, i] + step_reward[f, i] if add else step_reward[f, i]
                success[f, i] |= succ[f, i]
                collision[f, i] |= hit[f, i]
                live[f, i] = not (succ[f, i] or hit[f, i] or out_of_time)
                if live[f, i]:
                    remaining += 1
                    elapsed[f, i] += count
            timeout[f, i] = start[f, i] and not (live[f, i] or success[f, i] or collision[f, i])
    return remaining


class Period:
    """The running per-robot values (N, M) of one decision period, or of one control step: the robots
    ``start`` live and those still ``live``, their ``reward``, whether they left with ``success`` or
    ``collision`` or ran out of time (``timeout``), and the control steps ``elapsed`` while live. New
    arrays every period: the core's result hands them out."""

    __slots__ = ("_running", "collision", "elapsed", "live", "reward", "start", "success", "timeout")

    def __init__(self, start: np.ndarray) -> None:
        """A period in which the robots of ``start`` (N, M) bool are live and nothing has happened yet."""
        shape = start.shape
        self.start, self.live, self.reward = start, start.copy(), np.zeros(shape)
        self.success, self.collision = np.zeros(shape, bool), np.zeros(shape, bool)
        self.timeout, self.elapsed = np.zeros(shape, bool), start.astype(np.int64)
        # What ``tally_control_step`` updates, in its order.
        self._running = (self.live, self.reward, self.success, self.collision, self.elapsed, self.timeout)

    def tally(
        self,
        outcome: tuple[np.ndarray, np.ndarray, np.ndarray],
        steps: np.ndarray,
        max_steps: int,
        add: bool,
        count: bool,
    ) -> int:
        """One control step's ``outcome`` (reward, success, collision, as ``control_step`` returns them)
        into the period, as ``tally_control_step`` says; how many robots are still live."""
        return tally_control_step(*outcome, steps, max_steps, add, count, self.start, *self._running)


__all__ = ["Period", "take_decisions", "tally_control_step"]
