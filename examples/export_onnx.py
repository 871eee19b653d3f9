"""Export a trained manager to ONNX, then run the file in a fresh interpreter that never imports hier_ssl.

    python examples/export_onnx.py runs/<run>             # a run of `hier-ssl train`
    python examples/export_onnx.py --train-steps 200      # no run yet: train a tiny one first (seconds)

The exported file is the whole manager: raw state in (target, robot, obstacles; metres, radians, field
frame), sub-goal out. ``run_exported_manager.py`` beside this file runs it with numpy and onnxruntime only,
as a robot's software would.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

from hier_ssl.cli import main as hier_ssl_main
from hier_ssl.policies.export import export_manager

RUNNER = Path(__file__).with_name("run_exported_manager.py")


def tiny_run(out: Path, steps: int) -> Path:
    """A SAC manager on the Proposed task trained for ``steps`` vector steps: enough to export, not to use."""
    settings = [f"total_steps={steps}", f"eval_interval={steps // 2}", "eval_episodes=10", "num_envs=4"]
    settings.append(f"sac.learning_starts={steps // 4}")
    argv = ["train", "proposed/fscaps", "--out", str(out), "--no-progress"]
    if hier_ssl_main([*argv, *(arg for key in settings for arg in ("--set", key))]) != 0:
        raise SystemExit("training failed")
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", nargs="?", type=Path, help="a run directory (default: train a tiny one)")
    parser.add_argument("--train-steps", type=int, default=200)
    parser.add_argument("--out", type=Path, help="where the files go (default: a new temporary directory)")
    args = parser.parse_args()

    work = args.out or Path(tempfile.mkdtemp(prefix="hier_ssl-export-"))
    work.mkdir(parents=True, exist_ok=True)
    run = args.run or tiny_run(work / "run", args.train_steps)
    onnx_file = export_manager(run, "onnx", work / "manager.onnx")
    print(f"exported {run} -> {onnx_file} ({onnx_file.stat().st_size / 1000:.0f} kB)")
    subprocess.run([sys.executable, str(RUNNER), str(onnx_file)], check=True)


if __name__ == "__main__":
    main()
