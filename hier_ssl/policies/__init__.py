"""Learning: networks, replay, SAC + CAPS and the off-policy runner, and the protocol every learner behind
``hier-ssl train`` follows (``learner``)."""

from hier_ssl.policies.learner import Checkpoint, Learner, OnCheckpoint
from hier_ssl.policies.networks import SquashedGaussianActor, TwinQ, mlp
from hier_ssl.policies.replay import Batch, ReplayBuffer
from hier_ssl.policies.sac import SAC, SACConfig, caps_loss
from hier_ssl.policies.sac_runner import SACRunner

__all__ = [
    "SAC",
    "Batch",
    "Checkpoint",
    "Learner",
    "OnCheckpoint",
    "ReplayBuffer",
    "SACConfig",
    "SACRunner",
    "SquashedGaussianActor",
    "TwinQ",
    "caps_loss",
    "mlp",
]
