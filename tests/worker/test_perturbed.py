from __future__ import annotations

import math

import numpy as np
import pytest

from hier_ssl.config import EnvConfig, GoToPointConfig
from hier_ssl.envs import HierarchicalCore
from hier_ssl.envs.gotopoint import evaluate_worker, uniform_task
from hier_ssl.worker import PaperGoToPoint, make_worker
from hier_ssl.worker.perturbed import Perturbation, PerturbedWorker, parse_worker_spec
from hier_ssl.world.physics import RobotSpec, RobotState

SPEC, DT = RobotSpec(), 0.025


class _Counter:
    """A worker whose k-th call commands (k, k, k) everywhere; records resets."""

    def __init__(self) -> None:
        self.calls, self.resets = 0, []

    def reset(self, fields: np.ndarray) -> None:
        self.resets.append(np.asarray(fields).tolist())

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        self.calls += 1
        return np.full((*state.angle.shape, 3), float(self.calls))


class _Constant:
    """A worker that commands ``command`` (3,) to every robot."""

    def __init__(self, command: list[float]) -> None:
        self.command = np.array(command, dtype=float)

    def reset(self, fields: np.ndarray) -> None:
        pass

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        return np.broadcast_to(self.command, (*state.angle.shape, 3)).copy()


def _state(n: int = 2, angle: float = 0.0, vel: tuple[float, float] = (0.0, 0.0)) -> RobotState:
    return RobotState(
        np.zeros((n, 1, 2)), np.full((n, 1), angle), np.tile(np.array(vel), (n, 1, 1)), np.zeros((n, 1))
    )


def _wrap(**options: object) -> PerturbedWorker:
    return PerturbedWorker(_Counter(), Perturbation(**options), SPEC, DT)


# -- the spec string ---------------------------------------------------------------------------------------


def test_spec_strings_parse() -> None:
    assert parse_worker_spec("paper") == ("paper", Perturbation())
    assert parse_worker_spec("paper+latency=2+noise=0.2") == ("paper", Perturbation(latency=2, noise=0.2))
    base, p = parse_worker_spec("runs/w+1+accel=1.5+ang_accel=30+noise_add=0.01+seed=4")
    assert base == "runs/w+1"  # a '+' that starts no known key= part stays in the name
    assert p == Perturbation(accel=1.5, ang_accel=30.0, noise_add=0.01, seed=4)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("paper+lag=2", "unknown perturbation 'lag'"),
        ("paper+latency=1.5", "latency must be an integer"),
        ("paper+latency=-1", "latency: expected an integer >= 0"),
        ("paper+noise=x", "noise must be a number"),
        ("paper+noise=-0.1", "noise: expected a fraction >= 0"),
        ("paper+accel=0", "accel: expected a limit > 0"),
        ("paper+noise=0.1+noise=0.2", "noise given twice"),
        ("+latency=2", "no worker name"),
    ],
)
def test_bad_specs_name_the_part(spec: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make_worker(spec, SPEC, DT)


def test_make_worker_wraps_only_when_something_is_perturbed() -> None:
    assert isinstance(make_worker("paper", SPEC, DT), PaperGoToPoint)
    assert isinstance(make_worker("paper+seed=3", SPEC, DT), PaperGoToPoint)
    worker = make_worker("bangbang+latency=2+noise=0.2", SPEC, DT)
    assert isinstance(worker, PerturbedWorker) and worker.perturbation == Perturbation(latency=2, noise=0.2)


# -- each perturbation alone -------------------------------------------------------------------------------


def test_latency_delays_by_k_steps_and_reset_clears_only_given_fields() -> None:
    worker = _wrap(latency=2)
    state = _state(3)
    # Zero (stop) for the first two steps, then the command of two steps before.
    out = [worker(state, np.zeros((3, 1, 5)))[:, 0, 0].tolist() for _ in range(4)]
    assert out == [[0, 0, 0], [0, 0, 0], [1, 1, 1], [2, 2, 2]]
    worker.reset(np.array([1]))
    assert worker.worker.resets == [[1]]  # passed through to the wrapped worker
    assert worker(state, np.zeros((3, 1, 5)))[:, 0, 0].tolist() == [3, 0, 3]
    assert worker(state, np.zeros((3, 1, 5)))[:, 0, 0].tolist() == [4, 0, 4]
    assert worker(state, np.zeros((3, 1, 5)))[:, 0, 0].tolist() == [5, 5, 5]


def test_noise_is_seeded_and_has_the_given_size() -> None:
    def commands(**options: object) -> np.ndarray:
        worker = PerturbedWorker(_Constant([1.0, 1.0, 1.0]), Perturbation(**options), SPEC, DT)
        return worker(_state(4000), np.zeros((4000, 1, 5)))

    a, b = commands(noise=0.2, seed=1), commands(noise=0.2, seed=1)
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, commands(noise=0.2, seed=2))
    assert abs(a.mean() - 1.0) < 0.02 and abs(a.std() - 0.2) < 0.01
    # Additive noise is a fraction of the limits: 2.5 m/s for vx, vy and 10 rad/s for w.
    c = commands(noise_add=0.1)
    assert abs(c[..., 0].std() - 0.25) < 0.02 and abs(c[..., 2].std() - 1.0) < 0.05


def test_multiplicative_noise_leaves_a_stop_a_stop() -> None:
    worker = PerturbedWorker(_Constant([0.0, 0.0, 0.0]), Perturbation(noise=0.5), SPEC, DT)
    assert not worker(_state(5), np.zeros((5, 1, 5))).any()


def test_acceleration_limit_ramps_the_command_in_the_field_frame() -> None:
    # 2 m/s along the robot's x, robot facing +y (90 deg): field velocity (0, 2) wanted.
    worker = PerturbedWorker(_Constant([2.0, 0.0, 8.0]), Perturbation(accel=1.0, ang_accel=40.0), SPEC, DT)
    state = _state(1, angle=math.pi / 2)
    first = worker(state, np.zeros((1, 1, 5)))[0, 0]
    np.testing.assert_allclose(first, [0.025, 0.0, 1.0], atol=1e-12)  # a * dt = 0.025 m/s, 40 * dt = 1 rad/s
    second = worker(state, np.zeros((1, 1, 5)))[0, 0]
    np.testing.assert_allclose(second, [0.05, 0.0, 2.0], atol=1e-12)
    # After a reset the ramp starts from the robot's own velocity: 1 m/s along the field's +y.
    worker.reset(np.array([0]))
    moving = _state(1, angle=math.pi / 2, vel=(0.0, 1.0))
    np.testing.assert_allclose(worker(moving, np.zeros((1, 1, 5)))[0, 0, 0:2], [1.025, 0.0], atol=1e-12)


# -- in the loop -------------------------------------------------------------------------------------------


def test_perturbed_paper_worker_still_reaches_subgoals_but_later() -> None:
    config, task = EnvConfig(max_steps=400), uniform_task(GoToPointConfig())
    clean = evaluate_worker(make_worker("paper", SPEC, DT), config, task, 40, seed=5)
    late = evaluate_worker(make_worker("paper+latency=2+noise=0.2", SPEC, DT), config, task, 40, seed=5)
    slow = evaluate_worker(make_worker("paper+accel=0.5", SPEC, DT), config, task, 40, seed=5)
    assert clean["success_rate"] == 1.0 and late["success_rate"] >= 0.9
    assert late["time_s"]["median"] > clean["time_s"]["median"]
    assert slow["time_s"]["median"] > clean["time_s"]["median"] + 0.5


def test_core_takes_a_perturbed_worker_from_the_config() -> None:
    core = HierarchicalCore(EnvConfig(worker="paper+latency=3"), num_fields=2)
    assert isinstance(core.worker, PerturbedWorker)
    core.reset(seed=0)
    for _ in range(3):
        result = core.step(np.tile([0.5, 0.5, 0.0, 1.0], (2, 1, 1)))
    assert result.obs.shape == (2, 1, 13)


def test_the_episode_seed_seeds_the_noise_through_every_view() -> None:
    """A seeded reset replays the same noise: twice through Gymnasium's id, through the PettingZoo view
    alike, and for one worker object handed to two evaluations (its generator is not built once)."""
    import gymnasium

    import hier_ssl
    from hier_ssl.envs.planners import make_planner
    from hier_ssl.evaluation.evaluate import evaluate

    def first_steps(env: gymnasium.Env) -> list[np.ndarray]:
        obs = [env.reset(seed=0)[0]]
        obs += [env.step(np.array([0.3, -0.2, 0.5, 1.0]))[0] for _ in range(3)]
        return obs

    made = gymnasium.make("hier_ssl/Proposed-v0", frame_skip=16, worker="paper+noise=0.2")
    np.testing.assert_array_equal(first_steps(made), first_steps(made))
    other = gymnasium.make("hier_ssl/Proposed-v0", frame_skip=16, worker="paper+noise=0.2+seed=1")
    assert not np.array_equal(first_steps(made)[1], first_steps(other)[1])

    pz = hier_ssl.parallel_env(task="proposed", frame_skip=16, worker="paper+noise=0.2")
    pz_obs = [pz.reset(seed=0)[0]["manager_0"]]
    pz_obs += [pz.step({"manager_0": np.array([0.3, -0.2, 0.5, 1.0])})[0]["manager_0"] for _ in range(3)]
    np.testing.assert_array_equal(pz_obs, first_steps(made))

    config = EnvConfig(task="proposed", frame_skip=16)
    worker = make_worker("paper+noise=0.6+latency=1", SPEC, DT)
    runs = [evaluate(make_planner("direct", config), config, 30, seed=3, worker=worker) for _ in range(2)]
    np.testing.assert_array_equal(runs[0]["per_robot"]["length"], runs[1]["per_robot"]["length"])
