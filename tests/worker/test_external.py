from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from hier_ssl import cli
from hier_ssl.config import ConfigError, EnvConfig
from hier_ssl.envs import HierarchicalCore, parse_config
from hier_ssl.evaluation.compare import compare
from hier_ssl.worker import (
    CheckedWorker,
    PaperGoToPoint,
    PerturbedWorker,
    WorkerError,
    check_worker_spec,
    make_worker,
    resolve_worker,
)
from hier_ssl.world.physics import RobotSpec, RobotState

ROBOT, DT = RobotSpec(max_speed=2.0), 0.025
HERE = __name__  # the module's import name, so specs can name the controllers below


class Toward:
    """Commands ``speed`` m/s along the field's x axis towards the sub-goal's x; remembers its resets."""

    def __init__(self, robot: RobotSpec, speed: float = 1.0) -> None:
        self.robot, self.speed, self.resets = robot, speed, []
        self.max_speed = 0.5 * robot.max_speed

    def reset(self, fields: np.ndarray) -> None:
        self.resets.append(np.asarray(fields).tolist())

    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        command = np.zeros((*state.angle.shape, 3))
        command[..., 0] = self.speed * np.sign(subgoal[..., 0] - state.pos[..., 0])
        return command


def make_toward(dt: float, **settings: object) -> Toward:
    """A factory: takes ``dt`` by name and the rest as keywords."""
    worker = Toward(settings["robot"], speed=0.5)
    worker.dt = dt
    return worker


def needs_gain(robot: RobotSpec, gain: float) -> Toward:
    return Toward(robot, gain)


class WrongShape(Toward):
    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        return np.zeros((*state.angle.shape, 2))


class NaNCommand(Toward):
    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        command = super().__call__(state, subgoal)
        command[-1, 0, 2] = np.nan
        return command


class NoReset:
    def __call__(self, state: RobotState, subgoal: np.ndarray) -> np.ndarray:
        return np.zeros((*state.angle.shape, 3))


NOT_A_CLASS = 3


def _state(n: int = 2) -> RobotState:
    return RobotState(np.zeros((n, 1, 2)), np.zeros((n, 1)), np.zeros((n, 1, 2)), np.zeros((n, 1)))


def _subgoal(n: int = 2) -> np.ndarray:
    subgoal = np.zeros((n, 1, 5))
    subgoal[:, 0, 0] = [1.0, -1.0][:n] + [1.0] * max(0, n - 2)
    return subgoal


# -- import specs -------------------------------------------------------------------------------------------


def test_an_import_spec_builds_a_class_with_the_arguments_it_accepts() -> None:
    worker = make_worker(f"{HERE}:Toward", ROBOT, DT)
    assert isinstance(worker, CheckedWorker) and isinstance(worker.worker, Toward)
    assert worker.robot is ROBOT and not hasattr(worker.worker, "dt")  # Toward takes robot, not dt
    assert worker.max_speed == 1.0  # the controller's own attribute reads through
    np.testing.assert_array_equal(worker(_state(), _subgoal())[:, 0, 0], [1.0, -1.0])
    worker.reset(np.array([1]))
    assert worker.worker.resets == [[1]]


def test_an_import_spec_calls_a_factory_with_keywords_and_takes_perturbations() -> None:
    worker = make_worker(f"{HERE}:make_toward+latency=1", ROBOT, DT)
    assert isinstance(worker, PerturbedWorker) and isinstance(worker.worker, CheckedWorker)
    inner = worker.worker.worker
    assert (inner.dt, inner.robot, inner.speed) == (DT, ROBOT, 0.5)
    first, second = worker(_state(), _subgoal()), worker(_state(), _subgoal())
    np.testing.assert_array_equal(first, 0.0)  # one step late: nothing applied yet
    np.testing.assert_array_equal(second[:, 0, 0], [0.5, -0.5])


def test_objects_classes_and_factories_resolve_as_specs_do() -> None:
    obj = Toward(ROBOT)
    checked = resolve_worker(obj, ROBOT, DT)
    assert isinstance(checked, CheckedWorker) and checked.worker is obj
    assert resolve_worker(checked, ROBOT, DT) is checked  # not wrapped twice
    assert f"{HERE}:Toward" in str(resolve_worker(obj, ROBOT, DT))
    assert isinstance(resolve_worker(Toward, ROBOT, DT).worker, Toward)
    assert resolve_worker(make_toward, ROBOT, DT).worker.dt == DT
    assert isinstance(resolve_worker("paper", ROBOT, DT), PaperGoToPoint)
    assert isinstance(resolve_worker(f"{HERE}:Toward", ROBOT, DT).worker, Toward)


def test_an_imported_worker_drives_as_the_built_in_one() -> None:
    # The paper's own controller named by its import spec: the check changes nothing it commands.
    spec = "hier_ssl.worker.scripted:PaperGoToPoint"
    imported, builtin = compare(["sampling"], task="obstacle", workers=[spec, "paper"], episodes=12, seed=4)
    assert imported.env.worker == spec and imported.record["worker"] == spec
    for key in ("success_rate", "collision_rate", "episode_length", "cpad"):
        assert imported.record[key] == builtin.record[key], key


def test_config_validation_accepts_import_specs_and_names_the_key_when_they_fail() -> None:
    assert EnvConfig(worker=f"{HERE}:Toward+noise=0.1").worker == f"{HERE}:Toward+noise=0.1"
    cases = {
        "no_such_module_xyz:Ctrl": "cannot import 'no_such_module_xyz' (ModuleNotFoundError",
        f"{HERE}:Missing": f"{HERE!r} has no attribute 'Missing'",
        f"{HERE}:NOT_A_CLASS": "names a int object; expected a class or a factory function",
        f"{HERE}:Toward+gain=2": "unknown perturbation 'gain'",
    }
    for spec, message in cases.items():
        with pytest.raises(ConfigError) as err:
            parse_config({"env": {"worker": spec}})
        assert str(err.value).startswith("env.worker: ") and message in str(err.value), spec


def test_a_module_that_fails_on_import_is_one_error_naming_the_worker(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "broken_controller_xyz.py").write_text("raise RuntimeError('no robot firmware here')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(WorkerError, match=r"worker 'broken_controller_xyz:C': cannot import .*firmware"):
        check_worker_spec("broken_controller_xyz:C")
    sys.modules.pop("broken_controller_xyz", None)


def test_bad_construction_and_bad_objects_name_the_worker() -> None:
    with pytest.raises(WorkerError, match=rf"worker '{HERE}:needs_gain': needs_gain\(robot=...\) failed"):
        make_worker(f"{HERE}:needs_gain", ROBOT, DT)
    with pytest.raises(WorkerError, match=rf"worker '{HERE}:NoReset': got a NoReset without reset"):
        resolve_worker(NoReset(), ROBOT, DT)
    with pytest.raises(WorkerError, match="without __call__ or reset"):
        resolve_worker(object(), ROBOT, DT)


# -- the check at every step --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "message"),
    [
        ("WrongShape", r"returned commands of shape \(3, 1, 2\); expected \(3, 1, 3\)"),
        ("NaNCommand", r"returned a non-finite command \[-?[01].0, 0.0, nan\] \(field 2, robot 0\)"),
    ],
)
def test_bad_commands_stop_the_step_with_one_error_naming_the_worker(name: str, message: str) -> None:
    core = HierarchicalCore(EnvConfig(worker=f"{HERE}:{name}"), 3)
    core.reset(0)
    with pytest.raises(WorkerError, match=rf"worker '{HERE}:{name}' {message}"):
        core.step(np.zeros((3, 1, core.act_dim)))


def test_a_worker_returning_no_numbers_is_named() -> None:
    class Words(Toward):
        def __call__(self, state: RobotState, subgoal: np.ndarray) -> object:
            return "forward"

    with pytest.raises(WorkerError, match="returned a str, not an array of numbers"):
        resolve_worker(Words(ROBOT), ROBOT, DT)(_state(), _subgoal())


def test_eval_command_puts_an_imported_worker_in_the_matrix(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["eval", "direct", "--task", "proposed", "--episodes", "4", "--out", str(tmp_path)]
    assert cli.main([*argv, "--worker", f"{HERE}:Toward", "--worker", "paper"]) == 0
    out = capsys.readouterr().out
    assert f"| direct | {HERE}:Toward |" in out and "| direct | paper |" in out
    with pytest.raises(SystemExit) as exit_info:
        cli.main([*argv, "--worker", f"{HERE}:Missing"])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and err.count("\n") == 1 and f"worker '{HERE}:Missing'" in err
