"""The second team (``hier_ssl.envs.opponents``): role targets worked by hand, seeded replays, the rules
kept, decisions only where they are due."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from hier_ssl.envs.opponents import MARK_DISTANCE, ROLE_SHARE, ROLES, OpponentTeam
from hier_ssl.game import referee as ref
from hier_ssl.game.legal import distances
from hier_ssl.game.zones import STOP_SPEED, forbidden_zones
from hier_ssl.world.field import get_field
from hier_ssl.world.physics import RobotSpec, RobotState

FIELD = get_field("division_b")
HALF = np.array([FIELD.half_length, FIELD.half_width])


def _team(num_ours: int = 2, count: int = 3, num_fields: int = 1, **options) -> OpponentTeam:
    return OpponentTeam(FIELD, RobotSpec(), num_fields, num_ours, count, **options)


def _lineup(num_ours: int, count: int) -> ref.Lineup:
    team = np.r_[np.full(num_ours, ref.YELLOW), np.full(count, ref.BLUE)]
    return ref.lineup(team, np.r_[np.arange(num_ours), np.arange(count)], FIELD)


def _state(pos: np.ndarray, vel: np.ndarray | None = None) -> RobotState:
    n, r = pos.shape[:2]
    vel = np.zeros((n, r, 2)) if vel is None else vel
    return RobotState(pos.astype(float), np.zeros((n, r)), vel, np.zeros((n, r)))


def _random_world(rng: np.random.Generator, n: int, r: int) -> tuple[RobotState, np.ndarray]:
    pos = rng.uniform(-HALF + 0.3, HALF - 0.3, (n, r, 2))
    return _state(pos, rng.normal(0.0, 0.5, (n, r, 2))), rng.uniform(-HALF + 0.5, HALF - 0.5, (n, 2))


def _targets(team: OpponentTeam, pos: np.ndarray, ball: np.ndarray, positive: bool = True) -> np.ndarray:
    """The team's targets after one decision on one field, the game running."""
    referee = ref.referee_state(ref.FORCE_START, FIELD, blue_on_positive_half=positive)
    team.reset(np.array([0]), np.random.default_rng(1))
    lineup = _lineup(team.num_ours, team.count)
    team.commands(_state(pos[None]), ball[None], referee, lineup, np.zeros(1, int), np.random.default_rng(2))
    return team.targets[0]


def test_mark_stands_goal_side_of_its_robot_facing_it():
    # Ours at (1, 1); BLUE defends +x, its goal at (4.5, 0): the marker stands on the line from our robot to
    # that goal, gap metres from it, and faces it.
    team = _team(num_ours=1, count=1, roles=("mark",), planner="sampling")
    pos = np.array([[1.0, 1.0], [-2.0, -2.0]])
    target = _targets(team, pos, np.array([0.0, 0.0]))[0]
    gap = team.gap[0, 0]
    assert MARK_DISTANCE[0] <= gap <= MARK_DISTANCE[1]
    unit = np.array([3.5, -1.0]) / np.hypot(3.5, -1.0)
    np.testing.assert_allclose(target[:2], [1.0, 1.0] + gap * unit, atol=1e-12)
    np.testing.assert_allclose(target[2], np.arctan2(1.0, -3.5), atol=1e-12)
    # BLUE on the other half: the marker moves to our robot's -x side.
    target = _targets(team, pos, np.array([0.0, 0.0]), positive=False)[0]
    assert target[0] < 1.0


def test_markers_mark_different_robots_while_there_are_enough():
    team = _team(num_ours=3, count=5, roles=("mark",), num_fields=4)
    team.reset(np.arange(4), np.random.default_rng(0))
    for marked in team.marked:
        assert sorted(marked[:3]) == [0, 1, 2]
        np.testing.assert_array_equal(marked[3:], marked[:2])


def test_cover_lies_on_the_ball_goal_segment_facing_the_ball():
    team = _team(count=4, roles=("cover",), planner="sampling")
    pos = np.array([[0.0, 2.0], [1.0, -2.0], [-3.0, 0.0], [-3.0, 1.0], [-3.0, 2.0], [-3.0, -1.0]])
    ball = np.array([1.5, -1.0])
    targets = _targets(team, pos, ball, positive=False)
    goal = np.array([-4.5, 0.0])
    span = (targets[:, :2] - goal) @ (ball - goal) / np.sum((ball - goal) ** 2)
    np.testing.assert_allclose(targets[:, :2], goal + span[:, None] * (ball - goal), atol=1e-12)
    np.testing.assert_allclose(span, team.cover[0], atol=1e-12)
    assert ((span > 0.0) & (span < 1.0)).all()
    np.testing.assert_allclose(targets[:, 2], np.arctan2(-1.0, 6.0), atol=1e-12)


def test_ball_role_goes_to_the_ball_facing_it_from_where_it_is():
    team = _team(num_ours=1, count=2, roles=("ball",), planner="sampling")
    pos = np.array([[0.0, 0.0], [1.0, 1.0], [3.0, 0.0]])
    targets = _targets(team, pos, np.array([2.0, 1.0]))
    np.testing.assert_allclose(targets[:, :2], [[2.0, 1.0], [2.0, 1.0]])
    np.testing.assert_allclose(targets[:, 2], [0.0, np.arctan2(1.0, -1.0)])


def test_free_spots_are_on_the_field_and_kept_between_draws():
    team = _team(count=6, roles=("free",), planner="random", decide_every=1)
    rng = np.random.default_rng(3)
    state, ball = _random_world(rng, 1, 8)
    referee = ref.referee_state(ref.FORCE_START, FIELD)
    lineup = _lineup(2, 6)
    team.reset(np.array([0]), rng)
    spots = []
    for step in range(3):
        team.commands(state, ball, referee, lineup, np.array([step]), rng)
        spots.append(team.targets[0, :, :2].copy())
    assert (np.abs(spots[0]) <= HALF).all()
    # A free robot keeps its spot for about FREE_HOLD s (120 decisions of one step): these three agree.
    np.testing.assert_array_equal(spots[0], spots[2])
    # Each spot is the emptiest of its draws: farther from every robot than the robots are apart, mostly.
    gaps = np.linalg.norm(spots[0][:, None] - state.pos[0][None], axis=-1).min(axis=1)
    assert np.median(gaps) > 0.5


@pytest.mark.parametrize("planner", ["trajectory", "sampling", "random"])
def test_a_seed_replays_roles_and_commands(planner):
    def play(team: OpponentTeam) -> tuple[np.ndarray, list[np.ndarray]]:
        rng = np.random.default_rng(7)
        state, ball = _random_world(np.random.default_rng(5), 2, 5)
        referee = ref.referee_state(ref.FORCE_START, FIELD, n=2)
        team.reset(np.arange(2), rng)
        out = [team.commands(state, ball, referee, _lineup(2, 3), np.array([s, s]), rng) for s in range(3)]
        return team.role.copy(), out

    team = _team(num_fields=2, planner=planner, decide_every=2)
    roles, first = play(team)
    again_roles, again = play(team)
    other_roles, other = play(_team(num_fields=2, planner=planner, decide_every=2))
    for r, c in ((again_roles, again), (other_roles, other)):
        np.testing.assert_array_equal(r, roles)
        for a, b in zip(c, first, strict=True):
            np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("planner", ["trajectory", "sampling"])
def test_stop_caps_speed_and_keeps_subgoals_out_of_the_zones(planner):
    rng = np.random.default_rng(11)
    m, k, n = 2, 6, 2
    referee = ref.referee_state(ref.STOP, FIELD, n=n, keeper=(0, 0), blue_on_positive_half=[True, False])
    lineup = _lineup(m, k)
    ruled, free = _team(m, k, n, planner=planner), _team(m, k, n, planner=planner, obey_rules=False)
    fastest = 0.0
    for team in (ruled, free):
        team.reset(np.arange(n), np.random.default_rng(0))
    for step in range(3):
        state, ball = _random_world(rng, n, m + k)
        # Moving at 2 m/s, over STOP's limit: the worker commands about that, the cap must not let it.
        state.vel[:] = 2.0 * np.exp(1j * rng.uniform(-np.pi, np.pi, (n, m + k)))[..., None].view(float)
        steps = np.full(n, step * ruled.decide_every)
        command = ruled.commands(state, ball, referee, lineup, steps, rng)
        assert np.hypot(command[..., 0], command[..., 1]).max() <= STOP_SPEED + 1e-12
        team = ref.Lineup(lineup.team[m:], lineup.robot_id[m:])
        zones = forbidden_zones(referee, ball, FIELD, team)
        assert (distances(zones, ruled.subgoal[..., :2]) >= 0.0).all()
        command = free.commands(state, ball, referee, lineup, steps, rng)
        fastest = max(fastest, np.hypot(command[..., 0], command[..., 1]).max())
    assert fastest > STOP_SPEED  # the rule-breaking team does not slow down


@pytest.mark.parametrize("planner", ["trajectory", "sampling", "random"])
def test_halt_gives_zeros(planner):
    rng = np.random.default_rng(2)
    state, ball = _random_world(rng, 2, 5)
    team = _team(num_fields=2, planner=planner)
    team.reset(np.arange(2), rng)
    referee = ref.referee_state(np.array([ref.HALT, ref.FORCE_START]), FIELD)
    command = team.commands(state, ball, referee, _lineup(2, 3), np.zeros(2, int), rng)
    assert command.shape == (2, 3, 3)
    np.testing.assert_array_equal(command[0], 0.0)
    assert np.abs(command[1]).max() > 0.0


class _Counting:
    """A planner that counts its rows per call, then plans as the one it wraps."""

    def __init__(self, inner):
        self.inner, self.rows = inner, []

    def plan(self, scene, rules=None):
        self.rows.append(len(scene.target))
        return self.inner.plan(scene, rules)


def test_decisions_come_every_decide_every_steps_and_after_a_reset():
    rng = np.random.default_rng(4)
    team = _team(num_fields=2, count=3, planner="sampling", decide_every=4)
    counting = team.planner = _Counting(team.planner)
    state, ball = _random_world(rng, 2, 5)
    referee = ref.referee_state(ref.FORCE_START, FIELD, n=2)
    team.reset(np.arange(2), rng)
    # Field 1 two steps into its episode: step 0 decides both (fresh), then field 1 at steps 2 and 6 (its
    # 4 and 8), field 0 at steps 4 and 8; none at the odd steps.
    for step in range(9):
        team.commands(state, ball, referee, _lineup(2, 3), np.array([step, step + 2]), rng)
    assert counting.rows == [6, 3, 3, 3, 3]
    team.reset(np.array([1]), rng)  # a reset decides at the next step, whatever the count
    team.commands(state, ball, referee, _lineup(2, 3), np.array([9, 3]), rng)
    assert counting.rows[-1] == 3


@pytest.mark.parametrize(
    ("options", "message"),
    [
        ({"planner": "tiger"}, "unknown opponent planner 'tiger'"),
        ({"roles": ("mark", "goalie")}, "unknown opponent role 'goalie'"),
        ({"roles": ()}, r"roles must name at least one of .*, got \(\)"),
        ({"num_ours": -1, "roles": ("cover",)}, "num_ours must be >= 0, got -1"),
        ({"decide_every": 0}, "decide_every must be >= 1, got 0"),
        ({"count": 0}, "count must be >= 1, got 0"),
        ({"num_ours": 0}, "'mark' needs robots of ours"),
    ],
)
def test_bad_options_are_named(options, message):
    with pytest.raises(ValueError, match=message):
        _team(**options)


def test_bad_inputs_are_named():
    rng = np.random.default_rng(0)
    team = _team()
    team.reset(np.array([0]), rng)
    state, ball = _random_world(rng, 1, 5)
    referee = ref.referee_state(ref.STOP, FIELD)
    with pytest.raises(ValueError, match=r"ball must have shape \(1, 2\), got \(2,\)"):
        team.commands(state, ball[0], referee, _lineup(2, 3), np.zeros(1, int), rng)
    with pytest.raises(ValueError, match=r"state.pos must have shape \(1, 5, 2\), got \(1, 4, 2\)"):
        team.commands(state.robots(slice(0, 4)), ball, referee, _lineup(2, 3), np.zeros(1, int), rng)
    yellow = ref.lineup(np.zeros(5, int), np.arange(5))
    with pytest.raises(ValueError, match=r"opponents \(slots 2..4\) must be BLUE"):
        team.commands(state, ball, referee, yellow, np.zeros(1, int), rng)


def test_the_guide_gives_the_codes_roles_and_shares():
    page = (Path(__file__).parents[2] / "docs" / "guide" / "ssl-game.md").read_text()
    section = page.split("## The second team\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| `")]
    assert tuple(re.match(r"\| `(\w+)`", row)[1] for row in rows) == ROLES
    shares = re.findall(r"(\d+) % `(\w+)`", " ".join(section.split()))
    assert {role: int(share) / 100 for share, role in shares} == ROLE_SHARE
