"""What a learned scorer sees of each of the ``sampling`` planner's candidate sub-goals: per-candidate
features, in closed form, of the path robot -> candidate -> target against obstacles at constant velocity.

The planner ranks candidates by rolling that path out at 50 ms steps (``SamplingPlanner.rollout``), where
its time goes. Here the path is two straight legs at the planner's speed, with the robot parked on the
sub-goal until it is no longer held, and each leg's closest approach to every obstacle is solved exactly
(a distance between two points in uniform motion is smallest at one time, found in closed form), with the
planner's own safety distances (collision distance + margin, growing with the prediction time). Cheap and
approximate: these say what the rollout measures, and a network learns the rest from the planner's labels.

Torch tensors of one float dtype, batched over (B scenes, C candidates, K obstacles); 2-D vectors are a
last axis of 2, or split into components (no complex dtype: ONNX has none). Training, evaluation and the
exported file all compute the features here (``hier_ssl.policies.candidate_graph``); TorchScript compiles
these functions, so their tensor arguments carry no annotation and their constants are literals.
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


def _dot(ax, ay, bx, by):
    """Dot products of vectors given by their x and y components (any broadcastable shapes)."""
    return ax * bx + ay * by


def closest_approach(sx, sy, vx, vy, t0, t1):
    """Closest distance and its time for a relative position ``s + v (t - t0)`` over [t0, t1], vectors by
    their components (sx, sy, vx, vy), all broadcastable; +inf where t1 < t0 (an empty piece)."""
    speed2 = _dot(vx, vy, vx, vy).clamp(min=1e-12)
    t = t0 + (-_dot(sx, sy, vx, vy) / speed2).clamp(min=0.0)
    t = torch.minimum(t, t1)
    gx, gy = sx + vx * (t - t0), sy + vy * (t - t0)
    return _dot(gx, gy, gx, gy).sqrt().masked_fill(t1 < t0, math.inf), t


def _half(rx, ry, vx, vy, lo, hi, model: PathModel, held: bool):
    """One piece of path on one side of the prediction horizon: relative position r + v t at absolute
    time t in [lo, hi]; its closest distance, the time of it and the clearance beyond the growing safety
    distance at its ends and closest point (an upper bound of the smallest one, whose growing margin can
    put it between, by up to 6 cm on random scenes). ``held``: after the horizon, where the obstacles and
    the safety distance hold, so the closest point is the least clear."""
    sx, sy = rx + vx * lo, ry + vy * lo
    d, t = closest_approach(sx, sy, vx, vy, lo, hi)
    h, growth = model.horizon, model.growth
    if held:
        return d, t, d - (model.safety + growth * h**1.5)
    ex, ey = rx + vx * hi, ry + vy * hi
    # The distances at the ends and at the closest point, each less the growing margin there.
    first = _dot(sx, sy, sx, sy).sqrt() - growth * lo.clamp(max=h) ** 1.5
    last = _dot(ex, ey, ex, ey).sqrt() - growth * hi.clamp(max=h) ** 1.5
    closest = d - growth * t.clamp(max=h) ** 1.5
    clearance = torch.minimum(torch.minimum(first, closest), last) - model.safety
    return d, t, clearance.masked_fill(hi < lo, math.inf)


def _piece(
    r0: list[torch.Tensor],
    w: list[torch.Tensor],
    begin,
    end,
    q: list[torch.Tensor],
    u: list[torch.Tensor],
    model: PathModel,
):
    """The robot at r0 + w (t - begin) over [begin, end] (components (B, C, 1) each) against obstacles at
    q + u min(t, H) (components (B, 1, K)): closest distance, its time, clearance, each (B, C, K). The piece
    is split at H: before it the obstacles move, after it they hold where the prediction left them."""
    h = model.horizon
    sx, sy = r0[0] - w[0] * begin - q[0], r0[1] - w[1] * begin - q[1]
    d_a, t_a, c_a = _half(sx, sy, w[0] - u[0], w[1] - u[1], begin, end.clamp(max=h), model, False)
    d_b, t_b, c_b = _half(sx - u[0] * h, sy - u[1] * h, w[0], w[1], begin.clamp(min=h), end, model, True)
    closer = d_b < d_a
    return torch.where(closer, d_b, d_a), torch.where(closer, t_b, t_a), torch.minimum(c_a, c_b)


def two_legs(model: PathModel, target, robot, obstacles, velocities, cand) -> dict[str, torch.Tensor]:
    """The straight path robot -> candidate (parked there while held) -> target at the planner's speed.

    Shapes: target, robot (B, 2); obstacles, velocities (B, K, 2); cand (B, C, 2). Returns leg times
    "t1" (to the candidate), "tp" (until it leaves the candidate), "t2" (on to the target), (B, C); per leg
    "1" (incl. the park) and "2" the closest distance d, its time s and the growing-margin clearance c to
    each obstacle, (B, C, K). Vectors are split into their components, (B, C, 1) for the robot's and
    (B, 1, K) for the obstacles': a sum over a last axis of 2 costs torch more than the arithmetic."""
    speed = model.speed
    p = [robot[:, i, None, None] for i in range(2)]
    g = [target[:, i, None, None] for i in range(2)]
    c = [cand[:, :, i, None] for i in range(2)]
    q = [obstacles[:, None, :, i] for i in range(2)]
    u = [velocities[:, None, :, i] for i in range(2)]
    out, on = [c[i] - p[i] for i in range(2)], [g[i] - c[i] for i in range(2)]
    l1, l2 = _dot(out[0], out[1], out[0], out[1]).sqrt(), _dot(on[0], on[1], on[0], on[1]).sqrt()
    w1 = [speed * out[i] / l1.clamp(min=1e-9) for i in range(2)]
    w2 = [speed * on[i] / l2.clamp(min=1e-9) for i in range(2)]
    t1 = l1 / speed
    # The worker drives to a held sub-goal and waits there; the target itself is never left.
    tp = torch.where(l2 == 0, t1, t1.clamp(min=model.hold))
    t2 = tp + l2 / speed
    parked = [0.0 * w1[i] for i in range(2)]
    d0, s0, c0 = _piece(p, w1, torch.zeros_like(t1), t1, q, u, model)  # to the candidate
    d1, s1, c1 = _piece(c, parked, t1, tp, q, u, model)  # parked there
    d2, s2, c2 = _piece(c, w2, tp, t2, q, u, model)  # on to the target
    closer = d1 < d0
    return {
        "t1": t1[..., 0], "tp": tp[..., 0], "t2": (t2 - tp)[..., 0],
        "d1": torch.where(closer, d1, d0), "s1": torch.where(closer, s1, s0), "c1": torch.minimum(c0, c1),
        "d2": d2, "s2": s2, "c2": c2,
    }  # fmt: skip


def _smallest(x):
    """The smallest value over the last axis (B, C, K) -> (B, C); +inf where K = 0."""
    return torch.cat([x, torch.full_like(x.sum(-1, keepdim=True), math.inf)], -1).amin(-1)


def _nearest_two(d, s) -> list[torch.Tensor]:
    """The nearest and second-nearest distance over the obstacles (B, C) and the time of the nearest;
    with fewer than two obstacles the missing ones are far (3 m) and the time 0."""
    pad = torch.full_like(d.sum(-1, keepdim=True), math.inf)
    near, order = torch.topk(torch.cat([d, pad, pad], -1), 2, dim=-1, largest=False, sorted=True)
    when = torch.gather(torch.cat([s, 0.0 * pad, 0.0 * pad], -1), -1, order)
    first = near[..., 0]
    return [first.clamp(max=3.0), near[..., 1].clamp(max=3.0), when[..., 0].masked_fill(first.isinf(), 0.0)]


def _line_frame(target, robot, robot_vel, obstacles, velocities, cand) -> list[torch.Tensor]:
    """Positions and velocities in the frame of the robot -> target line, float32 pieces of (B, C, 8 + 7K):
    candidate minus robot, minus target; target minus robot; robot velocity; per obstacle its position
    minus the candidate's and the robot's, its velocity (all x, then all y); then each obstacle's distance
    to the candidate. Shapes as in ``two_legs``; robot_vel (B, 2)."""
    line = target - robot
    length = _dot(line[:, 0], line[:, 1], line[:, 0], line[:, 1]).sqrt()[:, None]
    # A robot on its target has no line: the field's axes then (not a division by zero).
    far = length > 1e-9
    ux = torch.where(far, line[:, 0:1] / length.clamp(min=1e-9), 1.0)[:, :, None]  # (B, 1, 1)
    uy = torch.where(far, line[:, 1:2] / length.clamp(min=1e-9), 0.0)[:, :, None]
    b, m, k = cand.shape[0], cand.shape[1], obstacles.shape[1]
    # Vectors by components: (B, C, 4) of the candidate's own, (B, C, K) and (B, 1, K) of the obstacles'.
    own = torch.stack(
        [cand - robot[:, None], cand - target[:, None], line[:, None].expand(b, m, 2),
         robot_vel[:, None].expand(b, m, 2)],
        2,
    )  # fmt: skip
    to_x = obstacles[:, None, :, 0] - cand[:, :, None, 0]
    to_y = obstacles[:, None, :, 1] - cand[:, :, None, 1]
    seen = [(obstacles - robot[:, None])[:, None], velocities[:, None]]
    xs = [own[..., 0] * ux + own[..., 1] * uy, to_x * ux + to_y * uy]
    ys = [own[..., 1] * ux - own[..., 0] * uy, to_y * ux - to_x * uy]
    parts = [part.float() for part in xs]
    parts += [(v[..., 0] * ux + v[..., 1] * uy).float().expand(b, m, k) for v in seen]
    parts += [part.float() for part in ys]
    parts += [(v[..., 1] * ux - v[..., 0] * uy).float().expand(b, m, k) for v in seen]
    return parts + [_dot(to_x, to_y, to_x, to_y).sqrt().float()]


def candidate_features(model: PathModel, target, robot, robot_vel, obstacles, velocities, cand):
    """Features (B, C, 27 + 7K) float32 of candidates ``cand`` (B, C, 2) in scenes of K obstacles (shapes
    as in ``two_legs``; robot_vel (B, 2)): the positions and velocities in the frame of the robot -> target
    line (``_line_frame``), then per leg the nearest and second-nearest obstacle distance, the
    time of the nearest and the smallest growing-margin clearance; the leg times and the arrival time T, T
    behind the soonest candidate and behind the soonest safe one; the clearances of the whole path against
    the growing and the fixed safety distance, whether each is kept, whether any candidate is safe."""
    legs = two_legs(model, target, robot, obstacles, velocities, cand)
    columns: list[torch.Tensor] = []
    for leg in ("1", "2"):
        columns += _nearest_two(legs["d" + leg], legs["s" + leg])
        columns.append(_smallest(legs["c" + leg]).clamp(-1.0, 3.0))
    arrival = legs["tp"] + legs["t2"]
    clear = _smallest(torch.minimum(legs["c1"], legs["c2"]))
    hard = _smallest(torch.minimum(legs["d1"], legs["d2"])) - model.safety
    safe, close = clear >= 0, hard >= 0
    any_safe = safe.any(1, keepdim=True).expand_as(safe)
    soonest_safe = arrival.masked_fill(~safe, math.inf).amin(1, keepdim=True)
    late = torch.where(any_safe, (arrival - soonest_safe).clamp(max=5.0), 5.0)
    columns += [
        legs["t1"], legs["tp"], legs["t2"], arrival, arrival - arrival.amin(1, keepdim=True), late,
        clear.clamp(-1.0, 3.0), hard.clamp(-1.0, 3.0), safe.to(arrival.dtype), close.to(arrival.dtype),
        any_safe.to(arrival.dtype),
    ]  # fmt: skip
    frame = _line_frame(target, robot, robot_vel, obstacles, velocities, cand)
    return torch.cat(frame + [torch.stack(columns, -1).float()], -1)


def feature_dim(num_obstacles: int) -> int:
    """Length of ``candidate_features``'s last axis with ``num_obstacles`` obstacles seen."""
    return 27 + 7 * num_obstacles


__all__ = ["PathModel", "candidate_features", "closest_approach", "feature_dim", "path_model", "two_legs"]
