"""Learning: networks, replay, SAC + CAPS and the off-policy runner."""

from hier_ssl.policies.networks import SquashedGaussianActor, TwinQ, mlp
from hier_ssl.policies.replay import Batch, ReplayBuffer
from hier_ssl.policies.sac import SAC, SACConfig, caps_loss
from hier_ssl.policies.sac_runner import SACRunner

__all__ = [
    "SAC",
    "Batch",
    "ReplayBuffer",
    "SACConfig",
    "SACRunner",
    "SquashedGaussianActor",
    "TwinQ",
    "caps_loss",
    "mlp",
]
