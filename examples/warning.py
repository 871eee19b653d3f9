"""A braking warning that reads its team's plans, learned from exact copies where the student goes.

    python examples/warning.py record --scenario configs/game/ball_placement_residual.yaml \
        --planner sampling+trapped=brake --seeds 100 101 --episodes 25 --out w0.npz
    python examples/warning.py record --scenario configs/game/ball_placement_residual.yaml \
        --planner sampling+trapped=brake --seeds 102 103 --episodes 25 --out w1.npz --labels w0.npz
    python examples/warning.py play --scenario configs/game/ball_placement_residual.yaml \
        --planner sampling+trapped=brake --labels w0.npz w1.npz --episodes 100 --seed 11

``distill.py``'s warning reads one robot's candidates, and on their ball placement, where most robots
are lost against a teammate, it raised about fifty alarms for each one a perfect warning raised. This
one reads what a team knows of itself: each robot's chosen sub-goal (its own and its ``NEAREST``
teammates'), where they are and how they move, and where the ``NEAREST`` opponents are and move, in the
frame of the robot's way to its sub-goal, with each pair's closest approach over ``APPROACH`` seconds
(at their velocities, and driving straight for their sub-goals at their speeds).

``record`` plays the planner (or, with ``--labels``, the student fitted on them: states where the student
goes, as DAgger gathers them) and every 5 control steps asks exact copies (``foresight.py``'s, braking
its only way out): does the plan lose the robot within 1.5 s, and does braking, held 15 steps, keep it?
It keeps every robot at risk and a share ``--calm`` of the others. ``play`` fits a (64, 64) network to
the chance that braking keeps a robot the plan loses (``--label risk``: that the plan loses it), and
brakes a robot it rates above ``--threshold`` that moves faster than ``--brake-speed``, held ``--hold``
steps; a robot whose planner already brakes is left alone.
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from distill import STOP, auc, fit_rows
from foresight import LOOK, Foresight, choose, game_planner, standing, summary
from torch import nn

from hier_ssl.config import TaskConfig
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.play import play
from hier_ssl.manager.game_observation import RuledPlanner
from hier_ssl.policies.candidate_residual import residual_features, residual_inputs

NEAREST = 3  # teammates, and opponents, a robot's warning reads, nearest first
APPROACH = 1.5  # s over which a pair's closest approach is predicted
FAR = 10.0  # m: where a missing neighbour is put
BRAKE = argparse.Namespace(**{**vars(LOOK), "way_out": "brake"})  # the copies' look ahead


def approach(pos: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Time and distance (..., 2) of the closest approach within ``APPROACH`` of a pair at relative
    position ``pos`` and velocity ``vel`` (..., 2), both held."""
    t = -(pos * vel).sum(-1) / np.maximum((vel * vel).sum(-1), 1e-9)
    t = t.clip(0.0, APPROACH)
    return np.stack([t, np.linalg.norm(pos + vel * t[..., None], axis=-1)], -1)


def neighbours(
    pos: np.ndarray,
    vel: np.ndarray,
    axis: np.ndarray,
    others: tuple[np.ndarray, np.ndarray, np.ndarray],
    planned: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[np.ndarray]:
    """Of each robot at ``pos`` (N, M, 2) moving at ``vel``, its ``NEAREST`` of ``others`` (positions and
    velocities (N, K, 2), which of them it sees (N, M or 1, K) bool), in its frame ``axis`` (N, M, 2) unit
    (along, across): relative position, velocity, closest approach at those velocities and, with
    ``planned`` (the others' planned velocities (N, K, 2), the robots' (N, M, 2)), at the planned ones;
    each (N, M, 2 * NEAREST). A missing neighbour is ``FAR`` ahead and still."""
    o_pos, o_vel, present = others
    rel = o_pos[:, None] - pos[:, :, None]  # (N, M, K, 2)
    dist = np.where(present, np.linalg.norm(rel, axis=-1), np.inf)
    order = np.argsort(dist, axis=-1)[..., :NEAREST, None]
    missing = ~np.isfinite(np.take_along_axis(dist[..., None], order, 2))

    def pick(theirs: np.ndarray, own: np.ndarray, still: float | np.ndarray) -> np.ndarray:
        return np.where(missing, still, np.take_along_axis(theirs[:, None] - own[:, :, None], order, 2))

    def turned(v: np.ndarray) -> np.ndarray:
        x, y = axis[:, :, None, 0], axis[:, :, None, 1]
        return np.stack([v[..., 0] * x + v[..., 1] * y, v[..., 1] * x - v[..., 0] * y], -1)

    r, v = pick(o_pos, pos, FAR * axis[:, :, None]), pick(o_vel, vel, 0.0)  # far ahead, still
    columns = [turned(r), turned(v), approach(r, v)]
    if planned is not None:
        columns.append(approach(r, pick(*planned, 0.0)))
    return [c.reshape(c.shape[:2] + (-1,)) for c in columns]


def features(
    core: HierarchicalCore, planner: RuledPlanner, obs: np.ndarray, pose: np.ndarray, held: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """What the warning reads (N, M, S) of every field's robots (module docstring; zero for ``held`` ones,
    which it does not rate), and whether each robot's planner chooses to brake where it stands (N, M)
    bool. ``pose`` (N, M, 5): the sub-goals ``held`` robots hold; the others' are the planner's choice."""
    m, state = core.num_agents, core.state
    live, free = core.active, core.active & ~held
    pos, vel = state.pos[:, :m], state.vel[:, :m]
    goal = pos.copy()
    goal[held] = pose[held, 0:2]
    own = np.zeros(live.shape + (residual_features(True),))
    braking = np.zeros(live.shape, bool)
    if free.any():  # the planner's rollouts of the free robots' candidates: what the features cost
        scene, _ = planner.read_ruled(obs[free])
        cand = planner.candidates(scene)
        inputs = residual_inputs(planner, obs[free], cand, zone_features=True).numpy()
        rows, chosen = np.arange(len(cand)), inputs[..., 1].argmax(1)
        own[free], braking[free] = inputs[rows, chosen, 2:], chosen == STOP
        goal[free] = np.stack([cand[rows, chosen].real, cand[rows, chosen].imag], -1)
    way, speed = goal - pos, np.linalg.norm(vel, axis=-1, keepdims=True)
    length = np.linalg.norm(way, axis=-1, keepdims=True)
    toward = way / np.maximum(length, 1e-6)
    heading = np.where(speed > 1e-6, vel / np.maximum(speed, 1e-6), np.array([1.0, 0.0]))
    axis = np.where(length > 1e-6, toward, heading)
    planned = np.where(length > 1e-6, toward, 0.0) * speed
    mates = live[:, None, :] & ~np.eye(m, dtype=bool)
    team = neighbours(pos, vel, axis, (pos, vel, mates), (planned, planned))
    foes = neighbours(pos, vel, axis, (state.pos[:, m:], state.vel[:, m:], np.ones((1, 1, 1), bool)))
    along = np.stack([(vel * axis).sum(-1), vel[..., 1] * axis[..., 0] - vel[..., 0] * axis[..., 1]], -1)
    return np.concatenate([own, along, length, *team, *foes], -1).astype(np.float32), braking


class BrakeWarning:
    """The network's chance (M,) that braking keeps a robot the plan loses, of the features (M, S) it reads,
    standardised as those it was fitted on."""

    def __init__(self, x: np.ndarray, y: np.ndarray, epochs: int, seed: int) -> None:
        self.mean, self.std = x.mean(0), x.std(0) + 1e-6
        self.net: nn.Module = fit_rows((x - self.mean) / self.std, y, epochs, seed)

    def __call__(self, x: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return torch.sigmoid(self.net(torch.as_tensor((x - self.mean) / self.std))[:, 0]).numpy()


class Warned(Foresight):
    """The planner with the warning's brakes, a policy of ``play``; with ``calm`` it records, at each look,
    what exact copies show (module docstring) in ``rows``; ``braked`` counts the brakes."""

    def __init__(
        self,
        core: HierarchicalCore,
        planner: RuledPlanner,
        warn: argparse.Namespace,
        warning: BrakeWarning | None = None,
        calm: float | None = None,
    ) -> None:
        super().__init__(core, planner, BRAKE)
        self.warn, self.warning, self.calm, self.braked = warn, warning, calm, 0
        self.rows: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.rng = np.random.default_rng(warn.seed)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        core, plan, live = self.core, self.plan, self.core.active
        self.obs[live] = obs
        if core.steps.max() % BRAKE.every == 0 and live.any():
            held = live & (plan.until > core.steps[:, None])
            x, braking = features(core, plan.planner, self.obs, plan.pose, held)
            if self.calm is not None:
                self.label(x, live & ~held)
            if self.warning is not None:
                self.brake(x, live & ~held & ~braking)
        return plan.actions(core, self.obs, self.act)[live]

    def label(self, x: np.ndarray, free: np.ndarray) -> None:
        shown: dict[str, np.ndarray] = {}
        look = self.plan.copy()  # the copies' changes are not played: the student's are
        choose(
            self.copied, self.obs, look, self.core.steps, BRAKE, lambda r, i, lost: shown.update(r=r, l=lost)
        )
        risk, keeps = shown["r"], np.zeros_like(shown["r"])
        keeps[risk] = ~shown["l"][:, 0]
        keep = free & (risk | (self.rng.random(risk.shape) < self.calm))
        self.rows.append((x[keep], risk[keep], keeps[keep]))

    def brake(self, x: np.ndarray, at: np.ndarray) -> None:
        core, plan = self.core, self.plan
        fast = np.linalg.norm(core.state.vel[:, : core.num_agents], axis=-1) > self.warn.brake_speed
        at = at & fast
        change = self.warning(x[at]) > self.warn.threshold
        rows = tuple(np.argwhere(at)[change].T)
        plan.pose[rows] = standing(core.state.pos[rows], core.target[rows][:, 2])
        plan.until[rows] = core.steps[rows[0]] + self.warn.hold
        self.braked += int(change.sum())


def load(paths: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """Features, at risk, kept by braking, and the share of calm rows kept, of ``record`` files."""
    files = [np.load(path) for path in paths]
    calm = {float(f["calm"]) for f in files}
    if len(calm) > 1:
        raise SystemExit(f"label files {paths} were recorded with different --calm shares {sorted(calm)}")
    x, risk, keeps = (np.concatenate([f[k] for f in files]) for k in ("x", "risk", "keeps"))
    return x, risk, keeps, calm.pop()


def validate(warning: BrakeWarning, x: np.ndarray, risk: np.ndarray, keeps: np.ndarray, calm: float) -> str:
    """How the warning sorts held-out rows by whether braking keeps the robot: its AUC and, at a few
    thresholds, the share of those robots it catches and its alarms for each one caught (a calm row, of
    which ``record`` kept a share ``calm``, counted 1 / ``calm`` times)."""
    p = warning(x)
    weight = np.where(risk, 1.0, 1.0 / calm)
    parts = [f"validation: {int(keeps.sum())} kept by braking of {len(x)} rows, AUC {auc(p, keeps):.3f}"]
    for t in (0.05, 0.1, 0.2, 0.3, 0.5):
        up = p > t
        caught, alarms = up[keeps].sum(), (up * weight).sum()
        parts.append(
            f"at {t}: caught {caught / max(keeps.sum(), 1):.2f}, {alarms / max(caught, 1):.1f} alarms each"
        )
    return "; ".join(parts)


def record(args: argparse.Namespace, config: TaskConfig, planner: RuledPlanner) -> None:
    warning = fitted(args) if args.labels else None
    rows = []
    for seed in args.seeds:
        core = HierarchicalCore(config, args.episodes, autoreset=False)
        policy = Warned(core, planner, argparse.Namespace(**{**vars(args), "seed": seed}), warning, args.calm)
        ends = play(core, policy, seed)
        print(f"{summary(f'seed {seed}', ends, config.dt)} braked {policy.braked}", flush=True)
        rows += policy.rows
    x, risk, keeps = (np.concatenate(c) for c in zip(*rows, strict=True))
    np.savez_compressed(args.out, x=x, risk=risk, keeps=keeps, calm=args.calm)
    print(f"rows {len(x)}: at risk {risk.sum()}, kept by braking {keeps.sum()}")


def fitted(args: argparse.Namespace) -> BrakeWarning:
    x, risk, keeps, _ = load(args.labels)
    return BrakeWarning(x, keeps if args.label == "keeps" else risk, args.epochs, args.fit_seed)


def student(args: argparse.Namespace, config: TaskConfig, planner: RuledPlanner) -> None:
    warning = fitted(args)
    if args.val:
        print(validate(warning, *load(args.val)))
    ends = play(HierarchicalCore(config, args.episodes, autoreset=False), planner, args.seed)
    print(summary(args.planner, ends, config.dt), flush=True)
    core = HierarchicalCore(config, args.episodes, autoreset=False)
    policy = Warned(core, planner, args, warning)
    print(f"{summary('warned', play(core, policy, args.seed), config.dt)} braked {policy.braked}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("command", choices=("record", "play"))
    parser.add_argument("--scenario", default="configs/game/ball_placement_residual.yaml")
    parser.add_argument("--planner", default="sampling+trapped=brake", help="the planner, with its settings")
    parser.add_argument("--labels", nargs="*", default=[], help="record files to fit the warning on")
    parser.add_argument("--label", choices=("keeps", "risk"), default="keeps", help="what it is fitted to")
    parser.add_argument("--val", nargs="*", default=[], help="record files to validate it on (play)")
    parser.add_argument("--seeds", type=int, nargs="*", default=[100], help="record's seeds")
    parser.add_argument("--seed", type=int, default=11, help="play's seed")
    parser.add_argument("--episodes", type=int, default=25)
    parser.add_argument("--calm", type=float, default=0.05, help="share of the calm robots' rows kept")
    parser.add_argument("--out", default="warning.npz")
    parser.add_argument("--threshold", type=float, default=0.5)
    parser.add_argument("--brake-speed", type=float, default=0.5, help="m/s; slower robots are left alone")
    parser.add_argument("--hold", type=int, default=LOOK.hold, help="control steps a brake is held")
    parser.add_argument("--epochs", type=int, default=20)
    parser.add_argument("--fit-seed", type=int, default=0)
    args = parser.parse_args()
    for name in ("episodes", "hold", "epochs"):
        if getattr(args, name) < 1:
            parser.error(f"--{name} must be at least 1, got {getattr(args, name)}")
    if not 0.0 < args.calm <= 1.0:
        parser.error(f"--calm must be in (0, 1], got {args.calm}")
    if not 0.0 <= args.brake_speed < np.inf:
        parser.error(f"--brake-speed must be a speed of at least 0, got {args.brake_speed}")
    if args.command == "play" and not args.labels:
        parser.error("play needs --labels to fit the warning on")
    config, planner = game_planner(parser, args.scenario, args.planner)
    (record if args.command == "record" else student)(args, config, planner)


if __name__ == "__main__":
    main()
