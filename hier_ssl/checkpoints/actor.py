"""A trained run's deterministic actor read from its run directory, as a plain, frozen torch module
(``load_actor``), with the files a run directory holds and the helpers that read them.

Both learners' actors are an MLP whose mean action is squashed into [-1, 1]: SAC's
``SquashedGaussianActor`` (ReLU, output mean and log-std, action tanh(mean)) and rsl-rl's ``MLPModel``
(ELU, output the Gaussian mean, clipped to [-1, 1]). ``load_actor`` rebuilds either as
``nn.Sequential(Linear, act, ..., Linear, Tanh | Hardtanh)`` with only the mean's rows in the last layer:
no rsl-rl, tensordict or distribution objects, so the module scripts and exports as it is. The layer
sizes are read from the weights, so a checkpoint cannot disagree with the config about them.

Checkpoints are read with ``torch.load(weights_only=True)``. Every loader takes ``which``: "best" (the
default) is the policy model selection kept, ``best_actor.pt`` (PPO runs from before model selection: their
highest-numbered ``model_*.pt``); "final" is the policy training ended with, SAC's ``model.pt`` or PPO's
highest-numbered ``model_*.pt``. The paper reports its final models.

Below both the workers and the learners: a learned worker (``hier_ssl.worker.learned``) and the learners'
policies (``hier_ssl.policies.actor``) read their networks here.
"""

from __future__ import annotations

import pickle
import re
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import torch
from torch import nn

from hier_ssl.checkpoints.tensors import load_checkpoint
from hier_ssl.config import ConfigError, TrainConfig, validate_config
from hier_ssl.config.files import load_yaml

CONFIG_FILE, BEST_ACTOR_FILE, FINAL_SAC_FILE = "config.yaml", "best_actor.pt", "model.pt"
CHECKPOINTS = ("best", "final")
_PPO_FILE = re.compile(r"model_(\d+)\.pt")


def freeze(module: nn.Module) -> nn.Module:
    """``module`` in eval mode with every parameter's ``requires_grad`` off; returned for chaining."""
    module.eval()
    for parameter in module.parameters():
        parameter.requires_grad_(False)
    return module


def linear_layers(
    state_dict: dict[str, torch.Tensor], prefix: str
) -> list[tuple[torch.Tensor, torch.Tensor]]:
    """(weight, bias) of every ``{prefix}{i}.weight`` in index order."""
    found = {}
    for key in state_dict:
        match = re.fullmatch(re.escape(prefix) + r"(\d+)\.weight", key)
        if match:
            i = int(match.group(1))
            found[i] = (state_dict[key], state_dict[f"{prefix}{i}.bias"])
    return [found[i] for i in sorted(found)]


def mean_actor(
    state_dict: dict[str, torch.Tensor],
    prefix: str,
    activation: type[nn.Module],
    out_dim: int,
    squash: nn.Module,
) -> nn.Sequential:
    """An MLP from ``state_dict``'s ``{prefix}{i}`` linear layers, the last cut to its first ``out_dim``
    rows, then ``squash``. Shape: (B, obs_dim) -> (B, out_dim)."""
    layers = linear_layers(state_dict, prefix)
    if not layers:
        raise ValueError(f"no '{prefix}<i>.weight' layers in the state dict")
    modules: list[nn.Module] = []
    for i, (weight, bias) in enumerate(layers):
        last = i == len(layers) - 1
        weight, bias = (weight[:out_dim], bias[:out_dim]) if last else (weight, bias)
        linear = nn.Linear(weight.shape[1], weight.shape[0])
        with torch.no_grad():
            linear.weight.copy_(weight)
            linear.bias.copy_(bias)
        modules += [linear] if last else [linear, activation()]
    return nn.Sequential(*modules, squash)


def run_config(run_dir: str | Path) -> TrainConfig:
    """The config a run was trained with (written fully resolved, so the models alone read it back); a
    ValueError names the run directory if it is not one."""
    run_dir = Path(run_dir)
    if not (run_dir / CONFIG_FILE).is_file():
        raise ConfigError(f"{run_dir}: not a run directory (no {CONFIG_FILE})")
    return validate_config(load_yaml(run_dir / CONFIG_FILE))


def checkpoint_path(run_dir: str | Path, config: TrainConfig, which: str = "best") -> Path:
    """The file the loaders read for the ``which`` ("best" or "final") policy of the run (module
    docstring); a ``ConfigError`` names what is missing."""
    run_dir = Path(run_dir)
    if which not in CHECKPOINTS:
        raise ConfigError(f"checkpoint {which!r}: expected one of {list(CHECKPOINTS)}")
    best = run_dir / BEST_ACTOR_FILE
    if config.algo in ("sac", "candidates"):
        path = best if which == "best" else run_dir / FINAL_SAC_FILE
        if which == "best" and not path.is_file() and (run_dir / FINAL_SAC_FILE).is_file():
            # Killed before its first selection: the final policy is the only one there is (as for PPO).
            message = f"{run_dir}: no {BEST_ACTOR_FILE} yet; using the final policy, {FINAL_SAC_FILE}"
            warnings.warn(message, stacklevel=2)
            path = run_dir / FINAL_SAC_FILE
        if not path.is_file():
            raise ConfigError(f"{run_dir}: no {which} checkpoint ({path.name} missing)")
        return path
    if which == "best" and best.is_file():  # the best PPO policy on the selection episodes
        return best
    saved = [(int(m.group(1)), p) for p in run_dir.glob("model_*.pt") if (m := _PPO_FILE.fullmatch(p.name))]
    if not saved:
        raise ConfigError(f"{run_dir}: no usable checkpoint (no PPO model_<iteration>.pt)")
    return max(saved)[1]


def sac_actor_state(saved: dict, path: Path) -> dict[str, torch.Tensor]:
    """The actor weights: ``best_actor.pt`` holds {"actor": ...}, ``model.pt`` {"sac": {"actor": ...}}."""
    return saved["sac"]["actor"] if path.name == FINAL_SAC_FILE else saved["actor"]


@contextmanager
def reading(path: Path, algo: str) -> Iterator[None]:
    """Turns what a malformed checkpoint raises into a ``ConfigError`` naming the file (a ConfigError, such
    as an unsafe file's, already names it)."""
    try:
        yield
    except ConfigError:
        raise
    except (KeyError, IndexError, RuntimeError, ValueError, EOFError, pickle.UnpicklingError) as err:
        raise ConfigError(f"{path}: not a usable {algo} checkpoint ({type(err).__name__}: {err})") from None


def ppo_actor_state(saved: dict) -> dict[str, torch.Tensor]:
    state = saved["actor_state_dict"]
    if any(key.startswith("obs_normalizer.") for key in state):
        raise ValueError("actors with empirical observation normalisation are not supported")
    return state


def load_actor(run_dir: str | Path, which: str = "best") -> tuple[nn.Sequential, TrainConfig]:
    """The run's deterministic actor (its ``which`` checkpoint), frozen (eval mode, no gradients), and its
    config.

    Shape of the actor: (B, obs_dim) float32 -> (B, act_dim) in [-1, 1]. ValueErrors (``ConfigError``)
    name the run directory or the checkpoint file when either is unusable.
    """
    config = run_config(run_dir)
    if config.algo == "candidates":
        raise ConfigError(
            f"{run_dir}: algo 'candidates' chooses among the sampling planner's candidates; it has no "
            "stand-alone actor (hier_ssl.policies.actor.load_candidate_manager loads its whole decision, "
            "load_policy plays it, hier-ssl export exports it)"
        )
    path = checkpoint_path(run_dir, config, which)
    with reading(path, config.algo):
        saved = load_checkpoint(path, "cpu")
        if config.algo == "sac":
            state = sac_actor_state(saved, path)
            act_dim = linear_layers(state, "net.")[-1][0].shape[0] // 2
            actor = mean_actor(state, "net.", nn.ReLU, act_dim, nn.Tanh())
        else:
            state = ppo_actor_state(saved)
            act_dim = linear_layers(state, "mlp.")[-1][0].shape[0]
            actor = mean_actor(state, "mlp.", nn.ELU, act_dim, nn.Hardtanh(-1.0, 1.0))
    return freeze(actor), config


__all__ = [
    "BEST_ACTOR_FILE",
    "CHECKPOINTS",
    "CONFIG_FILE",
    "FINAL_SAC_FILE",
    "checkpoint_path",
    "freeze",
    "linear_layers",
    "load_actor",
    "mean_actor",
    "ppo_actor_state",
    "reading",
    "run_config",
    "sac_actor_state",
]
