"""Networks for SAC: a tanh-squashed Gaussian actor and twin Q critics batched in one module; a SAC actor
as a numpy policy (``sac_policy``)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

LOG_STD_MIN = -5.0
LOG_STD_MAX = 2.0
_HALF_LOG_2PI = 0.5 * math.log(2.0 * math.pi)
_LOG_2 = math.log(2.0)

NumpyPolicy = Callable[[np.ndarray], np.ndarray]
"""Manager observations (N, obs_dim) -> actions (N, act_dim) in [-1, 1], float32."""


def mlp(
    in_dim: int, hidden: Sequence[int], out_dim: int, activation: type[nn.Module] = nn.ReLU
) -> nn.Sequential:
    """Fully connected network ``in_dim -> hidden... -> out_dim`` with ``activation`` between layers.

    The output layer is linear (no activation).
    """
    dims = [in_dim, *hidden]
    layers: list[nn.Module] = []
    for fan_in, fan_out in zip(dims[:-1], dims[1:], strict=True):
        layers += [nn.Linear(fan_in, fan_out), activation()]
    layers.append(nn.Linear(dims[-1], out_dim))
    return nn.Sequential(*layers)


class SquashedGaussianActor(nn.Module):
    """Gaussian policy squashed by tanh into [-1, 1]^act_dim.

    One MLP outputs the mean and the log standard deviation of the pre-tanh Gaussian. The log-std is
    mapped smoothly into [LOG_STD_MIN, LOG_STD_MAX] (as in CleanRL) rather than hard-clamped, so its
    gradient never vanishes at the bounds.
    """

    def __init__(self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (256, 256)) -> None:
        super().__init__()
        self.net = mlp(obs_dim, hidden, 2 * act_dim)

    def mean_log_std(self, obs: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Pre-tanh mean and log-std. Shapes: obs (B, obs_dim) -> both (B, act_dim)."""
        mean, log_std = self.net(obs).chunk(2, dim=-1)
        log_std = LOG_STD_MIN + 0.5 * (LOG_STD_MAX - LOG_STD_MIN) * (torch.tanh(log_std) + 1.0)
        return mean, log_std

    def forward(
        self, obs: torch.Tensor, generator: torch.Generator | None = None
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Reparameterised sample and its log-probability.

        Shapes: obs (B, obs_dim) -> action (B, act_dim) in [-1, 1], log_prob (B,).
        """
        mean, log_std = self.mean_log_std(obs)
        noise = torch.randn(mean.shape, generator=generator, device=mean.device, dtype=mean.dtype)
        pre_tanh = mean + log_std.exp() * noise
        action = torch.tanh(pre_tanh)
        # (pre_tanh - mean) / std is exactly `noise`, so the Gaussian density needs no division.
        # log(1 - tanh(u)^2) = 2 (log 2 - u - softplus(-2u)) stays finite where tanh(u) rounds to +-1,
        # unlike log(1 - action^2 + eps).
        log_prob = -0.5 * noise.pow(2) - log_std - _HALF_LOG_2PI
        log_prob = log_prob - 2.0 * (_LOG_2 - pre_tanh - F.softplus(-2.0 * pre_tanh))
        return action, log_prob.sum(dim=-1)

    def deterministic(self, obs: torch.Tensor) -> torch.Tensor:
        """Mean action tanh(mean). Shape: obs (B, obs_dim) -> (B, act_dim) in [-1, 1]."""
        mean, _ = self.mean_log_std(obs)
        return torch.tanh(mean)


class TwinQ(nn.Module):
    """``num_critics`` independent Q networks evaluated by one batched forward.

    Layer ``i`` holds the weights of every critic in one tensor of shape (num_critics, fan_in, fan_out),
    applied with ``torch.baddbmm``: one kernel per layer instead of one per layer and critic, which is
    what makes the critic update cheap on a CPU where per-op overhead dominates.
    """

    def __init__(
        self, obs_dim: int, act_dim: int, hidden: Sequence[int] = (256, 256), num_critics: int = 2
    ) -> None:
        super().__init__()
        dims = [obs_dim + act_dim, *hidden, 1]
        self.weights = nn.ParameterList(
            nn.Parameter(torch.empty(num_critics, fan_in, fan_out))
            for fan_in, fan_out in zip(dims[:-1], dims[1:], strict=True)
        )
        self.biases = nn.ParameterList(
            nn.Parameter(torch.empty(num_critics, 1, fan_out)) for fan_out in dims[1:]
        )
        self.reset_parameters()

    def reset_parameters(self) -> None:
        """Same distribution as ``nn.Linear``'s default: U(-1/sqrt(fan_in), 1/sqrt(fan_in))."""
        for weight, bias in zip(self.weights, self.biases, strict=True):
            bound = 1.0 / math.sqrt(weight.shape[1])
            nn.init.uniform_(weight, -bound, bound)
            nn.init.uniform_(bias, -bound, bound)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        """Q values of every critic. Shapes: obs (B, obs_dim), action (B, act_dim) -> (num_critics, B)."""
        x = torch.cat([obs, action], dim=-1).expand(self.weights[0].shape[0], -1, -1)
        last = len(self.weights) - 1
        for i, (weight, bias) in enumerate(zip(self.weights, self.biases, strict=True)):
            x = torch.baddbmm(bias, x, weight)
            if i < last:
                x = torch.relu(x)
        return x.squeeze(-1)


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
