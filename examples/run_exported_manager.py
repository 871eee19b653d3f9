"""Run an exported hier_ssl manager (ONNX) with numpy and onnxruntime alone: no hier_ssl, no torch.

    python examples/run_exported_manager.py manager.onnx

Reads the input layout stored in the file, asks the manager for the sub-goal of a few robots at once and
prints them. On a robot, call it every ``frame_skip`` control periods of 25 ms and hand the sub-goal to
the goToPoint controller until the next call.
"""

from __future__ import annotations

import json
import sys

import numpy as np

try:
    import onnxruntime
except ModuleNotFoundError:  # the one package this script needs beyond numpy
    sys.exit("this example runs the file on onnxruntime: pip install onnxruntime (hier_ssl's export extra)")


def main() -> None:
    session = onnxruntime.InferenceSession(sys.argv[1], providers=["CPUExecutionProvider"])
    layout = json.loads(session.get_modelmeta().custom_metadata_map["layout"])
    width = session.get_inputs()[0].shape[1]
    print(f"task {layout['task']}, frame skip {layout['frame_skip']}, input columns {width}")

    # Target (x, y, theta, vx, vy), then robot (x, y, theta, vx, vy, omega): field frame, m, rad, m/s.
    states = np.array(
        [
            [1.5, 1.0, 0.0, 0.0, 0.0, -2.0, -1.0, np.pi / 2, 0.0, 0.0, 0.0],
            [-2.0, 0.5, np.pi, 0.0, 0.0, 2.0, 0.0, 0.0, 0.5, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0, 0.0, 0.3, -0.2, -1.0, 0.0, 0.0, 0.0],
        ],
        dtype=np.float32,
    )
    # The other robots the manager reads (obstacles, teammates: the layout names their columns) stand still
    # in a row along one side line, away from these robots' paths.
    others = layout["input_fields"][11:]
    columns = np.zeros((len(states), len(others)), dtype=np.float32)
    for i, name in enumerate(others):
        robot, value = name.split("_", 1)
        j = int(robot.lstrip("abcdefghijklmnopqrstuvwxyz"))
        if value in ("x", "y", "teammate"):
            columns[:, i] = {"x": -2.5 + 0.5 * j, "y": 1.8, "teammate": float(j < layout["teammates"])}[value]
    states = np.concatenate([states, columns], axis=1)
    assert states.shape[1] == width, (states.shape, width)
    (subgoals,) = session.run(["subgoal"], {"state": states})  # (B, 5): x, y, theta, vx, vy
    for state, subgoal in zip(states, subgoals, strict=True):
        print(
            f"robot at ({state[5]:+.2f}, {state[6]:+.2f}) -> target ({state[0]:+.2f}, {state[1]:+.2f}): "
            f"sub-goal ({subgoal[0]:+.2f}, {subgoal[1]:+.2f}) m, heading {subgoal[2]:+.2f} rad"
        )
    assert "hier_ssl" not in sys.modules and "torch" not in sys.modules


if __name__ == "__main__":
    main()
