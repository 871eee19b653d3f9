"""The field server as referee: the game controller's messages it sends and the fouls it calls.

Each time the world's clock moves on a period the field server sends the ``Referee`` message of the command
in force at the episode's time to 127.0.0.1:``referee_port`` (before the period's frames, so that the
controller's tick on them is under it): a referee script's (``hier_ssl.deploy.referee_script``) or a game
scenario's own state (``hier_ssl.envs.game``). Under a script it calls the fouls of each world step with
the rules' functions the environments call (``hier_ssl.game.fouls.step_fouls``), for every robot of both
teams; a game scenario's fouls are its own. Either way they are counted by robot and kind in each episode's
records and over the run.
"""

from __future__ import annotations

import socket
import time
from typing import Any

import numpy as np

from hier_ssl.deploy.game import InPlayWatch, labelled_lineup
from hier_ssl.deploy.net import LOOPBACK
from hier_ssl.deploy.referee_script import Call, GameController, ScriptedReferee
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.game import FOULED, GameScenario
from hier_ssl.game.fouls import KINDS, Motion, new_clocks, step_fouls

REFEREE_PORT = 10003  # the game controller's port in the league (its multicast group's)


class FieldReferee:
    """The referee of the field server's one field (``core``, world steps of ``step`` s) over its robots
    ``labels`` (team, id; the controlled robots of ``team`` first): a ``script``'s (parsed; None: no
    script, no fouls called) or a game scenario's own, its messages sent through ``out`` to
    127.0.0.1:``port``."""

    def __init__(
        self,
        core: HierarchicalCore,
        labels: list[tuple[str, int]],
        team: str,
        script: tuple[Call, ...] | None,
        port: int,
        out: socket.socket,
        step: float,
    ) -> None:
        self.game = isinstance(core.scenario, GameScenario)  # it plays its own referee, calls its fouls
        if self.game and (script is not None or team != "yellow"):
            raise ValueError(
                f"{core.scenario.name}: a game scenario plays its own referee (no referee script) and "
                f"its controlled robots are the yellow team (team 'yellow'), got team {team!r}"
            )
        self.core, self.labels, self.team, self.out, self.step = core, labels, team, out, step
        self.script = None if script is None else ScriptedReferee(script, core.field)
        self.in_play = InPlayWatch(core.field)
        self.game_controller, self.to = GameController(), (LOOPBACK, port)
        self.players = labelled_lineup(labels)
        self.fouls = np.zeros((len(labels), len(KINDS)), dtype=np.int64)  # by robot and kind, the run's

    def restart(self) -> None:
        """A new episode: the game controller's counters and, under a script, the fouls' clocks and its free
        kicks' ball in play."""
        self.game_controller.restart()
        self.in_play = InPlayWatch(self.core.field)
        if self.script is not None:
            self.clocks, self.episode_fouls = new_clocks(1, len(self.labels)), np.zeros_like(self.fouls)
            self.touching = np.zeros_like(self.core.world.robot_contacts)

    def call(self, ball: tuple[float, float] | None) -> None:
        """The referee's message at the episode's time, sent now: the script's or the game scenario's state
        (neither: nothing). Under a script the fouls are called under its state with the free kick's ball
        in play once it is (``InPlayWatch``, from the ``ball`` where it lies): the game controller goes on
        sending the kick, and a defender near a ball in play commits no foul (rules 5.4)."""
        if self.script is not None:
            now = self.core.steps[0] * self.step
            self.rules = self.in_play(self.script.at(now), now, ball)
        elif self.game:
            self.rules = self.core.scenario.referee_of(None)
        else:
            return
        wall = time.time()
        self.out.sendto(self.game_controller.packet(self.rules, wall), self.to)

    def motion(self) -> Motion:
        state = self.core.world.state
        return Motion(state.pos.copy(), state.vel.copy())

    def call_fouls(self, before: Motion, ball: tuple[float, float] | None) -> None:
        """The fouls of the world step from ``before`` (``step_fouls``) with the ``ball`` where it is, added
        to the episode's and the run's counts; a contact is a crash's only in the step it begins."""
        touching = np.triu(self.core.world.robot_contacts, 1)
        began = np.argwhere(touching & ~self.touching)
        self.touching = touching
        self.clocks, report = step_fouls(
            self.clocks,
            self.rules,
            self.players,
            self.core.field,
            before,
            self.motion(),
            np.array([ball], dtype=float),
            began,
            self.step,
        )
        self.episode_fouls += report.by_robot[0]
        self.fouls += report.by_robot[0]

    def foul_counts(self, fouls: np.ndarray | None = None) -> dict[str, dict[str, int]]:
        """``fouls`` (robots, kinds; default the run's) by robot ("blue 0") and kind, robots without any
        left out."""
        fouls = self.fouls if fouls is None else fouls
        return {
            f"{team} {robot}": {kind: int(n) for kind, n in zip(KINDS, row, strict=True) if n}
            for (team, robot), row in zip(self.labels, fouls, strict=True)
            if row.any()
        }

    def add_fouls(self, records: list[dict[str, Any]]) -> None:
        """The episode's fouls into its ``records`` (one per controlled robot): by kind under a script or a
        game scenario, and with the latter whether one ended the robot's episode."""
        if self.game:  # the scenario's own fouls, which end a robot's episode
            self.episode_fouls = np.zeros_like(self.fouls)
            self.episode_fouls[: len(records)] = self.core.scenario.fouls[0]
            self.fouls += self.episode_fouls
            for i, record in enumerate(records):
                record["foul"] = bool(self.core.scenario.way[0, i] == FOULED)
        if self.script is not None or self.game:
            fouls = self.foul_counts(self.episode_fouls)
            for i, record in enumerate(records):
                record["fouls"] = fouls.get(f"{self.team} {i}", {})
