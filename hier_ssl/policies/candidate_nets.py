"""The networks a candidates manager can choose with (``candidates.network``), and what each reads.

- ``classifier``: an MLP over the manager's observation (B, O) with one logit per candidate slot (B, C).
- ``scorer``: one small MLP shared by every candidate, over that candidate's features (B, C, F)
  (``hier_ssl.policies.candidate_features``), one logit each. It scores a candidate by what happens on the
  way to it, not by its slot, so "pass left of the second-nearest obstacle" is not a class of its own.
- ``residual``: the planner's own ranking plus a learned per-candidate correction, over the planner's
  score and rollouts (``hier_ssl.policies.candidate_residual``); it starts as the planner, without DAgger.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch
from torch import nn

from hier_ssl.checkpoints.actor import linear_layers, mean_actor
from hier_ssl.manager.game_observation import RuledPlanner, ruled_read
from hier_ssl.manager.planners import SamplingPlanner
from hier_ssl.policies.candidate_residual import Residual, residual_features
from hier_ssl.policies.networks import mlp

NETWORKS = ("classifier", "scorer", "residual")


class Scorer(nn.Module):
    """Logits (B, C) of features (B, C, F): ``body`` (F -> hidden -> 1) on each candidate's features,
    standardised by the ``mean`` and ``std`` (F,) of the first data it was fitted on."""

    def __init__(self, features: int, hidden: Sequence[int], mean: torch.Tensor, std: torch.Tensor) -> None:
        super().__init__()
        self.register_buffer("mean", mean.detach().clone().float())
        self.register_buffer("std", std.detach().clone().float())
        self.body = mlp(features, hidden, 1)

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.body((features - self.mean) / self.std)[..., 0]


def build_chooser(
    network: str,
    hidden: Sequence[int],
    inputs: torch.Tensor | None,
    candidates: int,
    tau: float = 1.0,
    keep: float = 0.0,
    zone_features: bool = False,
    memory: bool = False,
) -> nn.Module:
    """A new network of kind ``network`` for ``inputs`` (its first data: observations (B, O) for the
    classifier, features (B, C, F) for the scorer, whose standardisation they fix; the residual reads
    none: its features are scaled as they come, ``tau`` divides its planner's score, ``keep`` is its dead
    band, ``zone_features`` adds the legs' zone clearances to what it reads and ``memory`` the robot's last
    sub-goal)."""
    if network not in NETWORKS:
        raise ValueError(f"unknown candidates.network {network!r}; expected one of {NETWORKS}")
    if network == "residual":
        return Residual(residual_features(zone_features, memory), hidden, tau, keep)
    if inputs is None:
        raise ValueError(f"a {network} is built from its first data; none given (DAgger's first round)")
    if network == "classifier":
        return mlp(inputs.shape[1], hidden, candidates)
    flat = inputs.reshape(-1, inputs.shape[-1])
    return Scorer(flat.shape[1], hidden, flat.mean(0), flat.std(0).clamp_min(1e-3))


def chooser_from_state(state: dict[str, torch.Tensor]) -> nn.Module:
    """The classifier, scorer or residual rebuilt from its state dict (a scorer's holds "mean", a
    residual's "tau"), sizes from the weights."""
    if "mean" not in state and "tau" not in state:
        return mean_actor(state, "", nn.ReLU, linear_layers(state, "")[-1][0].shape[0], nn.Identity())
    layers = linear_layers(state, "body.")
    sizes = (layers[0][0].shape[1], [weight.shape[0] for weight, _ in layers[:-1]])
    residual = "tau" in state
    if residual:
        net = Residual(*sizes, float(state["tau"]), float(state["keep"]))
    else:
        net = Scorer(*sizes, state["mean"], state["std"])
    net.load_state_dict(state)
    return net


def soft_choice(
    planner: SamplingPlanner | RuledPlanner, obs: np.ndarray, cand: np.ndarray, tau: float
) -> np.ndarray:
    """The planner's soft choice (N, C) over its candidates ``cand`` (N, C) complex for observations ``obs``
    (N, O) (a game's: under the rules they carry, ``ruled_read``), rows summing to 1, which the networks are
    fitted to: a softmax of its ``score`` / ``tau`` (over the best tier it would choose from, by arrival
    time)."""
    scene, rules = ruled_read(planner, obs)
    score = planner.score(scene, cand, rules)
    weight = np.exp((score - score.max(1, keepdims=True)) / tau)
    return weight / weight.sum(1, keepdims=True)


def fit_chooser(
    net: nn.Module,
    optimizer: torch.optim.Optimizer,
    inputs: torch.Tensor,
    labels: torch.Tensor,
    epochs: int,
    batch_size: int,
) -> tuple[float, float]:
    """``epochs`` passes of the cross-entropy to the planner's soft choice ``labels`` (B, C) over
    ``inputs`` (observations, or a scorer's stored features); the mean loss and the share of states where the
    network's first choice is the planner's."""
    losses = []
    for _ in range(epochs):
        for rows in torch.randperm(len(inputs)).split(batch_size):
            loss = -(labels[rows] * torch.log_softmax(net(inputs[rows].float()), 1)).sum(1).mean()
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            losses.append(loss.item())
    with torch.no_grad():
        logits = torch.cat([net(part.float()) for part in inputs.split(4096)])
    return float(np.mean(losses)), float((logits.argmax(1) == labels.argmax(1)).float().mean())


__all__ = [
    "NETWORKS",
    "Scorer",
    "build_chooser",
    "chooser_from_state",
    "fit_chooser",
    "soft_choice",
]
