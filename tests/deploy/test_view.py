"""The deploy view: the core's own observation, decoding and worker on tracked robots, and an exported
file that decides as the run it came from."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from hier_ssl.deploy.bench import untrained_export
from hier_ssl.deploy.controller import Controller
from hier_ssl.deploy.tracker import Tracker
from hier_ssl.deploy.view import DeployView, load_exported, manager_task
from hier_ssl.deploy.wire import Detection, DetectionFrame
from hier_ssl.envs import task_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.game.referee import HALT, STOP, referee_state
from hier_ssl.policies.export import export_manager


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Each task's untrained run, exported as TorchScript (manager.pt) and ONNX (manager.onnx)."""
    folder = tmp_path_factory.mktemp("runs")
    files = {task: untrained_export(folder, task) for task in ("obstacle", "crossing")}
    for exported in files.values():
        export_manager(exported.parent, "onnx")
    return files


def _rows(count: int, seed: int = 0) -> np.ndarray:
    """Tracked rows (count, 6): x, y, angle, vx, vy, w inside the paper field."""
    rng = np.random.default_rng(seed)
    return np.concatenate(
        [
            rng.uniform((-2.5, -1.5), (2.5, 1.5), (count, 2)),
            rng.uniform(-np.pi, np.pi, (count, 1)),
            rng.uniform(-1, 1, (count, 2)),
            rng.uniform(-2, 2, (count, 1)),
        ],
        axis=1,
    )


def test_the_observation_is_the_cores_own_of_the_same_robots() -> None:
    config = manager_task("sampling", "obstacle")
    view = DeployView("sampling", 1, config)
    rows = _rows(1 + view.k)
    view.target[0, 0] = [1.0, 0.5, 0.3, 0.0, 0.0]
    state = view.state(rows, view.fields(rows))
    core = HierarchicalCore(config, num_fields=1, autoreset=False)
    core.reset(seed=0)
    core.world.set_state([0], state.pos, state.angle, state.vel, state.ang_vel)
    core.target[0, 0] = view.target[0, 0]
    np.testing.assert_array_equal(view.core.observe(state=state), core.observe())


def test_each_robot_of_a_one_robot_manager_sees_its_nearest_others() -> None:
    view = DeployView("sampling", 2, manager_task("sampling", "obstacle"))
    assert (view.n, view.m) == (2, 1)
    rows = np.zeros((5, 6))
    rows[:, 0] = [-2.0, 2.0, -1.5, 1.0, 0.0]  # robots 0 and 1 controlled, 2..4 others, all on y = 0
    rows[3, :] = np.nan  # an other robot not seen
    fields = view.fields(rows)
    # Robot 0 (at -2) has robot 2 (at -1.5) nearest, robot 1 (at 2) robot 4 (at 0); with no other robot
    # seen, each has its teammate: a teammate is an obstacle to a robot in a field of its own.
    np.testing.assert_array_equal(fields.others[:, 0], [2, 4])
    rows[2:, :] = np.nan
    np.testing.assert_array_equal(view.fields(rows).others[:, 0], [1, 0])
    state = view.state(rows, view.fields(rows))
    assert np.isfinite(state.pos).all()


def test_missing_robots_stand_in_the_far_corner() -> None:
    view = DeployView("sampling", 1, manager_task("sampling", "obstacle"))
    rows = np.array([[1.0, 0.5, 0.0, 0.0, 0.0, 0.0]])  # nobody else seen
    state = view.state(rows, view.fields(rows))
    if view.k:
        np.testing.assert_allclose(state.pos[0, 1], -view.reach)
        assert (state.vel[0, 1] == 0).all()


@pytest.mark.parametrize("suffix", [".pt", ".onnx"])
@pytest.mark.parametrize(("task", "robots"), [("obstacle", 2), ("crossing", 6)])
def test_an_exported_file_decides_as_its_run(
    runs: dict[str, Path], task: str, robots: int, suffix: str
) -> None:
    exported = runs[task].with_suffix(suffix)
    run = str(exported.parent)
    config = manager_task(run)
    by_run, by_file = (
        DeployView(run, robots, config),
        DeployView(str(exported), robots, manager_task(str(exported))),
    )
    assert (by_run.n, by_run.m, by_run.k) == (by_file.n, by_file.m, by_file.k)
    rows = _rows(robots + 3, seed=1)
    rng = np.random.default_rng(2)
    for view in (by_run, by_file):
        view.target[:] = np.concatenate(
            [rng.uniform((-2, -1.5), (2, 1.5), (robots, 2)), np.zeros((robots, 3))], 1
        ).reshape(view.target.shape)
        rng = np.random.default_rng(2)
        state = view.state(rows, view.fields(rows))
        view.decide(state, np.ones((view.n, view.m), dtype=bool))
    np.testing.assert_allclose(by_file.subgoal[..., 0:2], by_run.subgoal[..., 0:2], atol=1e-4)
    turn = np.angle(np.exp(1j * (by_file.subgoal[..., 2] - by_run.subgoal[..., 2])))
    np.testing.assert_allclose(turn, 0.0, atol=1e-3)
    np.testing.assert_allclose(by_file.commands(state), by_run.commands(state), atol=1e-3)


def test_only_live_robots_decide() -> None:
    view = DeployView("direct", 2, manager_task("direct", "proposed"))
    view.target[:, 0] = [[1.0, 1.0, 0.0, 0, 0], [-1.0, -1.0, 0.0, 0, 0]]
    rows = _rows(2)
    before = view.subgoal.copy()
    view.decide(view.state(rows, view.fields(rows)), np.array([[True], [False]]))
    np.testing.assert_allclose(view.subgoal[0, 0, 0:2], [1.0, 1.0])
    np.testing.assert_array_equal(view.subgoal[1], before[1])


def test_unknown_managers_and_counts_are_named() -> None:
    with pytest.raises(ValueError, match="neither a planner"):
        manager_task("no-such-run")
    with pytest.raises(ValueError, match=r"\.pt or \.onnx"):
        load_exported("manager.bin")
    assert (
        DeployView("sampling", 4, task_config("formation", num_agents=6)).m == 4
    )  # a scenario takes any count


def test_an_onnx_manager_without_onnxruntime_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "onnxruntime", None)  # as on the base install
    with pytest.raises(ValueError, match=r"runs on onnxruntime: pip install -e '\.\[export\]'"):
        load_exported("manager.onnx")


def test_an_onnx_manager_drives_the_controller_as_its_torchscript_twin_and_its_run(
    runs: dict[str, Path],
) -> None:
    # Two controlled robots and two others driving across, seen every period for 20 periods (decisions at
    # periods 0 and 16): the commands of the three managers agree.
    exported = runs["obstacle"]
    managers = [str(exported.parent), str(exported), str(exported.with_suffix(".onnx"))]
    controllers = [
        Controller(DeployView(manager, 2, manager_task(manager)), Tracker(), "blue", [0, 1])
        for manager in managers
    ]
    commands = []
    for controller in controllers:
        controller.set_target(0, [1.5, 0.5, 0.0])
        controller.set_target(1, [-1.5, -0.5, 1.0])
        sent = []
        for k in range(20):
            t = k * 0.025
            seen = (
                Detection("blue", 0, -1.5 + 0.02 * k, 0.0, 0.0),
                Detection("blue", 1, 1.5 - 0.02 * k, 0.2, 3.0),
                Detection("yellow", 0, 0.0, -1.0 + 0.03 * k, 1.57),
                Detection("yellow", 1, 0.5, 1.0, 0.0),
            )
            controller.on_frame(DetectionFrame(t, t, 0, seen), arrival=t)
            sent.append([c[1:] for c in controller.tick(t + 0.001)])
        commands.append(np.array(sent))
    assert np.abs(commands[0]).max() > 0.1  # the robots drive
    # ONNX against TorchScript: float32 sub-goals whose rounding the heading controller multiplies (a CI
    # run saw 1.3e-4 rad/s on a turn of 5.07 rad/s), so relative as well as absolute.
    np.testing.assert_allclose(commands[2], commands[1], rtol=1e-4, atol=1e-4)
    np.testing.assert_allclose(commands[2], commands[0], atol=1e-3)  # and against the run directory


def test_a_game_scenario_observes_the_referee_received_and_the_ball_tracked() -> None:
    config = manager_task("direct", "game_stop")
    view = DeployView("direct", 6, config)
    field = view.field
    before = view.core.observe()
    view.set_game(referee_state(STOP, field, keeper=(2, 0), blue_on_positive_half=True), (1.0, -0.5))
    scenario = view.core.scenario
    assert scenario.referee.command.tolist() == [STOP] and scenario.referee.keeper.tolist() == [[2, 0]]
    np.testing.assert_allclose(view.core.world.ball.pos[0, 0], (1.0, -0.5))
    assert not np.array_equal(view.core.observe(), before)  # the game's columns read them
    view.set_game(referee_state(HALT, field, keeper=(2, 0)), None)  # no ball seen: it stays where it was
    np.testing.assert_allclose(view.core.world.ball.pos[0, 0], (1.0, -0.5))


def test_a_planner_with_settings_deploys_as_its_name_says() -> None:
    config = manager_task("sampling+trapped=brake", "obstacle")
    assert config.frame_skip == manager_task("sampling", "obstacle").frame_skip  # a planner's task
    view = DeployView("sampling+trapped=brake", 1, config)
    assert view.planner and view.policy.trapped == "brake"
