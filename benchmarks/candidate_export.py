"""Measurement, not CI: an ``algo: candidates`` run's exported files against its Python policy.

1. Agreement: plays held-out episodes (seed ``--seed``, then the next ones) with the Python policy
   (``load_policy``) until ``--decisions`` decisions are made; at every decision the TorchScript and the ONNX
   file (``hier-ssl export``) are called on the same robots' raw states (``exported_rows``, as ``hier-ssl
   deploy`` calls them) and their sub-goals compared with the Python policy's (its action decoded). A
   disagreement is a sub-goal more than 1 mm from the Python one; for each, the gap between the Python
   network's two highest logits is reported, and whether the Python policy makes the file's choice on the
   observation of the float32 raw state the file reads (the environment's is of the float64 state): then
   the input's rounding moved a threshold (a flag, an order) of the candidates' features.
2. Held out: ``--episodes`` episodes from seed ``--seed`` played by the Python policy and by each file (its
   sub-goal encoded as the task's action): success and collision rates, median length in control steps.

Run: python benchmarks/candidate_export.py RUN_DIR [--decisions 100000] [--episodes 1000] [--seed 7]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from hier_ssl.checkpoints.actor import run_config
from hier_ssl.deploy.view import exported_rows, load_exported
from hier_ssl.envs import make_scenario
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.play import play
from hier_ssl.manager import decode_subgoal, encode_subgoal
from hier_ssl.policies.actor import load_candidate_manager, load_policy
from hier_ssl.policies.export import export_manager
from hier_ssl.world.physics import RobotState


class Decisions:
    """A policy for ``play``: the Python policy ``python`` acts, or ``act(obs, raw rows, targets)`` where
    given; each exported file of ``files`` is asked the same question. The sub-goals of every decision are
    kept, (D, 5) per name, with the observations."""

    def __init__(self, core: HierarchicalCore, python, files: dict, act=None) -> None:
        self.core, self.python, self.files, self.act = core, python, files, act
        self.seen: dict[str, list[np.ndarray]] = {
            name: [] for name in ["python", "obs", "obs32", "targets", *files]
        }

    def forget(self, count: int) -> None:
        """Nothing to forget: the protocol gives the rows' robots, which the raw states need."""

    def __call__(self, obs: np.ndarray, rows: np.ndarray) -> np.ndarray:
        core = self.core
        raw = exported_rows(core.target, core.world.state, core.num_agents)[rows]
        target = core.target.reshape(-1, 5)[rows]
        if self.act is not None:
            return self.act(obs, raw, target)
        action = self.python(obs)
        self.seen["python"].append(_decode(core, action, target))
        self.seen["obs"].append(obs)
        self.seen["obs32"].append(_rounded_observation(core)[rows])
        self.seen["targets"].append(target)
        for name, call in self.files.items():
            self.seen[name].append(call(raw))
        return action


def _rounded_observation(core: HierarchicalCore) -> np.ndarray:
    """Every robot's observation (N * M, O) of the state and targets rounded to float32, as a file reads
    them."""
    state = core.world.state
    parts = (state.pos, state.angle, state.vel, state.ang_vel)
    rounded = RobotState(*(part.astype(np.float32).astype(np.float64) for part in parts))
    target = core.target.copy()
    core.target[:] = target.astype(np.float32)
    try:
        return core.observe(state=rounded).reshape(-1, core.obs_dim)
    finally:
        core.target[:] = target


def _decode(core: HierarchicalCore, action: np.ndarray, target: np.ndarray) -> np.ndarray:
    env, task = core.config, make_scenario(core.config)
    s = task.scales
    return decode_subgoal(
        action, env.action_form, s["half_length"], s["half_width"], s["max_v"], task.zero_velocity,
        env.action_frame, target,
    )  # fmt: skip


def _encode(core: HierarchicalCore, subgoal: np.ndarray, target: np.ndarray) -> np.ndarray:
    env, s = core.config, make_scenario(core.config).scales
    return encode_subgoal(
        subgoal.astype(np.float64), env.action_form, s["half_length"], s["half_width"], s["max_v"],
        env.action_frame, target,
    )  # fmt: skip


def agreement(run_dir: str, files: dict, decisions: int, seed: int) -> None:
    config = run_config(run_dir).task_config
    policy = load_policy(run_dir)
    manager = load_candidate_manager(run_dir)
    batch, seen, began, first = 500, None, time.perf_counter(), seed
    while seen is None or len(np.concatenate(seen.seen["python"])) < decisions:
        core = HierarchicalCore(config, batch, autoreset=False)
        recorder = Decisions(core, policy, files)
        play(core, recorder, seed)
        seed += 1
        if seen is None:
            seen = recorder
        else:
            for key, parts in recorder.seen.items():
                seen.seen[key].extend(parts)
    assert seen is not None
    want = np.concatenate(seen.seen["python"])[:decisions]
    obs = np.concatenate(seen.seen["obs"])[:decisions]
    obs32 = np.concatenate(seen.seen["obs32"])[:decisions]
    targets = np.concatenate(seen.seen["targets"])[:decisions]
    print(f"{run_dir}: {len(want)} decisions of held-out episodes (seeds {first}-{seed - 1}, {batch} each), "
          f"{time.perf_counter() - began:.0f} s")  # fmt: skip
    for name in files:
        got = np.concatenate(seen.seen[name])[:decisions]
        other = np.flatnonzero(np.abs(got[:, 0:2] - want[:, 0:2]).max(1) > 1e-3)
        with torch.no_grad():
            x = torch.from_numpy(obs[other])
            top = manager.net(manager.inputs(x, manager.geometry(x))).topk(2, 1).values
        gaps = (top[:, 0] - top[:, 1]).numpy()
        core = HierarchicalCore(config, 1, autoreset=False)
        rounded = _decode(core, policy(obs32[other]), targets[other]) if len(other) else got[other]
        explained = int((np.abs(rounded[:, 0:2] - got[other, 0:2]).max(1) <= 1e-3).sum())
        rate = 100 * (1 - len(other) / len(want))
        listed = np.array2string(gaps, precision=6, max_line_width=200)
        print(f"  {name:12s} same candidate {rate:.3f} % ({len(other)} of {len(want)} differ); "
              f"their top-two logit gaps: {listed}; the Python policy makes the file's choice on the "
              f"rounded state's observation in {explained} of them")  # fmt: skip


def held_out(run_dir: str, files: dict, episodes: int, seed: int) -> None:
    config = run_config(run_dir).task_config
    policy = load_policy(run_dir)
    print(f"held out: {episodes} episodes from seed {seed}")
    players = {"python": None, **files}
    for name, call in players.items():
        core = HierarchicalCore(config, episodes, autoreset=False)

        def act(obs, raw, target, call=call, core=core):
            return policy(obs) if call is None else _encode(core, call(raw), target)

        ends = play(core, Decisions(core, policy, {}, act), seed)
        success, collision = 100 * ends["success"].mean(), 100 * ends["collision"].mean()
        print(f"  {name:12s} success {success:.1f} %, collisions {collision:.1f} %, "
              f"median length {np.median(ends['length']):.1f}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("--decisions", type=int, default=100_000)
    parser.add_argument("--episodes", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        files = {}
        for fmt, suffix in (("torchscript", ".pt"), ("onnx", ".onnx")):
            path = export_manager(args.run_dir, fmt, Path(tmp) / f"manager{suffix}")
            files[fmt] = load_exported(path)[0]
        if args.decisions:
            agreement(args.run_dir, files, args.decisions, args.seed)
        if args.episodes:
            held_out(args.run_dir, files, args.episodes, args.seed)


if __name__ == "__main__":
    main()
