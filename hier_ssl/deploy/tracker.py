"""Detections from several cameras -> each robot's pose and velocity, predicted to the command's send time.

Every robot (team, id) has a constant-velocity Kalman filter on x, y and the heading, three independent
axes of (value, rate) with white-noise acceleration. The team's own robots are told what the loop sent
them (``command``): their filters take it as the control input, the velocity moving towards the command
within the robot's acceleration limits as the world's robots answer it (``follow``), so a robot that
speeds up or brakes is not lagged, and only what the commands do not explain is process noise
(``command_accel``). A constant-velocity filter on such a robot, agile enough to follow it, lags it by
about 0.1 m/s (``hier_ssl.deploy.bench.tracking_error``). A command holds from the vision time of the tick
that sent it until the next; a robot's delay in obeying (radio, firmware) is not modelled and shows as
process noise, and a robot that does not obey at all is pulled back by vision.

A camera frame updates every robot in it at the frame's capture time; a robot seen by two overlapping
cameras in one frame is simply measured twice, a frame older than a robot's filter is compared with the
filter's estimate back at its capture time and corrects the present estimate (no filter runs backwards).
A measurement further than ``gate`` from the prediction, or one after ``forget`` seconds unseen, restarts
that robot's filter where it was seen: a robot carried across the field, or replaced.

Times: filters run on the vision machine's clock (the frames' ``t_capture``). ``vision_time(now)`` maps
this process's monotonic clock onto it from the newest frame: its ``t_sent`` was read at its arrival, so
the vision time of ``now`` is ``t_sent + (now - arrival)``; prediction to that time hides the camera's
processing, the network and this process's own delay, without synchronised clocks. Scalar Python maths:
a handful of robots costs microseconds, where numpy's per-call overhead would dominate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from hier_ssl.deploy.wire import DetectionFrame
from hier_ssl.world.robot import RobotSpec

PREDICT_HORIZON = 0.2  # s
_UNSEEN = (math.nan,) * 6  # the state row of a robot never seen
COMMANDS_KEPT = 8  # a robot's commands kept: frames come every 17 ms, commands every 25 ms


@dataclass(frozen=True)
class TrackerSettings:
    """Measurement noise (``pos_noise`` m, ``angle_noise`` rad, one standard deviation), process noise
    (``accel`` m/s^2 and ``ang_accel`` rad/s^2: how hard a robot may change its velocity), the ``gate``
    (m) past which a measurement restarts the filter, and ``forget`` (s) after which an unseen robot's
    filter restarts at its next detection; ``command_accel`` and ``command_ang_accel``: the process noise of
    a robot given its commands (what they do not explain: contacts, a robot slower than its model)."""

    pos_noise: float = 0.004
    angle_noise: float = 0.02
    accel: float = 6.0
    ang_accel: float = 40.0
    gate: float = 0.5
    forget: float = 1.0
    command_accel: float = 1.0
    command_ang_accel: float = 10.0

    def __post_init__(self) -> None:
        names = ("pos_noise", "angle_noise", "accel", "ang_accel", "gate", "forget", "command_accel")
        for name in (*names, "command_ang_accel"):
            if not getattr(self, name) > 0:
                raise ValueError(f"tracker {name} must be > 0, got {getattr(self, name)}")


class _Axis:
    """One axis' Kalman filter: value p, rate v, covariance [[a, b], [b, c]]."""

    __slots__ = ("p", "v", "a", "b", "c")

    def __init__(self, p: float, var: float) -> None:
        self.p, self.v = p, 0.0
        self.a, self.b, self.c = var, 0.0, 25.0  # rate unknown at first: (5 units/s)^2

    def predict(self, dt: float, q: float, dv: float = 0.0) -> None:
        """Move ``dt`` seconds on, the rate changing by a known ``dv`` at a constant rate, with acceleration
        noise of variance q."""
        if dt <= 0.0:
            return
        self.p += (self.v + dv / 2) * dt
        self.v += dv
        dt2 = dt * dt
        a, b, c = self.a, self.b, self.c
        self.a = a + 2 * dt * b + dt2 * c + q * dt2 * dt2 / 4
        self.b = b + dt * c + q * dt2 * dt / 2
        self.c = c + q * dt2

    def update(self, innovation: float, r: float) -> None:
        """Measure the value with ``innovation`` (measured minus predicted) and noise variance r."""
        s = self.a + r
        ka, kb = self.a / s, self.b / s
        self.p += ka * innovation
        self.v += kb * innovation
        a, b = self.a, self.b
        self.a, self.b, self.c = (1 - ka) * a, (1 - ka) * b, self.c - kb * b

    def back(self, lag: float) -> float:
        """The value ``lag`` >= 0 seconds ago."""
        return self.p - self.v * lag


def follow(
    vx: float,
    vy: float,
    spin: float,
    command: tuple[float, float, float],
    angle: float,
    dt: float,
    spec: RobotSpec,
) -> tuple[float, float, float]:
    """A robot's velocity (vx, vy) m/s and spin rad/s ``dt`` s after ``command`` (forward, left, w), robot
    frame at heading ``angle``, as the world's robots answer it: the command capped at the speed limits,
    reached at no more than the acceleration limits."""
    c, s = math.cos(angle), math.sin(angle)
    gx, gy = command[0] * c - command[1] * s, command[0] * s + command[1] * c
    speed = math.hypot(gx, gy)
    if speed > spec.max_speed:
        gx, gy = gx * spec.max_speed / speed, gy * spec.max_speed / speed
    dx, dy = gx - vx, gy - vy
    change, step = math.hypot(dx, dy), spec.max_accel * dt
    if change > step:
        dx, dy = dx * step / change, dy * step / change
    goal_spin = min(max(command[2], -spec.max_ang_speed), spec.max_ang_speed)
    turn = spec.max_ang_accel * dt
    return vx + dx, vy + dy, spin + min(max(goal_spin - spin, -turn), turn)


@dataclass
class Track:
    """One robot's filters, the vision time they stand at, when it was last seen (monotonic s), and for an
    own robot the commands sent to it: (vision time from which it holds, (forward, left, w)), oldest first."""

    x: _Axis
    y: _Axis
    angle: _Axis
    t: float
    seen: float
    has_angle: bool = False
    commands: list[tuple[float, tuple[float, float, float]]] = field(default_factory=list)

    def command_at(self, t: float) -> tuple[tuple[float, float, float] | None, float]:
        """The command holding at vision time ``t`` (None before the first, or for a robot never told) and
        when the next one takes over (inf: none does)."""
        held = None
        for since, command in self.commands:
            if since > t:
                return held, since
            held = command
        return held, math.inf

    def change(self, command: tuple[float, float, float] | None, dt: float, spec: RobotSpec) -> tuple:
        """The rates' change (vx, vy, w) over the next ``dt`` s under ``command`` (0 without)."""
        if command is None or dt <= 0.0:
            return 0.0, 0.0, 0.0
        vx, vy, w = follow(self.x.v, self.y.v, self.angle.v, command, self.angle.p, dt, spec)
        return vx - self.x.v, vy - self.y.v, w - self.angle.v

    def advance(self, t: float, cfg: TrackerSettings, spec: RobotSpec) -> None:
        """Predict to vision time ``t`` (nothing if it is past), a segment per command holding on the way,
        with the process noise of a robot told its commands or not (``cfg``)."""
        while t > self.t:
            command, next_since = self.command_at(self.t)
            end = min(t, next_since)
            dt = end - self.t
            if command is None:
                q_pos, q_angle, (dvx, dvy, dw) = cfg.accel**2, cfg.ang_accel**2, (0.0, 0.0, 0.0)
            else:
                q_pos, q_angle = cfg.command_accel**2, cfg.command_ang_accel**2
                dvx, dvy, dw = self.change(command, dt, spec)
            self.x.predict(dt, q_pos, dvx)
            self.y.predict(dt, q_pos, dvy)
            self.angle.predict(dt, q_angle, dw)
            self.t = end
        # Commands superseded before the filter's time: no frame goes back to them.
        while len(self.commands) > 1 and self.commands[1][0] <= self.t:
            del self.commands[0]

    def at(self, t: float, spec: RobotSpec) -> tuple[float, float, float, float, float, float]:
        """(x, y, angle, vx, vy, w) predicted to vision time ``t`` (m, rad in [-pi, pi), m/s, rad/s), at
        most ``PREDICT_HORIZON`` past the last detection: a robot out of sight is not flown on."""
        dt = max(min(t - self.t, PREDICT_HORIZON), 0.0)
        vx, vy, w = self.x.v, self.y.v, self.angle.v
        held = self.command_at(self.t)[0] if self.commands else None
        if held is not None:
            vx, vy, w = follow(vx, vy, w, held, self.angle.p, dt, spec)
        x, y = self.x.p + (self.x.v + vx) / 2 * dt, self.y.p + (self.y.v + vy) / 2 * dt
        angle = self.angle.p + (self.angle.v + w) / 2 * dt
        return x, y, (angle + math.pi) % (2 * math.pi) - math.pi, vx, vy, w


@dataclass
class Tracker:
    """Tracks of every robot seen, by (team, id); ``update`` with camera frames, read with ``state``."""

    settings: TrackerSettings = field(default_factory=TrackerSettings)
    robot: RobotSpec = field(default_factory=RobotSpec)
    tracks: dict[tuple[str, int], Track] = field(default_factory=dict)
    newest_sent: float | None = None
    newest_arrival: float = 0.0
    # The ball where a camera saw it last (m) and when (monotonic s): not filtered, the rules' zones around
    # it need its position within centimetres, not its velocity.
    ball: tuple[float, float] | None = None
    ball_seen: float = -math.inf

    def update(self, frame: DetectionFrame, arrival: float) -> None:
        """Apply one camera frame that arrived at monotonic time ``arrival``."""
        if self.newest_sent is None or frame.t_sent >= self.newest_sent:
            self.newest_sent, self.newest_arrival = frame.t_sent, arrival
        if frame.ball is not None:
            self.ball, self.ball_seen = frame.ball, arrival
        cfg = self.settings
        r_pos, r_angle = cfg.pos_noise**2, cfg.angle_noise**2
        for seen in frame.robots:
            key = (seen.team, seen.robot)
            track = self.tracks.get(key)
            if track is not None and frame.t_capture - track.t > cfg.forget:
                track = None
            commands = [] if track is None else track.commands
            if track is not None:
                track.advance(frame.t_capture, cfg, self.robot)
                if math.hypot(seen.x - track.x.p, seen.y - track.y.p) > cfg.gate:
                    track = None
            if track is None:
                track = Track(
                    _Axis(seen.x, r_pos), _Axis(seen.y, r_pos), _Axis(0.0, 10.0), frame.t_capture, 0.0
                )
                track.commands = commands  # a robot moved or replaced still gets what the loop sends it
                self.tracks[key] = track
            else:
                # A frame older than the filter is compared with the filter's estimate back at its time.
                lag = track.t - frame.t_capture
                track.x.update(seen.x - track.x.back(lag), r_pos)
                track.y.update(seen.y - track.y.back(lag), r_pos)
            if seen.angle is not None:
                if track.has_angle:
                    turn = seen.angle - track.angle.back(track.t - frame.t_capture)
                    turn = (turn + math.pi) % (2 * math.pi) - math.pi
                    track.angle.update(turn, r_angle)
                else:
                    track.angle.p, track.angle.a, track.has_angle = seen.angle, r_angle, True
            track.seen = arrival

    def command(self, key: tuple[str, int], t: float, command: tuple[float, float, float]) -> None:
        """Tell own robot ``key`` the ``command`` (forward, left, w; robot frame) sent to it at vision time
        ``t``; it holds until the next. A robot not seen yet is not told."""
        track = self.tracks.get(key)
        if track is None:
            return
        while track.commands and track.commands[-1][0] >= t:  # a command replaces those it overtakes
            track.commands.pop()
        track.commands.append((t, tuple(command)))
        del track.commands[:-COMMANDS_KEPT]

    def vision_time(self, now: float) -> float:
        """The vision clock's reading at monotonic time ``now`` (module docstring); 0 before any frame."""
        return 0.0 if self.newest_sent is None else self.newest_sent + (now - self.newest_arrival)

    def fresh(self, key: tuple[str, int], now: float, max_age: float) -> bool:
        """Whether robot ``key`` was seen within ``max_age`` s of monotonic time ``now``."""
        track = self.tracks.get(key)
        return track is not None and now - track.seen <= max_age

    def state(self, keys: list[tuple[str, int]], t: float) -> np.ndarray:
        """(len(keys), 6) x, y, angle, vx, vy, w of the robots ``keys`` at vision time ``t``; NaN rows
        for robots never seen."""
        tracks = [self.tracks.get(key) for key in keys]
        rows = [_UNSEEN if track is None else track.at(t, self.robot) for track in tracks]
        return np.array(rows, dtype=np.float64).reshape(len(keys), 6)  # one array: row writes cost more


__all__ = ["COMMANDS_KEPT", "PREDICT_HORIZON", "Track", "Tracker", "TrackerSettings", "follow"]
