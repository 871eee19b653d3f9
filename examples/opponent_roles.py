"""What a team can tell of the opponents' intent from what its cameras show, and what that is worth.

    python examples/opponent_roles.py --scenario configs/game/stop_residual.yaml --episodes 100 --seed 11

``foresight.py`` showed that copies of the world which know where each opponent is going (its role and
that role's target, all but the dice) keep most of the robots ``sampling`` loses on STOP, and copies
whose opponents hold their velocity keep few. A team does not know the opponents' roles; it sees their
positions and velocities. This script plays ``foresight.py``'s policy with copies whose opponents play
the roles a team would infer from the last ``--window`` seconds of play (``infer``): each opponent's
observed velocity against the one each hypothesis asks for (driving at its present speed straight for
that role's target: goal-side of one of our robots, on the goal-ball line, at the ball, or a fixed spot
of its own, ``free``), the hypothesis that asks least taken. The rest of each opponent's state is what a
team cannot see and is left at a guess: a fresh decision at the copy's first step (not the sub-goal it
holds), the middle of the mark distance, a free spot ``SPOT_AHEAD`` seconds along its velocity, and the
copies' own dice. ``--known-roles`` gives the copies the true roles and their draws, the sub-goals held
still guessed: what a perfect inference of the roles would be worth. It prints the play beside
``sampling``'s, and how often the inferred role (and, for a marker, the robot marked) was the true one at
the looks ahead.
"""

from __future__ import annotations

import argparse
import copy

import numpy as np
import torch
from foresight import LOOK, Foresight, game_planner, summary
from torch import nn

from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.opponents import COVER_SPAN, MARK_DISTANCE, OpponentTeam
from hier_ssl.envs.play import play
from hier_ssl.manager.game_observation import RuledPlanner
from hier_ssl.policies.networks import mlp

ARRIVED = 0.15  # m from a hypothesis' target within which the robot is asked to stand still
# ... at the ball: where the rules keep an opponent in STOP and at our free kick (0.5 m and its radius)
BALL_ARRIVED = 0.7
STILL = 0.5  # 1/s: a robot standing still, m from a hypothesis' target, costs this much m/s for it
FREE_PRIOR = 0.3  # m/s added to ``free``'s mismatch: a straight drive fits a spot of its own anywhere
SPOT_AHEAD = 1.5  # s along its velocity where a free opponent's spot is guessed
FRAMES = 10  # frames of the window compared
WINDOWS = (3, 5, FRAMES)  # the last frames each mismatch is taken over, for the learned scorer


def hypotheses(
    pos: np.ndarray, vel: np.ndarray, ball: np.ndarray, goal: np.ndarray, roles: tuple[str, ...], m: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What each opponent's motion says of each hypothesis of its role, from frames of play: ``pos`` and
    ``vel`` (N, T, M + K, 2) of every robot (ours first), the ball (N, T, 2), the opponents' goal (N, 2);
    ``roles`` those the team plays. Returns the features (N, K, H, 8 + len(roles)) of the H hypotheses
    (``mark`` one of our M robots, then one each for the other roles): the velocity's mismatch and how
    fast it closed on the target over the last ``WINDOWS`` frames, the stillness term, the distance to
    the target and the speed at the last frame, the role one-hot; each hypothesis' role index and robot
    marked (H, 2); each opponent's fraction of the way goal -> ball (N, K) and free spot (N, K, 2)."""
    ours, theirs, v = pos[:, :, :m], pos[:, :, m:], vel[:, :, m:]
    goal = goal[:, None, None]
    away = goal - ours
    gap = np.mean(MARK_DISTANCE)
    marks = ours + gap * away / np.maximum(np.linalg.norm(away, axis=-1, keepdims=True), 1e-9)  # (N,T,M,2)
    line = ball[:, :, None] - goal  # (N, T, 1, 2)
    last = theirs[:, -1] - goal[:, 0]
    cover = ((last * line[:, -1]).sum(-1) / np.maximum((line[:, -1] ** 2).sum(-1), 1e-9)).clip(*COVER_SPAN)
    spot = theirs[:, -1] + SPOT_AHEAD * v[:, -1]
    k = theirs.shape[2]
    targets = {
        "mark": np.broadcast_to(marks[:, :, None], marks.shape[:2] + (k,) + marks.shape[2:]),
        "cover": (goal + cover[:, None, :, None] * line)[..., None, :],
        "ball": np.broadcast_to(ball[:, :, None, None], ball.shape[:2] + (k, 1, 2)),
        "free": np.broadcast_to(spot[:, None, :, None], spot.shape[:1] + (pos.shape[1], k, 1, 2)),
    }
    speed = np.linalg.norm(v, axis=-1)[..., None, None]
    features, owner = [], []
    for r, name in enumerate(roles):
        to = targets[name] - theirs[..., None, :]  # (N, T, K, H, 2)
        far = np.linalg.norm(to, axis=-1, keepdims=True)
        arrived = BALL_ARRIVED if name == "ball" else ARRIVED
        asked = np.where(far > arrived, speed * to / np.maximum(far, 1e-9), 0.0)
        mismatch = np.linalg.norm(asked - v[..., None, :], axis=-1)  # (N, T, K, H)
        # Standing still fits every target as well: then the nearest is the likelier.
        still = STILL * np.exp(-speed[:, -1, ..., 0] / 0.3) * np.maximum(far[:, -1, ..., 0] - arrived, 0.0)
        columns = [mismatch[:, -w:].mean(1) for w in WINDOWS]
        # How fast it closed on the target over each window, m per frame: a chase shows where it goes.
        columns += [(far[:, -min(w, len(far[0]))] - far[:, -1])[..., 0] / w for w in WINDOWS]
        moving = np.broadcast_to(speed[:, -1, ..., 0], still.shape)
        columns += [still, far[:, -1, ..., 0].clip(max=5.0), moving]
        columns += [np.full(still.shape, float(j == r)) for j in range(len(roles))]
        features.append(np.stack(columns, -1))
        owner += [(r, h) for h in range(still.shape[-1])]
    return np.concatenate(features, 2), np.array(owner), cover, spot


def infer(
    pos: np.ndarray,
    vel: np.ndarray,
    ball: np.ndarray,
    goal: np.ndarray,
    roles: tuple[str, ...],
    m: int,
    scorer: nn.Module | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each opponent's role from frames of play (``hypotheses``' arguments): its role index into ``roles``
    (N, K), the robot of ours it marks (N, K; 0 where not marking), its fraction of the way goal -> ball
    (N, K) and its free spot (N, K, 2). The hypothesis whose velocity mismatch over the whole window plus
    stillness term is least (``free`` paying ``FREE_PRIOR``), or, with ``scorer``, its highest logit."""
    features, owner, cover, spot = hypotheses(pos, vel, ball, goal, roles, m)
    if scorer is None:
        best = by_rule(features, roles)
    else:
        with torch.no_grad():
            best = scorer(torch.as_tensor(features, dtype=torch.float32))[..., 0].argmax(-1).numpy()
    role, marked = owner[best].transpose(2, 0, 1)
    return role, np.where(np.array(roles)[role] == "mark", marked, 0), cover, spot


def by_rule(features: np.ndarray, roles: tuple[str, ...]) -> np.ndarray:
    """The hypothesis (...) of least velocity mismatch over the whole window plus stillness term, ``free``
    paying ``FREE_PRIOR``, of ``hypotheses``' features (..., H, F)."""
    cost = features[..., len(WINDOWS) - 1] + features[..., 2 * len(WINDOWS)]
    if "free" in roles:
        cost = cost + FREE_PRIOR * features[..., 2 * len(WINDOWS) + 3 + roles.index("free")]
    return cost.argmin(-1)


def truth(team: OpponentTeam, owner: np.ndarray) -> np.ndarray:
    """The hypothesis (N, K) that is each opponent's true role (and robot marked), a column of ``owner``."""
    marking = np.array(team.roles)[team.role] == "mark"
    want = np.stack([team.role, np.where(marking, team.marked, 0)], -1)
    return (owner == want[..., None, :]).all(-1).argmax(-1)


def fit_scorer(features: np.ndarray, labels: np.ndarray, epochs: int = 20, seed: int = 0) -> nn.Module:
    """A (64, 64) network scoring each hypothesis of its features, fitted by cross-entropy over an
    opponent's hypotheses (``features`` (S, H, F), the true one ``labels`` (S,))."""
    torch.manual_seed(seed)
    x, y = torch.as_tensor(features, dtype=torch.float32), torch.as_tensor(labels)
    net = mlp(x.shape[-1], (64, 64), 1)
    optimizer = torch.optim.Adam(net.parameters(), lr=1e-3)
    for _ in range(epochs):
        for batch in torch.randperm(len(x)).split(256):
            loss = nn.functional.cross_entropy(net(x[batch])[..., 0], y[batch])
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
    return net


class Frames:
    """The last ``window`` seconds of play on ``core``'s fields as a team's cameras see them (every robot's
    position and velocity, the ball), ``FRAMES`` of them; ``add`` at each control step."""

    def __init__(self, core: HierarchicalCore, window: float) -> None:
        self.core, self.kept = core, []
        self.stride = max(1, round(window / FRAMES / core.config.dt))

    def add(self) -> None:
        world = self.core.world
        self.kept = [*self.kept, (world.state.pos.copy(), world.state.vel.copy(), world.ball.pos[:, 0])]
        self.kept = self.kept[-FRAMES * self.stride :]

    def stacked(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, tuple[str, ...], int]:
        """``hypotheses``' arguments for these frames."""
        team: OpponentTeam = self.core.scenario.team
        pos, vel, ball = (np.stack(x, 1) for x in zip(*self.kept[:: -self.stride][::-1], strict=True))
        side = np.where(self.core.scenario.referee.blue_on_positive_half, 1.0, -1.0)
        goal = np.stack([side * team.field.half_length, 0 * side], -1)
        return pos, vel, ball, goal, team.roles, team.num_ours


class Watch:
    """``planner`` as a policy of ``play`` that keeps, every ``LOOK.every`` control steps, each live field's
    opponents' hypotheses (``hypotheses``' features) and the true one: what ``fit_scorer`` learns from."""

    def __init__(self, core: HierarchicalCore, planner: RuledPlanner, window: float) -> None:
        self.core, self.planner, self.frames = core, planner, Frames(core, window)
        self.features: list[np.ndarray] = []
        self.labels: list[np.ndarray] = []

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        self.frames.add()
        live = self.core.active.any(1)
        if self.core.steps.max() % LOOK.every == 0 and live.any():
            features, owner, _, _ = hypotheses(*self.frames.stacked())
            self.features.append(features[live].reshape((-1,) + features.shape[2:]))
            self.labels.append(truth(self.core.scenario.team, owner)[live].ravel())
        return self.planner(obs)


class Inferred(Foresight):
    """``foresight.py``'s policy whose copies' opponents play the roles inferred from the last frames, by
    ``infer``'s rule or with ``scorer``."""

    def __init__(
        self,
        core: HierarchicalCore,
        planner: RuledPlanner,
        args: argparse.Namespace,
        scorer: nn.Module | None = None,
    ) -> None:
        super().__init__(core, planner, args)
        self.frames, self.scorer = Frames(core, args.window), scorer
        self.guessed: tuple[int, tuple[np.ndarray, ...]] | None = None
        self.right = self.marker_right = self.looks = self.markers = 0

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        self.frames.add()
        return super().__call__(obs)

    def guess(self) -> tuple[np.ndarray, ...]:
        """The roles inferred at this control step (once a step, however many copies), scored once."""
        step = int(self.core.steps.max())
        if self.guessed is not None and self.guessed[0] == step:
            return self.guessed[1]
        team: OpponentTeam = self.core.scenario.team
        guessed = infer(*self.frames.stacked(), scorer=self.scorer)
        live = self.core.active.any(1)
        right = guessed[0][live] == team.role[live]
        marking = right & (np.array(team.roles)[team.role[live]] == "mark")
        self.looks, self.right = self.looks + right.size, self.right + int(right.sum())
        self.markers += int(marking.sum())
        self.marker_right += int((guessed[1][live] == team.marked[live])[marking].sum())
        self.guessed = (step, guessed)
        return guessed

    def copied(self) -> HierarchicalCore:
        twin = copy.deepcopy(self.core)
        twin.rng = np.random.default_rng(self.dice.integers(2**63))
        team: OpponentTeam = twin.scenario.team
        guessed = self.guess()
        if not self.args.known_roles:
            team.role, team.marked, team.cover, team.spot = (x.copy() for x in guessed)
            team.gap[:], team.stale[:] = np.mean(MARK_DISTANCE), False
        team.memory[:], team.fresh[:] = np.nan, True
        return twin


def learned(config: object, planner: RuledPlanner, args: argparse.Namespace) -> nn.Module | None:
    """The scorer fitted on ``planner``'s play of ``--fit-episodes`` fields a ``--fit-seeds`` seed (None
    without those seeds); prints how often it and the rule name the true hypothesis on them."""
    features, labels = [], []
    for seed in args.fit_seeds:
        core = HierarchicalCore(config, args.fit_episodes, autoreset=False)
        watch = Watch(core, planner, args.window)
        play(core, watch, seed)
        features += watch.features
        labels += watch.labels
    if not features:
        return None
    x, y = np.concatenate(features), np.concatenate(labels)
    scorer = fit_scorer(x, y)
    with torch.no_grad():
        fitted = scorer(torch.as_tensor(x, dtype=torch.float32))[..., 0].argmax(-1).numpy()
    rule = by_rule(x, watch.core.scenario.team.roles)
    print(
        f"scorer fitted on {len(y)} opponent-looks: the true hypothesis {np.mean(fitted == y):.3f}, "
        f"the rule's {np.mean(rule == y):.3f}",
        flush=True,
    )
    return scorer


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="configs/game/stop_residual.yaml", help="a game scenario YAML")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--window", type=float, default=1.0, help="s of play the roles are inferred from")
    parser.add_argument("--fit-seeds", type=int, nargs="*", default=[], help="fit the scorer on these")
    parser.add_argument("--fit-episodes", type=int, default=50, help="fields a fit seed")
    parser.add_argument(
        "--known-roles",
        action="store_true",
        help="the copies know the true roles and their draws; only the sub-goals held are guessed",
    )
    args = parser.parse_args()
    if min(args.episodes, args.fit_episodes) < 1 or args.window <= 0:
        parser.error(f"--episodes and --fit-episodes at least 1, --window above 0; got {vars(args)}")
    if args.seed in args.fit_seeds:
        parser.error(f"--seed {args.seed} is among --fit-seeds: the roles are inferred on play not fitted on")
    config, planner = game_planner(parser, args.scenario)
    scorer = learned(config, planner, args)
    alone = play(HierarchicalCore(config, args.episodes, autoreset=False), planner, args.seed)
    print(summary("sampling", alone, config.dt), flush=True)
    core = HierarchicalCore(config, args.episodes, autoreset=False)
    policy = Inferred(core, planner, argparse.Namespace(**vars(LOOK), **vars(args)), scorer)
    ends = play(core, policy, args.seed)
    print(f"{summary('inferred roles', ends, config.dt)} sub-goals changed {policy.changed}")
    print(
        f"roles right {policy.right / max(policy.looks, 1):.3f} of {policy.looks} opponent-looks; "
        f"markers' robot right {policy.marker_right / max(policy.markers, 1):.3f} of {policy.markers}"
    )


if __name__ == "__main__":
    main()
