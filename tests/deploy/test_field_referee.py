"""The field server playing referee: its script and its checks, the fouls it calls with the envs' rules,
and the deploy loop under it over 127.0.0.1 (STOP, HALT and the opponent's ball placement)."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from hier_ssl.cli import main
from hier_ssl.deploy import wire
from hier_ssl.deploy.assemble import DeploySettings, build_loop
from hier_ssl.deploy.cameras import Cameras
from hier_ssl.deploy.field import STEP, FieldServer
from hier_ssl.deploy.referee import parse_referee
from hier_ssl.deploy.referee_script import START, Call, GameController, ScriptedReferee, parse_script
from hier_ssl.envs import task_config
from hier_ssl.game.fouls import GRACE
from hier_ssl.game.referee import BALL_PLACEMENT_BLUE, FORCE_START, STOP, referee_state
from hier_ssl.game.zones import BALL_DISTANCE, PLACEMENT_DISTANCE, ROBOT_RADIUS, STOP_SPEED
from hier_ssl.world.field import get_field

DIVISION_B = get_field("division_b")


def test_a_script_reads_times_commands_and_placements() -> None:
    calls = parse_script("2.0:STOP, 5:FORCE_START,8.5:BALL_PLACEMENT_YELLOW@1.0,-0.5,12:HALT", DIVISION_B)
    assert calls == (
        Call(2.0, "STOP"),
        Call(5.0, "FORCE_START"),
        Call(8.5, "BALL_PLACEMENT_YELLOW", (1.0, -0.5)),
        Call(12.0, "HALT"),
    )


@pytest.mark.parametrize(
    ("script", "error"),
    [
        (
            "2.0:STOP,1.0:HALT",
            r"entry '1\.0:HALT': time 1 s goes back \(expected after the previous entry's 2 s",
        ),
        ("1:STOP,1:HALT", r"entry '1:HALT': time 1 s goes back"),
        ("-0.5:STOP", r"entry '-0\.5:STOP': time -0\.5 s goes back \(expected at least 0\)"),
        ("soon:STOP", r"entry 'soon:STOP': time 'soon' is not a finite number"),
        ("inf:STOP", r"entry 'inf:STOP': time 'inf' is not a finite number"),
        ("2:STOPP", r"entry '2:STOPP': unknown command 'STOPP'; known: HALT, STOP"),
        ("2:TIMEOUT_BLUE", r"unknown command 'TIMEOUT_BLUE'"),
        ("STOP", r"entry 'STOP': expected TIME:COMMAND\[@X,Y\]"),
        ("2:BALL_PLACEMENT_BLUE", r"BALL_PLACEMENT_BLUE needs a position, BALL_PLACEMENT_BLUE@X,Y"),
        ("2:BALL_PLACEMENT_BLUE@1", r"entry '2:BALL_PLACEMENT_BLUE@1': the position '1': expected X,Y"),
        ("2:BALL_PLACEMENT_BLUE@1,up", r"the position: y 'up' is not a finite number"),
        (
            "2:BALL_PLACEMENT_BLUE@4.6,0",
            r"entry '2:BALL_PLACEMENT_BLUE@4\.6,0': ball placement position \(4\.6",
        ),
        ("2:STOP@1,1", r"entry '2:STOP@1,1': only a ball placement takes a position"),
    ],
)
def test_a_bad_script_entry_is_one_error_naming_it(script: str, error: str) -> None:
    with pytest.raises(ValueError, match=error):
        parse_script(script, DIVISION_B)


def test_the_field_command_refuses_a_bad_script_naming_the_entry(capsys: pytest.CaptureFixture) -> None:
    assert main(["field", "crossing", "--referee-script", "1:STOP,0.5:HALT", "--vision-port", "9"]) == 1
    assert "'0.5:HALT': time 0.5 s goes back" in capsys.readouterr().err


def test_the_game_controller_counts_each_command_issued_and_issues_anew_each_episode() -> None:
    referee = ScriptedReferee(parse_script("1.0:STOP,2.0:BALL_PLACEMENT_BLUE@1,0.5", DIVISION_B), DIVISION_B)
    controller, said = GameController(), []
    for t in (0.0, 0.5, 1.0, 1.5, 2.0):
        state = referee.at(t)
        said.append((int(state.command[0]), parse_referee(controller.packet(state, 1.76e9 + t))))
    assert [command for command, _ in said] == [FORCE_START, FORCE_START, STOP, STOP, BALL_PLACEMENT_BLUE]
    assert [m.counter for _, m in said] == [1, 1, 2, 2, 3]  # one count per command issued
    assert said[3][1].issued == pytest.approx(1.76e9 + 1.0) and said[3][1].sent == pytest.approx(1.76e9 + 1.5)
    assert said[4][1].designated == pytest.approx((1.0, 0.5)) and said[2][1].designated is None
    assert said[2][1].keepers == {"blue": 0, "yellow": 0} and said[2][1].blue_on_positive_half is False
    controller.restart()  # a new episode: FORCE_START issued again, with a new count
    again = parse_referee(controller.packet(referee.at(0.0), 0.0))
    assert (again.command, again.counter) == (START.command, 4)
    sides = referee_state(STOP, DIVISION_B, keeper=(3, 5), blue_on_positive_half=True)
    message = parse_referee(controller.packet(sides, 0.0))
    assert message.keepers == {"yellow": 3, "blue": 5} and message.blue_on_positive_half is True
    with pytest.raises(
        ValueError, match=r"keepers \[-1, 5\] \(yellow, blue\): a Referee message needs an id"
    ):
        controller.packet(referee_state(STOP, DIVISION_B, keeper=(-1, 5)), 0.0)


@pytest.mark.parametrize(("speed", "fouls"), [(1.8, {"stop_speed": 1}), (1.2, {})])
def test_the_field_server_calls_a_stop_speed_foul_with_the_envs_rules(speed: float, fouls: dict) -> None:
    # One robot driven on a 1 m circle through STOP: faster than 1.5 m/s past the 2 s of grace is a foul,
    # called once a stoppage; slower is none.
    config = task_config("proposed")
    script = parse_script("0.1:STOP", get_field(config.field))
    server = FieldServer(config, vision_port=9, seed=6, referee=script, referee_port=9)  # starts mid-field
    try:
        live = server._reset(0)
        server.command[0] = (speed, 0.0, -speed)
        for _ in range(round((0.1 + GRACE) / STEP) + 25):
            server.referee.call(server._ball())
            now = time.monotonic()
            server.commanded[:] = now
            live, over = server._step(live, now)
        [record] = server._records(0)
    finally:
        server.close()
    assert not over and record["fouls"] == fouls
    assert server.referee.foul_counts() == ({"blue 0": fouls} if fouls else {})


def test_the_field_servers_script_lifts_a_free_kicks_restrictions_once_its_ball_is_in_play() -> None:
    # Their free kick (yellow's; ours blue) with our robot held 0.3 m from the still ball: too close, a foul
    # every 2 s of the team's grace, until the ball is in play by the time alone (10 s in Division B, rules
    # 5.4); the script goes on saying the kick, and from then on no foul is called.
    config = task_config("proposed")
    script = parse_script("0.0:DIRECT_FREE_YELLOW", get_field(config.field))
    server = FieldServer(config, vision_port=9, seed=6, referee=script, referee_port=9)
    counts = []
    try:
        live = server._reset(0)
        server.ball = tuple((server.core.world.state.pos[0, 0] + (0.3, 0.0)).tolist())
        for step in range(round(13.0 / STEP)):
            server.referee.call(server._ball())
            now = time.monotonic()
            server.commanded[:] = now
            live, _ = server._step(live, now)
            counts.append((step * STEP, server.referee.rules.in_play[0], server.referee.episode_fouls.sum()))
        again = server._reset(1)
        server.referee.call(server._ball())
    finally:
        server.close()
    before = [fouls for t, in_play, fouls in counts if not in_play]
    after = [fouls for t, in_play, fouls in counts if in_play]
    assert [t for t, in_play, _ in counts if in_play][0] == pytest.approx(10.0, abs=2 * STEP)
    assert before[-1] >= 3 and after == [before[-1]] * len(after) and len(after) > 100
    assert again.all() and not server.referee.rules.in_play.any()  # the next episode's kick starts afresh


class Refereed:
    """The deploy loop (``sampling``, all of crossing's six robots, ``--referee`` on 127.0.0.1) and the
    lockstep field server playing ``script``, each in its thread, until the episode's world time reaches
    ``until`` s (or it ends). Records each world step (time, positions, speeds) and each tick (the command
    the loop took last, the commands it sent)."""

    def __init__(self, script: str, until: float) -> None:
        config = task_config("crossing")
        robots = list(range(config.num_agents))
        settings = DeploySettings(
            "sampling",
            "127.0.0.1:0",
            "grsim:127.0.0.1:9",
            "blue",
            robots,
            {},
            control_port=0,
            task="crossing",
        )
        settings.lockstep, settings.referee, settings.priority = True, "127.0.0.1:0", 0
        # Deciding every period: at the planners' 16, two of crossing's robots meet while braking into the
        # ball's zone and their episodes end there, inside it; the rules, not the planner, are tested here.
        settings.frame_skip = 1
        self.loop = build_loop(settings)
        self.server = FieldServer(
            config,
            self.loop.vision.getsockname()[1],
            cameras=Cameras(pos_noise=0.0, angle_noise=0.0),
            control_port=self.loop.control.port,
            seed=1,
            lockstep=True,
            referee=parse_script(script, get_field(config.field)),
            referee_port=self.loop.referee.sock.getsockname()[1],
        )
        self.loop.sender.address = ("127.0.0.1", self.server.grsim_port)
        self.steps: list[tuple[float, np.ndarray, np.ndarray]] = []
        self.ticks: list[tuple[str | None, list]] = []
        self.stop = threading.Event()
        step, tick = self.server.core.control_step, self.loop.controller.tick

        def recorded_step(*args: object, **kwargs: object) -> tuple:
            out = step(*args, **kwargs)
            state = self.server.core.world.state
            self.steps.append((self.server.core.steps[0] * STEP, state.pos[0].copy(), state.vel[0].copy()))
            if self.steps[-1][0] >= until:
                self.stop.set()
            return out

        def recorded_tick(now: float) -> list:
            commands = tick(now)
            message = self.loop.referee.message
            self.ticks.append((None if message is None else message.command, commands))
            return commands

        self.server.core.control_step, self.loop.controller.tick = recorded_step, recorded_tick

    def run(self) -> Refereed:
        thread = threading.Thread(target=self.loop.run, args=(self.stop, 60.0))
        thread.start()
        try:
            self.server.run(1, self.stop)
        finally:
            self.stop.set()
            thread.join()
            self.server.close()
            self.loop.close()
        return self

    def during(self, start: float, end: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
        """Positions and speeds (steps, M) of the steps that end in [start, end) s of world time."""
        kept = [(pos, np.hypot(*vel.T)) for t, pos, vel in self.steps if start <= t < end]
        return np.array([p for p, _ in kept]), np.array([s for _, s in kept])


def test_stop_slows_and_clears_the_ball_and_halt_stops_under_the_field_servers_script() -> None:
    # Crossing's robots meet in the middle, where the ball lies: STOP comes as they drive through it.
    game = Refereed("1.4:STOP,3.9:HALT", until=4.4).run()
    ball = np.array(game.server.ball)
    _, speed = game.during(1.4 - STEP, 1.4)
    assert speed.max() > STOP_SPEED + 0.3  # driving fast when STOP comes
    pos, _ = game.during(1.4, 1.4 + 1.0)
    assert (
        np.hypot(*(pos - ball).T) - ROBOT_RADIUS
    ).min() < BALL_DISTANCE  # and braking into the ball's zone
    _, slowed = game.during(1.4 + 1.0, 3.9)
    assert slowed.max() < STOP_SPEED  # rules 5.1.1, within a second
    pos, _ = game.during(1.4 + 2.0, 3.9)
    assert (np.hypot(*(pos - ball).T) - ROBOT_RADIUS).min() >= BALL_DISTANCE  # within 2 s
    halted = [commands for command, commands in game.ticks if command == "HALT"]
    assert len(halted) > 10 and all(c[1:] == (0.0, 0.0, 0.0) for commands in halted for c in commands)
    stopped = [commands for command, commands in game.ticks if command == "STOP"]
    assert any(c[1:] != (0.0, 0.0, 0.0) for commands in stopped for c in commands)  # STOP slows, HALT stops


def test_our_robots_leave_the_opponents_ball_placement_within_2_s_under_the_field_servers_script() -> None:
    target = np.array([1.0, 1.0])
    game = Refereed(f"1.0:BALL_PLACEMENT_YELLOW@{target[0]},{target[1]}", until=4.0).run()
    ball = np.array(game.server.ball)

    # Each robot's distance to the stadium's segment from the ball to the placement position.
    def gap(pos: np.ndarray) -> np.ndarray:
        along = np.clip(((pos - ball) @ (target - ball)) / np.sum((target - ball) ** 2), 0.0, 1.0)
        return np.linalg.norm(pos - (ball + along[..., None] * (target - ball)), axis=-1) - ROBOT_RADIUS

    assert gap(game.during(1.0, 2.0)[0]).min() < PLACEMENT_DISTANCE  # some drove into it meanwhile
    assert gap(game.during(1.0 + GRACE)[0]).min() >= PLACEMENT_DISTANCE  # rules 8.4.3: none after 2 s
    assert game.server.referee.foul_counts() == {}  # so no interference either


def test_the_cameras_see_the_worlds_ball_where_the_task_has_one_and_the_still_one_otherwise() -> None:
    game = FieldServer(task_config("game_stop"), vision_port=9, seed=0, team="yellow")
    still = FieldServer(task_config("proposed"), vision_port=9, seed=0, ball=(0.5, -0.25))
    try:
        seen = []
        for server in (game, still):
            server._reset(0)
            pending: list = []
            server._capture(0, pending, 0.0)
            frames = [wire.parse_vision(packet) for _, _, packet in pending]
            seen.append([f.ball for f in frames if isinstance(f, wire.DetectionFrame) and f.ball is not None])
        rolled = game.core.world.ball.pos[0, 0]
    finally:
        game.close()
        still.close()
    assert len(seen[0]) >= 1 and len(seen[1]) >= 1
    np.testing.assert_allclose(seen[0][0], rolled, atol=1e-4)  # mm on the wire, float32
    np.testing.assert_allclose(seen[1][0], (0.5, -0.25), atol=1e-4)
