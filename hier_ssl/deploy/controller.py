"""One control period of the controlled robots: tracked state -> decisions every ``frame_skip`` periods ->
worker commands, with the safety rule that a robot not seen lately gets a zero command.

Pure of sockets and clocks: ``tick(now)`` takes the monotonic time and returns the commands to send, so
the loop (``hier_ssl.deploy.loop``), the tests and the benchmark drive it alike.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from hier_ssl.deploy.game import InPlayWatch, game_rules, labelled_lineup, same_call
from hier_ssl.deploy.tracker import Tracker
from hier_ssl.deploy.view import DeployView
from hier_ssl.deploy.wire import Command, DetectionFrame
from hier_ssl.game.legal import SPEED_MARGIN, RowRules, cap_speed
from hier_ssl.game.referee import RefereeState
from hier_ssl.world.physics import RobotState

MAX_AGE = 0.05  # s: a robot unseen for longer is stopped (the loop ticks at most 35 ms apart: < 100 ms)
OTHERS_AGE = 0.5  # s: an other robot unseen for longer is no longer an obstacle
FEEDBACK = ("command", "tracked", "model")
BALL_AGE = 1.0  # s: a ball unseen for longer is not known (out of sight, or picked up)


def check_target(robot: object, target: object, robots: Sequence[int], reach: np.ndarray) -> np.ndarray:
    """``target`` as a float array (5,) x, y, theta, vx, vy for controlled ``robot``; ValueError naming
    what is wrong: an unknown robot, not 3 or 5 finite numbers, a position outside the walls."""
    if isinstance(robot, bool) or not isinstance(robot, int) or robot not in robots:
        raise ValueError(f"robot {robot!r} is not a controlled robot {list(robots)}")
    if not isinstance(target, (list, tuple)) or len(target) not in (3, 5):
        raise ValueError(
            f"target of robot {robot}: expected [x, y, theta] or [x, y, theta, vx, vy], got {target!r}"
        )
    if any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in target):
        raise ValueError(f"target of robot {robot}: expected finite numbers, got {target!r}")
    values = np.zeros(5)
    values[: len(target)] = target
    if (np.abs(values[0:2]) > reach).any():
        raise ValueError(
            # tolist(): plain floats, which print as numbers rather than as np.float64(...).
            f"target of robot {robot} at {values[0:2].tolist()} is outside the walls (+-{reach.tolist()} m)"
        )
    return values


class Controller:
    """The controlled ``robots`` (ids) of ``team``, acting through ``view`` on ``tracker``'s state.

    ``feedback`` is the velocity the worker steers from. "model" (the default): each controlled robot's
    velocity as the world's robot answers the commands sent to it (``DeployView.respond``: the command,
    reached within the acceleration limits), taken from the tracker when the robot gets a new target;
    that is what the core's worker steers from. "command": the last command itself, for robots that reach
    any command within a period. "tracked": the tracker's estimate, for robots that do not follow their
    commands closely (the same model, corrected by vision, with its noise). Obstacle, ``sampling``, the
    same 20 episodes through the wire (no vision noise) against ``hier-ssl eval``'s loop: episodes longer
    by 0.65 control steps on average with "model", 8.1 with "command", 29.5 with "tracked" (10, before
    the tracker was told the commands: its velocity lagged, and the paper's incremental worker accelerated
    late and overshot). The manager always observes the tracked state. Every command sent is told to the
    tracker (``Tracker.command``), the control input of the controlled robots' filters.
    """

    def __init__(
        self,
        view: DeployView,
        tracker: Tracker,
        team: str,
        robots: Sequence[int],
        max_age: float = MAX_AGE,
        feedback: str = "model",
    ) -> None:
        if len(set(robots)) != len(robots) or not robots:
            raise ValueError(f"robots: expected distinct ids, got {list(robots)}")
        if feedback not in FEEDBACK:
            raise ValueError(f"worker feedback {feedback!r}: expected one of {FEEDBACK}")
        self.feedback = feedback
        self.sent = np.zeros((view.n, view.m, 3))  # the last commands, robot frame
        # The "model" feedback: velocities (N, M, 2) and spins (N, M); ``anchor``: take them from the tracker
        # at the next tick (a new target: the robot may have been moved, e.g. a field server's new episode).
        self.model_vel, self.model_spin = np.zeros((view.n, view.m, 2)), np.zeros((view.n, view.m))
        self.anchor = np.ones((view.n, view.m), dtype=bool)
        self.view, self.tracker, self.team = view, tracker, team
        self.robots, self.max_age = list(robots), max_age
        self.keys = [(team, robot) for robot in robots]
        self.players = labelled_lineup(self.keys)  # the rules' lineup of the controlled robots
        self.has_target = np.zeros(len(robots), dtype=bool)
        self.was_live = np.zeros(len(robots), dtype=bool)
        self.since_decision = 0
        self.decide_now = True
        # The referee's state in force (None: no referee, no rules), set by the loop before each tick, and
        # the rules made of it and the ball (``game_rules``), kept while both are the same.
        self.referee: RefereeState | None = None
        self.in_play = InPlayWatch(view.field)  # the free kick's ball in play, which the controller sends not
        self._rules: tuple[RefereeState | None, tuple[float, float] | None, RowRules | None] = (
            None,
            None,
            None,
        )

    def set_target(self, robot: object, target: object) -> None:
        """Give controlled ``robot`` a new target (``check_target``); it decides at the next period."""
        values = check_target(robot, target, self.robots, self.view.reach)
        i = self.robots.index(robot)
        m = self.view.m
        self.view.target[i // m, i % m] = values
        self.has_target[i] = True
        self.anchor[i // m, i % m] = True
        self.decide_now = True

    def on_frame(self, frame: DetectionFrame, arrival: float) -> None:
        self.tracker.update(frame, arrival)

    def live(self, now: float) -> np.ndarray:
        """(robots,) bool: seen within ``max_age`` of ``now`` and given a target."""
        fresh = [self.tracker.fresh(key, now, self.max_age) for key in self.keys]
        return np.array(fresh) & self.has_target

    def tick(self, now: float) -> list[Command]:
        """Commands of one control period at monotonic time ``now``: a zero command for every robot that is
        not live, the worker's command toward the held sub-goal for the others."""
        live, t = self.live(now), self.tracker.vision_time(now)
        rules = self.rules(now)
        halted = rules is not None and not (rules.speed > 0).any()  # HALT: no robot may move
        if not live.any() or halted:
            self.decide_now = self.decide_now or halted  # out of a HALT, the robots decide afresh
            self.was_live, self.sent = live, np.zeros_like(self.sent)
            # Stopping: the modelled robots brake too (a zero command needs no heading).
            self.model_vel, self.model_spin = self.view.respond(
                self.model_vel, self.model_spin, self.sent, self.model_spin
            )
            return self._told(self.stop(), t)
        keys = set(self.keys)
        others = [
            key for key in self.tracker.tracks if key not in keys and self.tracker.fresh(key, now, OTHERS_AGE)
        ]
        rows = self.tracker.state(self.keys + others, t)
        view = self.view
        state = view.state(rows, view.fields(rows))
        grid = live.reshape(view.n, view.m)
        if self.decide_now or self.since_decision >= view.frame_skip or (live & ~self.was_live).any():
            if view.game and self.referee is not None:
                # The state ``rules`` played above: the one received, its free kick's ball in play or not.
                view.set_game(self._rules[0] or self.referee, self._ball(now))
            view.decide(state, grid, rules)
            self.since_decision, self.decide_now = 0, False
        self.since_decision += 1
        self.was_live = live
        self.sent = np.where(grid[..., None], view.commands(self._feedback(state)), 0.0)
        if rules is not None:
            limit = SPEED_MARGIN * rules.speed.reshape(view.n, view.m)
            self.sent[..., 0:2] = cap_speed(self.sent[..., 0:2], limit)
        self.model_vel, self.model_spin = view.respond(
            self.model_vel, self.model_spin, self.sent, state.angle[:, : view.m]
        )
        command = self.sent.reshape(-1, 3)
        return self._told([(robot, *map(float, command[i])) for i, robot in enumerate(self.robots)], t)

    def rules(self, now: float) -> RowRules | None:
        """The rules of the controlled robots under ``referee`` at monotonic ``now`` (None without a
        referee), the ball where vision saw it within ``BALL_AGE``."""
        if self.referee is None:
            return None
        ball = self._ball(now)
        played = self.in_play(self.referee, now, ball)
        referee, held_ball, _ = self._rules
        if referee is not played or held_ball != ball:
            rules = game_rules(played, self.view.field, self.players, ball)
            # A new call (command, keepers, sides, placement): decide under it now; a ball that moved: the
            # next decision plans round it. Compared by value: each message is a new object (a field server
            # sends one a period), and deciding on each would decide every period, not every frame_skip.
            self.decide_now = self.decide_now or not same_call(referee, played)
            self._rules = (played, ball, rules)
        return self._rules[2]

    def _ball(self, now: float) -> tuple[float, float] | None:
        """The ball where vision saw it within ``BALL_AGE`` of monotonic ``now`` (None: not known)."""
        return self.tracker.ball if now - self.tracker.ball_seen <= BALL_AGE else None

    def _told(self, commands: list[Command], t: float) -> list[Command]:
        """``commands``, told to the tracker as sent at vision time ``t``: its filters' control input."""
        for key, command in zip(self.keys, commands, strict=True):
            self.tracker.command(key, t, command[1:])
        return commands

    def _feedback(self, state: RobotState) -> RobotState:
        """``state`` with the controlled robots' velocities the worker steers from (class docstring)."""
        if self.feedback == "tracked":
            return state
        if self.feedback == "command":
            return self.view.commanded(state, self.sent)
        m, anchor = self.view.m, self.anchor
        self.model_vel[anchor] = state.vel[:, :m][anchor]
        self.model_spin[anchor] = state.ang_vel[:, :m][anchor]
        anchor[:] = False
        vel, spin = state.vel.copy(), state.ang_vel.copy()
        vel[:, :m], spin[:, :m] = self.model_vel, self.model_spin
        return RobotState(state.pos, state.angle, vel, spin)

    def stop(self) -> list[Command]:
        """A zero command for every controlled robot."""
        return [(robot, 0.0, 0.0, 0.0) for robot in self.robots]


__all__ = ["BALL_AGE", "FEEDBACK", "MAX_AGE", "Controller", "check_target"]
