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

The four scenarios are ``hier_ssl.envs.game_scenarios``; where a reset puts the robots, the ball and the
role positions is ``hier_ssl.envs.game_places``, whose ``MARK_DISTANCE``, ``GamePlacement``,
``assign_roles`` and ``rest_point`` this module's ``__all__`` names with its own (the game's public
names in one place).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, Literal

import numpy as np
from pydantic import Field, field_validator

from hier_ssl.config import ScenarioConfig, Strict
from hier_ssl.envs.game_places import MARK_DISTANCE, GamePlacement, GamePlaces, assign_roles, rest_point
from hier_ssl.envs.game_render import draw_game
from hier_ssl.envs.opponents import OpponentTeam
from hier_ssl.envs.scenario import Placement
from hier_ssl.game import (
    BLUE,
    COMMANDS,
    FORCE_START,
    HALT,
    KINDS,
    NO_KEEPER,
    YELLOW,
    Motion,
    RefereeState,
    ball_in_play,
    check_keepers,
    forbidden_zones,
    lineup,
    new_clocks,
    referee_state,
    speed_limit,
    step_fouls,
)
from hier_ssl.game.legal import SPEED_MARGIN, cap_speed
from hier_ssl.manager import HIT_REWARD, SUCCESS_REWARD
from hier_ssl.manager.game_observation import GAME_OBS_DIM, game_columns
from hier_ssl.world.entities import Entities
from hier_ssl.world.physics import RobotState, World

COMMAND_NUMBERS = {name: number for number, name in COMMANDS.items()}
# How a robot's episode ended, per robot: still in play, at its target, in a collision, by a foul.
IN_PLAY, SUCCEEDED, COLLIDED, FOULED = 0, 1, 2, 3
_NO_CONTACTS = np.empty((0, 3), np.int64)  # step_fouls' contacts where none began (never written)


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
    # Which of our robots takes which role position: "drawn", each the one drawn for it; "team", the least
    # total distance from where they stand when the positions come (the keeper keeps its own), as a team's
    # role assignment does, so that no two straight paths cross.
    assign: Literal["drawn", "team"] = "drawn"
    # Our robots' commands are capped at this share of the referee's speed limit, as the robot's own
    # software does in every SSL team (and the deploy controller, with the same ``SPEED_MARGIN``): the rules
    # foul the robot, not the planner. None: no cap, for a manager that is to learn the limit itself.
    speed_guard: float | None = Field(SPEED_MARGIN, gt=0, le=1)

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
    way = np.where(fouled, FOULED, np.where(collided, COLLIDED, np.where(counts, SUCCEEDED, IN_PLAY)))
    return reward, counts, collided | fouled, way


class GameScenario(GamePlaces):
    """Base of the game scenarios (module docstring): subclasses set ``name``, ``Options``, ``defaults``
    and the boxes of starts, targets and the ball (``GamePlaces``)."""

    Options = GameOptions
    stat_names = ("foul", *(f"foul_{kind}" for kind in KINDS))
    rules_in_observation = True
    ssl_teams = True

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
        # Where each field's ball lay when its command came: a free kick's ball is in play once it has moved
        # (``ball_in_play``, rules 5.4), which the game tells itself, as a team's software does.
        self.ball_at_command = np.zeros((n, 2))
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

    def post_reset(self, core: Any, fields: np.ndarray, placement: Placement) -> None:
        """The referee's state, the fouls' clocks and counts, and the opponents of ``fields`` start afresh."""
        r = self.referee
        r.command[fields] = np.where(placement.command_step == 0, self.command, FORCE_START)
        r.placement[fields] = placement.placement_pos
        r.blue_on_positive_half[fields] = placement.blue_on_positive_half
        r.in_play[fields] = False
        self.command_step[fields] = placement.command_step
        self.ball_at_command[fields] = placement.ball_pos[:, 0]  # a command that comes later writes its own
        fresh = new_clocks(len(fields), self.num_robots)
        for name, value in vars(fresh).items():
            getattr(self.clocks, name)[fields] = value
        self.fouls[fields], self.way[fields], self.fouled[fields] = 0, IN_PLAY, False
        self.foul_at[fields], self._touching[fields] = np.nan, False
        self.team.reset(fields, core.rng)

    # -- each control step ---------------------------------------------------------------------------------

    def pre_step(self, core: Any, command: np.ndarray) -> None:
        """The command comes where its time has (with new role positions for the ball where it will stop);
        the opponents' commands into their rows; ours capped at ``speed_guard`` of the speed limit; HALT
        stops every robot."""
        steps, playing = core.steps, core.active.any(axis=1)
        came = np.flatnonzero(playing & (steps == self.command_step) & (self.command_step > 0))
        world = core.world
        if len(came):
            self.referee.command[came] = self.command
            self.referee.in_play[came] = False
            referee = self.referee_of(came)
            mirror = self._mirror(referee, core.rng)
            ball = world.ball.fields(came)
            self.ball_at_command[came] = ball.pos[:, 0]
            rest = rest_point(ball.pos[:, 0], ball.vel[:, 0], world.ball_spec.deceleration, self.field)
            theirs = world.state.pos[came, self.num_agents :]
            ours = world.state.pos[came, : self.num_agents]
            core.set_targets(came, self._targets(core.rng, referee, rest, mirror, theirs, ours))
        state = world.state
        moves = self.team.commands(state, world.ball.pos[:, 0], self.referee, self.lineup, steps, core.rng)
        np.copyto(command[:, self.num_agents :], moves, where=playing[:, None, None])
        guard = self.options.speed_guard
        if guard is not None:
            ours = command[:, : self.num_agents, :2]
            ours[:] = cap_speed(ours, guard * speed_limit(self.referee)[:, None])
        command[self.referee.command == HALT] = 0.0
        self._before = Motion(state.pos, state.vel)

    def post_step(self, core: Any) -> None:
        """Whether a free kick's ball is now in play, then the step's fouls (``step_fouls``), counted for our
        robots still in play."""
        world, m = core.world, self.num_agents
        ball = world.ball.pos[:, 0]
        # In play stays in play (the ball rolling back changes nothing); the step's fouls and the next
        # observation's zones are judged with it. ``steps`` counts this step already.
        since = (core.steps - self.command_step) * core.config.dt
        division_a = self.field.name == "division_a"
        self.referee.in_play[:] |= ball_in_play(
            self.referee.command, since, ball, self.ball_at_command, division_a
        )
        began = world.robot_contacts & ~self._touching
        np.copyto(self._touching, world.robot_contacts)
        # Most control steps begin no contact: the pairs' search only where one did.
        contacts = np.argwhere(np.triu(began, k=1)) if began.any() else _NO_CONTACTS
        after = Motion(world.state.pos, world.state.vel)
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
        zones = forbidden_zones(referee, ball.pos[:, 0], self.field, self.ours)
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

    def drawing(self, field_index: int) -> Callable[[Any], None]:
        """Field ``field_index``'s referee state, ball and fouls as they are now, drawn when called on a
        matplotlib ``ax`` (``draw_game``): a recorded episode's frames draw the game as it was."""
        i = [field_index]
        return functools.partial(
            draw_game,
            field=self.field,
            lineup=self.lineup,
            robot=int(self.options.keeper == 0 and self.num_agents > 1),
            referee=self.referee_of(i),
            ball=self.world.ball.pos[i, 0],
            fouls=self.foul_at[field_index].copy(),
        )

    def extra_render(self, ax: Any, field_index: int) -> None:
        """``draw_game`` of field ``field_index`` now."""
        self.drawing(field_index)(ax)


__all__ = [
    "COLLIDED",
    "COMMAND_NUMBERS",
    "FOULED",
    "IN_PLAY",
    "MARK_DISTANCE",
    "SUCCEEDED",
    "GameOptions",
    "GamePlacement",
    "GameScenario",
    "assign_roles",
    "game_outcome",
    "rest_point",
]
