"""Measurement, not CI: size and batch-1 inference time of an exported manager on one CPU thread.

Exports RUN_DIR's manager as TorchScript and ONNX into a temporary folder, then times single-state calls
(after 200 warm-up calls): TorchScript through ``torch.jit.load`` under ``torch.inference_mode``,
ONNX through an onnxruntime session with one intra-op thread, and, for reference, the Python path that
``hier_ssl.evaluation.evaluate`` uses (numpy observation builder, actor, ``decode_subgoal``) and the scripted
``sampling`` planner on the same observation (the manager a learned one has to beat, also at batch 1).
Prints one line per path: file size, and the median and 90th percentile time per call. An ``algo:
candidates`` run's file holds its whole decision (the planner's candidates, their features, the classifier
or scorer, the choice); its Python path is the same torch graph called from numpy.

Run: python benchmarks/export_latency.py RUN_DIR [--calls 5000]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from hier_ssl.checkpoints.actor import run_config
from hier_ssl.envs import make_scenario
from hier_ssl.envs.planners import make_planner
from hier_ssl.manager import decode_subgoal, manager_observation
from hier_ssl.manager.neighbours import neighbour_observation
from hier_ssl.policies.actor import load_policy
from hier_ssl.policies.export import export_manager


def _time(call, calls: int) -> tuple[float, float]:
    for _ in range(200):
        call()
    times = np.empty(calls)
    for i in range(calls):
        start = time.perf_counter()
        call()
        times[i] = time.perf_counter() - start
    return float(np.median(times)) * 1e6, float(np.percentile(times, 90)) * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir")
    parser.add_argument("--calls", type=int, default=5000)
    args = parser.parse_args()
    torch.set_num_threads(1)
    import onnxruntime

    config = run_config(args.run_dir)
    policy = load_policy(args.run_dir)
    env, task = config.task_config, make_scenario(config.task_config)
    # The other robots of the exported input: a scenario's teammates (flagged 1) and its obstacles.
    k, teammates = task.num_agents - 1 + task.num_obstacles, task.num_agents > 1
    width = 5 + int(teammates)
    state = np.random.default_rng(0).uniform(-1.0, 1.0, (1, 11 + width * k)).astype(np.float32)
    if teammates:
        state[0, 16::width] = np.arange(k) < task.num_agents - 1
    with tempfile.TemporaryDirectory() as tmp:
        script = export_manager(args.run_dir, "torchscript", Path(tmp) / "manager.pt")
        onnx = export_manager(args.run_dir, "onnx", Path(tmp) / "manager.onnx")
        module = torch.jit.load(str(script))
        options = onnxruntime.SessionOptions()
        options.intra_op_num_threads = options.inter_op_num_threads = 1
        session = onnxruntime.InferenceSession(str(onnx), options, providers=["CPUExecutionProvider"])
        x = torch.from_numpy(state)

        def torchscript() -> None:
            with torch.inference_mode():
                module(x)

        def onnx_call() -> None:
            session.run(["subgoal"], {"state": state})

        paths = [
            ("torchscript", torchscript, script.stat().st_size),
            ("onnxruntime", onnx_call, onnx.stat().st_size),
        ]

        fld = task.field

        def observe() -> np.ndarray:
            s = state.astype(np.float64)
            own = (s[:, 0:5], s[:, 5:7], s[:, 7], s[:, 8:10], s[:, 10])
            others = s[:, 11:].reshape(1, k, width)
            if env.observation != "paper":
                teammate = others[:, :, 5] > 0.5 if teammates else np.zeros((1, k), dtype=bool)
                extra = {"encounters": env.observation == "encounters"}
                return neighbour_observation(
                    *own, others[:, :, 0:2], others[:, :, 2:4], teammate, env.neighbours, max_pos=fld.max_pos,
                    **extra,
                )  # fmt: skip
            return manager_observation(
                *own, others[:, :, 0:2], others[:, :, 2:4], others[:, :, 4], max_pos=fld.max_pos
            )

        planner = make_planner("sampling", env)

        def sampling() -> None:
            planner(observe())

        def python() -> None:
            s, obs = state.astype(np.float64), observe()
            with torch.inference_mode():
                action = policy(obs)
            decode_subgoal(
                action, env.action_form, fld.half_length, fld.half_width, zero_velocity=task.zero_velocity,
                frame=env.action_frame, target=s[:, 0:5],
            )  # fmt: skip

        print(f"{args.run_dir}: {config.algo}, task {task.name}, {k} other robot(s), batch 1, one thread")
        learned = (
            f"candidates + torch {config.candidates.network}"
            if config.algo == "candidates"
            else "torch actor"
        )
        for name, call, size in (
            *paths,
            (f"python (numpy obs + {learned} + decode)", python, None),
            ("sampling planner (numpy obs + plan)", sampling, None),
        ):
            median, p90 = _time(call, args.calls if call is not sampling else max(1, args.calls // 10))
            where = f"{size:,} bytes, " if size else ""
            print(f"  {name:42s} {where}median {median:7.1f} us, p90 {p90:7.1f} us per state")


if __name__ == "__main__":
    main()
