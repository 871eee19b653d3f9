"""How much of the copies' foresight one observation carries: a risk model distilled from exact copies.

    python examples/distill.py record --scenario configs/game/ball_placement_residual.yaml \
        --seeds 100 101 102 --episodes 25 --out labels-a.npz
    python examples/distill.py play --scenario configs/game/ball_placement_residual.yaml \
        --labels labels-a.npz labels-b.npz --val labels-c.npz --episodes 100 --seed 11

A privileged teacher and its student, as legged robots are trained (a teacher that sees the simulator's
state, a student that sees what the robot sees). ``record`` plays ``foresight.py``'s policy with copies
that know everything and keeps, at each look ahead, each robot's candidate sub-goals as the residual
manager reads them (``residual_inputs``: the planner's own rollout figures of each candidate) with what
the copies showed: the planner's choice kept or lost the robot; for a robot it lost, each other sub-goal
offered (the planner's next-best, ``foresight.SPACING`` apart, offered to all of a field's robots at risk
at once) kept or lost it. Only robots the planner decides for are kept (a held sub-goal is not the
planner's choice), and of the calm ones (not lost) a share ``--calm``, so that losses are not one row in a
hundred.

``play`` fits a small network on those rows: the chance that a candidate loses its robot (logistic loss
over every labelled candidate). The student plays ``sampling`` and, every ``--every`` control steps, each
robot whose planner choice the network rates above ``--threshold`` gets the lowest-rated of the other
sub-goals the teacher would have offered, where that one rates lower, held ``--hold`` steps. It reads one
observation a robot, as a manager does. ``--val`` labels (other seeds) say how well the network sorts
states (the area under the ROC curve of the planner's choice) and, at states the planner's choice loses,
how often its pick keeps the robot against a random option.

``--planner`` names the planner the teacher and the student play over (``sampling+trapped=brake``: the
one that brakes where it is trapped); with ``--way-out brake`` a robot at risk brakes where it stands
instead, held as long, where it is faster than ``--brake-speed`` and its planner does not already brake.
"""

from __future__ import annotations

import argparse

import numpy as np
import torch
from foresight import LOOK, Foresight, Plan, game_planner, standing, summary
from torch import nn

from hier_ssl.config import TaskConfig
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.play import play
from hier_ssl.manager.game_observation import RuledPlanner
from hier_ssl.policies.candidate_residual import residual_inputs
from hier_ssl.policies.networks import mlp

UNSEEN = -1  # a candidate no copy played
STOP = 1  # the candidate that is the robot's own position (``SamplingPlanner.candidates``' order)


class Labels:
    """The rows ``record`` keeps: candidates' inputs (R, C, F) and what the copies showed of each (R, C):
    1 lost the robot, 0 kept it, ``UNSEEN``."""

    def __init__(self, foresight: Foresight, calm: float, rng: np.random.Generator) -> None:
        self.foresight, self.calm, self.rng = foresight, calm, rng
        self.inputs: list[np.ndarray] = []
        self.labels: list[np.ndarray] = []

    def __call__(self, risk: np.ndarray, index: np.ndarray, lost: np.ndarray) -> None:
        core, plan, obs = self.foresight.core, self.foresight.plan, self.foresight.obs
        free = core.active & (plan.until <= core.steps[:, None])
        if not free.any():
            return
        planner = plan.planner
        scene, _ = planner.read_ruled(obs[free])
        inputs = residual_inputs(planner, obs[free], planner.candidates(scene), zone_features=True).numpy()
        labels = np.full(inputs.shape[:2], UNSEEN, np.int8)
        rows = np.arange(len(labels))
        labels[rows, inputs[..., 1].argmax(1)] = risk[free]
        lost_free = free[risk]  # of the robots at risk, those the planner decides for
        at, offered = rows[risk[free]], index[lost_free] >= 0
        labels[np.repeat(at, offered.sum(1)), index[lost_free][offered]] = lost[lost_free][offered]
        keep = risk[free] | (self.rng.random(len(labels)) < self.calm)
        self.inputs.append(inputs[keep].astype(np.float16))
        self.labels.append(labels[keep])


def record(args: argparse.Namespace, config: TaskConfig, planner: RuledPlanner) -> None:
    inputs, labels = [], []
    for seed in args.seeds:
        core = HierarchicalCore(config, args.episodes, autoreset=False)
        teacher = Foresight(core, planner, LOOK)
        teacher.seen = seen = Labels(teacher, args.calm, np.random.default_rng(seed))
        ends = play(core, teacher, seed)
        print(f"{summary(f'teacher seed {seed}', ends, config.dt)} sub-goals changed {teacher.changed}")
        inputs += seen.inputs
        labels += seen.labels
    rows = np.concatenate(labels)
    np.savez_compressed(args.out, inputs=np.concatenate(inputs), labels=rows)
    print(f"rows {len(rows)} candidates labelled lost {(rows == 1).sum()} kept {(rows == 0).sum()}")


def load(paths: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Inputs (R, C, F) float32 and labels (R, C) of the ``record`` files ``paths``."""
    files = [np.load(path) for path in paths]
    return (
        np.concatenate([f["inputs"] for f in files]).astype(np.float32),
        np.concatenate([f["labels"] for f in files]),
    )


def fit(inputs: np.ndarray, labels: np.ndarray, epochs: int, seed: int) -> nn.Module:
    """The chance a candidate loses its robot, as a logit, of its features (the inputs after the planner's
    score and choice), fitted on the labelled candidates."""
    seen = labels != UNSEEN
    return fit_rows(inputs[seen][:, 2:], labels[seen] == 1, epochs, seed)


def fit_rows(x: np.ndarray, y: np.ndarray, epochs: int, seed: int) -> nn.Module:
    """A (64, 64) network's logit of the chance of ``y`` (R,) bool given ``x`` (R, F), logistic loss."""
    torch.manual_seed(seed)
    x, y = torch.as_tensor(x), torch.as_tensor(y, dtype=torch.float32)
    net = mlp(x.shape[1], (64, 64), 1)
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-3, weight_decay=1e-4)
    for _ in range(epochs):
        for batch in torch.randperm(len(x)).split(512):
            loss = nn.functional.binary_cross_entropy_with_logits(net(x[batch])[:, 0], y[batch])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    return net


def rated(net: nn.Module, inputs: np.ndarray | torch.Tensor) -> np.ndarray:
    """The network's chance of losing the robot (..., C) of candidates' inputs (..., C, F)."""
    with torch.no_grad():
        return torch.sigmoid(net(torch.as_tensor(inputs)[..., 2:])[..., 0]).numpy()


def auc(score: np.ndarray, positive: np.ndarray) -> float:
    """The chance that a positive scores above a negative (the area under the ROC curve; ties in order)."""
    order = np.argsort(score, kind="stable")
    ranks = np.empty(len(score))
    ranks[order] = np.arange(1, len(score) + 1)
    p, n = positive.sum(), (~positive).sum()
    return float((ranks[positive].sum() - p * (p + 1) / 2) / max(p * n, 1))


def validate(net: nn.Module, inputs: np.ndarray, labels: np.ndarray) -> str:
    """How the network sorts held-out states, and how often its pick keeps a robot the planner loses."""
    risk, rows = rated(net, inputs), np.arange(len(inputs))
    top = inputs[..., 1].argmax(1)
    state = auc(risk[rows, top], labels[rows, top] == 1)
    other = (labels != UNSEEN) & (np.arange(labels.shape[1]) != top[:, None])
    at = np.nonzero((labels[rows, top] == 1) & other.any(1))[0]
    picked = [labels[i, np.flatnonzero(other[i])[risk[i, other[i]].argmin()]] == 0 for i in at]
    chance = [(labels[i, other[i]] == 0).mean() for i in at]
    return (
        f"validation: state AUC {state:.3f}; at {len(at)} states the planner's choice loses, the pick "
        f"keeps the robot {np.mean(picked):.2f} against {np.mean(chance):.2f} for a random option"
    )


class Student:
    """``sampling`` with the network's changes (module docstring), a policy of ``play`` for ``core``."""

    def __init__(
        self, core: HierarchicalCore, planner: RuledPlanner, net: nn.Module, args: argparse.Namespace
    ) -> None:
        self.core, self.net, self.args, self.changed = core, net, args, 0
        self.plan = Plan(planner, core.active.shape)
        self.obs = np.zeros(core.active.shape + (core.obs_dim,), np.float32)
        self.act = np.zeros(core.active.shape + (core.act_dim,))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        core, plan, live = self.core, self.plan, self.core.active
        self.obs[live] = obs
        free = live & (plan.until <= core.steps[:, None])
        if core.steps.max() % self.args.every == 0 and free.any():
            scene, rules = plan.planner.read_ruled(self.obs[free])
            cand = plan.planner.candidates(scene)
            ranked = plan.planner.ranking(scene, cand, rules)  # one set of rollouts for both uses
            inputs = residual_inputs(plan.planner, self.obs[free], cand, zone_features=True, ranked=ranked)
            risk, rows = rated(self.net, inputs), np.arange(len(cand))
            chosen = inputs[..., 1].numpy().argmax(1)
            top = risk[rows, chosen]
            if self.args.way_out == "brake":  # where it stands, unless it already brakes or barely moves
                pose = standing(scene.robot_pos, scene.target[:, 2])
                fast = np.linalg.norm(scene.robot_vel, axis=-1) > self.args.brake_speed
                better = fast & (chosen != STOP)
            else:
                poses, index = plan.alternatives(self.obs[free], LOOK.options, (cand, ranked[0]))
                option = np.where(index >= 0, np.take_along_axis(risk, index.clip(0), 1), np.inf)
                pick = option.argmin(1)
                pose, better = poses[rows, pick], option[rows, pick] < top
            change = (top > self.args.threshold) & better & (rules.speed > 0)
            at = tuple(np.argwhere(free)[change].T)
            plan.pose[at], plan.until[at] = pose[change], core.steps[at[0]] + self.args.hold
            self.changed += int(change.sum())
        return plan.actions(core, self.obs, self.act)[live]


def student(args: argparse.Namespace, config: TaskConfig, planner: RuledPlanner) -> None:
    net = fit(*load(args.labels), args.epochs, args.fit_seed)
    if args.val:
        print(validate(net, *load(args.val)))
    ends = play(HierarchicalCore(config, args.episodes, autoreset=False), planner, args.seed)
    print(summary(args.planner, ends, config.dt))
    core = HierarchicalCore(config, args.episodes, autoreset=False)
    policy = Student(core, planner, net, args)
    print(
        f"{summary('student', play(core, policy, args.seed), config.dt)} sub-goals changed {policy.changed}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    rec = commands.add_parser("record", help="play the teacher and keep what its copies showed")
    rec.add_argument("--seeds", type=int, nargs="+", default=[100])
    rec.add_argument("--episodes", type=int, default=25)
    rec.add_argument("--calm", type=float, default=0.25, help="share of the calm robots' rows kept")
    rec.add_argument("--out", required=True, help="the labels file (.npz)")
    stu = commands.add_parser("play", help="fit the risk network and play the student beside the planner")
    stu.add_argument("--labels", nargs="+", required=True, help="record's files to fit on")
    stu.add_argument("--val", nargs="*", default=[], help="record's files of other seeds, to validate on")
    stu.add_argument("--episodes", type=int, default=50)
    stu.add_argument("--seed", type=int, default=11)
    stu.add_argument("--epochs", type=int, default=30)
    stu.add_argument("--fit-seed", type=int, default=0)
    stu.add_argument("--threshold", type=float, default=0.2, help="the rated chance of a loss that acts")
    stu.add_argument("--every", type=int, default=LOOK.every, help="control steps between ratings")
    stu.add_argument("--hold", type=int, default=LOOK.hold, help="control steps a change is held")
    stu.add_argument(
        "--way-out",
        choices=("option", "brake"),
        default="option",
        help="a robot at risk takes the teacher's lowest-rated option, or brakes where it is",
    )
    stu.add_argument(
        "--brake-speed", type=float, default=0.0, help="m/s: brake only a robot faster than this"
    )
    for sub in (rec, stu):
        sub.add_argument("--scenario", default="configs/game/ball_placement_residual.yaml")
        sub.add_argument(
            "--planner", default="sampling", help="the teacher's and student's planner, with settings"
        )
    args = parser.parse_args()
    for name in ("episodes", "epochs", "every", "hold"):
        if getattr(args, name, 1) < 1:
            parser.error(f"--{name} must be at least 1, got {getattr(args, name)}")
    if not 0.0 <= getattr(args, "calm", 0.0) <= 1.0 or not 0.0 <= getattr(args, "threshold", 0.0) <= 1.0:
        parser.error("--calm and --threshold are shares in [0, 1]")
    if not 0.0 <= getattr(args, "brake_speed", 0.0) < np.inf:
        parser.error(f"--brake-speed must be a speed of at least 0 m/s, got {args.brake_speed}")
    config, planner = game_planner(parser, args.scenario, args.planner)
    (record if args.command == "record" else student)(args, config, planner)


if __name__ == "__main__":
    main()
