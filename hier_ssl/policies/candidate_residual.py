"""The ``residual`` candidates network: the ``sampling`` planner's own ranking of its candidates plus a
learned correction, so that learning starts from the planner's choice rather than from imitating it.

Logits (B, C) = ``score`` / tau + ``keep`` on the planner's own choice + an MLP over each candidate's
features. ``score`` is the planner's
(``SamplingPlanner.ranking``): minus the arrival time within the tier it would choose from, -inf outside
it, so the correction re-ranks the candidates the planner would consider and never picks one it rules out.
The MLP's last layer starts at zero: the untrained network's argmax is the planner's choice (ties to the
earlier candidate, as ``np.argmax``), and PPO (``hier_ssl.policies.candidates``) moves it from there.
``keep`` is a dead band: the planner's score is an arrival time on its 50 ms rollout grid, so its top is
often an exact tie, which the planner breaks by the candidates' order, the same from one control step to
the next; a correction with no band breaks it by features that move every step, and the robot switches
sub-goals (docs/results.md, "A residual over `sampling`'s own ranking"). With it the correction changes
the choice only where it outweighs ``keep``.

With ``candidates.memory`` it reads two more (``MEMORY_FEATURES``): how far each candidate is from the
sub-goal this robot chose at its last decision, and how far the robot is from that. The observation holds
no sub-goal, so a correction without them cannot tell holding a way round from switching to the other
one; replanning every step, the planner flips between two ways round a block of parked robots and the
robot stands still until the time limit (docs/results.md, "What stops it"). The caller keeps the memory
(``hier_ssl.policies.candidate_graph.RememberingPolicy``).

With ``candidates.zone_features`` the MLP reads two more columns (``ZONE_FEATURES``): how far each of a
candidate's two straight legs keeps from the game's forbidden zones. The planner's ``clear`` only says
whether a leg breaks one, so a correction could not learn to keep a margin from a zone that moves (the
circle around a rolling ball at the opponent's free kick). Off by default: a network trained without them
reads ``RESIDUAL_FEATURES`` and is rebuilt so.

The features are the planner's rollout outputs (numba, numpy): the decision is not one torch graph, so a
residual run does not export (``hier_ssl.policies.export``).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

from hier_ssl.game.legal import RowRules, path_clearance
from hier_ssl.manager.game_observation import RuledPlanner, ruled_read
from hier_ssl.manager.planners import SamplingPlanner
from hier_ssl.policies.networks import mlp

RESIDUAL_FEATURES = 11
"""Per candidate, after the score: arrival time (s), how much later than the row's soonest, the three
clearances (growing, fixed, within the prediction window; m), clear of the zones, in the ranked tier, the
distances robot -> candidate and candidate -> target (m), the robot's speed and the speed it may drive at
(m/s), each clipped to a few units: the MLP reads them as they are."""

ZONE_FEATURES = 2
"""With ``candidates.zone_features``, after ``RESIDUAL_FEATURES``: how far the first leg (robot ->
candidate) and the second (candidate -> target) keep from the row's zones, the least over them of
``path_clearance`` (m; negative through one), clipped to [-1, 3]; 3 where there is none to keep from (no
rules, empty slots)."""


MEMORY_FEATURES = 2
"""With ``candidates.memory``, last: how far the candidate and the robot are from the sub-goal the robot's
last decision chose (m), clipped to [0, 5]; 5 both at an episode's first decision, which has none."""


def residual_features(zone_features: bool = False, memory: bool = False) -> int:
    """How many features a candidate's row of ``residual_inputs`` holds after its two prior columns."""
    return RESIDUAL_FEATURES + ZONE_FEATURES * bool(zone_features) + MEMORY_FEATURES * bool(memory)


class Residual(nn.Module):
    """Logits (B, C) of inputs (B, C, 2 + ``features``) (``residual_inputs``): column 0 the
    planner's score relative to the row's best, divided by ``tau`` (s), plus ``keep`` times column 1 (1 on
    the planner's choice), plus ``body`` (features -> hidden -> 1, last layer zero at the start) of the
    rest."""

    def __init__(self, features: int, hidden: Sequence[int], tau: float, keep: float = 0.0) -> None:
        super().__init__()
        if not keep >= 0.0:
            raise ValueError(f"candidates.keep must be >= 0, got {keep!r}")
        self.register_buffer("tau", torch.tensor(float(tau)))
        self.register_buffer("keep", torch.tensor(float(keep)))
        self.body = mlp(features, hidden, 1)
        nn.init.zeros_(self.body[-1].weight)
        nn.init.zeros_(self.body[-1].bias)

    def forward(self, inputs: torch.Tensor) -> torch.Tensor:
        prior = inputs[..., 0] / self.tau + self.keep * inputs[..., 1]
        return prior + self.body(inputs[..., 2:])[..., 0]


def residual_planner(planner: object) -> None:
    """Raise unless ``planner`` is the ``sampling`` planner (a game's: under ``RuledPlanner``), whose
    ranking a residual corrects."""
    inner = planner.planner if isinstance(planner, RuledPlanner) else planner
    if not isinstance(inner, SamplingPlanner):
        name = type(inner).__name__
        raise ValueError(f"a residual candidates network corrects the sampling planner's ranking; got {name}")


def zone_clearances(
    rules: RowRules | None, robot: np.ndarray, target: np.ndarray, cand: np.ndarray
) -> list[np.ndarray]:
    """The ``ZONE_FEATURES`` columns (B, C) of candidates ``cand`` (B, C) of robots at ``robot`` going to
    ``target`` (B,) (complex, m) under ``rules``: the first leg's clearance from the zones, the second's."""
    if rules is None:
        return [np.full(cand.shape, 3.0)] * ZONE_FEATURES
    # (B, 1, S): each row's zones against its own C paths, which path_clearance reads without copying.
    zones = rules.zones.take(np.s_[:, None])
    legs = path_clearance(zones, robot[:, None], cand), path_clearance(zones, cand, target[:, None])
    return [leg.min(-1, initial=np.inf).clip(-1.0, 3.0) for leg in legs]


def residual_inputs(
    planner: SamplingPlanner | RuledPlanner,
    obs: np.ndarray,
    cand: np.ndarray,
    zone_features: bool = False,
    last: np.ndarray | None = None,
    ranked: tuple[np.ndarray, tuple[np.ndarray, ...], np.ndarray] | None = None,
) -> torch.Tensor:
    """What a ``Residual`` reads (B, C, 2 + ``residual_features(zone_features)``) float32 of observations
    ``obs`` (B, O) and their candidates ``cand`` (B, C) complex: the planner's score minus the row's best
    (so float32 keeps the gaps near the top that decide the argmax; 0 across a row it ranks nothing in,
    where the planner takes the first), 1 on the planner's choice (the first of its best) and 0 elsewhere,
    then the ``RESIDUAL_FEATURES`` and, with ``zone_features``, the ``ZONE_FEATURES``: the first leg's
    (robot -> candidate) and the second leg's (candidate -> ``scene``'s target, where the rules moved it)
    least clearance from the row's zones (``zone_clearances``), m in [-1, 3], 3 without rules; with
    ``last`` (B,) complex, each robot's last chosen sub-goal (NaN: none), the ``MEMORY_FEATURES``.
    ``ranked``: ``planner.ranking`` of these candidates where the caller has it already (its rollouts are
    what the features cost)."""
    scene, rules = ruled_read(planner, obs)
    ranked = planner.ranking(scene, cand, rules) if ranked is None else ranked
    score, (arrival, clearance, hard, near), clear = ranked
    best = score.max(1, keepdims=True)
    any_ranked = np.isfinite(best)
    prior = np.where(any_ranked, score - np.where(any_ranked, best, 0.0), 0.0)
    robot = scene.robot_pos @ np.array([1.0, 1j])
    target = scene.target[:, 0:2] @ np.array([1.0, 1j])
    speed = np.hypot(*scene.robot_vel.T)[:, None]
    limit = planner.speed if rules is None else np.minimum(planner.speed, rules.speed)
    row = np.ones_like(arrival)
    choice = np.arange(prior.shape[1]) == np.argmax(prior, 1)[:, None]
    columns = [
        prior,
        choice,
        arrival.clip(0.0, 10.0),
        (arrival - arrival.min(1, keepdims=True)).clip(0.0, 5.0),
        clearance.clip(-1.0, 3.0),
        hard.clip(-1.0, 3.0),
        near.clip(-1.0, 3.0),
        clear,
        np.isfinite(score),
        np.abs(cand - robot[:, None]).clip(max=5.0),
        np.abs(target[:, None] - cand).clip(max=5.0),
        speed * row,
        np.reshape(limit, (-1, 1)) * row,
    ]
    if zone_features:
        columns += zone_clearances(rules, robot, target, cand)
    if last is not None:
        none = np.isnan(last)[:, None]
        columns += [
            np.where(none, 5.0, np.abs(cand - last[:, None]).clip(max=5.0)),
            np.where(none, 5.0, np.abs(robot - last)[:, None].clip(max=5.0)) * row,
        ]
    return torch.as_tensor(np.stack(columns, -1), dtype=torch.float32)


__all__ = [
    "MEMORY_FEATURES",
    "RESIDUAL_FEATURES",
    "ZONE_FEATURES",
    "Residual",
    "residual_features",
    "residual_inputs",
    "residual_planner",
    "zone_clearances",
]
