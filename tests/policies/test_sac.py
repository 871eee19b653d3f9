from __future__ import annotations

import copy
import io
import math

import pytest
import torch
from pydantic import ValidationError

from hier_ssl.policies import SAC, SACConfig, SquashedGaussianActor, TwinQ, caps_loss
from hier_ssl.policies.networks import LOG_STD_MAX, LOG_STD_MIN
from hier_ssl.policies.sac import SAMPLED_CAPS_OBS_BOUND, perturbed_obs

OBS_DIM, ACT_DIM = 4, 2
TINY = {"hidden": (32, 32), "batch_size": 32, "buffer_size": 4096, "learning_starts": 0}

pytestmark = pytest.mark.usefixtures("one_thread")


def _build_sac(seed: int = 0, **overrides: object) -> SAC:
    return SAC(OBS_DIM, ACT_DIM, SACConfig(**{**TINY, **overrides}), seed=seed)


def _fill(sac: SAC, n: int = 256, seed: int = 0) -> None:
    gen = torch.Generator().manual_seed(seed)
    sac.process_env_step(
        torch.rand(n, OBS_DIM, generator=gen) * 2 - 1,
        torch.rand(n, ACT_DIM, generator=gen) * 2 - 1,
        -torch.rand(n, generator=gen),
        torch.rand(n, OBS_DIM, generator=gen) * 2 - 1,
        torch.rand(n, generator=gen) < 0.1,
    )


# --- config ---------------------------------------------------------------------------------------


def test_config_defaults_are_the_public_code_settings() -> None:
    cfg = SACConfig()
    assert cfg.hidden == (256, 256) and (cfg.actor_lr, cfg.critic_lr, cfg.alpha_lr) == (3e-4, 1e-3, 1e-3)
    assert (cfg.gamma, cfg.tau, cfg.batch_size, cfg.buffer_size) == (0.99, 0.005, 256, 1_000_000)
    assert (cfg.learning_starts, cfg.policy_frequency, cfg.alpha) == (5000, 2, 0.2)
    assert (cfg.caps_lambda_t, cfg.caps_lambda_s, cfg.caps_sigma) == (1.0, 5.0, 0.05)
    assert cfg.learns_alpha and not SACConfig(caps=True).learns_alpha


def test_public_code_differences_default_to_ours_and_reject_unknown_values() -> None:
    cfg = SACConfig()
    assert (cfg.caps_actions, cfg.actor_schedule, cfg.reward_scale) == ("mean", "catch_up", 1.0)
    public = SACConfig(caps=True, caps_actions="sampled", actor_schedule="delayed", learning_starts=80_000)
    assert not public.learns_alpha and public.alpha == 0.2
    for key, value in (("caps_actions", "noisy"), ("actor_schedule", "every")):
        with pytest.raises(ValidationError, match=key):
            SACConfig(**{key: value})


@pytest.mark.parametrize(
    ("field", "value"),
    [("actor_lr", -1e-3), ("critic_lr", 0.0), ("tau", 1.5), ("batch_size", 0), ("hidden", (64, 0))],
)
def test_config_rejects_out_of_range_values_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ValidationError, match=field):
        SACConfig(**{field: value})


def test_config_rejects_unknown_keys_and_learned_alpha_with_caps() -> None:
    with pytest.raises(ValidationError, match="actor_learning_rate"):
        SACConfig(actor_learning_rate=1e-3)
    with pytest.raises(ValidationError, match="autotune_alpha"):
        SACConfig(caps=True, autotune_alpha=True)


# --- networks -------------------------------------------------------------------------------------


def test_actor_log_prob_matches_torch_distributions() -> None:
    torch.manual_seed(0)
    actor = SquashedGaussianActor(OBS_DIM, ACT_DIM, hidden=(16,))
    obs = torch.randn(64, OBS_DIM)
    action, log_prob = actor(obs, torch.Generator().manual_seed(1))
    mean, log_std = actor.mean_log_std(obs)
    assert action.shape == (64, ACT_DIM) and log_prob.shape == (64,)
    assert action.abs().max() <= 1.0
    assert LOG_STD_MIN <= log_std.min() and log_std.max() <= LOG_STD_MAX
    # The same draw through torch.distributions; the pre-tanh value is recovered from the noise.
    noise = torch.randn(mean.shape, generator=torch.Generator().manual_seed(1))
    pre_tanh = mean + log_std.exp() * noise
    expected = torch.distributions.Normal(mean, log_std.exp()).log_prob(pre_tanh)
    expected = (expected - torch.log1p(-torch.tanh(pre_tanh).pow(2))).sum(-1)
    torch.testing.assert_close(action, torch.tanh(pre_tanh))
    torch.testing.assert_close(log_prob, expected, atol=1e-3, rtol=1e-4)
    torch.testing.assert_close(actor.deterministic(obs), torch.tanh(mean))
    # Where tanh saturates in float32 the textbook formula gives inf; ours stays finite.
    assert torch.isfinite(actor(obs * 1e4)[1]).all()


def test_twin_q_equals_two_separate_mlps() -> None:
    torch.manual_seed(0)
    qf = TwinQ(OBS_DIM, ACT_DIM, hidden=(8, 8))
    obs, action = torch.randn(5, OBS_DIM), torch.rand(5, ACT_DIM)
    q = qf(obs, action)
    assert q.shape == (2, 5)
    for c in range(2):
        x = torch.cat([obs, action], dim=1)
        for i, (w, b) in enumerate(zip(qf.weights, qf.biases, strict=True)):
            x = x @ w[c] + b[c, 0]
            x = torch.relu(x) if i < len(qf.weights) - 1 else x
        torch.testing.assert_close(q[c], x[:, 0])


# --- CAPS -----------------------------------------------------------------------------------------


def test_caps_loss_by_hand() -> None:
    def first_two(x: torch.Tensor) -> torch.Tensor:  # a deterministic "actor": mu(s) = s[:, :2]
        return x[:, :2]

    obs = torch.tensor([[0.0, 0.0, 9.0], [1.0, 1.0, 9.0]])
    next_obs = torch.tensor([[3.0, 4.0, -9.0], [1.0, 1.0, 5.0]])
    temporal, spatial = caps_loss(first_two, obs, next_obs, 2.0, 5.0, 0.1, torch.Generator().manual_seed(7))
    # ||(3, 4)|| = 5 and ||(0, 0)|| = 0: lambda_T * mean = 2 * 2.5.
    assert temporal.item() == pytest.approx(5.0)
    # s_bar = s + 0.1 * noise with the generator's first draw: ||mu(s_bar) - mu(s)|| = 0.1 ||noise[:, :2]||.
    noise = torch.randn(obs.shape, generator=torch.Generator().manual_seed(7))
    expected = 5.0 * (0.1 * noise[:, :2]).norm(dim=1).mean()
    assert spatial.item() == pytest.approx(expected.item(), rel=1e-5)
    _, spatial_zero_sigma = caps_loss(first_two, obs, next_obs, 2.0, 5.0, 0.0)
    assert spatial_zero_sigma.item() == 0.0


def test_sac_update_reports_the_caps_terms_of_its_actor() -> None:
    # One stored transition, so every sampled batch is that transition; sigma = 0 makes the spatial term 0.
    sac = _build_sac(caps=True, caps_lambda_t=3.0, caps_sigma=0.0, policy_frequency=1)
    obs, next_obs = torch.tensor([[0.5, -0.5, 0.2, 0.1]]), torch.tensor([[-0.3, 0.8, 0.2, 0.1]])
    sac.process_env_step(
        obs, torch.zeros(1, ACT_DIM), torch.zeros(1), next_obs, torch.zeros(1, dtype=torch.bool)
    )
    with torch.no_grad():
        expected = 3.0 * (sac.actor.deterministic(next_obs) - sac.actor.deterministic(obs)).norm().item()
    logged = sac.update()
    assert logged["caps_temporal"] == pytest.approx(expected, rel=1e-5)
    assert logged["caps_spatial"] == 0.0
    # The norm's gradient at a zero difference is taken as 0, not NaN.
    assert all(torch.isfinite(p).all() for p in sac.actor.parameters())


def test_caps_changes_the_actor_update() -> None:
    plain, smooth = _build_sac(alpha=0.2, autotune_alpha=False), _build_sac(caps=True)
    for sac in (plain, smooth):
        _fill(sac)
        sac.update()
    assert not torch.equal(plain.actor.net[0].weight, smooth.actor.net[0].weight)
    assert torch.equal(plain.qf.weights[0], smooth.qf.weights[0])  # same seed, same batch, same critic step


def _one_transition_sac(**overrides: object) -> tuple[SAC, torch.Tensor, torch.Tensor]:
    """A SAC whose replay holds a single transition, so every batch row is that transition."""
    sac = _build_sac(**overrides)
    obs, next_obs = torch.tensor([[0.9, -1.1, 0.2, 1.0]]), torch.tensor([[-0.3, 0.8, 0.2, 0.1]])
    sac.process_env_step(
        obs, torch.zeros(1, ACT_DIM), torch.zeros(1), next_obs, torch.zeros(1, dtype=torch.bool)
    )
    return sac, obs, next_obs


def test_sampled_caps_is_the_public_codes_formula_on_the_clamped_state() -> None:
    lambda_t, lambda_s, sigma, batch = 3.0, 5.0, 0.5, 8
    sac, obs, next_obs = _one_transition_sac(
        caps=True,
        caps_actions="sampled",
        actor_schedule="delayed",
        batch_size=batch,
        caps_lambda_t=lambda_t,
        caps_lambda_s=lambda_s,
        caps_sigma=sigma,
    )
    actor = copy.deepcopy(sac.actor)
    gen = torch.Generator()
    gen.set_state(sac.generator.get_state())
    logged = sac.update()
    # The same draws by hand, in the update's order: replay indices, a'(s') of the critic target, the
    # perturbation of s, then one sample at s and at s_bar.
    torch.randint(1, (batch,), generator=gen)
    with torch.no_grad():
        next_action, _ = actor(next_obs.expand(batch, -1), gen)
        raw_bar = obs + sigma * torch.randn((batch, OBS_DIM), generator=gen)
        obs_bar = raw_bar.clamp(-1.2, 1.2)
        pi, pi_bar = actor(torch.cat([obs.expand(batch, -1), obs_bar]), gen)[0].chunk(2)
        unclamped_pi_bar = actor.deterministic(raw_bar)  # only to show that the clamp matters here
    assert SAMPLED_CAPS_OBS_BOUND == 1.2 and (raw_bar.abs() > 1.2).any()
    assert logged["caps_temporal"] == pytest.approx(lambda_t * (next_action - pi).norm(dim=1).mean().item())
    assert logged["caps_spatial"] == pytest.approx(lambda_s * (pi_bar - pi).norm(dim=1).mean().item())
    assert logged["caps_spatial"] != pytest.approx(
        lambda_s * (unclamped_pi_bar - pi).norm(dim=1).mean().item()
    )


def test_perturbed_obs_clamps_only_when_given_a_bound() -> None:
    obs = torch.tensor([[1.15, -1.15, 0.0]])
    noise = torch.randn(obs.shape, generator=torch.Generator().manual_seed(3))
    free = perturbed_obs(obs, 2.0, torch.Generator().manual_seed(3))
    clamped = perturbed_obs(obs, 2.0, torch.Generator().manual_seed(3), bound=1.2)
    torch.testing.assert_close(free, obs + 2.0 * noise)
    torch.testing.assert_close(clamped, (obs + 2.0 * noise).clamp(-1.2, 1.2))


def test_sampled_caps_terms_put_gradient_only_into_the_actor() -> None:
    sac = _build_sac(caps=True, caps_actions="sampled")
    _fill(sac)
    data = sac.replay.sample(32, torch.Generator().manual_seed(0))
    alpha = sac.log_alpha.detach().exp()
    _, next_state_actions = sac._critic_step(data, alpha)
    assert not next_state_actions.requires_grad  # a'(s') is a constant of the actor loss
    sac.q_optimizer.zero_grad(set_to_none=True)
    _, _, caps = sac.actor_loss(data, next_state_actions, alpha)
    (caps["caps_temporal"] + caps["caps_spatial"]).backward()
    assert all(p.grad is None for p in [*sac.qf.parameters(), *sac.qf_target.parameters(), sac.log_alpha])
    assert all(p.grad is not None and p.grad.abs().sum() > 0 for p in sac.actor.parameters())


# --- actor schedule -------------------------------------------------------------------------------


def _adam_steps(optimizer: torch.optim.Optimizer) -> int:
    return int(optimizer.state[optimizer.param_groups[0]["params"][0]]["step"])


@pytest.mark.parametrize(
    ("schedule", "policy_frequency", "actor_steps", "updates_that_step"),
    [
        ("catch_up", 1, 6, [0, 1, 2, 3, 4, 5]),
        ("delayed", 1, 6, [0, 1, 2, 3, 4, 5]),
        ("catch_up", 2, 6, [0, 2, 4]),  # 2 actor steps on each of updates 0, 2, 4
        ("delayed", 2, 3, [0, 2, 4]),  # the public code: one actor step per two critic steps
        ("catch_up", 3, 6, [0, 3]),
        ("delayed", 3, 2, [0, 3]),
    ],
)
def test_actor_schedule_counts(
    schedule: str, policy_frequency: int, actor_steps: int, updates_that_step: list[int]
) -> None:
    sac = _build_sac(actor_schedule=schedule, policy_frequency=policy_frequency)
    _fill(sac)
    stepped = [i for i in range(6) if "actor_loss" in sac.update()]
    assert stepped == updates_that_step
    assert _adam_steps(sac.q_optimizer) == 6
    assert _adam_steps(sac.actor_optimizer) == _adam_steps(sac.alpha_optimizer) == actor_steps


# --- alpha ----------------------------------------------------------------------------------------


@pytest.mark.parametrize("start", [0.2, 1.0])
def test_learned_alpha_starts_at_the_configured_value(start: float) -> None:
    learned = _build_sac(alpha=start, policy_frequency=1)
    fixed_same = _build_sac(alpha=start, autotune_alpha=False, policy_frequency=1)
    fixed_other = _build_sac(alpha=1.2 - start, autotune_alpha=False, policy_frequency=1)
    assert learned.config.learns_alpha and learned.log_alpha.item() == pytest.approx(math.log(start))
    for sac in (learned, fixed_same, fixed_other):
        _fill(sac)
    logged = learned.update()
    fixed_same.update()
    fixed_other.update()
    # The first critic target used alpha = start; then one Adam step moved log alpha by at most its lr.
    assert torch.equal(learned.qf.weights[0], fixed_same.qf.weights[0])
    assert not torch.equal(learned.qf.weights[0], fixed_other.qf.weights[0])
    assert logged["alpha"] != start and abs(math.log(logged["alpha"] / start)) < 1.01e-3


def test_alpha_is_fixed_with_caps_and_learned_with_autotune() -> None:
    fixed, learned = _build_sac(caps=True), _build_sac()
    for sac in (fixed, learned):
        _fill(sac)
        for _ in range(20):
            logged = sac.update()
    assert torch.equal(fixed.log_alpha, torch.tensor(math.log(0.2)))
    assert fixed.alpha_optimizer is None and "alpha_loss" not in fixed.update()
    assert learned.log_alpha.exp().item() != pytest.approx(0.2, abs=1e-4)
    assert logged["alpha"] == pytest.approx(learned.log_alpha.exp().item())


# --- checkpoints ----------------------------------------------------------------------------------


def test_state_dict_round_trip_continues_identically() -> None:
    sac = _build_sac(caps=True)
    _fill(sac)
    for _ in range(5):
        sac.update()
    blob = io.BytesIO()
    torch.save({"sac": sac.state_dict(), "replay": sac.replay.state_dict()}, blob)
    blob.seek(0)
    state = torch.load(blob, weights_only=True)
    restored = _build_sac(seed=99, caps=True)
    restored.load_state_dict(state["sac"])
    restored.replay.load_state_dict(state["replay"])

    obs = torch.rand(8, OBS_DIM) * 2 - 1
    assert torch.equal(restored.act(obs, deterministic=True), sac.act(obs, deterministic=True))
    assert torch.equal(restored.act(obs), sac.act(obs))  # the random stream is restored too
    for _ in range(2):  # the second one steps the actor
        assert restored.update() == sac.update()
    assert restored.num_updates == sac.num_updates == 7


def test_load_rejects_a_different_alpha_rule() -> None:
    with pytest.raises(ValueError, match="alpha"):
        _build_sac(caps=True).load_state_dict(_build_sac().state_dict())
