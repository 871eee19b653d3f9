"""Learning: networks, replay, SAC + CAPS and the off-policy runner."""

from hier_ssl.policies.networks import SquashedGaussianActor, TwinQ, mlp
from hier_ssl.policies.replay import Batch, ReplayBuffer
from hier_ssl.policies.sac import SAC, SACConfig, caps_loss

__all__ = [
    "SAC",
    "Batch",
    "ReplayBuffer",
    "SACConfig",
    "SquashedGaussianActor",
    "TwinQ",
    "caps_loss",
    "mlp",
]
