"""The planners' compiled loops against the exhaustive numpy forms they replace: the same choices, the same
distances, on random scenes with obstacles and with STOP's zones."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from hier_ssl.envs import env_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.game import zones as z
from hier_ssl.game.legal import RowRules, distances
from hier_ssl.game.segments import segment_away, segment_breaks
from hier_ssl.manager import manager_observation
from hier_ssl.manager.bangbang import bang_bang_2d
from hier_ssl.manager.scene import read_scene
from hier_ssl.manager.trajectory import accepted, composite, first_collisions
from hier_ssl.world.field import get_field

FIELD = get_field("hardware_challenge")
HALF = np.array([FIELD.half_length, FIELD.half_width])


def _stop(ball: np.ndarray) -> RowRules:
    """STOP for robots (n,) with a ball each (n, 2): the walls, an own defense area, the opponent's (0.29
    m), the ball (0.59 m)."""
    n = len(ball)
    kind = np.tile([z.KEEP_IN, z.BOX, z.BOX, z.CAPSULE], (n, 1))
    shape = np.stack(
        [
            np.tile([-3.3, -2.3, 3.3, 2.3], (n, 1)),
            np.tile([-3.0, -0.5, -2.5, 0.5], (n, 1)),
            np.tile([2.5, -0.5, 3.0, 0.5], (n, 1)),
            np.concatenate([ball, ball], axis=1),
        ],
        axis=1,
    )
    clearance = np.tile([0.09, 0.09, 0.29, 0.59], (n, 1))
    return RowRules(z.Zones(kind, shape, clearance), np.full(n, 1.5))


def _scenes(n: int, k: int, seed: int) -> np.ndarray:
    """Observations (n, 13 + 5k) of robots going to targets at random, k obstacles near the line between
    them, half of them still."""
    rng = np.random.default_rng(seed)
    robot, target = rng.uniform(-HALF, HALF, (n, 2)), rng.uniform(-HALF, HALF, (n, 2))
    along = rng.uniform(0.1, 0.9, (n, k, 1))
    obstacles = robot[:, None] + along * (target - robot)[:, None] + rng.normal(0.0, 0.25, (n, k, 2))
    vel = rng.normal(0.0, 0.6, (n, k, 2)) * (rng.random((n, k, 1)) < 0.5)
    return manager_observation(
        np.concatenate([target, np.zeros((n, 3))], axis=1),
        robot,
        np.zeros(n),
        rng.normal(0.0, 0.5, (n, 2)),
        np.zeros(n),
        np.clip(obstacles, -HALF, HALF),
        vel,
        np.zeros((n, k)),
        max_pos=FIELD.max_pos,
    )


@pytest.mark.parametrize("ruled", [False, True])
def test_sampling_drops_only_candidates_that_cannot_be_chosen(ruled: bool) -> None:
    planner = make_planner("sampling", env_config(task="obstacle"))
    obs = _scenes(24, 3, seed=1)
    rules = _stop(np.random.default_rng(1).uniform(-1.0, 1.0, (24, 2))) if ruled else None
    scene = planner.read(obs)
    cand = planner.candidates(scene)
    full, choice = planner.score(scene, cand, rules), planner.score(scene, cand, rules, choice=True)
    best = np.argmax(full, axis=1)
    np.testing.assert_array_equal(np.argmax(choice, axis=1), best)
    assert np.isneginf(choice).any()  # some rows stopped early: the check above has something to check
    # A dropped candidate arrives later than the one chosen, or never.
    arrival = planner.rollout(scene, cand, None if rules is None else rules.speed)[0]
    dropped = np.isneginf(choice) & np.isfinite(full)
    rows = np.nonzero(dropped)[0]
    assert (arrival[dropped] > arrival[rows, best[rows]]).all()


def _exhaustive_detour(planner, pos, vel, goal, normal, direct_miss, obstacles, rules):
    """``TrajectoryPlanner.detour`` as numpy arrays over every path: all walked to their end, then the
    first acceptable, else the closest miss, else under the rules the closest step into a zone (the rows
    that took that last, or None without rules)."""
    p, (speed, accel) = planner.params, planner.limits
    zones = None
    if rules is not None:
        zones, speed = rules[:2], rules[2][:, None, None]
    order = np.argsort(np.where(np.isnan(normal), np.inf, np.abs(np.angle(normal))), axis=1, kind="stable")
    normal = np.take_along_axis(normal, order, axis=1)
    valid = ~np.isnan(normal)
    sub = pos[:, None] + np.where(valid, normal, 0.0) * (goal - pos)[:, None]
    sub = np.clip(sub.real, -HALF[0], HALF[0]) + 1j * np.clip(sub.imag, -HALF[1], HALF[1])
    if zones is not None:
        inside = distances(zones[0].take(np.s_[:, None]), np.stack([sub.real, sub.imag], axis=-1))
        valid &= (inside >= 0.0).all(-1)
    first = bang_bang_2d(pos[:, None, None], sub[:, :, None], vel[:, None, None], speed, accel)
    last_switch = float(first.total_time.max(initial=0.0))
    count = max(math.ceil((last_switch - p.initial_time_offset) / p.step_size_on_sub_path) - 1, 1)
    switch = np.array([p.initial_time_offset + p.step_size_on_sub_path * j for j in range(1, count + 1)])
    at, going = first.at(switch)
    then = bang_bang_2d(at, goal[:, None, None], going, speed, accel)
    radius = planner.collision_distance + p.obstacle_margin
    hits = first_collisions(
        lambda t: composite(first, then, switch, t), switch + then.total_time, obstacles, radius, p, zones
    )
    valid = valid[:, :, None] & (switch < first.total_time)
    end, now, brake = goal[:, None, None], np.abs(vel)[:, None, None], planner.brake_accel or accel
    still_ok, moving_ok = accepted(hits, pos[:, None, None], end, now, brake, p)
    good = (valid & still_ok & moving_ok).reshape(len(pos), -1)
    miss = np.where(valid & still_ok, np.abs(hits.moving_pos - end) ** 2, np.inf).reshape(len(pos), -1)
    score = np.concatenate([direct_miss[:, None], np.where(good, -np.inf, miss)], axis=1)
    best = np.argmin(score, axis=1)
    found = np.isfinite(score[np.arange(len(pos)), best]) | good.any(axis=1)
    if zones is not None:
        free_ok, _ = accepted(
            dataclasses.replace(hits, zone_time=None), pos[:, None, None], end, now, brake, p
        )
        near = valid & free_ok & moving_ok & (hits.zone_time > switch)
        near = np.where(near, np.abs(hits.zone_pos - end), np.inf).reshape(len(pos), -1)
        round_zones = ~found & np.isfinite(near.min(axis=1, initial=np.inf))
        best = np.where(round_zones, np.argmin(near, axis=1) + 1, best)
        found |= round_zones
    return best, found, count, round_zones if zones is not None else None


@pytest.mark.parametrize("ruled", [False, True])
def test_trajectory_search_chooses_as_the_exhaustive_one(ruled: bool) -> None:
    # 30 robots among 4 obstacles each, 5 drawn sub-destinations and a remembered one (NaN for half), the
    # direct path rejected with or without a miss of its own; the compiled search stops at the first
    # acceptable path and walks a path only while it matters: the same winner, and the same sub-goal.
    planner = make_planner("trajectory", env_config(task="obstacle"))
    rng = np.random.default_rng(4)
    n = 30
    scene = read_scene(_scenes(n, 4, seed=4), FIELD.max_pos, planner.robot.max_speed)
    pos, vel, goal = (
        x @ np.array([1.0, 1j]) for x in (scene.robot_pos, scene.robot_vel, scene.target[:, :2])
    )
    q, u = scene.obstacle_pos @ np.array([1.0, 1j]), scene.obstacle_vel @ np.array([1.0, 1j])
    obstacles = (q, u, np.abs(u) < planner.params.motionless_speed)
    last = np.where(rng.random(n) < 0.5, planner.draw(n)[:, 0], np.nan)
    normal = np.concatenate([last[:, None], planner.draw(n)], axis=1)
    direct_miss = np.where(rng.random(n) < 0.5, rng.uniform(0.0, 4.0, n), np.inf)
    rules = None
    if ruled:  # a third of the robots with the ball half-way to their target
        ball = np.where(np.arange(n)[:, None] % 3 == 0, (scene.robot_pos + scene.target[:, :2]) / 2, 0.0)
        stop = _stop(ball + rng.uniform(-1.0, 1.0, (n, 2)) * (np.arange(n)[:, None] % 3 != 0))
        direct_miss[::3] = np.inf
        rules = (stop.zones, distances(stop.zones, scene.robot_pos) < 0.0, stop.speed)
    best, found, count, round_zones = _exhaustive_detour(
        planner, pos, vel, goal, normal, direct_miss, obstacles, rules
    )
    picked, won = planner.detour(pos, vel, goal, normal, direct_miss, obstacles, rules)
    via = found & (best > 0)
    assert (best > 1).sum() >= 5 and (best == 0).sum() >= 2 and not found.all()  # every outcome
    assert round_zones is None or round_zones.sum() >= 2
    order = np.argsort(np.where(np.isnan(normal), np.inf, np.abs(np.angle(normal))), axis=1, kind="stable")
    sorted_normal = np.take_along_axis(normal, order, axis=1)
    want = np.where(via, sorted_normal[np.arange(n), np.maximum(best - 1, 0) // count], np.nan)
    np.testing.assert_array_equal(won, want)
    np.testing.assert_array_equal(picked[found & ~via], goal[found & ~via])


def test_signed_distance_is_numpys_norms_bit_for_bit() -> None:
    rng = np.random.default_rng(0)
    n, m, s = 50, 20, 4
    kind = rng.integers(0, 4, (n, m, s))
    start = rng.uniform(-3.0, 3.0, (n, m, s, 2))
    shape = np.concatenate(
        [start, start + rng.uniform(0.0, 2.0, (n, m, s, 2)) * (rng.random((n, m, s, 1)) < 0.7)], -1
    )
    clearance = rng.uniform(0.0, 0.7, (n, m, s))
    points = rng.uniform(-4.0, 4.0, (n, m, 2))
    # The numpy form: a segment's distance and a box's signed one, with np.linalg.norm.
    p, a, b = points[:, :, None], shape[..., :2], shape[..., 2:]
    ab, ap = b - a, p - a
    length2 = np.sum(ab * ab, axis=-1)
    t = np.clip(np.sum(ap * ab, axis=-1) / np.where(length2 > 0, length2, 1.0), 0.0, 1.0)
    capsule = np.linalg.norm(ap - t[..., None] * ab, axis=-1)
    q = np.abs(p - (a + b) / 2) - (b - a) / 2
    box = np.linalg.norm(np.maximum(q, 0.0), axis=-1) + np.minimum(np.max(q, axis=-1), 0.0)
    away = np.select([kind == z.CAPSULE, kind == z.BOX, kind == z.KEEP_IN], [capsule, box, -box])
    want = np.where(kind == z.NONE, np.inf, away - clearance)
    got = z.signed_distance(z.Zones(kind, shape, clearance), points)
    assert got.tobytes() == want.tobytes()


def test_segment_breaks_is_the_measured_clearance_below_zero() -> None:
    # Short steps near and far from a capsule, a box and a keep-in box, some ending exactly at a clearance.
    rng = np.random.default_rng(3)
    shapes = [(z.CAPSULE, np.array([0.0, 0.0, 0.5, 0.2])), (z.BOX, np.array([-0.5, -0.3, 0.5, 0.3]))]
    shapes += [(z.KEEP_IN, np.array([-1.0, -1.0, 1.0, 1.0])), (z.NONE, np.zeros(4))]
    count = 0
    for kind, shape in shapes:
        for _ in range(400):
            x0, y0 = rng.uniform(-1.5, 1.5, 2)
            x1, y1 = np.array([x0, y0]) + rng.normal(0.0, 0.2, 2)
            away = segment_away(x0, y0, x1, y1, kind, *shape)
            clearance = rng.choice([0.0, 0.29, 0.59, away if math.isfinite(away) else 0.0])
            want = segment_away(x0, y0, x1, y1, kind, *shape) - clearance < 0.0
            assert segment_breaks(x0, y0, x1, y1, kind, shape, clearance) == want
            count += want
    assert count > 100


def test_zones_take_picks_rows_and_adds_axes() -> None:
    zones = _stop(np.random.default_rng(0).uniform(-1.0, 1.0, (3, 2))).zones
    two = zones.take(np.array([2, 0]))
    assert two.kind.tolist() == zones.kind[[2, 0]].tolist() and two.shape.shape == (2, 4, 4)
    assert two.clearance.tolist() == zones.clearance[[2, 0]].tolist()
    assert zones.take(np.s_[:, None]).shape.shape == (3, 1, 4, 4)
