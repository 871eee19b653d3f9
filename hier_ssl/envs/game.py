"""The SSL game's scenarios over the one batched core: our team (yellow, the M controlled robots, ids
0..M-1) repositions under the referee's command while the opponents (blue, the K robots after them, ids
0..K-1) play against it, with a ball (docs/guide/ssl-game.md, "The game scenarios").

Each scenario owns, per field, the referee's state (``hier_ssl.game.RefereeState``), when its command comes
(drawn at the reset from the core's generator, so a seed replays it), the fouls' clocks and each robot's
fouls. The league's rules are ``hier_ssl.game``'s pure functions: the zones and speed limits of the command,
``step_fouls`` every control step. A robot succeeds at its target pose (the thresholds of every scenario)
once the command is in force, with no foul and no collision, within the time limit; a foul ends its
episode like a collision and is counted as a foul (``info["task"]``: ``foul`` and ``foul_<kind>``), a
contact that is no crash stays a collision. The opponents are an ``OpponentTeam`` whose commands
``pre_step`` writes into their rows (their obstacle group is "stationary": the core has no second path);
in HALT every command is zero.

- ``game_stop`` (Division B, 6 v 6): the game runs with a rolling ball; STOP comes at a random time and our
  robots take their role positions, legally, for the ball where it will come to rest.
- ``game_free_kick``: the opponent's free kick in our half; our robots take defending positions.
- ``game_ball_placement``: an opponent carries the ball to the placement position; our robots cross the
  field around the stadium the rules forbid.
- ``game_match`` (Division A, 11 v 11): the game runs; the ball lost, our robots fall back from the half
  we attack into ours, through 21 other robots and a rolling ball.

Places are drawn in a frame where our goal is at negative x and mirrored into each field (the side each
team defends and the field's y are drawn per episode): the boxes below are fractions of the field's half
size less the spawn margin.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar, Literal

import numpy as np
from pydantic import Field, field_validator

from hier_ssl.config import ScenarioConfig, Strict
from hier_ssl.envs.opponents import OpponentTeam
from hier_ssl.envs.registry import register_scenario
from hier_ssl.envs.scenario import Placement
from hier_ssl.envs.scenarios import FieldScenario
from hier_ssl.game import (
    BALL_PLACEMENT_BLUE,
    BLUE,
    COMMANDS,
    FORCE_START,
    HALT,
    KINDS,
    NO_KEEPER,
    YELLOW,
    Motion,
    RefereeState,
    Zones,
    check_keepers,
    forbidden_zones,
    lineup,
    new_clocks,
    referee_state,
    step_fouls,
)
from hier_ssl.game.legal import nearest_legal
from hier_ssl.game.referee import own_side
from hier_ssl.game.zones import BALL, OPPONENT_DEFENSE, OWN_DEFENSE
from hier_ssl.manager import HIT_REWARD, SUCCESS_REWARD
from hier_ssl.manager.game_observation import GAME_OBS_DIM, game_columns
from hier_ssl.world.entities import Entities
from hier_ssl.world.field import Field as FieldSpec
from hier_ssl.world.physics import RobotState, World

COMMAND_NUMBERS = {name: number for number, name in COMMANDS.items()}
# Every game scenario's defaults: Division B, 6 v 6, the opponents' rows "stationary" (their team moves them).
GAME_DEFAULTS = {
    "field": "division_b",
    "num_agents": 6,
    "num_obstacles": 6,
    "obstacles": {"behaviour": "stationary"},
    "max_steps": 800,
}
# How a robot's episode ended, per robot: still in play, at its target, in a collision, by a foul.
IN_PLAY, SUCCEEDED, COLLIDED, FOULED = 0, 1, 2, 3
MARK_DISTANCE = 0.4  # m goal-side of the opponent a marking role position lies
Box = tuple[tuple[float, float], tuple[float, float]]  # (low, high) x, y in fractions of the half field


class GameOptions(Strict):
    """What every game scenario takes; each scenario's subclass changes the defaults."""

    command: str = "FORCE_START"  # the referee's command the scenario plays, by its protocol name
    # s after the reset at which it comes, drawn uniformly per episode; the game runs (FORCE_START) until.
    command_at: tuple[float, float] = (0.0, 0.0)
    keeper: int = 0  # our keeper's robot id; -1: no keeper
    opponent_keeper: int = 0  # the opponents' keeper's robot id; -1: no keeper
    opponent_planner: Literal["trajectory", "sampling", "random"] = "trajectory"
    decide_every: int = Field(8, ge=1)  # control steps between the opponents' decisions
    opponent_roles: tuple[str, ...] = ("mark", "cover", "ball", "free")
    ball_speed: tuple[float, float] = (0.0, 0.0)  # m/s of the ball at the reset, uniform, any heading
    target_margin: float = Field(0.15, ge=0)  # m a target and a start keep beyond every zone's clearance

    @field_validator("command")
    @classmethod
    def _known_command(cls, value: str) -> str:
        if value not in COMMAND_NUMBERS:
            raise ValueError(f"unknown referee state {value!r}; known: {sorted(COMMAND_NUMBERS)}")
        return value

    @field_validator("command_at", "ball_speed")
    @classmethod
    def _range(cls, value: tuple[float, float]) -> tuple[float, float]:
        if not 0 <= value[0] <= value[1]:
            raise ValueError(f"{value} is no range (low, high) with 0 <= low <= high")
        return value


@dataclass
class GamePlacement(Placement):
    """A reset of F game fields: the robots and the ball (``Placement``), and the referee's part, always
    set by ``GameScenario.reset_world_at``: ``blue_on_positive_half`` (F,) bool, ``command_step`` (F,) the
    control step at which the scenario's command comes, ``placement_pos`` (F, 2) m."""

    blue_on_positive_half: np.ndarray | None = None
    command_step: np.ndarray | None = None
    placement_pos: np.ndarray | None = None


def rest_point(pos: np.ndarray, vel: np.ndarray, deceleration: float, field: FieldSpec) -> np.ndarray:
    """(F, 2) m where balls at ``pos`` (F, 2) rolling at ``vel`` (F, 2) m/s come to rest under a constant
    ``deceleration`` m/s^2, if nothing stops them first, held inside ``field``'s playing area."""
    rolled = pos + vel * np.linalg.norm(vel, axis=-1, keepdims=True) / (2 * deceleration)
    return np.clip(rolled, [-field.half_length, -field.half_width], [field.half_length, field.half_width])


def _robots(zones: Zones, robots: slice) -> Zones:
    """The zones (N, R', S) of the robots ``robots`` among zones (N, R, S)."""
    return Zones(zones.kind[:, robots], zones.shape[:, robots], zones.clearance[:, robots])


def game_outcome(
    reward: np.ndarray,
    success: np.ndarray,
    hit: np.ndarray,
    fouled: np.ndarray,
    in_force: np.ndarray,
    success_bonus: float,
    hit_penalty: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A control step of the game from the task's own ``reward``, ``success`` and ``hit`` (N, M): success
    counts only with the command ``in_force`` (N, 1) and without a foul, whose robot leaves (``fouled``) and
    pays the collision's ``hit_penalty`` where it hit nothing; a success that does not count gives its
    ``success_bonus`` back. Returns reward, success, collision and the robots' way out (``IN_PLAY``,
    ``SUCCEEDED``, ``COLLIDED``, ``FOULED``), each (N, M)."""
    counts = success & in_force & ~fouled
    collided = hit & ~fouled
    reward = reward - success_bonus * (success & ~counts) + hit_penalty * (fouled & ~hit)
    way = np.select([fouled, collided, counts], [FOULED, COLLIDED, SUCCEEDED], IN_PLAY)
    return reward, counts, collided | fouled, way


class GameScenario(FieldScenario):
    """Base of the game scenarios (module docstring): subclasses set ``name``, ``Options``, ``defaults``
    and the boxes of starts, targets and the ball."""

    Options = GameOptions
    start_box: ClassVar[Box] = ((-1.0, -1.0), (1.0, 1.0))  # our robots' starts
    opponent_box: ClassVar[Box] = ((-1.0, -1.0), (1.0, 1.0))  # the opponents' starts
    target_box: ClassVar[Box] = ((-1.0, -1.0), (1.0, 1.0))  # our robots' role positions
    ball_box: ClassVar[Box] = ((-0.6, -0.8), (0.6, 0.8))
    placement_box: ClassVar[Box] = ((0.0, 0.0), (0.0, 0.0))  # the ball placement position (placement only)
    mark_share: ClassVar[float] = 0.0  # of our field robots, whose role position marks an opponent
    stat_names = ("foul", *(f"foul_{kind}" for kind in KINDS))
    rules_in_observation = True

    def __init__(self, config: ScenarioConfig) -> None:
        if config.obstacles.behaviour != "stationary":
            raise ValueError(
                f"obstacles.behaviour: {config.obstacles.behaviour!r}; the game's opponents are moved by "
                "their team (options.opponent_planner), over the 'stationary' behaviour"
            )
        for key in ("success_mode", "hit_mode"):
            if getattr(config, key) != "add":
                raise ValueError(f"{key}: {getattr(config, key)!r}; the game scenarios score in 'add' mode")
        if config.num_obstacles < 1:
            raise ValueError("num_obstacles: 0; a game needs at least one opponent")
        super().__init__(config)
        m, k, opt = self.num_agents, self.num_obstacles, self.options
        # Rules 3.1: each team within its division's limit, checked alone so the error names its key.
        for key, team, count in (("num_agents", YELLOW, m), ("num_obstacles", BLUE, k)):
            try:
                lineup(np.full(count, team), np.arange(count), self.field)
            except ValueError as err:
                raise ValueError(f"{key}: {err}") from None
        self.lineup = lineup(np.r_[np.full(m, YELLOW), np.full(k, BLUE)], np.r_[np.arange(m), np.arange(k)])
        self.ours = lineup(np.full(m, YELLOW), np.arange(m))
        for key, keepers in (
            ("keeper", (opt.keeper, NO_KEEPER)),
            ("opponent_keeper", (NO_KEEPER, opt.opponent_keeper)),
        ):
            try:
                check_keepers(referee_state(FORCE_START, self.field, keeper=keepers), self.lineup)
            except ValueError as err:
                raise ValueError(f"options.{key}: {err}") from None
        self.command = COMMAND_NUMBERS[opt.command]
        self.command_steps = np.round(np.array(opt.command_at) / config.dt).astype(np.int64)

    # -- the world and its per-field state -----------------------------------------------------------------

    def make_world(self, num_fields: int) -> World:
        """The world: our robots, the opponents, a ball; and the per-field state of the game, every field
        at rest until its reset. A scenario object serves the one core that made its world."""
        entities = Entities()
        entities.add("robot", self.num_agents, "controlled")
        entities.add("robot", self.num_obstacles, "opponents")
        entities.add("ball", 1, "ball")
        cfg, opt = self.config, self.options
        self.world = World(num_fields, entities, self.field, dt=cfg.dt, substeps=cfg.substeps)
        n, m, r = num_fields, self.num_agents, self.num_robots
        keepers = (opt.keeper, opt.opponent_keeper)
        self.referee = referee_state(FORCE_START, self.field, n=n, keeper=keepers)
        self.command_step = np.zeros(n, np.int64)
        self.clocks = new_clocks(n, r)
        self.fouls = np.zeros((n, m, len(KINDS)), np.int64)  # each robot's fouls of its episode, by kind
        self.way = np.zeros((n, m), np.int8)  # how each robot's episode ended (IN_PLAY, ...)
        self.fouled = np.zeros((n, m), bool)  # the robots that committed a foul in the last control step
        self.foul_at = np.full((n, m, 2), np.nan)  # where each robot's foul happened, for the render
        self._touching = np.zeros((n, r, r), bool)  # robot contacts of the last control step
        self._before: Motion | None = None
        self.team = OpponentTeam(
            self.field,
            self.robot,
            n,
            m,
            self.num_obstacles,
            planner=opt.opponent_planner,
            decide_every=opt.decide_every,
            dt=cfg.dt,
            roles=opt.opponent_roles,
        )
        return self.world

    def referee_of(self, fields: np.ndarray | list[int] | None) -> RefereeState:
        """The referee's state of ``fields`` (F,) ints, every field for None."""
        return self.referee if fields is None else self.referee.fields(fields)

    # -- resets --------------------------------------------------------------------------------------------

    def _mirror(self, referee: RefereeState, rng: np.random.Generator) -> np.ndarray:
        """(F, 1, 2) the signs that take the drawing frame (our goal at -x) into each field, y at random."""
        x = -own_side(referee, self.ours)[:, :1]
        y = np.where(rng.random((len(x), 1)) < 0.5, -1.0, 1.0)
        return np.stack([x, y], axis=-1)

    def _box(self, box: Box, count: int) -> tuple[np.ndarray, np.ndarray]:
        """A box of fractions as (low, high) m (count, 2) each."""
        low, high = np.array(box) * self.half
        return np.broadcast_to(low, (count, 2)), np.broadcast_to(high, (count, 2))

    def _spread(
        self,
        rng: np.random.Generator,
        box: tuple[np.ndarray, np.ndarray],
        mirror: np.ndarray,
        zones: Zones,
        placed: np.ndarray,
        first: np.ndarray | None = None,
    ) -> np.ndarray:
        """Points (F, C, 2) drawn in ``box`` (low, high (C, 2), drawing frame), mirrored into each field,
        moved to the nearest point ``target_margin`` beyond their zones (F, C, S), inside the field lines and
        at least ``gap`` from each other and from ``placed`` (F, P, 2): a point that is not is drawn again
        until none is. ``first`` (F, C, 2), field frame: the points to try before any draw, where not NaN."""
        f, c = zones.kind.shape[:2]
        inflated = Zones(zones.kind, zones.shape, zones.clearance + self.options.target_margin)
        earlier = np.tril(np.ones((c, c), bool), k=-1)
        pts, bad = np.zeros((f, c, 2)), np.ones((f, c), bool)
        for attempt in range(1000):
            fresh = rng.uniform(box[0], box[1], (f, c, 2)) * mirror
            if attempt == 0 and first is not None:
                fresh = np.where(np.isnan(first), fresh, first)
            pts = nearest_legal(inflated, np.where(bad[..., None], fresh, pts))
            near = np.linalg.norm(pts[:, :, None] - pts[:, None], axis=-1) < self.gap
            near_placed = np.linalg.norm(pts[:, :, None] - placed[:, None], axis=-1) < self.gap
            # A point a zone pushed beyond the box's field lines (the drawing box's bound) is drawn again.
            off = (np.abs(pts) > self.half + self.config.spawn_margin).any(axis=-1)
            bad = (near & earlier).any(axis=2) | near_placed.any(axis=2) | off
            if not bad.any():
                return pts
        raise RuntimeError(f"scenario {self.name!r}: cannot place {c} robots {self.gap} m apart, legally")

    def _marks(self, rng: np.random.Generator, referee: RefereeState, theirs: np.ndarray) -> np.ndarray:
        """(F, M, 2) m: for a share ``mark_share`` of our robots but the keeper, drawn per robot, a point
        ``MARK_DISTANCE`` goal-side of an opponent at ``theirs`` (F, K, 2) (each its own while there are
        enough), on the line to our goal's centre; NaN for the others."""
        f, m, k = len(theirs), self.num_agents, self.num_obstacles
        marked = np.argsort(rng.random((f, k)), axis=1)[:, np.arange(m) % k]
        opponent = np.take_along_axis(theirs, marked[..., None], axis=1)
        goal = np.stack([own_side(referee, self.ours)[:, 0] * self.field.half_length, np.zeros(f)], axis=-1)
        to_goal = goal[:, None] - opponent
        unit = to_goal / np.maximum(np.linalg.norm(to_goal, axis=-1, keepdims=True), 1e-9)
        marking = rng.random((f, m)) < self.mark_share
        marking[:, self.options.keeper if 0 <= self.options.keeper < m else []] = False
        return np.where(marking[..., None], opponent + MARK_DISTANCE * unit, np.nan)

    def _targets(
        self,
        rng: np.random.Generator,
        referee: RefereeState,
        ball: np.ndarray,
        mirror: np.ndarray,
        theirs: np.ndarray,
    ) -> np.ndarray:
        """Our robots' role positions (F, M, 5) under ``referee`` with the ball at ``ball`` (F, 2) and the
        opponents at ``theirs`` (F, K, 2): the keeper before its goal, a share marking opponents
        (``_marks``), the others in ``target_box``, all legal, facing the ball, at rest."""
        m = self.num_agents
        zones = _robots(forbidden_zones(referee, ball, self.field, self.lineup), slice(0, m))
        low, high = (np.array(a) for a in self._box(self.target_box, m))
        keeper = self.options.keeper
        if 0 <= keeper < m:  # the keeper's box: 0.25 m before the goal line, within the goal's width
            edge, half_goal = self.field.half_length, self.field.goal_width / 2
            low[keeper], high[keeper] = (-edge + 0.2, -0.6 * half_goal), (-edge + 0.3, 0.6 * half_goal)
        marks = self._marks(rng, referee, theirs)
        pos = self._spread(rng, (low, high), mirror, zones, ball[:, None], marks)
        target = np.zeros(pos.shape[:2] + (5,))
        target[..., 0:2] = pos
        to_ball = ball[:, None] - pos
        target[..., 2] = np.arctan2(to_ball[..., 1], to_ball[..., 0])
        return target

    def reset_world_at(self, num_fields: int, rng: np.random.Generator) -> GamePlacement:
        f, m, k = num_fields, self.num_agents, self.num_obstacles
        opt = self.options
        blue_positive = rng.random(f) < 0.5
        steps = rng.integers(self.command_steps[0], self.command_steps[1] + 1, f)
        keepers = (opt.keeper, opt.opponent_keeper)
        first = np.where(steps == 0, self.command, FORCE_START)
        side = referee_state(first, self.field, keeper=keepers, blue_on_positive_half=blue_positive)
        mirror = self._mirror(side, rng)
        ball = rng.uniform(*self._box(self.ball_box, 1), (f, 1, 2)) * mirror
        heading = rng.uniform(-np.pi, np.pi, (f, 1))
        speed = rng.uniform(*opt.ball_speed, (f, 1))
        ball_vel = np.stack([np.cos(heading), np.sin(heading)], axis=-1) * speed[..., None]
        placement = self.placement_position(rng, mirror)
        start = referee_state(
            first, self.field, placement=placement, keeper=keepers, blue_on_positive_half=blue_positive
        )
        zones = forbidden_zones(start, ball[:, 0], self.field, self.lineup)
        ours = self._spread(rng, self._box(self.start_box, m), mirror, _robots(zones, slice(0, m)), ball)
        placed = np.concatenate([ball, ours], axis=1)
        theirs = self._spread(
            rng, self._box(self.opponent_box, k), mirror, _robots(zones, slice(m, None)), placed
        )
        played = RefereeState(
            np.full(f, self.command), start.placement, start.keeper, start.blue_on_positive_half
        )
        pos = np.concatenate([ours, theirs], axis=1)
        return GamePlacement(
            pos,
            rng.uniform(-np.pi, np.pi, (f, m + k)),
            self._targets(rng, played, ball[:, 0], mirror, theirs),
            ball_pos=ball,
            ball_vel=ball_vel,
            blue_on_positive_half=blue_positive,
            command_step=steps,
            placement_pos=start.placement,
        )

    def placement_position(self, rng: np.random.Generator, mirror: np.ndarray) -> np.ndarray:
        """(F, 2) m: where the ball is to be placed (read in a ball placement only)."""
        return rng.uniform(*self._box(self.placement_box, 1), (len(mirror), 1, 2))[:, 0] * mirror[:, 0]

    def post_reset(self, core: Any, fields: np.ndarray, placement: Placement) -> None:
        """The referee's state, the fouls' clocks and counts, and the opponents of ``fields`` start afresh."""
        r = self.referee
        r.command[fields] = np.where(placement.command_step == 0, self.command, FORCE_START)
        r.placement[fields] = placement.placement_pos
        r.blue_on_positive_half[fields] = placement.blue_on_positive_half
        self.command_step[fields] = placement.command_step
        fresh = new_clocks(len(fields), self.num_robots)
        for name, value in vars(fresh).items():
            getattr(self.clocks, name)[fields] = value
        self.fouls[fields], self.way[fields], self.fouled[fields] = 0, IN_PLAY, False
        self.foul_at[fields], self._touching[fields] = np.nan, False
        self.team.reset(fields, core.rng)

    # -- each control step ---------------------------------------------------------------------------------

    def pre_step(self, core: Any, command: np.ndarray) -> None:
        """The command comes where its time has (with new role positions for the ball where it will stop);
        the opponents' commands into their rows; HALT stops every robot."""
        steps, playing = core.steps, core.active.any(axis=1)
        came = np.flatnonzero(playing & (steps == self.command_step) & (self.command_step > 0))
        world = core.world
        if len(came):
            self.referee.command[came] = self.command
            referee = self.referee_of(came)
            mirror = self._mirror(referee, core.rng)
            ball = world.ball.fields(came)
            rest = rest_point(ball.pos[:, 0], ball.vel[:, 0], world.ball_spec.deceleration, self.field)
            theirs = world.state.pos[came, self.num_agents :]
            core.set_targets(came, self._targets(core.rng, referee, rest, mirror, theirs))
        state = world.state
        moves = self.team.commands(state, world.ball.pos[:, 0], self.referee, self.lineup, steps, core.rng)
        np.copyto(command[:, self.num_agents :], moves, where=playing[:, None, None])
        command[self.referee.command == HALT] = 0.0
        self._before = Motion(state.pos, state.vel)

    def post_step(self, core: Any) -> None:
        """The step's fouls (``step_fouls``), counted for our robots still in play."""
        world, m = core.world, self.num_agents
        began = world.robot_contacts & ~self._touching
        self._touching = world.robot_contacts.copy()
        contacts = np.argwhere(np.triu(began, k=1))
        after = Motion(world.state.pos, world.state.vel)
        ball = world.ball.pos[:, 0]
        self.clocks, report = step_fouls(
            self.clocks,
            self.referee,
            self.lineup,
            self.field,
            self._before,
            after,
            ball,
            contacts,
            core.config.dt,
        )
        ours = report.by_robot[:, :m] * (self.way == IN_PLAY)[..., None]
        self.fouls += ours
        self.fouled = ours.any(axis=-1)
        self.foul_at[self.fouled] = after.pos[:, :m][self.fouled]

    def score(
        self, terms: Any, target: np.ndarray, subgoal: np.ndarray, world: World
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The task's reward, success and hit, with the game's rules over them (``game_outcome``)."""
        reward, success, hit = super().score(terms, target, subgoal, world)
        cfg = self.config
        in_force = (self.referee.command == self.command)[:, None]
        bonus, penalty = cfg.success_weight * SUCCESS_REWARD, cfg.hit_weight * HIT_REWARD
        reward, success, out, way = game_outcome(reward, success, hit, self.fouled, in_force, bonus, penalty)
        playing = self.way == IN_PLAY
        self.way[playing] = way[playing]
        return reward, success, out

    def episode_stats(self, rows: np.ndarray) -> dict[str, np.ndarray]:
        """``collision`` (a contact, not a foul), ``foul`` (the robot left for a foul) and its fouls by kind
        ``foul_<kind>``, (E,) float64 each."""
        way = self.way.ravel().take(rows)
        fouls = self.fouls.reshape(-1, len(KINDS)).take(rows, axis=0).astype(np.float64)
        stats = {
            "collision": (way == COLLIDED).astype(np.float64),
            "foul": (way == FOULED).astype(np.float64),
        }
        return stats | {f"foul_{kind}": fouls[:, i] for i, kind in enumerate(KINDS)}

    # -- observation ---------------------------------------------------------------------------------------

    @property
    def obs_dim(self) -> int:
        return self.observation_layout.dim + GAME_OBS_DIM

    def observation(
        self, target: np.ndarray, state: RobotState, fields: np.ndarray | None = None
    ) -> np.ndarray:
        """The "neighbours" layout (teammates marked 1, opponents 0) followed by the game's columns
        (``hier_ssl.manager.game_observation``), (F, M, obs_dim) float32."""
        m, ball = self.num_agents, self.world.ball
        ball = ball if fields is None else ball.fields(fields)
        referee = self.referee_of(fields)
        zones = _robots(forbidden_zones(referee, ball.pos[:, 0], self.field, self.lineup), slice(0, m))
        scales = self.scales
        game = game_columns(
            referee,
            self.ours,
            zones,
            state.pos[:, :m],
            ball.pos[:, 0],
            ball.vel[:, 0],
            scales["max_pos"],
            scales["max_v"],
        )
        return np.concatenate([self.observation_layout(target, state), game], axis=-1)

    # -- render --------------------------------------------------------------------------------------------

    def extra_render(self, ax: Any, field_index: int) -> None:
        """Field ``field_index``'s active zones of our first robot that is no keeper (shaded), the referee's
        command, and a cross where each of our robots committed a foul."""
        i = [field_index]
        referee, ball = self.referee_of(i), self.world.ball.pos[i, 0]
        zones = forbidden_zones(referee, ball, self.field, self.lineup)
        robot = int(self.options.keeper == 0 and self.num_agents > 1)
        for slot in (OWN_DEFENSE, OPPONENT_DEFENSE, BALL):
            kind, (x0, y0, x1, y1), clear = (
                a[0, robot, slot] for a in (zones.kind, zones.shape, zones.clearance)
            )
            if kind == 0:
                continue
            if slot == BALL:  # a capsule: the stadium of the points within the clearance of the segment
                ax.fill(*_stadium(x0, y0, x1, y1, clear).T, color="#e03131", alpha=0.25, zorder=1)
            else:
                xs, ys = (
                    (x0 - clear, x1 + clear, x1 + clear, x0 - clear),
                    (y0 - clear, y0 - clear, y1 + clear, y1 + clear),
                )
                ax.fill(xs, ys, color="#e03131", alpha=0.2, zorder=1)
        name = COMMANDS[int(referee.command[0])]
        ax.text(
            -self.field.half_length, self.field.half_width + 0.1, name, color="white", fontsize=8, zorder=6
        )
        fouls = self.foul_at[field_index]
        fouls = fouls[~np.isnan(fouls[:, 0])]
        if len(fouls):
            ax.plot(fouls[:, 0], fouls[:, 1], "x", color="#e03131", markersize=9, mew=2.5, zorder=6)


def _stadium(x0: float, y0: float, x1: float, y1: float, radius: float) -> np.ndarray:
    """The outline (P, 2) of the points within ``radius`` of the segment (x0, y0) -> (x1, y1)."""
    heading = np.arctan2(y1 - y0, x1 - x0)
    turn = np.linspace(-np.pi / 2, np.pi / 2, 16)
    ends = [(x1, y1, heading + turn), (x0, y0, heading + np.pi + turn)]
    return np.concatenate(
        [np.stack([x + radius * np.cos(a), y + radius * np.sin(a)], -1) for x, y, a in ends]
    )


class StopOptions(GameOptions):
    command: str = "STOP"
    command_at: tuple[float, float] = (1.0, 4.0)
    ball_speed: tuple[float, float] = (0.5, 2.5)


@register_scenario
class GameStop(GameScenario):
    """Division B, 6 v 6: the game runs with a rolling ball; STOP comes at a random time and our robots take
    role positions in our half, legally for the ball where it will come to rest, under STOP's speed
    limit."""

    name = "game_stop"
    Options = StopOptions
    defaults = GAME_DEFAULTS
    target_box = ((-1.0, -1.0), (0.0, 1.0))


class FreeKickOptions(GameOptions):
    command: str = "DIRECT_FREE_BLUE"


@register_scenario
class GameFreeKick(GameScenario):
    """The opponent's free kick in our half (Division B, 6 v 6): our robots take defending positions in our
    half, 0.5 m from the ball, half of them marking an attacker goal-side, while the opponents move."""

    name = "game_free_kick"
    Options = FreeKickOptions
    defaults = GAME_DEFAULTS
    start_box = ((-1.0, -1.0), (0.5, 1.0))
    target_box = ((-1.0, -1.0), (-0.1, 1.0))
    ball_box = ((-0.7, -0.8), (-0.1, 0.8))
    mark_share = 0.5  # half the defenders mark an attacker goal-side, as a defence does at a free kick


class PlacementOptions(GameOptions):
    command: str = "BALL_PLACEMENT_BLUE"
    # m, field frame: where the ball is to be placed; None: drawn per episode across the field's middle.
    placement: tuple[float, float] | None = None


@register_scenario
class GameBallPlacement(GameScenario):
    """The opponents place the ball (Division B, 6 v 6): one of them carries it along the field's middle to
    the placement position while our robots cross the field, from one side to the other, around the
    stadium the rules forbid them (0.5 m from the segment ball -> placement position)."""

    name = "game_ball_placement"
    Options = PlacementOptions
    defaults = GAME_DEFAULTS
    start_box = ((-0.9, 0.45), (0.9, 1.0))
    target_box = ((-0.9, -1.0), (0.9, -0.45))
    ball_box = ((-0.8, -0.25), (-0.15, 0.25))
    placement_box = ((0.15, -0.25), (0.8, 0.25))

    def __init__(self, config: ScenarioConfig) -> None:
        super().__init__(config)
        fixed = self.options.placement
        if fixed is not None:
            try:
                referee_state(BALL_PLACEMENT_BLUE, self.field, placement=np.array(fixed))
            except ValueError as err:
                raise ValueError(f"options.placement: {err}") from None

    def placement_position(self, rng: np.random.Generator, mirror: np.ndarray) -> np.ndarray:
        drawn = super().placement_position(rng, mirror)
        fixed = self.options.placement
        return drawn if fixed is None else np.broadcast_to(np.array(fixed, float), drawn.shape).copy()


class MatchOptions(GameOptions):
    ball_speed: tuple[float, float] = (1.0, 3.0)


@register_scenario
class GameMatch(GameScenario):
    """Division A, 11 v 11, the game running (FORCE_START): the ball lost, our robots fall back from the
    half we attack to positions in ours, half of them marking an opponent goal-side, through the 21 other
    robots and a rolling ball."""

    name = "game_match"
    Options = MatchOptions
    # Moves anywhere were solved by ``sampling`` at 96 % (frame skip 1), falling back across the field
    # alone at 97 %: the team falls back to mark, half of it goal-side of an opponent that moves on.
    start_box = ((0.0, -1.0), (1.0, 1.0))
    target_box = ((-1.0, -1.0), (0.0, 1.0))
    mark_share = 0.5
    defaults = GAME_DEFAULTS | {
        "field": "division_a",
        "num_agents": 11,
        "num_obstacles": 11,
        "max_steps": 1200,
    }
    ball_box = ((-0.8, -0.8), (0.8, 0.8))


__all__ = [
    "COMMAND_NUMBERS",
    "GameBallPlacement",
    "GameFreeKick",
    "GameMatch",
    "GameOptions",
    "GamePlacement",
    "GameScenario",
    "GameStop",
    "game_outcome",
    "rest_point",
]
