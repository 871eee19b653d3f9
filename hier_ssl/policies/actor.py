"""A trained run's policy read from its run directory: deterministic as a plain, frozen torch module
(``load_actor``), or as a numpy policy that samples or not (``load_policy``).

Both learners' actors are an MLP whose mean action is squashed into [-1, 1]: SAC's
``SquashedGaussianActor`` (ReLU, output mean and log-std, action tanh(mean)) and rsl-rl's ``MLPModel``
(ELU, output the Gaussian mean, clipped to [-1, 1] by ``ppo_policy``). ``load_actor`` rebuilds either as
``nn.Sequential(Linear, act, ..., Linear, Tanh | Hardtanh)`` with only the mean's rows in the last layer:
no rsl-rl, tensordict or distribution objects, so the module scripts and exports as it is. The layer
sizes are read from the weights, so a checkpoint cannot disagree with the config about them.

Checkpoints are read with ``torch.load(weights_only=True)``. Every loader takes ``which``: "best" (the
default) is the policy model selection kept, ``best_actor.pt`` (PPO runs from before model selection: their
highest-numbered ``model_*.pt``); "final" is the policy training ended with, SAC's ``model.pt`` or PPO's
highest-numbered ``model_*.pt``. The paper reports its final models.

The paper's test script evaluates *sampled* actions (SPEC "Public-code details"): ``load_policy(run_dir,
sample=True, seed=...)`` draws them from the whole SAC actor (``SquashedGaussianActor``, log-std head
included) or from PPO's Gaussian with its saved standard deviation, with a seeded generator of its own.
"""

from __future__ import annotations

import pickle
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch
from torch import nn

from hier_ssl.config import ConfigError, TrainConfig, validate_config
from hier_ssl.config_files import load_yaml
from hier_ssl.policies.networks import SquashedGaussianActor

NumpyPolicy = Callable[[np.ndarray], np.ndarray]
"""Manager observations (N, obs_dim) -> actions (N, act_dim) in [-1, 1], float32."""

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
        if not path.is_file():
            raise ConfigError(f"{run_dir}: no {which} checkpoint ({path.name} missing)")
        return path
    if which == "best" and best.is_file():  # the best PPO policy on the selection episodes
        return best
    saved = [(int(m.group(1)), p) for p in run_dir.glob("model_*.pt") if (m := _PPO_FILE.fullmatch(p.name))]
    if not saved:
        raise ConfigError(f"{run_dir}: no usable checkpoint (no PPO model_<iteration>.pt)")
    return max(saved)[1]


def _sac_actor_state(saved: dict, path: Path) -> dict[str, torch.Tensor]:
    """The actor weights: ``best_actor.pt`` holds {"actor": ...}, ``model.pt`` {"sac": {"actor": ...}}."""
    return saved["sac"]["actor"] if path.name == FINAL_SAC_FILE else saved["actor"]


@contextmanager
def _reading(path: Path, algo: str) -> Iterator[None]:
    """Turns what a malformed checkpoint raises into a ``ConfigError`` naming the file."""
    try:
        yield
    except (KeyError, IndexError, RuntimeError, ValueError, EOFError, pickle.UnpicklingError) as err:
        raise ConfigError(f"{path}: not a usable {algo} checkpoint ({type(err).__name__}: {err})") from None


def _ppo_actor_state(saved: dict) -> dict[str, torch.Tensor]:
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
            f"{run_dir}: algo 'candidates' chooses among the sampling planner's candidates, which hier_ssl "
            "builds in numpy at every decision; it has no stand-alone actor to load or export "
            "(load_policy plays it)"
        )
    path = checkpoint_path(run_dir, config, which)
    with _reading(path, config.algo):
        saved = torch.load(path, map_location="cpu", weights_only=True)
        if config.algo == "sac":
            state = _sac_actor_state(saved, path)
            act_dim = linear_layers(state, "net.")[-1][0].shape[0] // 2
            actor = mean_actor(state, "net.", nn.ReLU, act_dim, nn.Tanh())
        else:
            state = _ppo_actor_state(saved)
            act_dim = linear_layers(state, "mlp.")[-1][0].shape[0]
            actor = mean_actor(state, "mlp.", nn.ELU, act_dim, nn.Hardtanh(-1.0, 1.0))
    return freeze(actor), config


def sac_policy(actor: SquashedGaussianActor, generator: torch.Generator | None = None) -> NumpyPolicy:
    """A SAC actor as a numpy policy: tanh(mean), or with ``generator`` a sample of its squashed Gaussian
    drawn from that generator (which must live on the actor's device).

    A live view: it acts with the actor's current weights, on the device they are on.
    """
    device = next(actor.parameters()).device

    def policy(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            x = torch.as_tensor(obs, dtype=torch.float32, device=device)
            action = actor.deterministic(x) if generator is None else actor(x, generator)[0]
            return action.cpu().numpy()

    return policy


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


def _candidate_policy(
    run_dir: str | Path, config: TrainConfig, which: str, generator: torch.Generator | None
) -> NumpyPolicy:
    """An ``algo: candidates`` run's classifier or scorer over the planner's candidates
    (``hier_ssl.policies.candidates``): ``best_actor.pt`` and ``model.pt`` both hold its weights under
    "net"."""
    from hier_ssl.policies.candidate_nets import chooser_from_state
    from hier_ssl.policies.candidates import candidate_planner, candidate_policy

    path = checkpoint_path(run_dir, config, which)
    with _reading(path, config.algo):
        net = chooser_from_state(torch.load(path, map_location="cpu", weights_only=True)["net"])
    return candidate_policy(freeze(net), candidate_planner(config), generator)


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
        return _candidate_policy(run_dir, config, which, generator)
    if not sample:
        actor, _ = load_actor(run_dir, which)

        def policy(obs: np.ndarray) -> np.ndarray:
            with torch.no_grad():
                return actor(torch.as_tensor(obs, dtype=torch.float32)).numpy()

        return policy
    path = checkpoint_path(run_dir, config, which)
    generator = torch.Generator().manual_seed(seed)
    with _reading(path, config.algo):
        saved = torch.load(path, map_location="cpu", weights_only=True)
        if config.algo == "sac":
            return _sampling_sac_policy(_sac_actor_state(saved, path), generator)
        return _sampling_ppo_policy(_ppo_actor_state(saved), generator)


__all__ = [
    "CHECKPOINTS",
    "NumpyPolicy",
    "checkpoint_path",
    "freeze",
    "load_actor",
    "load_policy",
    "mean_actor",
    "run_config",
    "sac_policy",
]
