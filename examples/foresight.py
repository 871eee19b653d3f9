"""How many of a planner's fouls and collisions a manager that foresaw the game would avoid, at what cost.

    python examples/foresight.py --scenario configs/game/stop_residual.yaml --episodes 100 --seed 11
    python examples/foresight.py --scenario configs/game/stop_residual.yaml --episodes 100 --seed 11 \
        --copies unseen-draws

Not a manager: a measure of what foresight is worth. It plays ``sampling`` and, every ``--every`` control
steps, a copy of the whole world (``copy.deepcopy`` of the core: physics, referee, both teams' planners
and the generator of their random draws; close, not bit for bit: a copied pymunk space resolves
contacts a little differently) plays the same plan ``--horizon`` steps ahead. Each robot the
copy sees leave for a collision or a foul is offered ``--options`` other sub-goals (the planner's
next-best candidates, at least 0.25 m apart, then its own position: wait), each played in its own copy,
held ``--hold`` steps and then the planner's again; a field takes the option whose copy loses the fewest
robots, then has the least time to target (arrived: its step; not yet: the horizon plus the distance
left at 1.5 m/s), and holds it for real. A manager that reads one observation does not know what the
copies show. ``--copies`` says what they know: everything (``exact``); all but the dice
(``unseen-draws``: the opponents' free spots and sub-destinations drawn afresh); or our team alone
(``steady-opponents``: the opponents hold the velocity they have, as ``sampling`` predicts them).
``--options 0`` plays the planner alone. ``--way-out brake`` offers a robot at risk one way out, braking
where it stands, to measure what a perfect warning is worth to a manager that can only brake;
``--planner`` names the planner played (``sampling+trapped=brake``); ``--manager RUN`` plays a trained run
(its ``--policy`` checkpoint) in its place, here and in the copies, the planner (the run's own unless
``--planner`` names one) still reading the scene for the options and the held sub-goals.
"""

from __future__ import annotations

import argparse
import copy
from collections.abc import Callable

import numpy as np

from hier_ssl.config import TaskConfig
from hier_ssl.envs import task_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.play import play
from hier_ssl.evaluation.compare import load_manager, run_config
from hier_ssl.manager.game_observation import RuledPlanner

SPACING = 0.25  # m between the alternatives offered to a robot
LOST = 1e4  # the cost of a robot lost in a copy, against its control steps to target
DICE = 12345  # seeds the copies' own draws with ``--copies unseen-draws`` (docs/results.md's rows used it)
# The look ahead docs/results.md's rows used: every 5 control steps, 60 ahead, 6 options held 15 steps.
LOOK = argparse.Namespace(every=5, horizon=60, options=6, hold=15, copies="exact", way_out="option")


class Plan:
    """The actions of ``decide`` (the planner unless given: a manager's numpy policy), with held sub-goals
    (field frame) for some robots until a control step, which ``planner`` turns into actions."""

    def __init__(self, planner: RuledPlanner, shape: tuple[int, int], decide: Callable | None = None) -> None:
        self.planner, self.pose, self.until = planner, np.zeros(shape + (5,)), np.full(shape, -1)
        self.decide = planner if decide is None else decide

    def copy(self) -> Plan:
        out = Plan(self.planner, self.until.shape, self.decide)
        out.pose[...], out.until[...] = self.pose, self.until
        return out

    def actions(self, core: HierarchicalCore, obs: np.ndarray, act: np.ndarray) -> np.ndarray:
        held = core.active & (self.until > core.steps[:, None])
        planned = core.active & ~held
        if planned.any():  # the managers keep nothing between calls: the held robots' calls are not needed
            act[planned] = self.decide(obs[planned])
        if held.any():
            scene = self.planner.read(self.planner.rules(obs[held])[0])
            act[held] = self.planner.action(scene, self.pose[held])
        return act

    def alternatives(
        self,
        obs: np.ndarray,
        count: int,
        scored: tuple[np.ndarray, np.ndarray] | None = None,
        wait: bool = False,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Sub-goal poses (B, count, 5) for robots ``obs`` (B, O): the planner's candidates in its order
        after its choice, each ``SPACING`` from those before, then the robot's own position (repeated to
        fill); and their indices (B, count) among ``planner.candidates``, -1 for the robot's position.
        ``scored``: those candidates and the planner's score of them, where the caller has them already.
        ``wait``: the robot's own position alone (B, 1)."""
        scene, rules = self.planner.read_ruled(obs)
        if wait:  # no candidate scored: their rollouts are what this costs
            cand, index = np.zeros((len(obs), 1), complex), np.full((len(obs), 1), -1)
        else:
            if scored is None:
                cand = self.planner.candidates(scene)
                scored = cand, self.planner.score(scene, cand, rules)
            cand, score = scored
            index = spaced(cand, score, count)
        own = (scene.robot_pos @ np.array([1.0, 1j]))[:, None]
        points = np.where(index >= 0, np.take_along_axis(cand, index.clip(0), 1), own)
        out = np.zeros(index.shape + (5,))
        out[..., 0], out[..., 1], out[..., 2] = points.real, points.imag, scene.target[:, 2, None]
        halted = rules.speed <= 0  # HALT: the robot holds where it is, whatever the option
        out[halted, :, 0:2], out[halted, :, 3:5] = scene.robot_pos[halted, None], 0.0
        return out, np.where(halted[:, None], -1, index)


def standing(pos: np.ndarray, heading: np.ndarray) -> np.ndarray:
    """Sub-goal poses (B, 5) that hold robots where they stand, at ``pos`` (B, 2), facing ``heading`` (B,):
    the worker brakes to them."""
    out = np.zeros((len(pos), 5))
    out[:, 0:2], out[:, 2] = pos, heading
    return out


def spaced(cand: np.ndarray, score: np.ndarray, count: int) -> np.ndarray:
    """Indices (B, count) of the candidates ``cand`` (B, C) ranked ``score`` (B, C) after the best, in its
    order, each ``SPACING`` from those before it and the best, -1 past the last one ranked."""
    out = np.full((len(cand), count), -1)
    for b, order in enumerate(np.argsort(-score, axis=1, kind="stable")):
        picked = [order[0]]
        for j in order[1:]:
            if len(picked) > count or not np.isfinite(score[b, j]):
                break
            if np.min(np.abs(cand[b, j] - cand[b, picked])) > SPACING:
                picked.append(j)
        out[b, : len(picked) - 1] = picked[1:]
    return out


def ahead(core: HierarchicalCore, obs: np.ndarray, plan: Plan, horizon: int) -> tuple[np.ndarray, np.ndarray]:
    """Play ``plan`` in ``core`` (a copy) ``horizon`` control steps. Returns, per field, LOST per robot that
    left for a collision or a foul plus each live robot's steps to its target (module docstring); and
    those robots (N, M) bool."""
    lost, arrived = np.zeros(core.active.shape, bool), np.full(core.active.shape, np.inf)
    live, act = core.active.copy(), np.zeros(core.active.shape + (core.act_dim,))
    for t in range(horizon):
        if not core.active.any():
            break
        result = core.step(plan.actions(core, obs, act))
        stats, obs = result.info["task"], result.obs
        at = (stats["field"], stats["agent"])
        lost[at] |= (stats["collision"] > 0) | (stats["foul"] > 0)
        arrived[at] = np.where(stats["success"] > 0, t + 1, np.inf)
    m = core.active.shape[1]
    left = np.linalg.norm(core.state.pos[:, :m] - core.target[..., 0:2], axis=-1)
    steps = np.where(np.isfinite(arrived), arrived, horizon + left / (1.5 * core.config.dt))
    return LOST * lost.sum(1) + np.where(live, steps, 0.0).sum(1), lost


Seen = Callable[[np.ndarray, np.ndarray, np.ndarray], None]
"""What the copies showed at a look ahead: the robots the planner's plan loses (N, M) bool; for those R
robots, the candidates offered (R, options) (``Plan.alternatives``) and whether each option loses the
robot in its copy (R, options) bool."""


class Foresight:
    """The planner (or ``decide``, a manager's numpy policy) with the copies' changes (module docstring), a
    policy of ``hier_ssl.envs.play.play`` for the episodes of ``core``, which it copies; ``changed`` counts
    the times it handed a robot another sub-goal than its manager's."""

    def __init__(
        self,
        core: HierarchicalCore,
        planner: RuledPlanner,
        args: argparse.Namespace,
        seen: Seen | None = None,
        decide: Callable | None = None,
    ) -> None:
        self.core, self.args, self.changed, self.seen = core, args, 0, seen
        self.plan, self.dice = Plan(planner, core.active.shape, decide), np.random.default_rng(DICE)
        self.obs = np.zeros(core.active.shape + (core.obs_dim,), np.float32)
        self.act = np.zeros(core.active.shape + (core.act_dim,))

    def copied(self) -> HierarchicalCore:
        twin = copy.deepcopy(self.core)
        if self.args.copies == "unseen-draws":
            twin.rng = np.random.default_rng(self.dice.integers(2**63))
        elif self.args.copies == "steady-opponents":
            steady(twin)
        return twin

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        """Actions for the live robots' observations ``obs``, as ``play`` hands them (its core's order)."""
        core, live = self.core, self.core.active
        self.obs[live] = obs
        if self.args.options and core.steps.max() % self.args.every == 0:
            self.changed += choose(self.copied, self.obs, self.plan, core.steps, self.args, self.seen)
        return self.plan.actions(core, self.obs, self.act)[live]


def steady(core: HierarchicalCore) -> None:
    """Make ``core``'s opponents (a game's second team) hold their velocity from now on, as ``sampling``
    predicts them: each its own command, in its own frame, that keeps it (no turning)."""
    m, state = core.num_agents, core.world.state
    vel, angle = state.vel[:, m:], state.angle[:, m:]
    cos, sin = np.cos(angle), np.sin(angle)
    held = np.stack(
        [cos * vel[..., 0] + sin * vel[..., 1], cos * vel[..., 1] - sin * vel[..., 0], 0 * cos], -1
    )
    core.scenario.team.commands = lambda *args: held.copy()


def choose(
    copied: Callable[[], HierarchicalCore],
    obs: np.ndarray,
    plan: Plan,
    steps: np.ndarray,
    args: argparse.Namespace,
    seen: Seen | None = None,
) -> int:
    """Look ahead from here: each robot a copy of the world loses gets the option that does best in its
    own copy, each field choosing for its robots together; returns how many robots changed sub-goal.
    ``seen``, where given, is told what the copies showed before the plan changes."""
    best, risk = ahead(copied(), obs, plan.copy(), args.horizon)
    options, index = plan.alternatives(obs[risk], args.options, wait=args.way_out == "brake")
    field, lost = np.nonzero(risk)[0], np.zeros(index.shape, bool)
    pick = np.full(len(best), -1)
    for j in range(index.shape[1] if risk.any() else 0):
        trial = plan.copy()
        trial.pose[risk], trial.until[risk] = options[:, j], steps[field] + args.hold
        cost, lost_j = ahead(copied(), obs, trial, args.horizon)
        lost[:, j] = lost_j[risk]
        pick, best = np.where(cost < best, j, pick), np.minimum(cost, best)
    if seen is not None:
        seen(risk, index, lost)
    chosen = pick[field] >= 0
    rows = tuple(np.argwhere(risk)[chosen].T)
    plan.pose[rows] = options[chosen, pick[field[chosen]]]
    plan.until[rows] = steps[field[chosen]] + args.hold
    return int(chosen.sum())


def summary(name: str, ends: dict, dt: float) -> str:
    """One line: success, fouls + collisions (robots), median time to target of those that succeeded."""
    success, lost = ends["success"] > 0, (ends["collision"] > 0) | (ends["foul"] > 0)
    time = np.median(ends["length"][success]) * dt if success.any() else float("nan")
    return (
        f"{name}: robots {success.size} success {100 * success.mean():.2f} % fouls+collisions "
        f"{100 * lost.mean():.2f} % ({lost.sum()}) median time to target {time:.3f} s"
    )


def game_planner(
    parser: argparse.ArgumentParser, scenario: str, spec: str = "sampling"
) -> tuple[TaskConfig, RuledPlanner]:
    """The ``scenario`` file's task and the planner ``spec`` (with its settings) in it, where the copies can
    play it: a game scenario at frame skip 1; else the parser's error, naming what is wrong."""
    config = task_config(scenario)
    try:
        planner = load_manager(spec, config)
    except ValueError as err:
        parser.error(f"--planner {spec}: {err}")
    if not isinstance(planner, RuledPlanner) or config.frame_skip != 1:
        parser.error(f"--scenario {scenario}: a game scenario at frame skip 1 (a decision a control step)")
    return config, planner


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="configs/game/stop_residual.yaml", help="a game scenario YAML")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--every", type=int, default=LOOK.every, help="control steps between looks ahead")
    parser.add_argument("--horizon", type=int, default=LOOK.horizon, help="control steps a copy plays ahead")
    parser.add_argument(
        "--options", type=int, default=LOOK.options, help="other sub-goals a robot at risk is offered"
    )
    parser.add_argument("--hold", type=int, default=LOOK.hold, help="control steps an option is held")
    parser.add_argument(
        "--copies",
        choices=("exact", "unseen-draws", "steady-opponents"),
        default=LOOK.copies,
        help="what the copies know: everything; all but the dice; our team only, the opponents held at "
        "their velocity",
    )
    parser.add_argument(
        "--way-out",
        choices=("option", "brake"),
        default=LOOK.way_out,
        help="a robot a copy loses is offered --options other sub-goals, or braking where it stands alone",
    )
    parser.add_argument(
        "--planner", help="the planner played, with its settings (sampling; with --manager, the run's own)"
    )
    parser.add_argument("--manager", help="a run directory: its manager is played in the planner's place")
    parser.add_argument("--policy", choices=("best", "final"), default="final", help="the run's checkpoint")
    args = parser.parse_args()
    for name in ("episodes", "every", "horizon", "hold", "options"):
        least = 0 if name == "options" else 1
        if getattr(args, name) < least:
            parser.error(f"--{name} must be at least {least}, got {getattr(args, name)}")
    if args.planner is None:  # a run's ways out read the scene as its own planner does
        try:
            args.planner = "sampling" if args.manager is None else run_config(args.manager).candidates.planner
        except ValueError as err:
            parser.error(f"--manager {args.manager}: {err}")
    config, planner = game_planner(parser, args.scenario, args.planner)
    decide, name = planner, args.planner
    if args.manager is not None:
        try:
            decide, name = load_manager(args.manager, config, args.policy), f"{args.manager} ({args.policy})"
        except ValueError as err:
            parser.error(f"--manager {args.manager}: {err}")
    alone = play(HierarchicalCore(config, args.episodes, autoreset=False), decide, args.seed)
    print(summary(name, alone, config.dt), flush=True)
    core = HierarchicalCore(config, args.episodes, autoreset=False)
    foresight = Foresight(core, planner, args, decide=decide)
    ends = play(core, foresight, args.seed)
    print(f"{summary('foresight', ends, config.dt)} sub-goals changed {foresight.changed}")


if __name__ == "__main__":
    main()
