"""A worker given as a Python object (``worker=``) to every env constructor, to evaluation and to the
planners; and a worker that fails inside a step leaves the core as it was, or refuses to step on."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
import torch

import hier_ssl
from hier_ssl.config import EnvConfig
from hier_ssl.envs import HierarchicalCore, env_config
from hier_ssl.envs.planners import make_planner
from hier_ssl.envs.play import play
from hier_ssl.evaluation.compare import compare, load_manager
from hier_ssl.evaluation.evaluate import evaluate
from hier_ssl.worker import CheckedWorker, PaperGoToPoint, WorkerError, worker_name
from hier_ssl.world.physics import RobotState

LABEL = f"{__name__}:Counting"


class Counting:
    """The paper's controller, counting its calls; with ``fail`` set, or at call number ``fail_call``, it
    returns NaN commands (the CheckedWorker around it raises a WorkerError) without calling the
    controller."""

    def __init__(self, max_speed: float = 2.2) -> None:
        self.inner, self.calls = PaperGoToPoint(dt=0.025, max_speed=max_speed), 0
        self.fail, self.fail_call = False, 0
        self.max_speed = max_speed

    def reset(self, fields: np.ndarray) -> None:
        self.inner.reset(fields)

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        self.calls += 1
        if self.fail or self.calls == self.fail_call:
            return np.full((*subgoal.shape[:-1], 3), np.nan)
        return self.inner(state, subgoal)


def _inner(core: HierarchicalCore) -> object:
    assert isinstance(core.worker, CheckedWorker)
    return core.worker.worker


def test_every_constructor_takes_an_object_and_steps_with_it() -> None:
    views = {
        "parallel_env": hier_ssl.parallel_env(task="proposed", worker=Counting()),
        "env": hier_ssl.env(task="proposed", worker=Counting()).unwrapped,
        "manager_env": hier_ssl.manager_env(task="proposed", worker=Counting()).env,
        "scenario_env": hier_ssl.scenario_env("crossing", num_agents=2, worker=Counting()),
    }
    for name, view in views.items():
        worker = _inner(view.core)
        view.reset(seed=0)
        view.step({a: view.action_space(a).sample() for a in view.agents})
        assert worker.calls == view.config.frame_skip, name
    vectors = {
        "vector_env": hier_ssl.vector_env(task="proposed", num_envs=2, frame_skip=4, worker=Counting()),
        "scenario_vector_env": hier_ssl.scenario_vector_env("crowd", num_fields=2, worker=Counting()),
    }
    for name, view in vectors.items():
        view.reset(seed=0)
        view.step(torch.zeros(view.num_envs, view.num_actions))
        assert _inner(view.core).calls == view.config.frame_skip, name
    core = HierarchicalCore(EnvConfig(), 2, worker=Counting)  # a class is built, as an import spec is
    assert isinstance(_inner(core), Counting)
    worker = Counting()
    made = gymnasium.make("hier_ssl/Obstacle-v0", frame_skip=4, worker=worker)
    made.reset(seed=0)
    made.step(made.action_space.sample())
    assert worker.calls == 4 and _inner(made.unwrapped.env.core) is worker


def test_a_spec_given_as_worker_goes_into_the_config() -> None:
    assert hier_ssl.parallel_env(task="proposed", worker="bangbang").config.worker == "bangbang"
    assert hier_ssl.scenario_env("crowd", worker="bangbang").config.worker == "bangbang"
    assert hier_ssl.manager_env(task="obstacle", worker="bangbang").env.config.worker == "bangbang"


def test_an_object_drives_as_the_spec_it_equals() -> None:
    spec_env = hier_ssl.parallel_env(task="obstacle", frame_skip=4)
    object_env = hier_ssl.parallel_env(task="obstacle", frame_skip=4, worker=PaperGoToPoint(dt=0.025))
    for env in (spec_env, object_env):
        env.reset(seed=5)
    action = {"manager_0": np.array([0.3, -0.2, 0.0, 1.0])}
    for _ in range(5):
        a, b = spec_env.step(action)[0], object_env.step(action)[0]
        np.testing.assert_array_equal(a["manager_0"], b["manager_0"])


def test_evaluation_planners_and_compare_take_objects() -> None:
    config = env_config(task="proposed", frame_skip=16)
    slow = Counting(max_speed=1.0)
    assert make_planner("sampling", config, worker=slow).speed == 1.0
    assert load_manager("sampling", config, worker=slow).speed == 1.0
    assert make_planner("sampling", config).speed == 2.2  # the config's own (paper) worker
    ours = evaluate(make_planner("direct", config), config, 6, seed=1, worker=Counting())
    paper = evaluate(make_planner("direct", config), config, 6, seed=1)
    assert ours["per_robot"]["length"].tolist() == paper["per_robot"]["length"].tolist()

    evaluations = compare(["direct"], task="proposed", workers=[slow, "paper"], episodes=6, seed=1)
    assert [e.record["worker"] for e in evaluations] == [LABEL, "paper"]
    assert [e.worker for e in evaluations] == [LABEL, "paper"] and worker_name(slow) == LABEL
    assert slow.calls > 0  # it drove its row
    slow_length = evaluations[0].record["episode_length"]["median"]
    assert slow_length > evaluations[1].record["episode_length"]["median"]  # capped at 1 m/s


# -- a worker that fails inside a step ----------------------------------------------------------------------


def _snapshot(core: HierarchicalCore) -> dict[str, object]:
    s = core.state
    return {
        "pos": s.pos.copy(),
        "vel": s.vel.copy(),
        "subgoal": core.subgoal.copy(),
        "decisions": core.decisions.copy(),
        "cpad": core.ep_cpad.copy(),
        "steps": core.steps.copy(),
        "control_steps": core.control_steps,
        "rng": core.rng.bit_generator.state,
    }


def _assert_same(a: dict[str, object], b: dict[str, object]) -> None:
    assert a.keys() == b.keys()
    for key in a:
        np.testing.assert_equal(a[key], b[key], err_msg=key)


def _pair(**settings: object) -> tuple[HierarchicalCore, HierarchicalCore]:
    config = env_config(task="obstacle", frame_skip=4, **settings)
    cores = HierarchicalCore(config, 3, worker=Counting()), HierarchicalCore(config, 3, worker=Counting())
    for core in cores:
        core.reset(seed=2)
    return cores


def test_a_failure_at_a_decisions_first_control_step_is_undone_whole() -> None:
    core, twin = _pair()
    rng = np.random.default_rng(0)
    first, second = (rng.uniform(-1, 1, (3, 1, 4)) for _ in range(2))
    for c in (core, twin):
        c.step(first)
    before = _snapshot(core)
    _inner(core).fail = True
    with pytest.raises(WorkerError, match=rf"worker '{LABEL}' returned a non-finite command"):
        core.step(second)
    _assert_same(_snapshot(core), before)  # sub-goals, decisions, CPAD, world, counters, obstacle rng
    _inner(core).fail = False
    for _ in range(3):
        a, b = core.step(second), twin.step(second)
        np.testing.assert_array_equal(a.obs, b.obs)
        np.testing.assert_array_equal(a.reward, b.reward)
    _assert_same(_snapshot(core), _snapshot(twin))


def test_a_failure_later_in_a_decision_needs_a_reset() -> None:
    core, _ = _pair()
    core.step(np.zeros((3, 1, 4)))
    _inner(core).fail_call = 7  # the 3rd control step of the 2nd decision
    with pytest.raises(WorkerError):
        core.step(np.zeros((3, 1, 4)))
    assert core.interrupted
    with pytest.raises(RuntimeError, match=r"part-way through a decision: call reset\(\) first"):
        core.step(np.zeros((3, 1, 4)))
    core.reset(seed=2)
    assert not core.interrupted
    core.step(np.zeros((3, 1, 4)))


def test_the_pettingzoo_view_with_exposed_obstacles_undoes_a_failed_step() -> None:
    envs = [
        hier_ssl.parallel_env(task="obstacle", frame_skip=4, expose_obstacles=True, worker=Counting())
        for _ in range(2)
    ]
    actions = {"manager_0": np.array([0.5, 0.1, 0.0, 1.0]), "obstacle_0": np.array([0.2, 0.0, 0.1])}
    for env in envs:
        env.reset(seed=3)
    env, twin = envs
    _inner(env.core).fail = True
    before = _snapshot(env.core)
    with pytest.raises(WorkerError):
        env.step(actions)
    _assert_same(_snapshot(env.core), before)
    assert env.agents == twin.agents
    _inner(env.core).fail = False
    for _ in range(6):  # across a decision step and the control steps after it
        a, b = env.step(actions), twin.step(actions)
        for agent in a[0]:
            np.testing.assert_array_equal(a[0][agent], b[0][agent])
        assert a[1] == b[1]


def test_play_runs_a_class_given_as_the_worker() -> None:
    config = env_config(task="proposed", frame_skip=16)
    core = HierarchicalCore(config, 4, autoreset=False, worker=Counting)
    ends = play(core, make_planner("direct", config), 0)
    assert ends["success"].all()
