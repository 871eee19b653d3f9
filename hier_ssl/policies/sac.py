"""Soft Actor-Critic with optional CAPS smoothness regularisation.

Follows CleanRL's ``sac_continuous_action.py`` (whose defaults the paper's public code uses) with two
changes for speed: both critics live in one batched module (``TwinQ``), and the Polyak update and Adam
run on foreach kernels. CAPS (Mysore et al. 2021) adds a temporal and a spatial smoothness term to the
actor loss; with a teacher (``hier_ssl.policies.teacher``) an imitation term of a planner's actions joins.

Where this SAC and the paper's public code differ (docs/paper.md, its settings), a key of ``SACConfig``
chooses; the default is ours, the public code's value is given in brackets:

- ``caps_actions``: "mean" takes CAPS on the deterministic actions tanh(mean) at s, s' and an unclamped
  s_bar ["sampled": on sampled actions, the critic target's next action a'(s') without gradient, and
  s_bar clamped to [-1.2, 1.2]].
- ``actor_schedule``: "catch_up" runs ``policy_frequency`` actor steps on every ``policy_frequency``-th
  critic update, as many actor steps as critic steps ["delayed": one actor step there, TD3's schedule].
- ``learning_starts`` counts transitions [80,000: 5,000 vector steps x 16 envs]; ``alpha`` with a learned
  alpha is its start value [1.0 without CAPS]; ``reward_scale`` [1].

Rule: with ``caps=True`` the entropy coefficient alpha is fixed at ``SACConfig.alpha`` and not learned,
as in the paper (section 5: a learned alpha works against the smoothness loss).
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable

import torch

from hier_ssl.config.learners import SACConfig
from hier_ssl.policies.networks import SquashedGaussianActor, TwinQ
from hier_ssl.policies.replay import Batch, ReplayBuffer
from hier_ssl.policies.teacher import imitation_loss, teacher_weight

# The public code clamps the perturbed state s_bar of sampled CAPS to this box; observations are scaled to
# about [-1, 1] (docs/paper.md "Observations").
SAMPLED_CAPS_OBS_BOUND = 1.2


def perturbed_obs(
    obs: torch.Tensor, sigma: float, generator: torch.Generator | None = None, bound: float | None = None
) -> torch.Tensor:
    """CAPS's perturbed state s_bar ~ N(s, sigma^2 I), clamped to [-bound, bound] when ``bound`` is given.

    Shape: obs (B, obs_dim) -> (B, obs_dim).
    """
    obs_bar = obs + sigma * torch.randn(obs.shape, generator=generator, device=obs.device, dtype=obs.dtype)
    return obs_bar if bound is None else obs_bar.clamp(-bound, bound)


def caps_terms(
    action: torch.Tensor,
    next_action: torch.Tensor,
    perturbed_action: torch.Tensor,
    lambda_t: float,
    lambda_s: float,
) -> tuple[torch.Tensor, torch.Tensor]:
    """CAPS's temporal and spatial terms, weighted: lambda_t * mean_b ||a(s'_b) - a(s_b)||_2 and
    lambda_s * mean_b ||a(s_bar_b) - a(s_b)||_2 (unsquared norms, as the public code).

    Shapes: the three actions (B, act_dim); returns two scalars.
    """
    temporal = lambda_t * torch.linalg.vector_norm(next_action - action, dim=-1).mean()
    spatial = lambda_s * torch.linalg.vector_norm(perturbed_action - action, dim=-1).mean()
    return temporal, spatial


def caps_loss(
    actor_mean_fn: Callable[[torch.Tensor], torch.Tensor],
    obs: torch.Tensor,
    next_obs: torch.Tensor,
    lambda_t: float,
    lambda_s: float,
    sigma: float,
    generator: torch.Generator | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """CAPS on the deterministic actions mu: ``caps_terms`` of mu(s), mu(s'), mu(s_bar), s_bar ~ N(s, sigma).

    Shapes: obs, next_obs (B, obs_dim); ``actor_mean_fn`` maps (N, obs_dim) -> (N, act_dim). Returns two
    scalars. The three policy evaluations share one call of ``actor_mean_fn`` on 3B rows.
    """
    obs_bar = perturbed_obs(obs, sigma, generator)
    mu, mu_next, mu_bar = actor_mean_fn(torch.cat([obs, next_obs, obs_bar])).chunk(3)
    return caps_terms(mu, mu_next, mu_bar, lambda_t, lambda_s)


class SAC:
    """SAC agent: networks, optimisers and the replay buffer it learns from.

    ``act`` picks actions, ``process_env_step`` stores transitions, ``update`` runs one gradient update.
    All randomness (exploration noise, replay sampling, CAPS noise) comes from ``self.generator``, which
    is checkpointed, so a resumed run continues the same random stream.
    """

    def __init__(
        self,
        num_obs: int,
        num_actions: int,
        config: SACConfig | None = None,
        device: torch.device | str = "cpu",
        seed: int = 0,
    ) -> None:
        self.config = cfg = (config or SACConfig()).model_copy(deep=True)
        self.device = torch.device(device)
        self.generator = torch.Generator(device=self.device)
        self.generator.manual_seed(seed)
        # Initialise weights from `seed` without disturbing the caller's global RNG.
        with torch.random.fork_rng(devices=[]):
            torch.manual_seed(seed)
            self.actor = SquashedGaussianActor(num_obs, num_actions, cfg.hidden).to(self.device)
            self.qf = TwinQ(num_obs, num_actions, cfg.hidden).to(self.device)
        self.qf_target = copy.deepcopy(self.qf).requires_grad_(False)
        self._actor_params = list(self.actor.parameters())
        self._qf_params = list(self.qf.parameters())
        self._qf_target_params = list(self.qf_target.parameters())
        self.actor_optimizer = torch.optim.Adam(self._actor_params, lr=cfg.actor_lr, fused=True)
        self.q_optimizer = torch.optim.Adam(self._qf_params, lr=cfg.critic_lr, fused=True)

        self.target_entropy = cfg.target_entropy if cfg.target_entropy is not None else -float(num_actions)
        self.log_alpha = torch.full(
            (), math.log(cfg.alpha), device=self.device, requires_grad=cfg.learns_alpha
        )
        self.alpha_optimizer = (
            torch.optim.Adam([self.log_alpha], lr=cfg.alpha_lr, fused=True) if cfg.learns_alpha else None
        )

        teacher = cfg.teacher is not None
        self.replay = ReplayBuffer(cfg.buffer_size, num_obs, num_actions, self.device, teacher=teacher)
        self.num_updates = 0

    @torch.no_grad()
    def act(self, obs: torch.Tensor, deterministic: bool = False) -> torch.Tensor:
        """Actions for a batch of observations. Shapes: obs (N, num_obs) -> (N, num_actions) in [-1, 1]."""
        if deterministic:
            return self.actor.deterministic(obs)
        return self.actor(obs, self.generator)[0]

    def process_env_step(
        self,
        obs: torch.Tensor,
        actions: torch.Tensor,
        rewards: torch.Tensor,
        next_obs: torch.Tensor,
        terminated: torch.Tensor,
        teacher_actions: torch.Tensor | None = None,
    ) -> None:
        """Store one vector step. Shapes: obs, next_obs (N, num_obs); actions (N, num_actions); rewards,
        terminated (N,); teacher_actions (N, num_actions), the teacher's labels for obs, required with a
        teacher. ``next_obs`` must be the true last observation of finished episodes."""
        self.replay.add(obs, actions, rewards, next_obs, terminated, teacher_actions)

    def update(self) -> dict[str, float]:
        """One critic update, the actor (and alpha) updates when due, and the Polyak step.

        Returns qf_loss, qf_values (mean Q of the batch) and alpha; on updates that step the actor also
        actor_loss, alpha_loss (when alpha is learned), caps_temporal, caps_spatial (with CAPS) and
        imitation, imitated (the share of rows imitated) while the teacher's weight is above 0, each from
        the last actor step of the update.
        """
        cfg = self.config
        data = self.replay.sample(cfg.batch_size, self.generator)
        alpha = self.log_alpha.detach().exp()
        logged, next_state_actions = self._critic_step(data, alpha)

        # Actor: delayed like TD3; catch_up then takes policy_frequency steps to keep the count (CleanRL).
        if self.num_updates % cfg.policy_frequency == 0:
            for _ in range(cfg.policy_frequency if cfg.actor_schedule == "catch_up" else 1):
                actor_loss, log_pi, terms = self.actor_loss(data, next_state_actions, alpha)
                self.actor_optimizer.zero_grad(set_to_none=True)
                # `inputs` restricts backward to the actor: the critic's weight gradients are never computed.
                actor_loss.backward(inputs=self._actor_params)
                self.actor_optimizer.step()
                logged |= {"actor_loss": actor_loss.detach(), **{k: v.detach() for k, v in terms.items()}}

                if self.alpha_optimizer is not None:
                    alpha_loss = (-self.log_alpha.exp() * (log_pi.detach() + self.target_entropy)).mean()
                    self.alpha_optimizer.zero_grad(set_to_none=True)
                    alpha_loss.backward()
                    self.alpha_optimizer.step()
                    alpha = self.log_alpha.detach().exp()
                    logged["alpha_loss"] = alpha_loss.detach()

        # Target critics: Polyak averaging, one foreach kernel over all parameters.
        torch._foreach_lerp_(self._qf_target_params, self._qf_params, cfg.tau)
        self.num_updates += 1

        logged["alpha"] = alpha
        return dict(zip(logged, torch.stack(list(logged.values())).tolist(), strict=True))

    def _critic_step(self, data: Batch, alpha: torch.Tensor) -> tuple[dict[str, torch.Tensor], torch.Tensor]:
        """One step of both critics on ``data``. Returns the logged tensors and the next-state actions
        a'(s') its target was computed with, shape (B, num_actions), without gradient."""
        cfg = self.config
        # Soft Bellman target from the target critics, bootstrapped only through non-terminal ends.
        with torch.no_grad():
            next_state_actions, next_state_log_pi = self.actor(data.next_obs, self.generator)
            qf_next_target = self.qf_target(data.next_obs, next_state_actions).min(dim=0).values
            min_qf_next_target = qf_next_target - alpha * next_state_log_pi
            rewards = cfg.reward_scale * data.rewards
            target_q = rewards + (1.0 - data.terminated) * cfg.gamma * min_qf_next_target
        qf_a_values = self.qf(data.obs, data.actions)  # (2, B)
        qf_loss = (qf_a_values - target_q).pow(2).mean(dim=1).sum()  # qf1_loss + qf2_loss
        self.q_optimizer.zero_grad(set_to_none=True)
        qf_loss.backward()
        self.q_optimizer.step()
        # Kept as tensors so that logging costs one host sync, when `update` returns.
        return {"qf_loss": qf_loss.detach(), "qf_values": qf_a_values.detach().mean()}, next_state_actions

    def actor_loss(
        self, data: Batch, next_state_actions: torch.Tensor, alpha: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, dict[str, torch.Tensor]]:
        """SAC's actor loss on ``data``, plus the CAPS terms with ``caps`` and the imitation term while the
        teacher's weight is above 0.

        ``next_state_actions`` (B, num_actions) are the critic target's a'(s'), used by sampled CAPS.
        Returns the loss (scalar), log pi(a|s) of the sampled actions (B,) and the added terms by name
        (caps_temporal, caps_spatial; imitation and imitated, the share of rows imitated).
        """
        cfg = self.config
        sampled_caps = cfg.caps and cfg.caps_actions == "sampled"
        if sampled_caps:  # a(s) and a(s_bar) from one forward pass over 2B rows
            obs_bar = perturbed_obs(data.obs, cfg.caps_sigma, self.generator, SAMPLED_CAPS_OBS_BOUND)
            actions, log_probs = self.actor(torch.cat([data.obs, obs_bar]), self.generator)
            (pi, pi_bar), log_pi = actions.chunk(2), log_probs.chunk(2)[0]
        else:
            pi, log_pi = self.actor(data.obs, self.generator)
        min_qf_pi = self.qf(data.obs, pi).min(dim=0).values
        actor_loss = (alpha * log_pi - min_qf_pi).mean()
        terms = self._imitation(data, min_qf_pi)
        if not cfg.caps:
            return actor_loss + terms["imitation"] if terms else actor_loss, log_pi, terms
        if sampled_caps:
            caps_temporal, caps_spatial = caps_terms(
                pi, next_state_actions, pi_bar, cfg.caps_lambda_t, cfg.caps_lambda_s
            )
        else:
            caps_temporal, caps_spatial = caps_loss(
                self.actor.deterministic,
                data.obs,
                data.next_obs,
                cfg.caps_lambda_t,
                cfg.caps_lambda_s,
                cfg.caps_sigma,
                self.generator,
            )
        actor_loss = actor_loss + caps_temporal + caps_spatial
        if terms:  # added last: float addition is not associative, and a seeded run repeats only in one order
            actor_loss = actor_loss + terms["imitation"]
        return actor_loss, log_pi, {"caps_temporal": caps_temporal, "caps_spatial": caps_spatial, **terms}

    def _imitation(self, data: Batch, min_qf_pi: torch.Tensor) -> dict[str, torch.Tensor]:
        """The imitation term of ``hier_ssl.policies.teacher`` on ``data`` and the share of rows it
        imitates, or nothing when the teacher's weight has fallen to 0. ``min_qf_pi`` (B,) sets its scale."""
        weight = teacher_weight(self.config, self.num_updates)
        if weight <= 0.0:
            return {}
        mean_action = self.actor.deterministic(data.obs)
        keep = None
        if self.config.teacher_filter:
            with torch.no_grad():
                q_teacher = self.qf(data.obs, data.teacher_actions).min(dim=0).values
                keep = q_teacher > self.qf(data.obs, mean_action).min(dim=0).values
        q_scale = min_qf_pi.detach().abs().mean()
        loss = imitation_loss(mean_action, data.teacher_actions, q_scale, weight, keep)
        imitated = keep.float().mean() if keep is not None else torch.ones((), device=loss.device)
        return {"imitation": loss, "imitated": imitated}

    def imitate(self, steps: int) -> float:
        """``steps`` supervised actor steps towards the stored teacher actions (mean squared error of the
        mean action, replay batches of ``batch_size``); the critic is left alone. Returns the last loss."""
        loss, unscaled = torch.zeros(()), torch.ones(())
        for _ in range(steps):
            data = self.replay.sample(self.config.batch_size, self.generator)
            loss = imitation_loss(self.actor.deterministic(data.obs), data.teacher_actions, unscaled, 1.0)
            self.actor_optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.actor_optimizer.step()
        return float(loss.detach())

    def state_dict(self) -> dict[str, object]:
        """Everything needed to resume learning except the replay buffer (``self.replay.state_dict()``)."""
        alpha_optimizer = self.alpha_optimizer
        return {
            "actor": self.actor.state_dict(),
            "qf": self.qf.state_dict(),
            "qf_target": self.qf_target.state_dict(),
            "actor_optimizer": self.actor_optimizer.state_dict(),
            "q_optimizer": self.q_optimizer.state_dict(),
            "alpha_optimizer": alpha_optimizer.state_dict() if alpha_optimizer is not None else None,
            "log_alpha": self.log_alpha.detach().clone(),
            "num_updates": self.num_updates,
            "generator": self.generator.get_state(),
        }

    def load_state_dict(self, state: dict[str, object]) -> None:
        """Inverse of ``state_dict``; the config (network sizes, alpha rule) must match the saved one."""
        self.actor.load_state_dict(state["actor"])
        self.qf.load_state_dict(state["qf"])
        self.qf_target.load_state_dict(state["qf_target"])
        self.actor_optimizer.load_state_dict(state["actor_optimizer"])
        self.q_optimizer.load_state_dict(state["q_optimizer"])
        if (self.alpha_optimizer is None) != (state["alpha_optimizer"] is None):
            raise ValueError("checkpoint and config disagree on whether alpha is learned")
        if self.alpha_optimizer is not None:
            self.alpha_optimizer.load_state_dict(state["alpha_optimizer"])
        with torch.no_grad():
            self.log_alpha.copy_(state["log_alpha"])
        self.num_updates = int(state["num_updates"])
        self.generator.set_state(state["generator"])
