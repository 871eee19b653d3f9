"""The learners' config sections: SAC (+ CAPS), PPO and the candidate classifier's two phases.

Data, as ``hier_ssl.config.schema`` (which assembles them into ``TrainConfig``): models that check types and
ranges, and nothing from the rest of the package.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator


class Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


LayerSizes = Annotated[tuple[Annotated[int, Field(ge=1)], ...], Field(min_length=1)]
"""Hidden layer sizes: at least one layer, each of at least one unit."""


class SACConfig(BaseModel):
    """Hyper-parameters. Networks, optimisers, gamma, tau, batch, buffer and policy_frequency default to
    the paper's public code (docs/paper.md); the keys where ours differ say what the public code
    uses: a config with ``caps_actions: sampled``, ``actor_schedule: delayed``, ``learning_starts: 80000``
    and ``alpha: 1.0`` (learned, no CAPS) or ``alpha: 0.2`` (with CAPS) reproduces it."""

    model_config = ConfigDict(extra="forbid")

    hidden: tuple[int, ...] = (256, 256)
    actor_lr: float = Field(3e-4, gt=0)
    critic_lr: float = Field(1e-3, gt=0)
    alpha_lr: float = Field(1e-3, gt=0)
    gamma: float = Field(0.99, ge=0, le=1)
    tau: float = Field(0.005, gt=0, le=1)
    batch_size: int = Field(256, ge=1)
    buffer_size: int = Field(1_000_000, ge=1)
    learning_starts: int = Field(
        5000,
        ge=0,
        description="transitions (vector steps x num_envs) of uniform random actions before the first "
        "update; the public code: 5,000 vector steps x 16 envs = 80,000",
    )
    policy_frequency: int = Field(2, ge=1, description="the actor steps on every policy_frequency-th update")
    actor_schedule: Literal["catch_up", "delayed"] = Field(
        "catch_up",
        description="actor steps on each policy_frequency-th update: catch_up runs policy_frequency of them "
        "(CleanRL: as many actor as critic steps), delayed runs one (TD3, the paper's public code)",
    )
    alpha: float = Field(
        0.2,
        gt=0,
        description="entropy coefficient: fixed, or the start value if learned; the public code learns it "
        "from 1.0 without CAPS and fixes it at 0.2 with CAPS",
    )
    autotune_alpha: bool | None = Field(None, description="learn alpha; None means: learn unless caps")
    target_entropy: float | None = Field(None, description="None means -act_dim")
    caps: bool = False
    caps_lambda_t: float = Field(1.0, ge=0)
    caps_lambda_s: float = Field(5.0, ge=0)
    caps_sigma: float = Field(0.05, ge=0)
    caps_actions: Literal["mean", "sampled"] = Field(
        "mean",
        description="CAPS on the mean actions tanh(mean) at s, s', s_bar; or as the public code on sampled "
        "actions, a'(s') the critic target's next action, s_bar clamped to +-SAMPLED_CAPS_OBS_BOUND",
    )
    updates_per_step: float = Field(1.0, gt=0, description="gradient updates per vector env step")
    reward_scale: float = Field(
        1.0, gt=0, description="multiplies rewards in the critic target; the env rewards stay as they are"
    )
    # Learning from a scripted planner (hier_ssl.policies.teacher); the planner only teaches, the policy
    # stays a network.
    teacher: Literal["sampling", "direct"] | None = Field(
        None, description="planner whose action for each stored observation is kept as a label"
    )
    teacher_weight: float = Field(
        0.0,
        ge=0,
        description="weight of the imitation term ||tanh(mean(s)) - a_teacher(s)||^2 in the actor loss, in "
        "units of the batch's mean |Q| (TD3+BC's normalisation)",
    )
    teacher_steps: int = Field(
        0, ge=0, description="updates over which teacher_weight falls linearly to 0; 0 keeps it constant"
    )
    teacher_filter: bool = Field(
        False, description="imitate only where the critic rates the teacher's action above the actor's"
    )
    teacher_warmup: bool = Field(
        False, description="the warm-up's actions are the teacher's plus Gaussian noise, not uniform"
    )
    teacher_noise: float = Field(0.1, ge=0, description="std of the noise on the teacher's warm-up actions")
    teacher_pretrain: int = Field(
        0, ge=0, description="supervised actor steps on the teacher's labels when the warm-up ends"
    )

    @field_validator("hidden")
    @classmethod
    def _hidden_positive(cls, hidden: tuple[int, ...]) -> tuple[int, ...]:
        if not hidden or min(hidden) < 1:
            raise ValueError(f"hidden must be a non-empty sequence of positive layer sizes, got {hidden}")
        return hidden

    @model_validator(mode="after")
    def _caps_fixes_alpha(self) -> SACConfig:
        if self.caps and self.autotune_alpha:
            raise ValueError("autotune_alpha=True conflicts with caps=True: CAPS runs with a fixed alpha")
        return self

    @model_validator(mode="after")
    def _teacher_used(self) -> SACConfig:
        uses = {"teacher_weight": self.teacher_weight > 0, "teacher_warmup": self.teacher_warmup}
        uses["teacher_pretrain"] = self.teacher_pretrain > 0
        if self.teacher is None and any(uses.values()):
            key = next(k for k, used in uses.items() if used)
            raise ValueError(f"{key}: needs a teacher (sac.teacher: sampling)")
        if self.teacher is not None and not any(uses.values()):
            raise ValueError("teacher: set teacher_weight, teacher_warmup or teacher_pretrain to use it")
        # Keys that only shape the imitation term would otherwise be accepted and do nothing.
        if self.teacher_weight == 0 and (self.teacher_filter or self.teacher_steps > 0):
            key = "teacher_filter" if self.teacher_filter else "teacher_steps"
            raise ValueError(f"{key}: only read with teacher_weight > 0")
        return self

    @property
    def learns_alpha(self) -> bool:
        """Whether alpha is learned: ``autotune_alpha`` if given, else not ``caps``."""
        return self.autotune_alpha if self.autotune_alpha is not None else not self.caps


class PPOConfig(Strict):
    """rsl-rl-lib's OnPolicyRunner settings that this project exposes. Defaults are the ones measured to
    learn the Proposed task with frame skip (benchmarks/ppo_proposed.py at commit d6783a1); rsl-rl's own
    (noise 1.0, entropy 0.005) stall near 30 % success there, because the sub-goal must be precise to 5 cm."""

    num_steps_per_env: int = Field(16, ge=1)
    learning_rate: float = Field(1e-3, gt=0)
    num_learning_epochs: int = Field(5, ge=1)
    num_mini_batches: int = Field(4, ge=1)
    gamma: float = Field(0.95, gt=0, le=1)
    lam: float = Field(0.95, gt=0, le=1)
    entropy_coef: float = Field(0.0, ge=0)
    clip_param: float = Field(0.2, gt=0)
    hidden: tuple[int, ...] = (128, 128)
    init_noise_std: float = Field(0.5, gt=0)


class CandidatePPOConfig(Strict):
    """Phase 2 of ``algo: candidates``: PPO on the network's categorical policy from its DAgger fit (a
    residual: from the planner; ``hier_ssl.policies.candidates``), rewarded by outcomes alone: minus
    ``time_cost`` per 100 control steps, plus ``success_reward`` at a success, minus ``collision_cost``
    at a collision."""

    iterations: int = Field(0, ge=0)  # 0: DAgger alone
    fields: int = Field(64, ge=1)  # fields played at once
    horizon: int = Field(32, ge=1)  # decisions per field per iteration
    learning_rate: float = Field(1e-4, gt=0)
    value_learning_rate: float = Field(1e-3, gt=0)
    # Both learning rates fall linearly to 1 / iterations of themselves by the last iteration, so the
    # final policy is not the last of a run of full-size noisy steps (rates near 99 % move by a few
    # episodes in 1000 between neighbouring checkpoints).
    anneal: bool = False
    value_hidden: LayerSizes = (256, 256)
    value_warmup: int = Field(10, ge=0)  # iterations that fit the value alone before the policy moves
    gamma: float = Field(0.99, gt=0, le=1)  # per decision
    lam: float = Field(0.95, ge=0, le=1)
    clip: float = Field(0.1, gt=0)
    epochs: int = Field(4, ge=1)
    minibatches: int = Field(4, ge=1)
    kl_weight: float = Field(0.05, ge=0)  # KL(policy || where PPO started) in the policy loss
    time_cost: float = Field(1.0, ge=0)
    success_reward: float = Field(10.0, ge=0)
    collision_cost: float = Field(20.0, ge=0)
    # A denser signal than outcomes alone (a collision ends about one robot-episode in 70 in game_stop):
    # minus near_cost x (1 - gap / near_distance) at every decision that ends with the nearest other robot
    # closer than near_distance (m), read from the neighbours observation.
    near_cost: float = Field(0.0, ge=0)
    near_distance: float = Field(0.35, gt=0)
    eval_interval: int = Field(50, ge=1)  # iterations between selection scores and checkpoints


class CandidatesConfig(Strict):
    """``algo: candidates``: a choice among the ``sampling`` planner's candidate sub-goals
    (``hier_ssl.policies.candidates``) by a ``network``: "classifier" (an MLP over the observation, a
    logit per candidate slot), "scorer" (an MLP shared by the candidates, over each one's features) or
    "residual" (the planner's own ranking / ``tau`` plus an MLP, zero at the start, over each candidate's
    rollouts). Phase 1 fits it by DAgger: ``rounds`` rounds of ``episodes`` episodes (the first played by
    the planner, the others by the network), each followed by ``epochs`` passes over every state gathered
    so far, none for a residual (it starts as the planner); phase 2 is ``ppo``."""

    network: Literal["classifier", "scorer", "residual"] = "classifier"
    # The planner whose candidates (and, for a residual, whose ranking) the network chooses among: `sampling`,
    # with settings of its own where given (`sampling+trapped=brake`, ``hier-ssl eval``'s spelling).
    planner: str = Field("sampling", pattern=r"^sampling(\+.*)?$")
    hidden: LayerSizes = (256, 256)
    rounds: int = Field(30, ge=0)
    episodes: int = Field(500, ge=1)
    epochs: int = Field(8, ge=1)
    tau: float = Field(0.05, gt=0)  # s: temperature of the planner's soft choice over arrival times
    # A residual's dead band: added to the logit of the planner's own choice, so a correction smaller than
    # it leaves the planner's tie-break alone (hier_ssl.policies.candidate_residual).
    keep: float = Field(0.0, ge=0)
    # A residual's inputs add how far each leg of a candidate keeps from the game's zones, not only whether
    # it is clear; off, a residual reads what runs trained before it read.
    zone_features: bool = False
    # A residual's inputs add how far each candidate and the robot are from the robot's last sub-goal: a
    # memory, so that it can learn to hold a way round where the planner flips between two.
    memory: bool = False
    learning_rate: float = Field(1e-3, gt=0)
    batch_size: int = Field(256, ge=1)
    ppo: CandidatePPOConfig = Field(default_factory=CandidatePPOConfig)

    @model_validator(mode="after")
    def _rounds_fit_the_network(self) -> CandidatesConfig:
        # DAgger's labels are the planner's soft choice, which a residual already is; the others start
        # untrained.
        if (self.rounds == 0) != (self.network == "residual"):
            raise ValueError(
                f"rounds: {self.rounds} with network {self.network!r}; a residual takes 0 (it starts as "
                "the planner), a classifier or scorer at least 1"
            )
        if self.keep and self.network != "residual":
            raise ValueError(f"keep: {self.keep} is a residual's dead band; network is {self.network!r}")
        for key in ("zone_features", "memory"):
            if getattr(self, key) and self.network != "residual":
                raise ValueError(
                    f"{key}: {getattr(self, key)} adds to a residual's inputs; network is {self.network!r}"
                )
        return self


__all__ = ["CandidatePPOConfig", "CandidatesConfig", "PPOConfig", "SACConfig", "Strict"]
