"""What a learned scorer sees of each of the ``sampling`` planner's candidate sub-goals: per-candidate
features, in closed form, of the path robot -> candidate -> target against obstacles at constant velocity.

The planner ranks candidates by rolling that path out at 50 ms steps (``SamplingPlanner.rollout``), where
its time goes. Here the path is two straight legs at the planner's speed, with the robot parked on the
sub-goal until it is no longer held, and each leg's closest approach to every obstacle is solved exactly
(a distance between two points in uniform motion is smallest at one time, found in closed form), with the
planner's own safety distances (collision distance + margin, growing with the prediction time). Cheap and
approximate: these say what the rollout measures, and a network learns the rest from the planner's labels.

Everything is (N, C) or (N, C, K) complex or float arrays: N scenes, C candidates, K obstacles.
"""

from __future__ import annotations

import numpy as np

from hier_ssl.manager.planners import SamplingPlanner, Scene
from hier_ssl.world.frames import as_complex

_CAP = 3.0  # m: distances and clearances beyond this say nothing more
_LATE = 5.0  # s: arrival behind the soonest safe candidate beyond this says nothing more


def closest_approach(
    start: np.ndarray, velocity: np.ndarray, t0: np.ndarray, t1: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Closest distance and its time for a relative position ``start + velocity * (t - t0)`` over
    [t0, t1] (all broadcastable complex / float arrays); +inf where t1 < t0 (an empty piece)."""
    speed2 = np.abs(velocity) ** 2
    t = t0 + np.clip(-(start * velocity.conj()).real / np.maximum(speed2, 1e-12), 0.0, None)
    t = np.minimum(t, t1)
    distance = np.abs(start + velocity * (t - t0))
    return np.where(t1 < t0, np.inf, distance), t


def _pieces(
    planner: SamplingPlanner,
    r0: np.ndarray,
    w: np.ndarray,
    begin: np.ndarray,
    end: np.ndarray,
    q: np.ndarray,
    u: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pieces of the robot's path, each r0 + w (t - begin) over [begin, end] ((P, N, C, 1) complex and
    float), against obstacles at q + u min(t, H) ((N, 1, K); H: the planner's prediction horizon): per
    piece the closest distance (P, N, C, K), its time, and the clearance beyond the growing safety distance
    at its ends and closest point: an upper bound of the smallest one, whose growing margin can put it
    between (by up to 6 cm on random scenes). All pieces at once: on one scene numpy's per-call cost is
    the price."""
    h = planner.predict_horizon
    # Each piece split at H: before it the obstacles move, after it they hold where the prediction left
    # them. rel0 + rel_v * t is the relative position at absolute time t.
    start = r0 - w * begin - q
    lo = np.concatenate([begin, np.maximum(begin, h)])
    hi = np.concatenate([np.minimum(end, h), end])
    rel0 = np.concatenate([start, start - u * h])
    rel_v = np.concatenate([w - u, np.broadcast_to(w, (w - u).shape)])
    d, t = closest_approach(rel0 + rel_v * lo, rel_v, lo, hi)
    ends = np.stack(np.broadcast_arrays(lo, t, hi))
    safety = planner.collision_distance + planner.margin
    gap = np.abs(rel0 + rel_v * ends) - safety - planner.margin_growth * np.minimum(ends, h) ** 1.5
    clearance = np.where(hi < lo, np.inf, gap.min(0))
    # The halves back together: the closer of the two, the smaller clearance.
    half = len(begin)
    closer = d[half:] < d[:half]
    distance = np.where(closer, d[half:], d[:half])
    when = np.where(closer, t[half:], t[:half])
    return distance, when, np.minimum(clearance[half:], clearance[:half])


def two_legs(planner: SamplingPlanner, scene: Scene, cand: np.ndarray) -> dict[str, np.ndarray]:
    """The straight path robot -> candidate (parked there while held) -> target at the planner's speed:
    leg times t1 (to the candidate), tp (until it leaves the candidate), t2 (on to the target), (N, C);
    per leg "1" (incl. the park) and "2" the closest distance d, its time s and the growing-margin
    clearance c to each obstacle, (N, C, K)."""
    speed = planner.speed
    p, g = as_complex(scene.robot_pos)[:, None, None], as_complex(scene.target[..., 0:2])[:, None, None]
    q, u = as_complex(scene.obstacle_pos)[:, None, :], as_complex(scene.obstacle_vel)[:, None, :]
    c = cand[:, :, None]
    l1, l2 = np.abs(c - p), np.abs(g - c)
    w1 = speed * (c - p) / np.maximum(l1, 1e-9)
    w2 = speed * (g - c) / np.maximum(l2, 1e-9)
    t1 = l1 / speed
    # The worker drives to a held sub-goal and waits there; the target itself is never left.
    tp = np.where(np.abs(c - g) == 0, t1, np.maximum(t1, planner.hold))
    t2 = tp + l2 / speed
    zero = np.zeros_like(t1)
    shape = np.broadcast_shapes(c.shape, p.shape)
    pieces = (  # to the candidate, parked there, on to the target
        (np.broadcast_to(p, shape), w1, zero, t1),
        (np.broadcast_to(c, shape), 0 * w1, t1, tp),
        (np.broadcast_to(c, shape), w2, tp, t2),
    )
    r0, w, begin, end = (np.stack(parts) for parts in zip(*pieces, strict=True))
    d, s, clear = _pieces(planner, r0, w, begin, end, q, u)
    closer = d[1] < d[0]
    d1, s1 = np.where(closer, d[1], d[0]), np.where(closer, s[1], s[0])
    c1, d2, s2, c2 = np.minimum(clear[0], clear[1]), d[2], s[2], clear[2]
    return {"t1": t1[..., 0], "tp": tp[..., 0], "t2": (t2 - tp)[..., 0], "d1": d1, "s1": s1, "c1": c1,
            "d2": d2, "s2": s2, "c2": c2}  # fmt: skip


def _nearest_two(d: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nearest and second-nearest distance over the obstacles (N, C) and the time of the nearest;
    with fewer than two obstacles the missing ones are far (``_CAP``) and the time 0."""
    pad = np.full(d.shape[:-1] + (2,), np.inf)
    d, s = np.concatenate([d, pad], -1), np.concatenate([s, np.zeros_like(pad)], -1)
    order = np.argsort(d, -1)[..., :2]
    near, when = np.take_along_axis(d, order, -1), np.take_along_axis(s, order, -1)
    return (
        np.minimum(near[..., 0], _CAP),
        np.minimum(near[..., 1], _CAP),
        np.where(np.isinf(near[..., 0]), 0, when[..., 0]),
    )


def _line_frame(scene: Scene, cand: np.ndarray) -> np.ndarray:
    """Positions and velocities (N, C, 8 + 7K) in the frame of the robot -> target line: candidate minus
    robot, minus target; target minus robot; robot velocity; per obstacle its position minus the
    candidate's and the robot's, its velocity; then each obstacle's distance to the candidate."""
    p, g, v = as_complex(scene.robot_pos), as_complex(scene.target[..., 0:2]), as_complex(scene.robot_vel)
    q, u = as_complex(scene.obstacle_pos), as_complex(scene.obstacle_vel)
    line = g - p
    # A robot on its target has no line: the field's axes then (not a division by zero).
    unit = np.where(np.abs(line) > 1e-9, line / np.maximum(np.abs(line), 1e-9), 1.0)[:, None]
    shape = cand.shape
    own = [
        cand - p[:, None],
        cand - g[:, None],
        np.broadcast_to(line[:, None], shape),
        np.broadcast_to(v[:, None], shape),
    ]
    to_obstacle = q[:, None, :] - cand[:, :, None]
    seen = (
        to_obstacle,
        np.broadcast_to((q - p[:, None])[:, None, :], to_obstacle.shape),
        np.broadcast_to(u[:, None, :], to_obstacle.shape),
    )
    z = np.concatenate([np.stack(own, -1), *seen], -1) / unit[..., None]
    return np.concatenate([z.real, z.imag, np.abs(to_obstacle)], -1)


def candidate_features(planner: SamplingPlanner, scene: Scene, cand: np.ndarray) -> np.ndarray:
    """Features (N, C, 27 + 7K) float32 of candidates ``cand`` (N, C) complex in ``scene`` (K obstacles):
    ``_line_frame``'s, then per leg the nearest and second-nearest obstacle distance, the time of the
    nearest and the smallest growing-margin clearance; the leg times and the arrival time T, T behind the
    soonest candidate and behind the soonest safe one; the clearances of the whole path against the
    growing and the fixed safety distance, whether each is kept, whether any candidate is safe."""
    legs = two_legs(planner, scene, cand)
    columns = []
    for leg in "12":
        d, s, c = legs["d" + leg], legs["s" + leg], legs["c" + leg]
        columns += [*_nearest_two(d, s), np.clip(np.min(c, -1, initial=np.inf), -1.0, _CAP)]
    arrival = legs["tp"] + legs["t2"]
    clear = np.min(np.minimum(legs["c1"], legs["c2"]), -1, initial=np.inf)
    hard = np.min(np.minimum(legs["d1"], legs["d2"]), -1, initial=np.inf)
    hard = hard - planner.collision_distance - planner.margin
    safe, close = clear >= 0, hard >= 0
    any_safe = np.broadcast_to(safe.any(1, keepdims=True), arrival.shape)
    soonest_safe = np.where(safe, arrival, np.inf).min(1, keepdims=True)
    columns += [
        legs["t1"], legs["tp"], legs["t2"], arrival, arrival - arrival.min(1, keepdims=True),
        np.where(any_safe, np.minimum(arrival - soonest_safe, _LATE), _LATE),
        np.clip(clear, -1.0, _CAP), np.clip(hard, -1.0, _CAP), safe, close, any_safe,
    ]  # fmt: skip
    extra = np.stack(columns, -1)
    return np.concatenate([_line_frame(scene, cand), extra], -1).astype(np.float32)


def feature_dim(num_obstacles: int) -> int:
    """Length of ``candidate_features``'s last axis with ``num_obstacles`` obstacles seen."""
    return 27 + 7 * num_obstacles


__all__ = ["candidate_features", "closest_approach", "feature_dim", "two_legs"]
