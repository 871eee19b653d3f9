"""Measurement, not CI: the candidate scorer's features at batch 256, before and after the torch port.

Reads 256 manager observations of reset states of each task (``obstacle/scorer``, ``scenarios/crowd_scorer``,
``scenarios/formation_scorer``) and times, alternately, ``--repeats`` times each on one thread: "after",
``CandidateGeometry`` (the scene and the candidates from the observations, then their features, torch);
and, with ``--before FILE``, "before", the numpy implementation in FILE (``candidate_features(planner, scene,
candidates)``, hier_ssl/manager/candidate_features.py before the port) after the planner's ``read`` and
``candidates``. Prints the best and the median time per state, and the largest difference of the two.

Run: git show 094eea9:hier_ssl/manager/candidate_features.py > /tmp/numpy_features.py
     python benchmarks/candidate_features.py [--before /tmp/numpy_features.py] [--repeats 10]
"""

from __future__ import annotations

import argparse
import importlib.util
import time

import numpy as np
import torch

from hier_ssl.config.files import config_dir, load_yaml
from hier_ssl.envs import parse_config
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.planners import make_planner
from hier_ssl.policies.candidate_graph import candidate_geometry

TASKS = ("obstacle/scorer", "scenarios/crowd_scorer", "scenarios/formation_scorer")
BATCH = 256


def _module(path: str):
    spec = importlib.util.spec_from_file_location("numpy_candidate_features", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", help="the numpy implementation's file")
    parser.add_argument("--repeats", type=int, default=10)
    args = parser.parse_args()
    torch.set_num_threads(1)
    before = _module(args.before) if args.before else None
    print(f"features of {BATCH} states, one thread; ms per state, best / median of {args.repeats}")
    for name in TASKS:
        config = parse_config(load_yaml(config_dir() / f"{name}.yaml"))
        core = HierarchicalCore(config.task_config, BATCH)
        obs = core.reset(1).reshape(-1, core.obs_dim)[:BATCH]
        planner = make_planner("sampling", config.task_config)
        geometry = candidate_geometry(config, planner)
        x = torch.from_numpy(obs)

        def after(x=x, geometry=geometry) -> np.ndarray:
            with torch.inference_mode():
                return geometry.features(geometry(x)).numpy()

        def numpy(planner=planner, obs=obs) -> np.ndarray:
            scene = planner.read(obs)
            return before.candidate_features(planner, scene, planner.candidates(scene))

        calls = {"after": after, **({"before": numpy} if before else {})}
        times: dict[str, list[float]] = {key: [] for key in calls}
        out = {}
        for _ in range(args.repeats):
            for key, call in calls.items():
                start = time.perf_counter()
                out[key] = call()
                times[key].append((time.perf_counter() - start) / len(obs) * 1e3)
        line = ", ".join(f"{key} {min(t):.3f} / {np.median(t):.3f}" for key, t in times.items())
        shape = "x".join(map(str, out["after"].shape))
        if before:
            ratio = np.median(times["before"]) / np.median(times["after"])
            gap = np.abs(out["after"] - out["before"]).max()
            line += f"; {ratio:.1f} times faster; largest difference {gap:.1e}"
        print(f"  {name:28s} ({shape}) {line}")


if __name__ == "__main__":
    main()
