"""A loopback field server: hier_ssl's own world standing in for grSim or a real field.

One field of a task or scenario (``HierarchicalCore``, its obstacle behaviours and rules) steps every
25 ms of wall-clock time. Cameras (``hier_ssl.deploy.cameras``) split the walled area along x into strips
that overlap, each publishing an SSL-Vision detection frame at ``rate`` Hz of what it sees (the latest
world step, with Gaussian noise, each detection dropped with probability ``drop``, sent ``latency`` s after
capture), and a geometry packet once a second. The controlled robots are team ``team`` ids 0..M-1, the
obstacles the other team's ids 0..K-1. Commands arrive as grSim packets or simulation-protocol
``RobotControl`` (answered with a ``RobotControlResponse``) on 127.0.0.1; a robot whose last command is
older than ``COMMAND_TIMEOUT`` stops, as robot firmware does.

Episodes: after a reset the robots stand for ``settle`` s while the cameras publish, then each controlled
robot's target goes to the controller's control socket (JSON lines); the world steps from the first
period in which every controlled robot has been commanded since (or ``COMMAND_TIMEOUT`` later) and the
episode runs to success, collision or ``max_steps``, scored by the task's rules, one record per robot.

Lockstep (``lockstep``): the world steps once per command period instead of on its own clock. After each
step every camera publishes the frames of the step's period at once (capture time: the world's own clock,
25 ms a step), then the world waits for a command of every controlled robot, or ``COMMAND_TIMEOUT`` so that
a lost command cannot stall it, and steps once. Two free-running clocks (the world's steps, the
controller's ticks) let one command act for no step or for two; in lockstep each acts for exactly one, as
in ``hier-ssl eval``, so the through-the-wire episodes follow the directly played ones. The controller
ticks on the frames (``hier-ssl deploy --lockstep``). grSim and a real field run on their own clocks: the
free-running mode is the one that stands in for them.

Referee (``referee``, a script of ``hier_ssl.deploy.referee_script``): the field server plays the game
controller too, and calls the fouls of every robot of both teams (``hier_ssl.deploy.field_referee``). A
game scenario (``hier_ssl.envs.game``) plays its own referee: its state goes out the same way, its targets
go to the controller again when its command changes them, and its fouls are its own (the team is then
yellow, as the scenario's). The ball is the world's where the task's world has one (the game
scenarios), otherwise one lying still at ``ball`` (the centre spot unless given); either goes into the
cameras' frames and the rules.
"""

from __future__ import annotations

import heapq
import json
import math
import selectors
import socket
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from hier_ssl.config import TaskConfig
from hier_ssl.deploy.cameras import Cameras, camera_frames, camera_strips
from hier_ssl.deploy.field_referee import REFEREE_PORT, FieldReferee
from hier_ssl.deploy.net import LOOPBACK, receive
from hier_ssl.deploy.referee_script import Call
from hier_ssl.deploy.wire import (
    TEAMS,
    PacketError,
    encode_detection,
    encode_geometry,
    encode_response,
    parse_grsim,
    parse_simulation,
)
from hier_ssl.envs.core import HierarchicalCore

STEP = 0.025  # s
COMMAND_TIMEOUT = 0.1  # s
# How long the controller may take to answer the targets (s): a loaded machine can hold its loop for a
# second or more, a controller that never answers must not hang the field.
ANSWER_WAIT = 10.0


class FieldServer:
    """Serves one field of ``config`` over 127.0.0.1 (module docstring), free-running or in ``lockstep``,
    playing ``referee`` (a parsed script; None: no referee, no fouls called). Ports 0 pick free ones, read
    back as ``grsim_port`` and ``simulation_port``."""

    def __init__(
        self,
        config: TaskConfig,
        vision_port: int,
        team: str = "blue",
        cameras: Cameras | None = None,
        grsim_port: int = 0,
        simulation_port: int = 0,
        control_port: int | None = None,
        seed: int = 0,
        settle: float = 0.15,
        lockstep: bool = False,
        referee: tuple[Call, ...] | None = None,
        referee_port: int = REFEREE_PORT,
        ball: tuple[float, float] | None = None,
    ) -> None:
        if team not in TEAMS:
            raise ValueError(f"team {team!r}: expected one of {TEAMS}")
        self.team, self.cameras, self.lockstep = team, cameras or Cameras(), lockstep
        if lockstep and (self.cameras.rate * STEP < 1 or self.cameras.latency > 0):
            raise ValueError(
                f"lockstep: every camera must see every world step (rate >= {1 / STEP:g} Hz) and the world "
                f"waits for the commands (latency 0), got rate {self.cameras.rate} Hz, latency "
                f"{self.cameras.latency} s"
            )
        self.core = HierarchicalCore(config, num_fields=1, autoreset=False)
        self.m, self.k = self.core.num_agents, self.core.num_obstacles
        # One step before the ports are announced builds the core's compiled kernels (seconds on a cold
        # cache), which a client timing from the announcement would count; ``run`` resets first.
        self.core.reset(seed)
        self.core.hold_subgoal(self.core.target)
        self.core.control_step(np.ones((1, self.m), bool), worker_action=np.zeros((1, self.m, 3)))
        other = TEAMS[1 - TEAMS.index(team)]
        self.labels = [(team, i) for i in range(self.m)] + [(other, j) for j in range(self.k)]
        fld = self.core.field
        self.strips = camera_strips(self.cameras, fld.wall_half_extent[0])
        self.geometry = encode_geometry(fld)
        self.vision_to, self.control_port = (LOOPBACK, vision_port), control_port
        self.seed, self.settle, self.rng = seed, settle, np.random.default_rng(seed)
        self.out = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.out.bind((LOOPBACK, 0))
        self.grsim, self.simulation = (self._listen(p) for p in (grsim_port, simulation_port))
        self.grsim_port, self.simulation_port = (s.getsockname()[1] for s in (self.grsim, self.simulation))
        limits = self.core.robot
        self.scale = np.array([limits.max_speed, limits.max_speed, limits.max_ang_speed])
        self.command = np.zeros((self.m, 3))
        self.commanded = np.full(self.m, -np.inf)
        self.dropped = self.frames_sent = 0
        self.capture_time = time.time()
        self.stopping = threading.Event()  # ``run``'s stop
        self.referee = FieldReferee(self.core, self.labels, team, referee, referee_port, self.out, STEP)
        self.ball = (0.0, 0.0) if ball is None and referee is not None else ball

    @staticmethod
    def _listen(port: int) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.bind((LOOPBACK, port))
        sock.setblocking(False)
        return sock

    def close(self) -> None:
        for sock in (self.out, self.grsim, self.simulation):
            sock.close()

    def run(
        self, episodes: int | None, stop: threading.Event, on_record: Callable[[dict], None] | None = None
    ) -> list[dict[str, Any]]:
        """Play ``episodes`` episodes (None: until ``stop``), in real time or in lockstep; one record per
        robot, each also handed to ``on_record`` as its episode ends."""
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.grsim, selectors.EVENT_READ, self._read_grsim)
        self.selector.register(self.simulation, selectors.EVENT_READ, self._read_simulation)
        control, self.stopping = None, stop
        if self.control_port is not None:
            control = socket.create_connection((LOOPBACK, self.control_port), timeout=1.0)
            control.settimeout(COMMAND_TIMEOUT)  # the answers' wait checks ``stop`` this often
        records: list[dict[str, Any]] = []

        def ended(episode: int) -> None:
            for record in self._records(episode):
                records.append(record)
                if on_record is not None:
                    on_record(record)

        try:
            play = self._run_lockstep if self.lockstep else self._run_free
            play(episodes, stop, control, ended)
        finally:
            self.selector.close()
            if control is not None:
                control.close()
        return records

    def _serve(self, timeout: float) -> None:
        """Take the commands that come within ``timeout`` s."""
        for key, _ in self.selector.select(timeout):
            key.data()

    def _run_free(
        self, episodes: int | None, stop: threading.Event, control: Any, ended: Callable[[int], None]
    ) -> None:
        """The world steps every ``STEP`` s of wall-clock time; the cameras publish at their rate."""
        pending: list[tuple[float, int, bytes]] = []  # (send time, order, packet)
        clock, episode, frame = time.monotonic, 0, 0
        live, start = self._reset(episode), clock()
        next_step, next_frame, running, sent = start + STEP, start, False, None
        while not stop.is_set() and (episodes is None or episode < episodes):
            self._serve(max(0.0, min(next_step, next_frame, pending[0][0] if pending else np.inf) - clock()))
            now = clock()
            while pending and pending[0][0] <= now:
                self.out.sendto(heapq.heappop(pending)[2], self.vision_to)
            if now >= next_frame:
                frame = self._capture(frame, pending, now)
                next_frame += 1.0 / self.cameras.rate
            if now < next_step:
                continue
            next_step += STEP
            self.capture_time = time.time()  # the world as it stands now: stepped below, or still
            self.referee.call(self._ball())
            if sent is None and now - start >= self.settle:
                self._send_targets(control)
                self._read_grsim()  # commands sent before the targets were taken: not the first ones
                self._read_simulation()
                sent = clock()
            # The first step waits for the controller's first commands (at most COMMAND_TIMEOUT), as
            # the core's first control step already carries the worker's command.
            if not running and sent is not None:
                running = (self.commanded > sent).all() or now - sent > COMMAND_TIMEOUT
            if running:
                live, over = self._step(live, now)
                self._send_new_targets(control)
                if over:
                    ended(episode)
                    episode += 1
                    live, start, running, sent = self._reset(episode), now, False, None

    def _run_lockstep(
        self, episodes: int | None, stop: threading.Event, control: Any, ended: Callable[[int], None]
    ) -> None:
        """The world's clock advances ``STEP`` per world step (world time ``step * STEP`` from the start):
        after the frames of a step the world waits for every controlled robot's command, at most
        ``COMMAND_TIMEOUT`` of wall-clock time, and steps once. While the robots settle the world stands
        and its clock runs at wall-clock speed."""
        clock, episode, frame, step, epoch = time.monotonic, 0, 0, 0, time.time()
        while not stop.is_set() and (episodes is None or episode < episodes):
            live, over = self._reset(episode), False
            for _ in range(round(self.settle / STEP)):
                frame, step, until = self._publish(frame, step, epoch), step + 1, clock() + STEP
                while clock() < until:
                    self._serve(until - clock())
            self._send_targets(control)
            while not (over or stop.is_set()):
                # A command queued now answers older frames (a controller's tick on its own clock): it
                # acts, but is not this step's.
                self._read_grsim()
                self._read_simulation()
                frame, step, published = self._publish(frame, step, epoch), step + 1, clock()
                while not (self.commanded > published).all() and clock() - published <= COMMAND_TIMEOUT:
                    self._serve(max(0.0, published + COMMAND_TIMEOUT - clock()))
                live, over = self._step(live, clock())
                self._send_new_targets(control)
            if over:
                ended(episode)
                episode += 1

    def _publish(self, frame: int, step: int, epoch: float) -> int:
        """Lockstep: the frames of world step ``step`` (world time ``epoch + step * STEP``), sent now: each
        camera's frames whose capture falls in the step's period at the camera's rate (one or two at 60
        Hz, always at least one: the controller ticks on them); the next frame number."""
        self.capture_time = epoch + step * STEP
        self.referee.call(self._ball())
        t0, t1 = (round(k * STEP * self.cameras.rate, 9) for k in (step, step + 1))
        pending: list[tuple[float, int, bytes]] = []
        for _ in range(math.ceil(t1) - math.ceil(t0)):
            frame = self._capture(frame, pending, 0.0)
        for _, _, packet in sorted(pending):
            self.out.sendto(packet, self.vision_to)
        return frame

    def _reset(self, episode: int) -> np.ndarray:
        self.core.reset(self.seed + episode)
        # The managers act in the controller: success is the robot settled on its target.
        self.core.hold_subgoal(self.core.target)
        self.command[:] = 0.0
        self.outcome = {"success": np.zeros(self.m, bool), "collision": np.zeros(self.m, bool)}
        self.length = np.zeros(self.m, dtype=np.int64)
        self.referee.restart()
        return np.ones((1, self.m), dtype=bool)

    def _ball(self) -> tuple[float, float] | None:
        """Where the ball is: the world's first, where its world has balls, or the still one."""
        balls = self.core.world.ball
        return self.ball if balls is None else tuple(balls.pos[0, 0].tolist())

    def _step(self, live: np.ndarray, now: float) -> tuple[np.ndarray, bool]:
        command = np.where((now - self.commanded <= COMMAND_TIMEOUT)[:, None], self.command, 0.0)
        before = self.referee.motion() if self.referee.script is not None else None
        _, success, hit = self.core.control_step(live, worker_action=(command / self.scale)[None])
        if before is not None:
            self.referee.call_fouls(before, self._ball())
        self.length += live[0]
        self.outcome["success"] |= success[0]
        self.outcome["collision"] |= hit[0]
        live = live & ~(success | hit)
        timeout = self.core.steps[0] >= self.core.config.max_steps
        return live, bool(timeout or not live.any())

    def _records(self, episode: int) -> list[dict[str, Any]]:
        """One record per controlled robot; with a referee, its fouls of the episode by kind."""
        records = [
            {
                "episode": episode,
                "robot": i,
                "success": bool(self.outcome["success"][i]),
                "collision": bool(self.outcome["collision"][i]),
                "length": int(self.length[i]),
            }
            for i in range(self.m)
        ]
        self.referee.add_fouls(records)
        return records

    def _capture(self, frame: int, pending: list, now: float) -> int:
        """Every camera's frame of the world as it stands, queued in ``pending`` to go out ``latency`` s
        after ``now``; a geometry packet with every ``rate``-th round of frames; the next frame number."""
        s = self.core.world.state
        frames = camera_frames(
            s.pos[0],
            s.angle[0],
            self.labels,
            self.cameras,
            self.strips,
            self.capture_time,
            self.rng,
            self._ball(),
        )
        send_at = now + self.cameras.latency
        for camera in frames:
            heapq.heappush(pending, (send_at, frame, encode_detection(frame, camera)))
            frame += 1
        if frame // self.cameras.count % round(self.cameras.rate) == 0:
            heapq.heappush(pending, (send_at, frame, self.geometry))
        self.frames_sent += len(frames)
        return frame

    def _send_new_targets(self, control: socket.socket | None) -> None:
        """The targets again where the task changed them in mid-episode (a game scenario's command): held as
        the sub-goals, as at the reset, and sent to the controller."""
        if not np.array_equal(self.core.target, self.targets_sent):
            self.core.hold_subgoal(self.core.target)
            self._send_targets(control)

    def _send_targets(self, control: socket.socket | None) -> None:
        """Each controlled robot's target to the controller; RuntimeError with its answer if refused or if
        it closed the socket, TimeoutError if it did not answer within ``ANSWER_WAIT`` s. Once ``run``'s
        ``stop`` is set the answers are not waited for: the controller may be stopping too."""
        self.targets_sent = self.core.target.copy()
        if control is None:
            return
        for i in range(self.m):
            target = [round(float(v), 6) for v in self.core.target[0, i]]
            control.sendall(json.dumps({"robot": i, "target": target}).encode() + b"\n")
        answers, until = b"", time.monotonic() + ANSWER_WAIT
        while answers.count(b"\n") < self.m:
            try:
                data = control.recv(4096)
            except TimeoutError:
                data = None
            if self.stopping.is_set():
                return
            if data == b"":
                raise RuntimeError("the controller closed its control socket")
            if data is None and time.monotonic() > until:
                raise TimeoutError(f"the controller did not answer the targets within {ANSWER_WAIT} s")
            answers += data or b""
        refused = [a for a in answers.decode().splitlines() if "error" in json.loads(a)]
        if refused:
            raise RuntimeError(f"the controller refused a target: {refused[0]}")

    def _apply(self, commands: list, now: float) -> None:
        for robot, forward, left, angular in commands:
            if 0 <= robot < self.m:
                self.command[robot] = (forward, left, angular)
                self.commanded[robot] = now

    def _read_grsim(self) -> None:
        while (packet := receive(self.grsim)) is not None:
            try:
                yellow, commands = parse_grsim(packet[0])
            except PacketError:
                self.dropped += 1
                continue
            if yellow == (self.team == "yellow"):
                self._apply(commands, time.monotonic())

    def _read_simulation(self) -> None:
        while (packet := receive(self.simulation)) is not None:
            data, sender = packet
            try:
                commands, other = parse_simulation(data)
            except PacketError as err:
                self.dropped += 1
                self.simulation.sendto(encode_response([("INVALID_PACKET", str(err))]), sender)
                continue
            self._apply(commands, time.monotonic())
            errors = [("UNSUPPORTED_MOVE", f"robot {i}: only local velocity is simulated") for i in other]
            self.simulation.sendto(encode_response(errors), sender)
