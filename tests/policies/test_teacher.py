from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from hier_ssl.config import ConfigError, validate_config
from hier_ssl.envs import TorchVectorEnv, env_config, scenario_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.policies import SAC, SACConfig, SACRunner
from hier_ssl.policies.teacher import LABEL_BOUND, imitation_loss, teacher_labels, teacher_weight
from hier_ssl.worker import PaperGoToPoint

OBS_DIM, ACT_DIM = 4, 2
TINY = {"hidden": (32, 32), "batch_size": 32, "buffer_size": 4096, "learning_starts": 0}
TEACHING = {"teacher": "sampling", "teacher_weight": 2.0, "teacher_steps": 4}

pytestmark = pytest.mark.usefixtures("one_thread")


def _sac_with_labels(labels: torch.Tensor, **overrides: object) -> tuple[SAC, torch.Tensor]:
    """A SAC whose replay holds one transition labelled ``labels`` (1, ACT_DIM): every batch row is it."""
    sac = SAC(OBS_DIM, ACT_DIM, SACConfig(**{**TINY, **TEACHING, "policy_frequency": 1, **overrides}))
    obs = torch.tensor([[0.9, -0.4, 0.2, 0.5]])
    sac.process_env_step(obs, torch.zeros(1, ACT_DIM), torch.zeros(1), obs, torch.zeros(1), labels)
    return sac, obs


def test_config_names_the_teacher_keys_it_needs() -> None:
    for key, value in (("teacher_weight", 1.0), ("teacher_warmup", True), ("teacher_pretrain", 10)):
        with pytest.raises(ConfigError, match=f"sac.{key}: needs a teacher"):
            validate_config({"sac": {key: value}})
    with pytest.raises(ConfigError, match="sac.teacher: set teacher_weight"):
        validate_config({"sac": {"teacher": "sampling"}})
    with pytest.raises(ConfigError, match="sac.teacher"):
        validate_config({"sac": {"teacher": "astar", "teacher_weight": 1.0}})
    with pytest.raises(ConfigError, match="sac.teacher_weight"):
        validate_config({"sac": {"teacher": "sampling", "teacher_weight": -1.0}})
    for key, value in (("teacher_filter", True), ("teacher_steps", 100)):
        with pytest.raises(ConfigError, match=f"sac.{key}: only read with teacher_weight > 0"):
            validate_config({"sac": {"teacher": "sampling", "teacher_warmup": True, key: value}})
    with pytest.raises(ConfigError, match="sac.teacher: only read with algo 'sac', got 'ppo'"):
        validate_config({"algo": "ppo", "sac": {"teacher": "sampling", "teacher_weight": 1.0}})


def test_the_weight_falls_linearly_to_zero() -> None:
    decaying = SACConfig(**{**TEACHING, "teacher_weight": 3.0, "teacher_steps": 300})
    assert [teacher_weight(decaying, u) for u in (0, 100, 150, 300, 10**6)] == [3.0, 2.0, 1.5, 0.0, 0.0]
    constant = SACConfig(**{**TEACHING, "teacher_steps": 0})
    assert teacher_weight(constant, 10**6) == 2.0


def test_imitation_loss_by_hand() -> None:
    mean = torch.tensor([[0.0, 0.0], [1.0, 1.0]])
    labels = torch.tensor([[0.3, 0.4], [1.0, 0.0]])
    q_scale = torch.tensor(10.0)
    # Squared errors 0.25 and 1.0: mean 0.625, times weight 2 and |Q| 10.
    assert imitation_loss(mean, labels, q_scale, 2.0).item() == pytest.approx(12.5)
    keep = torch.tensor([False, True])  # only the second row: 1.0 / 2 rows
    assert imitation_loss(mean, labels, q_scale, 2.0, keep).item() == pytest.approx(10.0)


def test_sac_adds_the_imitation_term_until_its_weight_has_decayed() -> None:
    labels = torch.tensor([[0.5, -0.5]])
    sac, obs = _sac_with_labels(labels)
    data = sac.replay.sample(TINY["batch_size"], sac.generator)
    with torch.no_grad():
        pi, _ = sac.actor(data.obs, torch.Generator().manual_seed(0))
        q_scale = sac.qf(data.obs, pi).min(dim=0).values.abs().mean()
    _, _, terms = sac.actor_loss(data, pi, torch.tensor(0.2))
    error = (sac.actor.deterministic(obs) - labels).square().sum()
    # The sampled actions differ between the two calls, so |Q| is compared loosely; the error exactly.
    assert terms["imitation"].item() == pytest.approx(2.0 * q_scale.item() * error.item(), rel=0.2)
    assert terms["imitated"].item() == 1.0
    logged = [sac.update() for _ in range(5)]
    assert [("imitation" in entry) for entry in logged] == [True, True, True, True, False]
    # The actor moved towards the label.
    assert (sac.actor.deterministic(obs) - labels).square().sum() < error


def test_the_q_filter_imitates_only_where_the_critic_prefers_the_teacher() -> None:
    sac, obs = _sac_with_labels(torch.tensor([[0.5, -0.5]]), teacher_filter=True)
    data = sac.replay.sample(8, sac.generator)
    with torch.no_grad():
        q_teacher = sac.qf(obs, data.teacher_actions[:1]).min(dim=0).values
        q_actor = sac.qf(obs, sac.actor.deterministic(obs)).min(dim=0).values
    _, _, terms = sac.actor_loss(data, data.actions, torch.tensor(0.2))
    assert terms["imitated"].item() == float(q_teacher.item() > q_actor.item())
    assert (terms["imitation"].item() > 0.0) == (q_teacher.item() > q_actor.item())


def test_labels_skip_rows_of_robots_that_have_left() -> None:
    seen = []

    def teacher(obs: np.ndarray) -> np.ndarray:
        seen.append(obs.copy())
        return obs[:, :ACT_DIM] + 0.5

    obs = torch.tensor([[0.1, 0.2, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.3, 0.4, 0.5, 0.0]])
    labels = teacher_labels(teacher, obs)
    np.testing.assert_array_equal(seen[0], obs[[0, 2]].numpy())
    assert torch.equal(labels, torch.tensor([[0.6, 0.7], [0.0, 0.0], [0.8, 0.9]]))


def test_labels_stay_inside_what_the_squashed_actor_can_reach() -> None:
    # A planner on the target's heading in the target frame: cos exactly 1.
    labels = teacher_labels(lambda obs: np.array([[0.0, 1.0], [-1.0, 0.5]]), torch.ones(2, 4))
    assert torch.equal(labels, torch.tensor([[0.0, LABEL_BOUND], [-LABEL_BOUND, 0.5]]))
    assert torch.isfinite(torch.atanh(labels)).all()


def test_runner_stores_the_planners_labels_and_warms_up_with_them(tmp_path: Path) -> None:
    task = env_config(
        task="obstacle", observation="encounters", neighbours=1, action_frame="target", frame_skip=16
    )
    env = TorchVectorEnv(task, num_fields=4)
    cfg = SACConfig(**{**TINY, "learning_starts": 40, "teacher": "sampling", "teacher_warmup": True})
    cfg = cfg.model_copy(update={"teacher_noise": 0.0})
    runner = SACRunner(env, cfg, tmp_path, progress=False)
    runner.learn(total_steps=6)
    replay, planner = runner.sac.replay, make_planner("sampling", task)
    n = len(replay)
    want = np.clip(planner(replay.obs[:n].numpy()), -LABEL_BOUND, LABEL_BOUND)
    np.testing.assert_allclose(replay.teacher_actions[:n].numpy(), want, atol=1e-6)
    # Noise 0: the warm-up acted exactly as the (clipped) labels.
    np.testing.assert_allclose(replay.actions[:n].numpy(), want, atol=1e-6)


def test_the_teacher_plans_with_the_envs_own_worker(tmp_path: Path) -> None:
    task = env_config(task="obstacle", observation="encounters", neighbours=1, action_frame="target")
    cfg = SACConfig(hidden=(8, 8), teacher="sampling", teacher_weight=1.0)
    slow = TorchVectorEnv(task, num_fields=1, worker=PaperGoToPoint(dt=task.dt, max_speed=1.0))
    assert SACRunner(slow, cfg, tmp_path / "slow", progress=False).teacher.speed == 1.0
    # Without an object the env runs the worker its config names (the paper's, 2.2 m/s).
    assert SACRunner(TorchVectorEnv(task, 1), cfg, tmp_path / "own", progress=False).teacher.speed == 2.2


def test_runner_labels_the_live_rows_of_a_scenario(tmp_path: Path) -> None:
    env = TorchVectorEnv(scenario_config("crossing", num_agents=3, action_frame="target"), num_fields=2)
    cfg = SACConfig(hidden=(8, 8), learning_starts=10**6, teacher="sampling", teacher_warmup=True)
    runner = SACRunner(env, cfg, tmp_path, progress=False)
    runner.learn(40)  # robots leave their episodes on the way; the planner sees only those still in them
    n = len(runner.sac.replay)
    assert n < 40 * 6 and runner.sac.replay.teacher_actions[:n].abs().sum(dim=1).gt(0).all()


class PointEnv:
    """Points in [-1, 1]^2 that move by 0.2 x action a step towards a goal; obs (x, y, goal x, goal y)."""

    def __init__(self, num_envs: int = 16) -> None:
        self.num_envs, self.num_obs, self.num_actions = num_envs, OBS_DIM, ACT_DIM
        self.device, self.generator = torch.device("cpu"), torch.Generator()
        self.state = torch.zeros(num_envs, OBS_DIM)

    def reset(self, seed: int | None = None) -> torch.Tensor:
        if seed is not None:
            self.generator.manual_seed(seed)
        self.state = torch.rand(self.num_envs, OBS_DIM, generator=self.generator) * 2 - 1
        return self.state.clone()

    def step(self, actions: torch.Tensor) -> tuple:
        self.state[:, :2] = (self.state[:, :2] + 0.2 * actions).clamp(-1, 1)
        reward = -torch.linalg.vector_norm(self.state[:, :2] - self.state[:, 2:], dim=1)
        no = torch.zeros(self.num_envs, dtype=torch.bool)
        return self.state.clone(), reward, no, no, {"final_obs": self.state.clone(), "task": {}}


def _heads_for_the_goal(obs: np.ndarray) -> np.ndarray:
    """Half the way to the goal, in [-1, 1]: a smooth policy the actor can fit."""
    return (obs[:, 2:] - obs[:, :2]) / 2.0


def test_pretraining_on_a_teachers_labels_learns_its_policy(tmp_path: Path) -> None:
    cfg = SACConfig(**{**TINY, "learning_starts": 320, "teacher": "direct", "teacher_pretrain": 400})
    runner = SACRunner(PointEnv(), cfg, tmp_path, progress=False, teacher=_heads_for_the_goal)
    runner.learn(total_steps=20)  # 320 random transitions, then 400 supervised steps, then 1 SAC update
    assert runner.sac.num_updates == 1
    obs = PointEnv(256).reset(seed=99)
    error = runner.sac.act(obs, deterministic=True) - torch.from_numpy(_heads_for_the_goal(obs.numpy()))
    assert error.abs().mean() < 0.15, error.abs().mean()
    with pytest.raises(ValueError, match="sac.teacher is not set"):
        SACRunner(PointEnv(), SACConfig(**TINY), tmp_path, teacher=_heads_for_the_goal)
