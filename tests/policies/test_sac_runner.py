from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch
from tensorboard.backend.event_processing.event_accumulator import EventAccumulator
from torch.overrides import TorchFunctionMode

import hier_ssl
from hier_ssl.policies import SACConfig, SACRunner
from hier_ssl.policies.learner import Checkpoint
from hier_ssl.policies.sac_runner import MODEL_FILE, REPLAY_FILE, to_learner

OBS_DIM, ACT_DIM = 4, 2
TINY = {"hidden": (32, 32), "batch_size": 32, "buffer_size": 4096, "learning_starts": 0}

pytestmark = pytest.mark.usefixtures("one_thread")


class PointEnv:
    """Vector env of 2-D points that must reach a random goal (the ``VectorEnv`` protocol).

    obs = (x, y, goal_x, goal_y) in [-1, 1]^4; action = velocity in [-1, 1]^2 times ``speed`` per step;
    reward = -distance to the goal after the move; episodes are truncated after ``episode_length`` steps
    and never terminate. ``info["task"]["final_distance"]`` reports the distance at the end.
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
        return self._obs(), reward, terminated, truncated, {"final_obs": final_obs, "task": episode}


def _mean_final_distance(policy: Callable[[torch.Tensor], torch.Tensor], episodes: int = 4) -> float:
    """Mean distance to the goal at the end of ``episodes`` x 16 fresh episodes."""
    env = PointEnv()
    obs = env.reset(seed=12345)
    distances = []
    for _ in range(episodes * env.episode_length):
        obs, _, _, _, info = env.step(policy(obs))
        distances.append(info["task"]["final_distance"])
    return torch.cat(distances).mean().item()


# --- runner ---------------------------------------------------------------------------------------


def test_runner_checkpoints_resume_and_calls_back(tmp_path: Path) -> None:
    cfg = SACConfig(**{**TINY, "learning_starts": 64, "updates_per_step": 0.5})
    calls: list[Checkpoint] = []

    def on_checkpoint(checkpoint: Checkpoint) -> dict[str, float]:
        calls.append(checkpoint)
        return {"steps": float(checkpoint.step)}

    runner = SACRunner(
        PointEnv(num_envs=4),
        cfg,
        tmp_path,
        seed=1,
        log_interval=5,
        save_interval=10,
        eval_interval=15,
        progress=False,
    )
    runner.learn(total_steps=32, on_checkpoint=on_checkpoint)
    # Warm-up is 64 transitions = 16 vector steps; then half an update per step.
    # Scored every eval_interval steps, and the final policy.
    assert runner.step == 32 and runner.sac.num_updates == 8
    assert [(c.step, c.transitions) for c in calls] == [(15, 60), (30, 120), (32, 128)]
    # The last checkpoint's state is the final actor, and its policy acts with it.
    assert calls[-1].state()["step"] == 32
    for key, value in calls[-1].state()["actor"].items():
        assert torch.equal(value, runner.sac.actor.state_dict()[key])
    obs = torch.rand(3, OBS_DIM)
    greedy = runner.sac.act(obs, deterministic=True).detach().numpy()
    np.testing.assert_array_equal(calls[-1].policy(obs.numpy()), greedy)
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


class FixedStartEnv(PointEnv):
    """``PointEnv`` whose episodes all start from the same state (origin, one fixed goal per env), so that
    at an episode boundary a fresh ``reset`` leaves the env exactly as its auto-reset would."""

    def _reset_envs(self, mask: torch.Tensor) -> None:
        self.pos[mask] = 0.0
        self.goal[mask] = torch.linspace(-0.9, 0.9, 2 * self.num_envs).view(-1, 2)[mask]
        self.t[mask] = 0
        self.ret[mask] = 0.0


def _learner_state(runner: SACRunner) -> dict[str, object]:
    sac = runner.sac
    return {
        **{
            f"{name}.{k}": v
            for name in ("actor", "qf", "qf_target")
            for k, v in sac.state_dict()[name].items()
        },
        "log_alpha": sac.log_alpha.detach(),
        "replay": sac.replay.state_dict(),
        "num_updates": sac.num_updates,
    }


@pytest.mark.parametrize("interrupt_at", [20, 40], ids=["in_warm_up", "after_warm_up"])
def test_resume_across_the_warm_up_continues_as_an_uninterrupted_run(
    tmp_path: Path, interrupt_at: int
) -> None:
    # Warm-up 120 transitions = 30 vector steps of 4 envs; episodes of 10 steps, so both interruptions
    # fall on an episode boundary, where the resumed run's reset gives the state the uninterrupted run has.
    cfg = SACConfig(**{**TINY, "learning_starts": 120, "updates_per_step": 0.5})
    env = FixedStartEnv(num_envs=4, episode_length=10)
    whole = SACRunner(env, cfg, tmp_path / "whole", seed=3, progress=False)
    whole.learn(total_steps=50)
    whole.close()
    first = SACRunner(
        FixedStartEnv(num_envs=4, episode_length=10), cfg, tmp_path / "split", seed=3, progress=False
    )
    first.learn(total_steps=interrupt_at)
    first.close()
    resumed = SACRunner(
        FixedStartEnv(num_envs=4, episode_length=10), cfg, tmp_path / "split", seed=3, progress=False
    )
    resumed.load(tmp_path / "split")
    resumed.learn(total_steps=50)
    resumed.close()
    # Updates at steps 31, 33, ..., 49: half an update per step from the step that completes the warm-up.
    assert whole.sac.num_updates == 10 and len(whole.sac.replay) == 200
    expected, got = _learner_state(whole), _learner_state(resumed)
    assert expected.keys() == got.keys()
    for key, value in expected.items():
        if isinstance(value, dict):
            assert all(torch.equal(torch.as_tensor(value[k]), torch.as_tensor(got[key][k])) for k in value), (
                key
            )
        else:
            assert torch.equal(torch.as_tensor(value), torch.as_tensor(got[key])), key


def test_a_warm_up_longer_than_the_replay_and_the_run_counts_transitions_collected(tmp_path: Path) -> None:
    # 200 transitions of warm-up against a replay of 64 rows: counted from the replay, it would never end.
    cfg = SACConfig(**{**TINY, "buffer_size": 64, "learning_starts": 200})
    runner = SACRunner(PointEnv(num_envs=4), cfg, tmp_path, log_interval=7, progress=False)
    runner.learn(total_steps=40)  # 160 transitions: all warm-up
    runner.close()
    assert runner.sac.num_updates == 0 and len(runner.sac.replay) == 64
    resumed = SACRunner(PointEnv(num_envs=4), cfg, tmp_path, log_interval=7, progress=False)
    resumed.load(tmp_path)
    assert resumed.num_transitions == 160 and resumed.sac.num_updates == 0
    resumed.learn(total_steps=60)  # the warm-up ends at step 50; one update per step from there
    resumed.close()
    assert resumed.sac.num_updates == 11 and len(resumed.sac.replay) == 64


class _DeviceCopies(TorchFunctionMode):
    """Records every explicit device move (``Tensor.to`` with a device, ``.cpu``, ``.cuda``): its name,
    the source shape, the arguments, and the result."""

    def __init__(self) -> None:
        super().__init__()
        self.calls: list[tuple[str, tuple[int, ...], tuple, dict, torch.Tensor]] = []

    def __torch_function__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        out = func(*args, **kwargs)
        moves = func in (torch.Tensor.cpu, torch.Tensor.cuda) or (
            func is torch.Tensor.to
            and ("device" in kwargs or any(isinstance(a, (str, torch.device)) for a in args[1:]))
        )
        if moves:
            self.calls.append((func.__name__, tuple(args[0].shape), args[1:], kwargs, out))
        return out


def test_runner_moves_one_packed_tensor_to_the_learner_and_the_actions_back(tmp_path: Path) -> None:
    num_envs, steps = 4, 6
    runner = SACRunner(
        PointEnv(num_envs=num_envs),
        SACConfig(**{**TINY, "learning_starts": 12}),
        tmp_path,
        device="cpu",
        log_interval=2,
        progress=False,
    )
    stored: list[tuple[torch.Tensor, ...]] = []
    store = runner.sac.process_env_step
    runner.sac.process_env_step = lambda *rows: (stored.append(rows), store(*rows))[1]
    with _DeviceCopies() as copies:
        runner.learn(total_steps=steps)  # 3 warm-up steps of random actions, 3 of the policy with updates
    runner.close()
    assert runner.sac.num_updates == 4
    reset, *per_step = copies.calls
    assert reset[:3] == ("to", (num_envs, OBS_DIM), (runner.device,))
    assert len(per_step) == 2 * steps  # nothing else crosses: one copy each way per vector step
    for i in range(steps):
        (a_name, a_shape, a_args, a_kwargs, _), (s_name, s_shape, s_args, s_kwargs, packed) = per_step[
            2 * i : 2 * i + 2
        ]
        assert (a_name, a_shape, a_args, a_kwargs) == ("to", (num_envs, ACT_DIM), (runner.env.device,), {})
        assert (s_name, s_shape, s_args, s_kwargs) == (
            "to",
            (num_envs, 2 * OBS_DIM + 3),
            (runner.device,),
            {"non_blocking": True},
        )
        # What is stored is the copy: reward, next obs and terminated are views of the packed tensor.
        _, _, rewards, next_obs, terminated = stored[i]
        pointer = packed.untyped_storage().data_ptr()
        assert all(x.untyped_storage().data_ptr() == pointer for x in (rewards, next_obs, terminated))


@pytest.mark.skipif(torch.cuda.is_available(), reason="the refusal is for machines without CUDA")
def test_a_cuda_learner_without_cuda_is_refused_naming_the_device(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="device 'cuda': torch sees no CUDA device"):
        SACRunner(PointEnv(num_envs=2), SACConfig(**TINY), tmp_path, device="cuda", progress=False)


def test_to_learner_splits_what_it_packed() -> None:
    gen = torch.Generator().manual_seed(0)
    next_obs, final_obs = torch.rand(5, 3, generator=gen), torch.rand(5, 3, generator=gen)
    rewards = torch.randn(5, generator=gen)
    terminated = torch.tensor([True, False, False, True, False])
    live = torch.tensor([True, True, False, True, False])
    out = to_learner(torch.device("cpu"), next_obs, rewards, final_obs, terminated, live)
    for got, want in zip(out, (next_obs, rewards, final_obs, terminated.float(), live), strict=True):
        assert got.dtype == want.dtype
        assert torch.equal(got, want)
    assert to_learner(torch.device("cpu"), next_obs, rewards, final_obs, terminated, None)[4] is None


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


def test_the_runner_steps_on_one_torch_thread_and_updates_on_the_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, torch_threads_seen
) -> None:
    seen, counted = torch_threads_seen
    env = hier_ssl.vector_env(task="proposed", frame_skip=16, num_envs=4)
    runner = SACRunner(env, SACConfig(**{**TINY, "learning_starts": 8}), tmp_path, progress=False)
    monkeypatch.setattr(env, "step", counted("step", env.step))
    monkeypatch.setattr(runner.sac, "update", counted("update", runner.sac.update))
    runner.learn(total_steps=4)
    runner.close()
    assert seen == {"step": {1}, "update": {2}} and torch.get_num_threads() == 2
