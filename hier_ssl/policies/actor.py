"""A trained run's policy read from its run directory as a numpy policy that samples or not
(``load_policy``): SAC, PPO or the candidates' chooser (its torch graph: ``load_candidate_manager``). The
deterministic torch module alone is ``hier_ssl.checkpoints.actor.load_actor``.

The paper's test script evaluates *sampled* actions (docs/paper.md): ``load_policy(run_dir,
sample=True, seed=...)`` draws them from the whole SAC actor (``SquashedGaussianActor``, log-std head
included) or from PPO's Gaussian with its saved standard deviation, with a seeded generator of its own.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch
from torch import nn

from hier_ssl.checkpoints.actor import (
    checkpoint_path,
    freeze,
    linear_layers,
    load_actor,
    mean_actor,
    ppo_actor_state,
    reading,
    run_config,
    sac_actor_state,
)
from hier_ssl.checkpoints.tensors import load_checkpoint
from hier_ssl.config import ConfigError
from hier_ssl.policies.candidate_graph import CandidateManager, candidate_policy
from hier_ssl.policies.candidate_nets import chooser_from_state
from hier_ssl.policies.candidates import candidate_manager
from hier_ssl.policies.networks import NumpyPolicy, SquashedGaussianActor, sac_policy


def _sampling_sac_policy(state: dict[str, torch.Tensor], generator: torch.Generator) -> NumpyPolicy:
    """The full SAC actor rebuilt from its state dict (sizes read from the weights), sampling."""
    layers = linear_layers(state, "net.")
    hidden = tuple(weight.shape[0] for weight, _ in layers[:-1])
    actor = SquashedGaussianActor(layers[0][0].shape[1], layers[-1][0].shape[0] // 2, hidden)
    actor.load_state_dict(state)
    return sac_policy(freeze(actor), generator)


def _sampling_ppo_policy(state: dict[str, torch.Tensor], generator: torch.Generator) -> NumpyPolicy:
    """rsl-rl's Gaussian: mean + std * N(0, 1) with the saved state-independent std (scalar or log form,
    clamped at rsl-rl's floor 1e-6), clipped to [-1, 1] as the env clips the actions it is given."""
    act_dim = linear_layers(state, "mlp.")[-1][0].shape[0]
    mean = freeze(mean_actor(state, "mlp.", nn.ELU, act_dim, nn.Identity()))
    if "distribution.std_param" in state:
        std = state["distribution.std_param"].clamp(min=1e-6)
    elif "distribution.log_std_param" in state:
        std = state["distribution.log_std_param"].exp().clamp(min=1e-6)
    else:
        raise ValueError("no state-independent std (distribution.std_param or distribution.log_std_param)")

    def policy(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            mu = mean(torch.as_tensor(obs, dtype=torch.float32))
            noise = torch.randn(mu.shape, generator=generator)
            return (mu + std * noise).clamp(-1.0, 1.0).numpy()

    return policy


def load_candidate_manager(run_dir: str | Path, which: str = "best") -> CandidateManager:
    """An ``algo: candidates`` run's classifier or scorer over the planner's candidates, frozen: the whole
    decision, observation (B, O) float32 in, action (B, A) float32 out
    (``hier_ssl.policies.candidate_graph``).
    ``best_actor.pt`` and ``model.pt`` both hold its weights under "net"."""
    config = run_config(run_dir)
    if config.algo != "candidates":
        raise ConfigError(f"{run_dir}: an algo {config.algo!r} run; expected algo 'candidates'")
    path = checkpoint_path(run_dir, config, which)
    with reading(path, config.algo):
        net = chooser_from_state(load_checkpoint(path, "cpu")["net"])
    return freeze(candidate_manager(config, net))


def load_policy(run_dir: str | Path, sample: bool = False, seed: int = 0, which: str = "best") -> NumpyPolicy:
    """The run's policy (its ``which`` checkpoint, "best" or "final") as a numpy function, on the CPU.

    ``sample=False``: the deterministic actor of ``load_actor`` (candidates: the one of highest logit).
    ``sample=True``: actions drawn from the policy's distribution (SAC: tanh of a Gaussian sample; PPO: the
    Gaussian, clipped to [-1, 1]; candidates: one drawn from the logits' softmax) with a
    generator seeded by ``seed``, so the same seed and the same calls give the same actions. Input
    (N, obs_dim), output (N, act_dim) float32 in [-1, 1]. ``ConfigError`` names an unusable run or file.
    """
    config = run_config(run_dir)
    if config.algo == "candidates":
        generator = torch.Generator().manual_seed(seed) if sample else None
        return candidate_policy(load_candidate_manager(run_dir, which), generator)
    if not sample:
        actor, _ = load_actor(run_dir, which)

        def policy(obs: np.ndarray) -> np.ndarray:
            with torch.no_grad():
                return actor(torch.as_tensor(obs, dtype=torch.float32)).numpy()

        return policy
    path = checkpoint_path(run_dir, config, which)
    generator = torch.Generator().manual_seed(seed)
    with reading(path, config.algo):
        saved = load_checkpoint(path, "cpu")
        if config.algo == "sac":
            return _sampling_sac_policy(sac_actor_state(saved, path), generator)
        return _sampling_ppo_policy(ppo_actor_state(saved), generator)


__all__ = ["load_candidate_manager", "load_policy"]
