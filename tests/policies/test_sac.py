from __future__ import annotations

import io
import math
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import torch
from pydantic import ValidationError
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

import hier_ssl
from hier_ssl.policies import SAC, SACConfig, SACRunner, SquashedGaussianActor, TwinQ, caps_loss
from hier_ssl.policies.networks import LOG_STD_MAX, LOG_STD_MIN
from hier_ssl.policies.sac_runner import MODEL_FILE, REPLAY_FILE, atomic_save

OBS_DIM, ACT_DIM = 4, 2
TINY = {"hidden": (32, 32), "batch_size": 32, "buffer_size": 4096, "learning_starts": 0}


@pytest.fixture(autouse=True)
def _one_thread() -> Iterator[None]:
    """Tiny networks run fastest on one thread, and two OpenMP threads stall badly on a busy 2-core CPU."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


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


class PointEnv:
    """Vector env of 2-D points that must reach a random goal (the ``VectorEnv`` protocol).

    obs = (x, y, goal_x, goal_y) in [-1, 1]^4; action = velocity in [-1, 1]^2 times ``speed`` per step;
    reward = -distance to the goal after the move; episodes are truncated after ``episode_length`` steps
    and never terminate. ``info["episode"]["final_distance"]`` reports the distance at the end.
    """

    def __init__(self, num_envs: int = 16, episode_length: int = 20, speed: float = 0.2) -> None:
        self.num_envs, self.num_obs, self.num_actions = num_envs, 4, 2
        self.device = torch.device("cpu")
        self.episode_length, self.speed = episode_length, speed
        self.generator = torch.Generator()
        self.pos = torch.zeros(num_envs, 2)
        self.goal = torch.zeros(num_envs, 2)
        self.t = torch.zeros(num_envs, dtype=torch.long)
        self.ret = torch.zeros(num_envs)

    def _obs(self) -> torch.Tensor:
        return torch.cat([self.pos, self.goal], dim=1)

    def _reset_envs(self, mask: torch.Tensor) -> None:
        n = int(mask.sum())
        self.pos[mask] = torch.rand(n, 2, generator=self.generator) * 2 - 1
        self.goal[mask] = torch.rand(n, 2, generator=self.generator) * 2 - 1
        self.t[mask] = 0
        self.ret[mask] = 0.0

    def reset(self, seed: int | None = None) -> torch.Tensor:
        if seed is not None:
            self.generator.manual_seed(seed)
        self._reset_envs(torch.ones(self.num_envs, dtype=torch.bool))
        return self._obs()

    def step(
        self, actions: torch.Tensor
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict]:
        self.pos = (self.pos + self.speed * actions.clamp(-1, 1)).clamp(-1, 1)
        distance = torch.linalg.vector_norm(self.pos - self.goal, dim=1)
        reward = -distance
        self.t += 1
        self.ret += reward
        truncated = self.t >= self.episode_length
        terminated = torch.zeros(self.num_envs, dtype=torch.bool)
        final_obs = self._obs()
        episode = {
            "return": self.ret[truncated].clone(),
            "length": self.t[truncated].float(),
            "final_distance": distance[truncated],
        }
        self._reset_envs(truncated)
        return self._obs(), reward, terminated, truncated, {"final_obs": final_obs, "episode": episode}


def _mean_final_distance(policy: Callable[[torch.Tensor], torch.Tensor], episodes: int = 4) -> float:
    """Mean distance to the goal at the end of ``episodes`` x 16 fresh episodes."""
    env = PointEnv()
    obs = env.reset(seed=12345)
    distances = []
    for _ in range(episodes * env.episode_length):
        obs, _, _, _, info = env.step(policy(obs))
        distances.append(info["episode"]["final_distance"])
    return torch.cat(distances).mean().item()


# --- config ---------------------------------------------------------------------------------------


def test_config_defaults_are_the_public_code_settings() -> None:
    cfg = SACConfig()
    assert cfg.hidden == (256, 256) and (cfg.actor_lr, cfg.critic_lr, cfg.alpha_lr) == (3e-4, 1e-3, 1e-3)
    assert (cfg.gamma, cfg.tau, cfg.batch_size, cfg.buffer_size) == (0.99, 0.005, 256, 1_000_000)
    assert (cfg.learning_starts, cfg.policy_frequency, cfg.alpha) == (5000, 2, 0.2)
    assert (cfg.caps_lambda_t, cfg.caps_lambda_s, cfg.caps_sigma) == (1.0, 5.0, 0.05)
    assert cfg.learns_alpha and not SACConfig(caps=True).learns_alpha


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


# --- alpha ----------------------------------------------------------------------------------------


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


# --- runner ---------------------------------------------------------------------------------------


def test_runner_checkpoints_resume_and_calls_back(tmp_path: Path) -> None:
    cfg = SACConfig(**{**TINY, "learning_starts": 64, "updates_per_step": 0.5})
    calls: list[int] = []

    def on_eval(runner: SACRunner) -> dict[str, float]:
        calls.append(runner.step)
        return {"steps": float(runner.step)}

    runner = SACRunner(
        PointEnv(num_envs=4),
        cfg,
        tmp_path,
        seed=1,
        log_interval=5,
        save_interval=10,
        eval_interval=15,
        eval_callback=on_eval,
        progress=False,
    )
    runner.learn(total_steps=32)
    # Warm-up is 64 transitions = 16 vector steps; then half an update per step.
    assert runner.step == 32 and runner.sac.num_updates == 8 and calls == [15, 30]
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith("events")) == [
        MODEL_FILE,
        REPLAY_FILE,
    ]
    scalars = EventAccumulator(str(tmp_path)).Reload().Tags()["scalars"]
    assert {"losses/qf_loss", "losses/actor_loss", "losses/alpha", "episode/return", "eval/steps"} <= set(
        scalars
    )
    model = torch.load(tmp_path / MODEL_FILE, weights_only=True)
    assert model["step"] == 32 and set(model["sac"]) >= {"actor", "qf", "qf_target", "log_alpha"}

    resumed = SACRunner(PointEnv(num_envs=4), cfg, tmp_path, seed=1, progress=False)
    resumed.load(tmp_path)
    assert resumed.step == 32 and resumed.sac.num_updates == 8
    assert torch.equal(resumed.sac.replay.obs, runner.sac.replay.obs)
    obs = torch.rand(3, OBS_DIM)
    assert torch.equal(resumed.sac.act(obs, deterministic=True), runner.sac.act(obs, deterministic=True))
    resumed.learn(total_steps=40)
    assert resumed.step == 40 and len(resumed.sac.replay) == 160 and resumed.sac.num_updates == 12
    resumed.close()
    runner.close()


def test_atomic_save_keeps_the_old_file_when_writing_fails(tmp_path: Path) -> None:
    path = tmp_path / MODEL_FILE
    atomic_save({"step": 1}, path)
    with pytest.raises(Exception, match="pickle"):
        atomic_save({"step": 2, "bad": lambda: None}, path)  # fails halfway through pickling
    assert torch.load(path, weights_only=True) == {"step": 1}
    assert [p.name for p in tmp_path.iterdir()] == [MODEL_FILE]


def test_runner_drives_the_real_vector_env(tmp_path: Path) -> None:
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=4)
    runner = SACRunner(env, SACConfig(**{**TINY, "learning_starts": 32}), tmp_path, progress=False)
    runner.learn(total_steps=12)
    runner.close()
    assert len(runner.sac.replay) == 48 and runner.sac.num_updates == 5
    assert torch.isfinite(runner.sac.replay.rewards[:48]).all()


def test_runner_load_rejects_a_different_config(tmp_path: Path) -> None:
    runner = SACRunner(PointEnv(num_envs=2), SACConfig(**TINY), tmp_path, progress=False)
    runner.save()
    other = SACRunner(PointEnv(num_envs=2), SACConfig(**{**TINY, "gamma": 0.5}), tmp_path, progress=False)
    with pytest.raises(ValueError, match="config"):
        other.load(tmp_path)


@pytest.mark.parametrize(
    "overrides",
    [{}, {"caps": True, "caps_lambda_t": 0.1, "caps_lambda_s": 0.5}],
    ids=["sac", "sac_caps"],
)
def test_sac_learns_to_reach_a_goal(tmp_path: Path, overrides: dict[str, object]) -> None:
    # Rewards here are ~0.2 per step apart, far smaller than the paper's, so CAPS gets lambdas scaled down
    # to match: at the paper's 1 and 5 the smoothness terms outweigh the Q gradient and the point stays put.
    cfg = SACConfig(
        hidden=(64, 64),
        batch_size=64,
        buffer_size=20_000,
        learning_starts=640,
        gamma=0.9,
        updates_per_step=2.0,
        **overrides,
    )
    runner = SACRunner(PointEnv(), cfg, tmp_path, seed=0, log_interval=50, progress=False)
    runner.learn(total_steps=400)  # 6,400 transitions, 720 updates after the 640-transition warm-up
    runner.close()
    assert runner.sac.num_updates == 722
    gen = torch.Generator().manual_seed(0)
    random_distance = _mean_final_distance(lambda obs: torch.rand(obs.shape[0], 2, generator=gen) * 2 - 1)
    learned_distance = _mean_final_distance(lambda obs: runner.sac.act(obs, deterministic=True))
    assert random_distance > 0.8  # about the mean distance between two uniform points of the square
    assert learned_distance < 0.2, (learned_distance, random_distance)


def test_runner_stores_only_the_rows_of_robots_still_in_their_episode(tmp_path: Path) -> None:
    from hier_ssl.envs import TorchVectorEnv, scenario_config

    env = TorchVectorEnv(scenario_config("crossing", num_agents=3, action_frame="target"), num_fields=2)
    live_rows = []
    step = env.step

    def counting_step(actions: torch.Tensor) -> tuple:
        out = step(actions)
        live_rows.append(int(out[4]["live"].sum()))
        return out

    env.step = counting_step
    runner = SACRunner(env, SACConfig(hidden=(8, 8), learning_starts=10**6), tmp_path, progress=False)
    runner.learn(40)
    assert min(live_rows) < 6  # robots left their episodes on the way
    assert runner.sac.replay.size == sum(live_rows)
