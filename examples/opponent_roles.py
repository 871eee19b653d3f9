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
from foresight import LOOK, Foresight, summary

from hier_ssl.envs import task_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.opponents import COVER_SPAN, MARK_DISTANCE, OpponentTeam
from hier_ssl.envs.play import play
from hier_ssl.evaluation.compare import load_manager
from hier_ssl.manager.game_observation import RuledPlanner

ARRIVED = 0.15  # m from a hypothesis' target within which the robot is asked to stand still
# ... at the ball: where the rules keep an opponent in STOP and at our free kick (0.5 m and its radius)
BALL_ARRIVED = 0.7
STILL = 0.5  # 1/s: a robot standing still, m from a hypothesis' target, costs this much m/s for it
FREE_PRIOR = 0.3  # m/s added to ``free``'s mismatch: a straight drive fits a spot of its own anywhere
SPOT_AHEAD = 1.5  # s along its velocity where a free opponent's spot is guessed
FRAMES = 10  # frames of the window compared


def infer(
    pos: np.ndarray, vel: np.ndarray, ball: np.ndarray, goal: np.ndarray, roles: tuple[str, ...], m: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each opponent's role from frames of play: ``pos`` and ``vel`` (N, T, M + K, 2) of every robot (ours
    first), the ball (N, T, 2), the opponents' goal (N, 2); ``roles`` those the team plays. Returns each
    opponent's role index into ``roles`` (N, K), the robot of ours it marks (N, K; 0 where not marking),
    its fraction of the way goal -> ball (N, K) and its free spot (N, K, 2)."""
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
    mismatch, owner = [], []
    for r, name in enumerate(roles):
        to = targets[name] - theirs[..., None, :]  # (N, T, K, H, 2)
        far = np.linalg.norm(to, axis=-1, keepdims=True)
        speed = np.linalg.norm(v, axis=-1)[..., None, None]
        arrived = BALL_ARRIVED if name == "ball" else ARRIVED
        asked = np.where(far > arrived, speed * to / np.maximum(far, 1e-9), 0.0)
        cost = np.linalg.norm(asked - v[..., None, :], axis=-1).mean(1)  # (N, K, H)
        # Standing still fits every target as well: then the nearest is the likelier.
        cost += STILL * np.exp(-speed[:, -1, ..., 0] / 0.3) * np.maximum(far[:, -1, ..., 0] - arrived, 0.0)
        mismatch.append(cost + (FREE_PRIOR if name == "free" else 0.0))
        owner += [(r, h) for h in range(cost.shape[-1])]
    best = np.concatenate(mismatch, -1).argmin(-1)
    role, marked = np.array(owner).T
    return role[best], np.where(np.array(roles)[role[best]] == "mark", marked[best], 0), cover, spot


class Inferred(Foresight):
    """``foresight.py``'s policy whose copies' opponents play the roles inferred from the last frames."""

    def __init__(self, core: HierarchicalCore, planner: RuledPlanner, seed: int, args: argparse.Namespace):
        super().__init__(core, planner, seed, args)
        self.frames: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.guessed: tuple[int, np.ndarray] | None = None
        self.right = self.marker_right = self.looks = self.markers = 0
        self.stride = max(1, round(args.window / FRAMES / core.config.dt))

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        world = self.core.world
        self.frames = [*self.frames, (world.state.pos.copy(), world.state.vel.copy(), world.ball.pos[:, 0])]
        self.frames = self.frames[-FRAMES * self.stride :]
        return super().__call__(obs)

    def guess(self) -> tuple[np.ndarray, ...]:
        """The roles inferred at this control step (once a step, however many copies), scored once."""
        step = int(self.core.steps.max())
        if self.guessed is not None and self.guessed[0] == step:
            return self.guessed[1]
        team: OpponentTeam = self.core.scenario.team
        pos, vel, ball = (np.stack(x, 1) for x in zip(*self.frames[:: -self.stride][::-1], strict=True))
        side = np.where(self.core.scenario.referee.blue_on_positive_half, 1.0, -1.0)
        goal = np.stack([side * team.field.half_length, 0 * side], -1)
        guessed = infer(pos, vel, ball, goal, team.roles, team.num_ours)
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default="configs/game/stop_residual.yaml", help="a game scenario YAML")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--window", type=float, default=1.0, help="s of play the roles are inferred from")
    parser.add_argument(
        "--known-roles",
        action="store_true",
        help="the copies know the true roles and their draws; only the sub-goals held are guessed",
    )
    args = parser.parse_args()
    if args.episodes < 1 or args.window <= 0:
        parser.error(f"--episodes at least 1 and --window above 0, got {args.episodes} and {args.window}")
    config = task_config(args.scenario)
    planner = load_manager("sampling", config)
    if not isinstance(planner, RuledPlanner) or config.frame_skip != 1:
        parser.error("a game scenario at frame skip 1, where a decision is a control step")
    alone = play(HierarchicalCore(config, args.episodes, autoreset=False), planner, args.seed)
    print(summary("sampling", alone, config.dt), flush=True)
    core = HierarchicalCore(config, args.episodes, autoreset=False)
    policy = Inferred(core, planner, args.seed, argparse.Namespace(**vars(LOOK), **vars(args)))
    ends = play(core, policy, args.seed)
    print(f"{summary('inferred roles', ends, config.dt)} sub-goals changed {policy.changed}")
    print(
        f"roles right {policy.right / max(policy.looks, 1):.3f} of {policy.looks} opponent-looks; "
        f"markers' robot right {policy.marker_right / max(policy.markers, 1):.3f} of {policy.markers}"
    )


if __name__ == "__main__":
    main()
