"""DAgger over the ``sampling`` planner's candidate sub-goals: a manager that chooses a sub-goal rather
than regressing one.

The planner's choice is discontinuous in the observation (pass an obstacle on the left or on the right),
and a Gaussian actor fitted to it lands between the branches. Here the manager's action is a class: one
of the planner's own candidate sub-goals (``SamplingPlanner.candidates``: the target, the robot's
position, rings around each seen obstacle, points along the robot-target line, a ring around the robot),
which the planner builds from the observation by geometry alone. An MLP maps the observation to one logit
per candidate. DAgger (Ross et al., 2011) fits it: round 0 plays the planner, every later round the
network; every state met is labelled with the planner's soft choice over all candidates (a softmax of
minus the arrival time over the candidates of the best safety tier the planner would choose from,
temperature ``tau`` seconds), and the network is refitted on everything gathered so far.

A hybrid: at every decision the trained manager runs the planner's candidate geometry (not its rollouts,
which are where the planner's time goes), so it needs hier_ssl at run time and does not export.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn
from torch.utils.tensorboard import SummaryWriter
from tqdm import tqdm

from hier_ssl.config import TrainConfig
from hier_ssl.evaluate import evaluate
from hier_ssl.manager.planners import SamplingPlanner, Scene, make_planner

Labelled = tuple[np.ndarray, np.ndarray]
"""Observations (S, obs_dim) and the planner's soft choice over the candidates (S, C), float32."""


def candidate_planner(config: TrainConfig) -> SamplingPlanner:
    """The ``sampling`` planner of the run's task: its candidates are the manager's classes."""
    return make_planner("sampling", config.task_config)


def soft_choice(planner: SamplingPlanner, scene: Scene, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """The planner's candidates (N, C) complex and its soft choice over them (N, C), rows summing to 1.

    The tiers are ``SamplingPlanner.plan``'s: the candidates clear of the growing safety distance; failing
    those, the ones clear of the fixed distance; failing those, all, scored by the distance they keep from
    the obstacles instead of by arrival time. Within the tier a softmax of minus the score / ``tau``.
    """
    cand = planner.candidates(scene)
    arrival, clearance, hard, near = planner.rollout(scene, cand)
    safe, close = clearance >= 0.0, hard >= 0.0
    score = np.where(np.isfinite(near), near, 1e3)  # no obstacle at all: every candidate keeps clear
    score = np.where(close.any(1, keepdims=True), np.where(close, -arrival, -np.inf), score)
    score = np.where(safe.any(1, keepdims=True), np.where(safe, -arrival, -np.inf), score)
    weight = np.exp((score - score.max(1, keepdims=True)) / tau)
    return cand, weight / weight.sum(1, keepdims=True)


def chooser(obs_dim: int, num_candidates: int, hidden: tuple[int, ...]) -> nn.Sequential:
    """The MLP: observations (B, obs_dim) -> one logit per candidate (B, C), ReLU between layers."""
    sizes = [obs_dim, *hidden]
    layers: list[nn.Module] = []
    for a, b in zip(sizes[:-1], sizes[1:], strict=True):
        layers += [nn.Linear(a, b), nn.ReLU()]
    return nn.Sequential(*layers, nn.Linear(sizes[-1], num_candidates))


def chooser_from_state(state: dict[str, torch.Tensor]) -> nn.Sequential:
    """The MLP rebuilt from its state dict, its sizes read from the weights."""
    weights = [state[key] for key in sorted((k for k in state if k.endswith(".weight")), key=_index)]
    hidden = tuple(w.shape[0] for w in weights[:-1])
    net = chooser(weights[0].shape[1], weights[-1].shape[0], hidden)
    net.load_state_dict(state)
    return net


def _index(key: str) -> int:
    return int(key.split(".")[0])


def candidate_policy(
    net: nn.Module, planner: SamplingPlanner, generator: torch.Generator | None = None
) -> Callable[[np.ndarray], np.ndarray]:
    """The network as a numpy manager: the candidate of highest logit (or, with ``generator``, one drawn
    from the logits' softmax), as the action that names it. A live view of ``net``'s weights."""

    def policy(obs: np.ndarray) -> np.ndarray:
        scene = planner.read(obs)
        cand = planner.candidates(scene)
        with torch.no_grad():
            logits = net(torch.as_tensor(obs, dtype=torch.float32))
        if logits.shape[1] != cand.shape[1]:
            raise ValueError(
                f"the network scores {logits.shape[1]} candidates, the planner builds {cand.shape[1]} "
                "for these observations (another obstacle count or planner)"
            )
        if generator is None:
            choice = logits.argmax(1).numpy()
        else:
            choice = torch.multinomial(logits.softmax(1), 1, generator=generator)[:, 0].numpy()
        chosen = cand[np.arange(len(cand)), choice]
        return planner.action(scene, planner.subgoals(scene, chosen)).astype(np.float32)

    return policy


def _round_seed(config: TrainConfig, round_: int) -> int:
    # Far from the selection and evaluation seeds (hier_ssl.train), so no round plays their episodes.
    return (config.seed + 1) * 100_000 + round_


def learn(
    config: TrainConfig,
    run_dir: Path,
    on_round: Callable[[Callable[[np.ndarray], np.ndarray], int, int, float, Callable[[], dict]], Any],
    saved: dict[str, Any] | None = None,
    progress: bool = True,
) -> tuple[nn.Sequential, float]:
    """Run the DAgger rounds of ``config.dagger``, continuing ``saved`` (a ``model.pt``) where given.

    After every round ``model.pt`` is rewritten (the network, its optimiser and every labelled state, for
    ``--resume``), then ``on_round(policy, round, states, train_time_s, state)`` scores the network (model
    selection; ``state()`` is what ``best_actor.pt`` keeps). Returns the final network and the training time
    in seconds (rollouts and fitting, without the selection's evaluations).
    """
    from hier_ssl.policies.sac_runner import MODEL_FILE, atomic_save

    settings = config.dagger
    planner = candidate_planner(config)
    torch.manual_seed(config.seed)
    obs_parts: list[np.ndarray] = []
    label_parts: list[np.ndarray] = []
    net: nn.Sequential | None = None
    optimizer: torch.optim.Optimizer | None = None
    first, train_time = 0, 0.0
    if saved is not None:
        net = chooser_from_state(saved["net"])
        optimizer = torch.optim.Adam(net.parameters(), lr=settings.learning_rate)
        optimizer.load_state_dict(saved["optimizer"])
        obs_parts, label_parts = [saved["obs"].numpy()], [saved["labels"].numpy()]
        first, train_time = saved["round"] + 1, saved["train_time_s"]
        torch.set_rng_state(saved["torch_rng"])

    def labelling(expert: bool) -> Callable[[np.ndarray], np.ndarray]:
        def policy(obs: np.ndarray) -> np.ndarray:
            scene = planner.read(obs)
            cand, soft = soft_choice(planner, scene, settings.tau)
            obs_parts.append(np.asarray(obs, dtype=np.float32))
            label_parts.append(soft.astype(np.float32))
            if expert:
                chosen = cand[np.arange(len(cand)), soft.argmax(1)]
                return planner.action(scene, planner.subgoals(scene, chosen))
            return student(obs)

        return policy

    writer = SummaryWriter(run_dir, purge_step=first)
    bar = tqdm(total=settings.rounds, initial=first, desc="dagger rounds", disable=not progress)
    student = None if net is None else candidate_policy(net, planner)
    try:
        for round_ in range(first, settings.rounds):
            began = time.perf_counter()
            seed = _round_seed(config, round_)
            played = evaluate(labelling(net is None), config.task_config, settings.episodes, seed)
            x = torch.as_tensor(np.concatenate(obs_parts))
            p = torch.as_tensor(np.concatenate(label_parts))
            obs_parts, label_parts = [x.numpy()], [p.numpy()]
            if net is None:
                net = chooser(x.shape[1], p.shape[1], settings.hidden)
                optimizer = torch.optim.Adam(net.parameters(), lr=settings.learning_rate)
                student = candidate_policy(net, planner)
            assert optimizer is not None
            losses = []
            for _ in range(settings.epochs):
                for rows in torch.randperm(len(x)).split(settings.batch_size):
                    loss = -(p[rows] * torch.log_softmax(net(x[rows]), 1)).sum(1).mean()
                    optimizer.zero_grad()
                    loss.backward()
                    optimizer.step()
                    losses.append(loss.item())
            with torch.no_grad():
                agreement = float((net(x).argmax(1) == p.argmax(1)).float().mean())
            train_time += time.perf_counter() - began
            writer.add_scalar("losses/cross_entropy", float(np.mean(losses)), round_)
            writer.add_scalar("dagger/first_choice_agreement", agreement, round_)
            writer.add_scalar("dagger/states", len(x), round_)
            writer.add_scalar("episode/round_success_rate", played["success_rate"], round_)
            writer.add_scalar("episode/round_collision_rate", played["collision_rate"], round_)
            # Saved before the round is scored: a run killed while scoring resumes at the next round, and
            # the curve never holds a round twice.
            atomic_save(
                {
                    "net": net.state_dict(),
                    "optimizer": optimizer.state_dict(),
                    "obs": x,
                    "labels": p,
                    "round": round_,
                    "train_time_s": train_time,
                    "torch_rng": torch.get_rng_state(),
                },
                run_dir / MODEL_FILE,
            )
            snapshot = {"net": net.state_dict(), "round": round_}
            on_round(student, round_ + 1, len(x), train_time, lambda kept=snapshot: kept)
            bar.update(1)
            bar.set_postfix(
                states=len(x), agreement=f"{agreement:.2f}", played=f"{played['success_rate']:.2f}"
            )
    finally:
        bar.close()
        writer.close()
    assert net is not None
    return net, train_time


__all__ = ["candidate_planner", "candidate_policy", "chooser", "chooser_from_state", "learn", "soft_choice"]
