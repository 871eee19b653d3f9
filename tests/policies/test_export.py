from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from hier_ssl import cli
from hier_ssl.config import TrainConfig, dump_config
from hier_ssl.config.files import config_dir, load_yaml
from hier_ssl.config.learners import PPOConfig
from hier_ssl.envs import make_scenario, parse_config, vector_env
from hier_ssl.manager import decode_subgoal, manager_observation
from hier_ssl.manager.neighbours import neighbour_observation
from hier_ssl.policies.actor import load_candidate_manager, load_policy
from hier_ssl.policies.candidate_features import feature_dim
from hier_ssl.policies.candidate_graph import candidate_geometry
from hier_ssl.policies.candidate_nets import build_chooser
from hier_ssl.policies.candidates import candidate_planner
from hier_ssl.policies.export import export_manager, layout
from hier_ssl.policies.networks import SquashedGaussianActor
from hier_ssl.policies.ppo import make_ppo_runner, ppo_policy
from hier_ssl.world.field import FIELDS

STATES = 1000

# Runs in a fresh interpreter that never imports hier_ssl, as a robot's software would: every exported
# file of the session in one process (an interpreter that imports torch takes seconds to start).
_LOAD_AND_RUN = """
import json
import sys
import numpy as np
import onnxruntime
import torch

out = {}
for name, path, states in json.loads(sys.argv[1]):
    x = np.load(states)
    if path.endswith(".onnx"):
        session = onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"])
        out[name] = session.run(["subgoal"], {"state": x})[0]
        out[name + "_meta"] = np.array(session.get_modelmeta().custom_metadata_map["layout"])
    else:
        with torch.no_grad():
            out[name] = torch.jit.load(path)(torch.from_numpy(x)).numpy()
assert not any(name.split(".")[0] == "hier_ssl" for name in sys.modules), "hier_ssl was imported"
np.savez(sys.argv[2], **out)
"""
VARIANTS = {
    # name: (learner, env settings, export formats)
    "ppo_obstacle": (
        "ppo",
        {"task": "obstacle", "obstacles": [{}], "min_start_distance": 0.6},
        ("torchscript", "onnx"),
    ),
    "sac_proposed": ("sac", {"task": "proposed", "frame_skip": 16}, ("torchscript",)),
    "sac_baseline_pose6": ("sac", {"task": "baseline", "action_form": "pose6"}, ("torchscript",)),
    # Relative observation (two obstacles sorted into three slots, one padded) and target-frame sub-goals.
    "sac_obstacle_target_frame": (
        "sac",
        {
            "task": "obstacle",
            "obstacles": [{}, {}],
            "min_start_distance": 0.6,
            "observation": "neighbours",
            "neighbours": 3,
            "action_frame": "target",
        },
        ("torchscript", "onnx"),
    ),
    # The same with the closest-approach columns (hier_ssl.manager.encounter), padding included.
    "sac_obstacle_encounters": (
        "sac",
        {
            "task": "obstacle",
            "obstacles": [{}, {}],
            "min_start_distance": 0.6,
            "observation": "encounters",
            "neighbours": 3,
            "action_frame": "target",
        },
        ("torchscript", "onnx"),
    ),
    # A shared scenario manager: 2 teammates and 2 obstacles in 3 slots, teammate flags read from the input.
    "sac_crossing_shared": (
        "sac",
        {
            "scenario": "crossing",
            "num_agents": 3,
            "num_obstacles": 2,
            "neighbours": 3,
            "action_frame": "target",
        },
        ("torchscript", "onnx"),
    ),
}

# Candidate managers (the planner's candidates, their features and a network in one graph): name ->
# (shipped config, network, export formats).
CANDIDATE_VARIANTS = {
    "scorer_obstacle": ("obstacle/scorer", "scorer", ("torchscript", "onnx")),
    "scorer_crowd": ("scenarios/crowd_scorer", "scorer", ("torchscript", "onnx")),
    "scorer_formation": ("scenarios/formation_scorer", "scorer", ("torchscript", "onnx")),
    "classifier_obstacle": ("obstacle/candidates", "classifier", ("torchscript",)),
}


def _config(algo: str, **task: object) -> TrainConfig:
    section = "scenario" if "scenario" in task else "env"
    return parse_config(
        {"algo": algo, section: task, "sac": {"hidden": [32, 32]}, "ppo": {"hidden": [32, 32]}}
    )


def _others(config: TrainConfig) -> tuple[int, int]:
    """(J, width): the other robots of the exported state and the columns of each."""
    task = make_scenario(config.task_config)
    return task.num_agents - 1 + task.num_obstacles, 5 + int(task.num_agents > 1)


def _sac_run(run_dir: Path, **env: object):
    """A run directory with a random SAC actor; returns its config and the Python policy."""
    config = _config("sac", **env)
    torch.manual_seed(1)
    probe = vector_env(config.task_config, num_envs=1)
    actor = SquashedGaussianActor(probe.num_obs, probe.num_actions, hidden=(32, 32))
    with torch.no_grad():  # a wider spread than the initial weights, so decoding and clipping get exercised
        for p in actor.parameters():
            p.mul_(3.0)
    run_dir.mkdir()
    (run_dir / "config.yaml").write_text(dump_config(config))
    torch.save({"actor": actor.state_dict(), "step": 0}, run_dir / "best_actor.pt")

    def policy(obs: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return actor.deterministic(torch.from_numpy(obs)).numpy()

    return config, policy


def _ppo_run(run_dir: Path, **env: object):
    """A run directory with an rsl-rl PPO checkpoint; returns its config and the Python policy."""
    config = _config("ppo", **env)
    torch.manual_seed(2)
    runner = make_ppo_runner(vector_env(config.env, num_envs=2), PPOConfig(hidden=(32, 32)), log_dir=None)
    with torch.no_grad():
        for p in runner.alg.get_policy().parameters():
            p.mul_(3.0)
    run_dir.mkdir()
    (run_dir / "config.yaml").write_text(dump_config(config))
    runner.save(str(run_dir / "model_7.pt"))
    return config, ppo_policy(runner)


def _candidates_run(run_dir: Path, name: str, network: str):
    """A run directory with a random classifier or scorer over the planner's candidates (its weights
    spread, so the choices differ from state to state); returns its config and the Python policy."""
    config = parse_config({**load_yaml(config_dir() / f"{name}.yaml"), "candidates": {"network": network}})
    geometry = candidate_geometry(config, candidate_planner(config))
    torch.manual_seed(3)
    width = feature_dim(geometry.k) if network == "scorer" else make_scenario(config.task_config).obs_dim
    first = torch.randn(64, geometry.num_candidates, width) * 2.0 + 1.0
    net = build_chooser(
        network, (32, 32), first if network == "scorer" else first[:, 0], geometry.num_candidates
    )
    with torch.no_grad():
        for p in net.parameters():
            p.mul_(3.0)
    run_dir.mkdir()
    (run_dir / "config.yaml").write_text(dump_config(config))
    torch.save({"net": net.state_dict(), "step": 0}, run_dir / "best_actor.pt")
    return config, load_policy(run_dir)


def _logit_gap(run_dir: Path, states: np.ndarray, config: TrainConfig) -> np.ndarray:
    """How far (B,) the Python policy's highest logit is above the next one on ``states``' observations."""
    manager = load_candidate_manager(run_dir)
    obs = torch.from_numpy(_observations(states, config))
    with torch.no_grad():
        top = manager.net(manager.inputs(obs, manager.geometry(obs))).topk(2, 1).values
    return (top[:, 0] - top[:, 1]).numpy()


def _states(config: TrainConfig, seed: int = 0) -> np.ndarray:
    """Raw states, some beyond the field and the speed limits so the observation's clipping matters; a
    teammate column, where there is one, holds 0 or 1 at random."""
    rng = np.random.default_rng(seed)
    j, width = _others(config)
    one = [3.5, 2.5, np.pi, 3.0, 3.0]  # x, y, theta, vx, vy
    scale = np.array(one + [*one, 12.0] + [3.5, 2.5, 3.0, 3.0, 12.0, 1.0][:width] * j)
    states = rng.uniform(-1.0, 1.0, (STATES, len(scale))) * scale
    if width == 6:
        states[:, 16::6] = rng.integers(0, 2, (STATES, j))
    return states.astype(np.float32)


def _observations(states: np.ndarray, config: TrainConfig) -> np.ndarray:
    """The numpy observation builder's manager observations (B, O) of raw states."""
    x, env = states.astype(np.float64), config.task_config
    field = FIELDS[env.field]
    (k, width), rows = _others(config), len(states)
    others = x[:, 11:].reshape(rows, k, width)
    own, scales = (
        (x[:, 0:5], x[:, 5:7], x[:, 7], x[:, 8:10], x[:, 10]),
        {"max_pos": field.max_pos, "max_v": 2.5},
    )
    if env.observation != "paper":
        teammate = others[:, :, 5] > 0.5 if width == 6 else np.zeros((rows, k), dtype=bool)
        encounters = env.observation == "encounters"
        return neighbour_observation(
            *own,
            others[:, :, 0:2],
            others[:, :, 2:4],
            teammate,
            env.neighbours,
            **scales,
            encounters=encounters,
        )
    return manager_observation(*own, others[:, :, 0:2], others[:, :, 2:4], others[:, :, 4], **scales)


def _python_subgoals(states: np.ndarray, config: TrainConfig, policy) -> tuple[np.ndarray, np.ndarray]:
    """The reference: the numpy observation builder, the actor, and ``decode_subgoal``. Returns the
    sub-goals (B, 5) and the length (B,) of the (sin, cos) pair their heading is the angle of."""
    x, env = states.astype(np.float64), config.task_config
    field = FIELDS[env.field]
    obs = _observations(states, config)
    action = np.clip(policy(obs).astype(np.float64), -1.0, 1.0)
    sin, cos = action[:, -2], action[:, -1] + (1.0 if env.action_frame == "target" else 0.0)
    subgoals = decode_subgoal(
        action,
        env.action_form,
        field.half_length,
        field.half_width,
        2.5,
        zero_velocity=env.scenario_name != "baseline",
        frame=env.action_frame,
        target=x[:, 0:5],
    )
    return subgoals, np.hypot(sin, cos)


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """Every variant exported, and run in one fresh interpreter: {variant: (config, states, want, radius,
    got)}."""
    root = tmp_path_factory.mktemp("export")
    jobs, cases = [], {}
    runs = {
        name: ((_ppo_run if algo == "ppo" else _sac_run), env, formats)
        for name, (algo, env, formats) in VARIANTS.items()
    }
    runs |= {
        name: (_candidates_run, {"name": config, "network": network}, formats)
        for name, (config, network, formats) in CANDIDATE_VARIANTS.items()
    }
    for name, (make_run, env, formats) in runs.items():
        run_dir = root / name
        config, policy = make_run(run_dir, **env)
        states = _states(config, seed=len(jobs))
        np.save(root / f"{name}.npy", states)
        for fmt in formats:
            path = export_manager(run_dir, fmt)
            assert not path.with_name(path.name + ".data").exists()  # the weights are inside the file
            jobs.append([f"{name}_{fmt}", str(path), str(root / f"{name}.npy")])
        cases[name] = (config, states, *_python_subgoals(states, config, policy))
        if name in CANDIDATE_VARIANTS:
            cases[name] += (_logit_gap(run_dir, states, config),)
    (root / "load.py").write_text(_LOAD_AND_RUN)
    command = [sys.executable, "-I", str(root / "load.py"), json.dumps(jobs), str(root / "out.npz")]
    subprocess.run(command, check=True, cwd=root)
    got = dict(np.load(root / "out.npz"))
    return {
        name: (*case, {k[len(name) + 1 :]: v for k, v in got.items() if k.startswith(name)})
        for name, case in cases.items()
    }


# The graph runs its actor and decoding in float32: a few units in the last place of the (sin, cos) pair
# its heading is the atan2 of. Those turn the heading by up to ulps / radius, the pair's length: nothing
# on the unit circle, much where the pair is short (in the target frame, cos near -1 makes 1 + cos small).
FLOAT32_ULPS = 32 * float(np.finfo(np.float32).eps)


def _assert_same_subgoals(got: np.ndarray, want: np.ndarray, radius: np.ndarray) -> None:
    assert got.shape == want.shape and got.shape[1] == 5 and got.dtype == np.float32
    np.testing.assert_allclose(got[:, [0, 1, 3, 4]], want[:, [0, 1, 3, 4]], rtol=0, atol=1e-5)
    # Angles compare on the circle: +pi and -pi name the same heading.
    turn = np.angle(np.exp(1j * (got[:, 2].astype(np.float64) - want[:, 2])))
    assert np.all(np.abs(turn) <= 1e-5 + FLOAT32_ULPS / radius), np.abs(turn).max()


@pytest.mark.parametrize("variant", list(VARIANTS))
def test_exported_files_match_the_python_policy(exported: dict, variant: str) -> None:
    config, states, want, radius, got = exported[variant]
    formats = VARIANTS[variant][2]
    assert sorted(k for k in got if not k.endswith("_meta")) == sorted(formats)
    for fmt in formats:
        _assert_same_subgoals(got[fmt], want, radius)
    if "onnx" in formats:
        assert json.loads(str(got["onnx_meta"])) == layout(config)
    j, width = _others(config)
    assert len(layout(config)["input_fields"]) == states.shape[1] == 11 + width * j
    # The Baseline's pose6 sub-goal carries a velocity; the other tasks' sub-goals are at rest.
    assert np.any(want[:, 3:5] != 0) == (config.task_config.scenario_name == "baseline")


@pytest.mark.parametrize("variant", list(CANDIDATE_VARIANTS))
def test_exported_candidate_managers_choose_as_the_python_policy(exported: dict, variant: str) -> None:
    config, states, want, radius, gap, got = exported[variant]
    formats = CANDIDATE_VARIANTS[variant][2]
    assert sorted(k for k in got if not k.endswith("_meta")) == sorted(formats)
    for fmt in formats:
        # The same candidate, so the same sub-goal to the float32 rounding of its action, but where two
        # candidates' logits tie to float32 rounding: the file computes its observation from the raw state
        # and ONNX Runtime its features with kernels of its own, a few units in the last place apart.
        other = np.abs(got[fmt][:, 0:2] - want[:, 0:2]).max(1) > 1e-5
        assert other.sum() <= STATES // 200 and (gap[other] < 1e-4).all(), (fmt, gap[other])
        _assert_same_subgoals(got[fmt][~other], want[~other], radius[~other])
    if "onnx" in formats:
        assert json.loads(str(got["onnx_meta"])) == layout(config)
    # The random network chooses among many candidates, not one slot everywhere.
    offsets = np.round(want[:, 0:2] - states[:, 0:2], 2)
    assert len(np.unique(offsets, axis=0)) > STATES // 4


def test_export_writes_one_file_where_asked(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _sac_run(tmp_path / "run", task="proposed")
    assert export_manager(tmp_path / "run", "torchscript") == tmp_path / "run" / "manager.pt"
    assert capsys.readouterr().err == ""
    export_manager(tmp_path / "run", "torchscript", progress=True)
    assert "export torchscript: step 2/2, tracing and writing manager.pt" in capsys.readouterr().err
    out = export_manager(tmp_path / "run", "torchscript", tmp_path / "deploy" / "m.pt")
    assert sorted(p.name for p in out.parent.iterdir()) == ["m.pt"]
    with pytest.raises(ValueError, match="unknown export format 'tflite'"):
        export_manager(tmp_path / "run", "tflite")


def test_export_command_and_its_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _sac_run(tmp_path / "run", task="proposed")
    assert cli.main(["export", str(tmp_path / "run"), "--out", str(tmp_path / "m.pt")]) == 0
    assert capsys.readouterr().out.startswith(f"wrote {tmp_path / 'm.pt'} (")
    assert cli.main(["export", str(tmp_path / "nowhere")]) == 1
    assert "nowhere: not a run directory" in capsys.readouterr().err
    (tmp_path / "run" / "best_actor.pt").unlink()
    assert cli.main(["export", str(tmp_path / "run")]) == 1
    assert "no best checkpoint (best_actor.pt missing)" in capsys.readouterr().err
    worker_run = tmp_path / "worker"
    worker_run.mkdir()
    (worker_run / "config.yaml").write_text(dump_config(parse_config({"kind": "worker", "algo": "ppo"})))
    assert cli.main(["export", str(worker_run)]) == 1
    assert "model_<iteration>.pt" in capsys.readouterr().err
    bare = tmp_path / "bare"
    bare.mkdir()
    (bare / "config.yaml").write_text(dump_config(parse_config({"scenario": {"scenario": "crossing"}})))
    torch.save({"actor": SquashedGaussianActor(13, 4, hidden=(8, 8)).state_dict()}, bare / "best_actor.pt")
    assert cli.main(["export", str(bare)]) == 1
    assert "actor maps 13 -> 4 values; its config needs 49 -> 4" in capsys.readouterr().err
