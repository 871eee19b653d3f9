"""Every script of examples/ runs as the docs show it, with budgets of seconds, and prints what it says."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import torch

from hier_ssl.checkpoints.actor import BEST_ACTOR_FILE, CONFIG_FILE
from hier_ssl.checkpoints.tensors import save_checkpoint
from hier_ssl.config import dump_config
from hier_ssl.config.files import load_yaml
from hier_ssl.envs import parse_config, task_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.play import play
from hier_ssl.evaluation.compare import load_manager
from hier_ssl.policies.candidate_nets import build_chooser

EXAMPLES = Path(__file__).parents[1] / "examples"


def _run(script: str, *args: str, cwd: Path) -> list[str]:
    """The script's printed lines; it must exit 0."""
    # One torch thread: two OpenMP threads stall badly on a busy 2-core CPU (tests/conftest.py).
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "OMP_NUM_THREADS": "1"}
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / script), *args], cwd=cwd, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


def _example(name: str) -> object:
    """The module of examples/``name``.py, imported as the scripts import each other (from examples/)."""
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(EXAMPLES))
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(EXAMPLES))
    return module


def test_every_example_is_tested_and_shown_in_the_docs() -> None:
    scripts = sorted(path.name for path in EXAMPLES.glob("*.py"))
    tested = set(re.findall(r'_run\(\s*"(\w+\.py)"', Path(__file__).read_text()))
    # Shown: each is a snippet the page includes whole (a formatter once broke them into `--8 < --"..."`,
    # which the docs then printed as it stood).
    shown = set(
        re.findall(
            r'^--8<-- "examples/(\w+\.py)"$', (EXAMPLES.parent / "docs" / "examples.md").read_text(), re.M
        )
    )
    assert scripts and set(scripts) == shown
    assert set(scripts) - {"run_exported_manager.py"} == tested  # that one is run by export_onnx.py


def test_pettingzoo_loop(tmp_path: Path) -> None:
    lines = _run("pettingzoo_loop.py", "--episodes", "3", cwd=tmp_path)
    assert lines[0] == "Passed Parallel API test"
    episodes = [
        re.fullmatch(r"episode (\d): success ([01]) collision ([01]) length (\d+) .*", x) for x in lines[1:]
    ]
    assert [m.group(1) for m in episodes] == ["0", "1", "2"]
    assert sum(m.group(2) == "1" for m in episodes) >= 2  # the sampling planner passes the obstacle


def test_sb3_on_a_gymnasium_id(tmp_path: Path) -> None:
    lines = _run("sb3_gymnasium.py", "--steps", "200", "--episodes", "2", cwd=tmp_path)
    assert [line.split(":")[0] for line in lines[:2]] == ["episode 0", "episode 1"]
    assert all(1 <= int(line.split()[2]) <= 75 for line in lines[:2])  # the TimeLimit at frame skip 16
    assert lines[2].startswith("success rate ") and lines[2].endswith("over 2 episodes")


def test_custom_worker(tmp_path: Path) -> None:
    lines = _run("custom_worker.py", "--episodes", "20", cwd=tmp_path)
    rows = {(words[0], words[1]): float(words[3]) for words in map(str.split, lines)}
    assert set(rows) == {
        (manager, worker)
        for manager in ("direct", "sampling")
        for worker in ("__main__:Proportional", "paper", "paper+latency=4")
    }
    # Past the obstacle the planner succeeds with either worker; driving straight at the target does not.
    assert rows["sampling", "__main__:Proportional"] >= 0.9 and rows["sampling", "paper"] >= 0.9
    assert rows["direct", "paper"] < rows["sampling", "paper"]


def test_shared_policy_scenario(tmp_path: Path) -> None:
    lines = _run("shared_policy_scenario.py", "--robots", "3", "--episodes", "2", cwd=tmp_path)
    assert len(lines) == 2
    for episode, line in enumerate(lines):
        # 7 columns per robot + 13 per controlled robot: 3 robots, all controlled (crossing has no obstacles)
        assert line.startswith(f"episode {episode}: state (60,), team return ")
        outcomes = dict(part.split() for part in line.split(", ")[2:])
        assert set(outcomes) == {"manager_0", "manager_1", "manager_2"}
        assert set(outcomes.values()) <= {"success", "collision", "timeout"}


def test_stuck_robots(tmp_path: Path) -> None:
    config = EXAMPLES.parent / "configs" / "scenarios" / "formation_residual.yaml"
    lines = _run(
        "stuck_robots.py",
        "sampling",
        "--scenario",
        str(config),
        "--episodes",
        "30",
        "--seed",
        "8",
        cwd=tmp_path,
    )
    counts = dict(zip(*[iter(lines[0].replace("timed out", "timed_out").split())] * 2, strict=True))
    robots, arrived, collided, fouled, late = map(int, counts.values())
    assert robots == 180 and arrived + collided + fouled + late == robots and arrived >= 170
    rest = lines[1:]
    if collided:
        met = re.match(r"collided nearest a teammate (\d+), another robot (\d+) ", rest.pop(0))
        assert int(met[1]) + int(met[2]) == collided
    if late:
        assert int(rest[0].split()[1]) <= late
        parked = [int(x) for x in rest[1].split("[")[1].split("]")[0].split(",")]
        assert sum(parked) == late


def test_stuck_robots_counts_jumps_in_the_window_only() -> None:
    module = _example("stuck_robots")
    # One field of two robots: robot 0's sub-goal flips between two points 0.9 m apart, robot 1's stays.
    # An opponent (index 2) stands next to robot 1, robot 0 is nearest robot 1 and closes on it at 1 m/s.
    state = SimpleNamespace(pos=np.array([[[0.0, 0.0], [1.0, 0.0], [1.2, 0.0]]]), vel=np.zeros((1, 3, 2)))
    state.vel[0, 0] = [1.0, 0.0]
    core = SimpleNamespace(subgoal=np.zeros((1, 2, 5)), state=state)
    watched = module.Watched(lambda obs: obs, core, jump=0.45, limit=20, window=8)
    watched.forget(2)
    for step in range(20):
        core.subgoal[0, :, 0:2] = [[0.45 * (-1) ** step, 0.0], [1.0, 1.0]]
        watched(np.zeros((2, 3)), rows=np.arange(2))
    assert watched.jumps.tolist() == [8, 0]
    assert watched.teammate.tolist() == [True, False] and watched.closing.tolist() == [1.0, 0.0]


def test_foresight(tmp_path: Path) -> None:
    # Seed 35's two STOP fields: `sampling` loses one robot of twelve at step 73 (a collision).
    config = EXAMPLES.parent / "configs" / "game" / "stop_residual.yaml"
    lines = _run(
        "foresight.py",
        "--scenario",
        str(config),
        "--episodes",
        "2",
        "--seed",
        "35",
        "--every",
        "10",
        cwd=tmp_path,
    )
    figures = [
        re.match(r"(\w+): robots 12 success ([\d.]+) % fouls\+collisions [\d.]+ % \((\d+)\)", x)
        for x in lines
    ]
    assert [f[1] for f in figures] == ["sampling", "foresight"]
    # The script reports what the project's one loop counts.
    ends = play(
        HierarchicalCore(task_config(config), 2, autoreset=False),
        load_manager("sampling", task_config(config)),
        35,
    )
    lost = ends["collision"] | (ends["foul"] > 0)
    assert (
        (float(figures[0][2]), int(figures[0][3]))
        == (round(100 * ends["success"].mean(), 2), lost.sum())
        == (83.33, 1)
    )
    # The copies foresee the collision and a changed sub-goal avoids it; braking alone does too.
    assert int(figures[1][3]) == 0 and int(lines[1].split()[-1]) >= 1
    braked = _run("foresight.py", "--scenario", str(config), *("--episodes", "2", "--seed", "35"),
                  *("--every", "10", "--way-out", "brake"), cwd=tmp_path)  # fmt: skip
    assert braked[0] == lines[0] and re.search(r"\(0\) .* sub-goals changed [1-9]\d*$", braked[1])
    # Braking offers the robot's own position alone, where the options are the planner's other candidates.
    module = _example("foresight")
    planner = load_manager("sampling", task_config(config))
    obs = HierarchicalCore(task_config(config), 2, autoreset=False).reset(35).reshape(12, -1)
    plan = module.Plan(planner, (2, 6))
    poses, index = plan.alternatives(obs, 6, wait=True)
    assert poses.shape == (12, 1, 5) and (index == -1).all()
    assert np.allclose(poses[:, 0, 0:2], planner.read_ruled(obs)[0].robot_pos)
    assert (plan.alternatives(obs, 6)[1] >= 0).any()


def test_foresight_plays_a_trained_manager(tmp_path: Path) -> None:
    # A STOP residual with a random correction chooses otherwise than `sampling`: the script plays it, alone
    # as `play` does and in its copies, the planner only reading the scene for the ways out.
    config = parse_config(load_yaml(EXAMPLES.parent / "configs" / "game" / "stop_residual.yaml"))
    torch.manual_seed(0)
    net = build_chooser("residual", (16, 16), None, 0, config.candidates.tau, 0.0, False)
    torch.nn.init.normal_(net.body[-1].weight, std=10.0)
    run = tmp_path / "run"
    run.mkdir()
    (run / CONFIG_FILE).write_text(dump_config(config))
    save_checkpoint({"net": net.state_dict(), "step": 1}, run / BEST_ACTOR_FILE)
    scenario = ("--scenario", str(EXAMPLES.parent / "configs" / "game" / "stop_residual.yaml"))
    look = (*scenario, "--episodes", "2", "--seed", "35", "--every", "10", "--way-out", "brake")
    lines = _run("foresight.py", *look, "--manager", str(run), "--policy", "best", cwd=tmp_path)
    ends = play(
        HierarchicalCore(config.task_config, 2, autoreset=False),
        load_manager(run, config.task_config, "best"),
        35,
    )
    module = _example("foresight")
    assert lines[0] == module.summary(f"{run} (best)", ends, config.task_config.dt)
    planner = load_manager("sampling", config.task_config)
    alone = play(HierarchicalCore(config.task_config, 2, autoreset=False), planner, 35)
    assert lines[0].split(": ", 1)[1] != module.summary("", alone, config.task_config.dt).split(": ", 1)[1]
    # The copies play it too: a plan copied for a copy of the world keeps the manager.
    decide = load_manager(run, config.task_config, "best")
    assert module.Plan(planner, (2, 6), decide).copy().decide is decide
    assert re.match(r"foresight: robots 12 .* sub-goals changed \d+$", lines[1])
    for manager, policy, message in [
        (run, "final", f"--manager {run}: {run}: no final checkpoint"),
        (
            tmp_path / "none",
            "best",
            f"--manager {tmp_path / 'none'}: manager '{tmp_path / 'none'}' is neither",
        ),
    ]:
        bad = subprocess.run(
            [
                sys.executable,
                str(EXAMPLES / "foresight.py"),
                *look,
                "--manager",
                str(manager),
                "--policy",
                policy,
            ],
            cwd=tmp_path,
            capture_output=True,
            text=True,
        )
        assert bad.returncode == 2 and message in bad.stderr


def test_distill(tmp_path: Path) -> None:
    # Seed 100's four ball placement fields: the teacher's copies see robots lost and options that keep them.
    config = str(EXAMPLES.parent / "configs" / "game" / "ball_placement_residual.yaml")
    scenario, labels = ("--scenario", config), str(tmp_path / "labels.npz")
    rec = _run(
        "distill.py", "record", *scenario, "--seeds", "100", "--episodes", "4", "--out", labels, cwd=tmp_path
    )
    # Recording leaves the teacher's play as foresight.py plays it.
    alone = _run("foresight.py", *scenario, "--episodes", "4", "--seed", "100", cwd=tmp_path)
    assert rec[0].split(": ", 1)[1] == alone[1].split(": ", 1)[1]
    saved = np.load(labels)["labels"]
    lost, kept = (int(x) for x in re.search(r"lost (\d+) kept (\d+)", rec[1]).groups())
    assert ((saved == 1).sum(), (saved == 0).sum()) == (lost, kept) and lost > 0
    # At some state the planner's choice lost the robot in a copy, and another sub-goal offered kept it.
    top = np.load(labels)["inputs"][..., 1].argmax(1)
    risky = saved[np.arange(len(saved)), top] == 1
    assert (saved[risky] == 0).any()
    lines = _run(
        "distill.py",
        "play",
        *scenario,
        "--labels",
        labels,
        "--val",
        labels,
        "--episodes",
        "2",
        "--seed",
        "35",
        "--epochs",
        "300",
        cwd=tmp_path,
    )
    # Fitted long enough, the network sorts the states it was fitted on.
    assert float(re.search(r"state AUC ([\d.]+)", lines[0])[1]) >= 0.9
    ends = play(
        HierarchicalCore(task_config(config), 2, autoreset=False),
        load_manager("sampling", task_config(config)),
        35,
    )
    robots = re.match(r"sampling: robots 12 success ([\d.]+) %", lines[1])
    assert float(robots[1]) == round(100 * ends["success"].mean(), 2)
    assert re.match(r"student: robots 12 success [\d.]+ % .* sub-goals changed \d+$", lines[2])
    # Over the braking planner, a student that brakes every robot at any risk never lets one move on; one
    # that acts on no risk plays the planner's own figures.
    brake = ("--planner", "sampling+trapped=brake", "--way-out", "brake", "--episodes", "2", "--seed", "35")
    common = (*scenario, "--labels", labels, "--epochs", "30", *brake)
    always = _run("distill.py", "play", *common, "--threshold", "0", cwd=tmp_path)
    never = _run("distill.py", "play", *common, "--threshold", "1", cwd=tmp_path)
    assert always[0].startswith("sampling+trapped=brake: robots 12 success")
    assert re.match(r"student: robots 12 success 0.00 % .* sub-goals changed [1-9]\d*$", always[1])
    assert never[1] == never[0].replace("sampling+trapped=brake", "student") + " sub-goals changed 0"


def test_opponent_roles(tmp_path: Path) -> None:
    config = str(EXAMPLES.parent / "configs" / "game" / "stop_residual.yaml")
    scenario = ("--scenario", config, "--episodes", "2", "--seed", "35")
    lines = first = _run("opponent_roles.py", *scenario, cwd=tmp_path)
    assert re.match(r"sampling: robots 12 success 83.33 % fouls\+collisions 8.33 % \(1\)", lines[0])
    assert re.match(r"inferred roles: robots 12 success [\d.]+ % .* sub-goals changed \d+$", lines[1])
    # Better than naming every opponent a marker, the commonest role (2 in 5).
    right, looks = re.match(r"roles right ([\d.]+) of (\d+) opponent-looks", lines[2]).groups()
    assert float(right) > 0.5 and int(looks) > 0
    # The scorer learns the hypotheses of the play it is fitted on better than the rule names them.
    lines = _run("opponent_roles.py", *scenario, "--fit-seeds", "36", "--fit-episodes", "4", cwd=tmp_path)
    fitted, rule = map(
        float, re.match(r"scorer fitted on \d+ .*hypothesis ([\d.]+), the rule's ([\d.]+)", lines[0]).groups()
    )
    assert fitted > rule and lines[1] == first[0]


def test_a_marker_is_told_from_the_robot_it_marks() -> None:
    module = _example("opponent_roles")
    # Two of ours standing still, at (0, 1) and (0, -1); the opponents' goal at (3, 0). Opponent 0 drives
    # at 1 m/s for the point 0.4 m goal-side of our robot 1, opponent 1 stands still on the goal-ball line.
    frames, m = 10, 2
    ours = np.array([[0.0, 1.0], [0.0, -1.0]])
    goal, ball = np.array([3.0, 0.0]), np.array([-1.0, 0.0])
    mark = ours[1] + 0.4 * (goal - ours[1]) / np.linalg.norm(goal - ours[1])
    way = (mark - np.array([2.0, -2.0])) / np.linalg.norm(mark - np.array([2.0, -2.0]))
    start = mark - way * 1.5
    pos = np.zeros((1, frames, m + 2, 2))
    vel = np.zeros_like(pos)
    pos[0, :, :m] = ours
    pos[0, :, m] = start + way * np.linspace(0.0, 0.5, frames)[:, None]
    vel[0, :, m] = way
    pos[0, :, m + 1] = goal + 0.5 * (ball - goal)
    play = (pos, vel, np.tile(ball, (1, frames, 1)), goal[None], ("mark", "cover", "ball", "free"), m)
    role, marked, cover, _ = module.infer(*play)
    assert role.tolist() == [[0, 1]] and marked[0, 0] == 1
    assert np.isclose(cover[0, 1], 0.5)
    # The hypotheses: marking robot 0 or 1, cover, ball, free; the truth names the scorer's target column.
    _, owner, _, _ = module.hypotheses(*play)
    team = SimpleNamespace(roles=play[4], role=np.array([[0, 1]]), marked=np.array([[1, 0]]))
    assert module.truth(team, owner).tolist() == [[1, 2]]


def test_export_and_run_without_hier_ssl(tmp_path: Path) -> None:
    lines = _run("export_onnx.py", "--train-steps", "100", "--out", str(tmp_path / "out"), cwd=tmp_path)
    assert (tmp_path / "out" / "manager.onnx").is_file()
    tail = lines[lines.index(next(x for x in lines if x.startswith("exported "))) + 1 :]
    assert tail[0] == "task proposed, frame skip 16, input columns 11"
    for line in tail[1:]:
        x, y = map(float, re.search(r"sub-goal \(([-+.\d]+), ([-+.\d]+)\) m", line).groups())
        assert abs(x) <= 3.0 and abs(y) <= 2.0  # inside the 6 x 4 m field's lines
    assert len(tail) == 4


def test_the_exported_manager_example_names_onnxruntime_where_it_is_missing(tmp_path: Path) -> None:
    # As on the first README line's install, which has no onnxruntime (the export extra installs it).
    blocked = "import sys, runpy; sys.modules['onnxruntime'] = None; sys.argv = ['x', 'm.onnx']; "
    run = f"runpy.run_path({str(EXAMPLES / 'run_exported_manager.py')!r}, run_name='__main__')"
    done = subprocess.run([sys.executable, "-c", blocked + run], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == 1 and "pip install onnxruntime" in done.stderr
    assert "Traceback" not in done.stderr


def test_the_exported_manager_example_runs_a_manager_that_sees_obstacles(tmp_path: Path) -> None:
    # The README's tour exports obstacle/scorer and runs this example on it: 11 + 5 columns, not 11.
    from hier_ssl.envs import parse_config
    from hier_ssl.runs.train import train

    settings = {
        "env": {"task": "obstacle", "frame_skip": 16, "max_steps": 160},
        "num_envs": 4,
        "total_steps": 50,
    }
    train(
        parse_config({**settings, "eval_interval": 50, "eval_episodes": 2}), tmp_path / "run", progress=False
    )
    lines = _run("export_onnx.py", str(tmp_path / "run"), "--out", str(tmp_path / "out"), cwd=tmp_path)
    tail = lines[lines.index(next(x for x in lines if x.startswith("exported "))) + 1 :]
    assert tail[0] == "task obstacle, frame skip 16, input columns 16" and len(tail) == 4


def test_a_warning_reads_where_its_neighbours_meet_it() -> None:
    warning = _example("warning")
    # Two robots 2 m apart driving at each other at 1 m/s meet after 1 s; moving apart, they are nearest now.
    meet = warning.approach(np.array([[2.0, 0.0], [2.0, 0.0]]), np.array([[-2.0, 0.0], [2.0, 0.0]]))
    np.testing.assert_allclose(meet, [[1.0, 0.0], [0.0, 2.0]])
    # Robot 0 at the origin heads along +y for (0, 2); robot 1 at (1, 1) drives along -x; robot 2 is gone.
    pos = np.array([[[0.0, 0.0], [1.0, 1.0], [5.0, 5.0]]])
    vel = np.array([[[0.0, 1.0], [-1.0, 0.0], [0.0, 0.0]]])
    axis = np.array([[[0.0, 1.0], [-1.0, 0.0], [1.0, 0.0]]])
    seen = np.array([[True, True, False]])[:, None] & ~np.eye(3, dtype=bool)
    rel, rel_vel, cpa = (c[0, 0] for c in warning.neighbours(pos, vel, axis, (pos, vel, seen)))
    # In robot 0's frame (along its way, +y; across to its left, -x) robot 1 is 1 m ahead and 1 m to its
    # right, coming at it at (-1, -1) m/s in the field: they meet after 1 s. The missing ones are far ahead
    # and still.
    np.testing.assert_allclose(rel[:2], [1.0, -1.0])
    np.testing.assert_allclose(rel_vel[:2], [-1.0, 1.0])
    np.testing.assert_allclose(cpa[:2], [1.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(rel[2:], [warning.FAR, 0.0] * 2, atol=1e-9)
    assert (rel_vel[2:] == 0).all() and (cpa[2:] == [0.0, warning.FAR] * 2).all()


def test_warning(tmp_path: Path) -> None:
    # Seed 100's four ball placement fields over `sampling`: the copies see robots lost and brakes that keep
    # some; recording does not change the play.
    config = str(EXAMPLES.parent / "configs" / "game" / "ball_placement_residual.yaml")
    common = ("--scenario", config, "--planner", "sampling", "--calm", "0.2")
    labels = str(tmp_path / "w.npz")
    rec = _run(
        "warning.py", "record", *common, "--seeds", "100", "--episodes", "4", "--out", labels, cwd=tmp_path
    )
    ends = play(
        HierarchicalCore(task_config(config), 4, autoreset=False),
        load_manager("sampling", task_config(config)),
        100,
    )
    assert (
        rec[0]
        == f"seed 100: robots 24 success {100 * ends['success'].mean():.2f} %" + rec[0].split("%", 1)[1]
    )
    assert rec[0].endswith(" braked 0")
    saved = np.load(labels)
    risk, keeps = (int(x) for x in re.search(r"at risk (\d+), kept by braking (\d+)", rec[1]).groups())
    assert (saved["risk"].sum(), saved["keeps"].sum()) == (risk, keeps) and risk > keeps > 0
    assert not (saved["keeps"] & ~saved["risk"]).any()
    play_ = ("--labels", labels, "--episodes", "2", "--seed", "35")
    fitted = _run("warning.py", "play", *common, *play_, "--val", labels, "--epochs", "300", cwd=tmp_path)
    # Fitted long enough, the warning sorts the rows it was fitted on.
    assert float(re.search(r"AUC ([\d.]+)", fitted[0])[1]) >= 0.9
    # A warning heeded at no rating plays the planner's own figures; one heeded at any rating brakes.
    never = _run("warning.py", "play", *common, *play_, "--threshold", "1", cwd=tmp_path)
    always = _run(
        "warning.py", "play", *common, *play_, "--threshold", "0", "--brake-speed", "0", cwd=tmp_path
    )
    assert never[1] == never[0].replace("sampling", "warned") + " braked 0"
    assert always[0] == never[0] and re.search(r" braked [1-9]\d*$", always[1]) and always[1] != never[1]


def test_warning_names_a_bad_option(tmp_path: Path) -> None:
    for bad, named in (
        (("record", "--calm", "0"), "--calm must be in (0, 1], got 0.0"),
        (("record", "--brake-speed", "nan"), "--brake-speed must be a speed of at least 0, got nan"),
        (("record", "--hold", "0"), "--hold must be at least 1, got 0"),
        (("play",), "play needs --labels"),
    ):
        done = subprocess.run(
            [sys.executable, str(EXAMPLES / "warning.py"), *bad], cwd=tmp_path, capture_output=True, text=True
        )
        assert done.returncode == 2 and named in done.stderr.splitlines()[-1], done.stderr
