"""What a learned scorer sees of each of the ``sampling`` planner's candidate sub-goals: per-candidate
features, in closed form, of the path robot -> candidate -> target against obstacles at constant velocity.

The planner ranks candidates by rolling that path out at 50 ms steps (``SamplingPlanner.rollout``), where
its time goes. Here the path is two straight legs at the planner's speed, with the robot parked on the
sub-goal until it is no longer held, and each leg's closest approach to every obstacle is solved exactly
(a distance between two points in uniform motion is smallest at one time, found in closed form), with the
planner's own safety distances (collision distance + margin, growing with the prediction time). Cheap and
approximate: these say what the rollout measures, and a network learns the rest from the planner's labels.

Torch, computed in float32. Inside, 2-D vectors are a first axis of 2 (x, y; no complex dtype: ONNX has
none) and the batch is laid out (K obstacles, B scenes, C candidates): every operation then broadcasts an
obstacle's (K, B, 1) against a candidate's (B, C) over a contiguous last axis of C, where a last axis of K
(a few obstacles) runs torch's loops a few elements at a time. The six pieces of path (three, each split
at the prediction horizon) go through one pass; nothing is masked (a boolean mask costs torch more than
the arithmetic), no reduction returns indices (as slow again), and results new to a function are updated
in place (at batch 256 a new tensor of tens of MB costs more than its arithmetic). Training, evaluation
and the exported file all compute the features here (``hier_ssl.policies.candidate_graph``); TorchScript
compiles these functions, so their tensor arguments carry no annotation and their constants are literals.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import torch

from hier_ssl.manager.planners import SamplingPlanner


class PathModel(NamedTuple):
    """The planner's constants the features read: speed (m/s), hold (s the sub-goal is held), horizon
    (s of constant-velocity prediction), safety (collision distance + margin, m), growth (m / s^1.5)."""

    speed: float
    hold: float
    horizon: float
    safety: float
    growth: float


def path_model(planner: SamplingPlanner) -> PathModel:
    """``planner``'s constants as a ``PathModel``."""
    safety = planner.collision_distance + planner.margin
    return PathModel(planner.speed, planner.hold, planner.predict_horizon, safety, planner.margin_growth)


def _dot(a, b):
    """Dot products of vectors (2, ...) (broadcastable) -> (...)."""
    return (a[0] * b[0]).addcmul_(a[1], b[1])


def _norm(a):
    """Lengths of vectors (2, ...) -> (...)."""
    return _dot(a, a).sqrt_()


def closest_approach_(s, v, t0, t1):
    """Closest distance of a relative position ``s + v (t - t0)`` over t in [t0, t1] (t1 >= t0) and the t
    of it; s, v vectors (2, ...), s of the whole shape, v and t0, t1 (...) broadcastable against it. s is
    overwritten: at batch 256 a new tensor (tens of MB) costs more than its arithmetic."""
    speed2 = _dot(v, v).clamp_(min=1e-12)
    # Minus the time after t0 of the closest point of the whole line, kept within the interval.
    back = _dot(s, v).div_(speed2).clamp_(t0 - t1, 0.0 * t0)
    closest = s.addcmul_(v, back, value=-1.0).square_()
    return closest[0].add_(closest[1]).sqrt_(), back.neg_().add_(t0)


def _margin(t, model: PathModel):
    """The growing part of the safety distance at times t: growth min(t, H)^1.5 (the prediction holds
    after the horizon H)."""
    held = t.clamp(max=model.horizon)
    return model.growth * held * held.sqrt()


def inner_layout(target, robot, robot_vel, obstacles, velocities, cand) -> list[torch.Tensor]:
    """Scenes as the features compute them, float32, 2-D vectors on a first axis of 2: target, robot and
    its velocity (B, 2) -> (2, B, 1) each; obstacles and their velocities (B, K, 2) -> (2, K, B, 1) each;
    candidates (B, C, 2) -> (2, B, C).

    Laid out in memory in that order, which every result then keeps: torch lays a result out as its
    first operand that is not broadcast along an axis, and a reduction over the first axes of another
    layout is slow."""
    scene = torch.stack([target, robot, robot_vel]).permute(2, 0, 1)
    scene = scene.to(torch.float32, memory_format=torch.contiguous_format)[..., None]
    moving = torch.stack([obstacles, velocities]).permute(3, 0, 2, 1)
    moving = moving.to(torch.float32, memory_format=torch.contiguous_format)[..., None]
    c = cand.permute(2, 0, 1).to(torch.float32, memory_format=torch.contiguous_format)
    return [scene[:, 0], scene[:, 1], scene[:, 2], moving[:, 0], moving[:, 1], c]


def two_legs(model: PathModel, g, p, q, u, c) -> dict[str, torch.Tensor]:
    """The straight path robot -> candidate (parked there while held) -> target at the planner's speed.

    Shapes as ``inner_layout``'s: g, p target and robot (2, B, 1); q, u obstacles and their velocities
    (2, K, B, 1); c candidates (2, B, C). Returns leg times "t1" (to the candidate), "tp" (until it leaves
    the candidate), "t2" (on to the target), (B, C); per leg "1" (incl. the park) and "2", on each of its
    n pieces of path (4, 2) against each obstacle, the closest distance "d" (1e30 m beyond where a piece
    is empty) and its time "s" (n, K, B, C), and the leg's smallest growing-margin clearance "c" (B, C)
    (an upper bound of the true one, whose growing margin can put it between the points measured, by up
    to 6 cm on random scenes; +inf without obstacles).

    Each of the three pieces (to the candidate, parked, on) is split at the horizon H clamped into it:
    before H the obstacles move, after it they hold where the prediction left them. A piece all on one
    side of H leaves a point on the other (its start or end), which its distances already cover.
    """
    h, speed = model.horizon, model.speed
    out, on = c - p, g - c
    l1, l2 = _norm(out), _norm(on)
    t1, t2 = l1 / speed, l2 / speed
    # The worker drives to a held sub-goal and waits there; the target itself is never left.
    tp = torch.where(l2 == 0, t1, t1.clamp(min=model.hold))
    times = torch.stack([0.0 * t1, t1, tp, tp + t2])
    begin, end = times[0:3], times[1:4]  # (3 pieces, B, C)
    split = torch.minimum(begin.clamp(min=h), end)
    edges = torch.stack([begin, split, end], 1)[:, :, None]
    lo, hi = edges[:, 0:2], edges[:, 1:3]  # (3, 2 sides of H, 1, B, C)
    w1, w2 = out * (speed / l1.clamp(min=1e-9)), on * (speed / l2.clamp(min=1e-9))
    # The robot at each piece's start and its velocity on it, (2, 3, B, C) each.
    start, w = torch.stack([p.expand_as(c), c, c, w1, 0.0 * c, w2], 1).split(3, 1)
    robot_at = torch.stack([start, torch.addcmul(start, w, split - begin)], 2)[:, :, :, None]
    # Robot minus obstacle at each side's start, and their relative velocity: (2, 3, 2, K, B, C).
    rel = (robot_at - q[:, None, None]).addcmul_(u[:, None, None], lo.clamp(max=h), value=-1.0)
    # Clearance beyond the growing margin at each leg's start, at each moving side's closest point and at
    # each held side's (its least clear, the margin holding too, which covers the moving side's end).
    starts = [_least(_norm(p[:, None] - q)), _least(_norm(rel[:, 2, 0])) - _margin(tp, model)]
    d, s = closest_approach_(rel, w[:, :, None, None] - torch.stack([u, 0.0 * u], 1)[:, None], lo, hi)
    held = s[:, 0].clamp(max=h)
    moved = _least(held.sqrt().mul_(held).mul_(-model.growth).add_(d[:, 0]))
    clear = torch.minimum(moved, _least(d[:, 1]) - _margin(split, model))  # (3, B, C)
    c1 = torch.minimum(clear[0:2].amin(0), starts[0])
    c2 = torch.minimum(clear[2], starts[1])
    # A side that is only a point of a piece all on the other side of H names no closest distance (a
    # rounding could make it one): pushed out by 1e30 m, where the side is empty.
    empty = torch.stack([begin - h, h - end], 1).clamp(min=0.0)[:, :, None]
    dist = d.add_(empty, alpha=1e30)
    return {
        "t1": t1, "tp": tp, "t2": t2,
        "d1": dist[0:2].flatten(0, 1), "s1": s[0:2].flatten(0, 1), "c1": c1 - model.safety,
        "d2": dist[2], "s2": s[2], "c2": c2 - model.safety,
    }  # fmt: skip


def _least(x):
    """The smallest value over the obstacles, (..., K, B, C) -> (..., B, C); +inf where K = 0."""
    if x.shape[-3] == 0:
        return torch.full_like(x.sum(-3), math.inf)
    return x.amin(-3)


def _nearest_two_(d, s) -> list[torch.Tensor]:
    """A leg's nearest obstacle distance, the time of it and the second-nearest obstacle's distance
    (B, C), of the distances d and times s on its pieces (n, K, B, C); +inf and 0 s for missing ones.
    d is overwritten."""
    k = d.shape[1]
    if k == 0:
        far = torch.full_like(d.sum((0, 1)), math.inf)
        return [far, torch.zeros_like(far), far]
    each = d.amin(0)  # (K, B, C)
    first = each.amin(0)
    # The earliest time at that distance: any farther point is pushed past every time. (The pieces run in
    # time order; no arg-min: torch's with indices takes 30 times its plain minimum.)
    when = d.sub_(first).mul_(1e30).add_(s).amin((0, 1))
    if k == 1:
        return [first, when, torch.full_like(first, math.inf)]
    # The farther of every two obstacles (K, K, B, C), the diagonal left out: the flattened K x K pairs but
    # the first, as (K - 1, K + 1), hold the rest of the diagonal in their last column (reduced in two
    # steps: a reduction over a sliced view takes torch a hundred times as long).
    pairs = torch.maximum(each[:, None], each[None]).flatten(0, 1)[1:]
    second = pairs.unflatten(0, (k - 1, k + 1)).amin(0)[:k].amin(0)
    return [first, when, second]


def _turned(v, ux, uy) -> list[torch.Tensor]:
    """Vectors v (2, ...) in the frame of unit vector (ux, uy) (...): along it, and to its left."""
    return [torch.addcmul(v[0] * ux, v[1], uy), torch.addcmul(v[1] * ux, v[0], uy, value=-1.0)]


def _line_frame(g, p, vel, q, u, c) -> list[torch.Tensor]:
    """Positions and velocities in the frame of the robot -> target line, pieces of (8 + 7K, B, C):
    candidate minus robot, minus target; target minus robot; robot velocity; per obstacle its position
    minus the candidate's and the robot's, its velocity (all x, then all y); then each obstacle's distance
    to the candidate. Shapes as in ``two_legs``; vel the robot's velocity (2, B, 1)."""
    line = g - p
    length = _norm(line)
    # A robot on its target has no line: the field's axes then (not a division by zero).
    far = length > 1e-9
    ux = torch.where(far, line[0] / length.clamp(min=1e-9), 1.0)  # (B, 1)
    uy = torch.where(far, line[1] / length.clamp(min=1e-9), 0.0)
    b, m, k = c.shape[1], c.shape[2], q.shape[1]
    # Candidate minus robot, then the rest from the robot on (rotations of (B, 1) vectors, not (B, C)).
    from_robot = _turned(c - p, ux, uy)  # (B, C) each
    line_vel = _turned(torch.stack([line, vel], 1), ux, uy)  # (2, B, 1) each
    to = q - c[:, None]  # (2, K, B, C)
    near = _turned(to, ux, uy)
    seen = [x.flatten(0, 1).expand(2 * k, b, m) for x in _turned(torch.stack([q - p[:, None], u], 1), ux, uy)]
    parts: list[torch.Tensor] = []
    for i in range(2):
        own = [from_robot[i][None], (from_robot[i] - line_vel[i][0])[None], line_vel[i].expand(2, b, m)]
        parts += own + [near[i], seen[i]]
    return parts + [_norm(to)]


def candidate_features(model: PathModel, target, robot, robot_vel, obstacles, velocities, cand):
    """Features (B, C, 27 + 7K) float32 of candidates ``cand`` (B, C, 2) in scenes of K obstacles: target,
    robot, robot_vel (B, 2); obstacles, velocities (B, K, 2); computed in float32. The positions and
    velocities in the frame of the robot -> target line (``_line_frame``), then per leg the nearest and
    second-nearest obstacle distance, the time of the nearest and the smallest growing-margin clearance;
    the leg times and the arrival time T, T behind the soonest candidate and behind the soonest safe one;
    the clearances of the whole path against the growing and the fixed safety distance, whether each is
    kept, whether any candidate is safe.

    A view of a (27 + 7K, B, C) tensor: a network's first layer reads it as it is (a transposed matrix)."""
    g, p, vel, q, u, c = inner_layout(target, robot, robot_vel, obstacles, velocities, cand)
    legs = two_legs(model, g, p, q, u, c)
    columns: list[torch.Tensor] = []
    nearest: list[torch.Tensor] = []
    for leg in ("1", "2"):
        first, when, second = _nearest_two_(legs["d" + leg], legs["s" + leg])
        nearest.append(first)
        columns += [first.clamp(max=3.0), second.clamp(max=3.0), when, legs["c" + leg].clamp(-1.0, 3.0)]
    arrival = legs["tp"] + legs["t2"]
    clear = torch.minimum(legs["c1"], legs["c2"])
    hard = torch.minimum(nearest[0], nearest[1]) - model.safety
    safe, close = clear >= 0, hard >= 0
    any_safe = safe.any(1, keepdim=True).expand_as(safe)
    soonest_safe = arrival.masked_fill(~safe, math.inf).amin(1, keepdim=True)
    late = torch.where(any_safe, (arrival - soonest_safe).clamp(max=5.0), 5.0)
    columns += [
        legs["t1"], legs["tp"], legs["t2"], arrival, arrival - arrival.amin(1, keepdim=True), late,
        clear.clamp(-1.0, 3.0), hard.clamp(-1.0, 3.0), safe.float(), close.float(), any_safe.float(),
    ]  # fmt: skip
    frame = _line_frame(g, p, vel, q, u, c)
    return torch.cat(frame + [column[None] for column in columns]).permute(1, 2, 0)


def feature_dim(num_obstacles: int) -> int:
    """Length of ``candidate_features``'s last axis with ``num_obstacles`` obstacles seen."""
    return 27 + 7 * num_obstacles


__all__ = [
    "PathModel",
    "candidate_features",
    "closest_approach_",
    "feature_dim",
    "inner_layout",
    "path_model",
    "two_legs",
]
