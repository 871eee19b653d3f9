"""A trained manager as one self-contained file for robot software: TorchScript or ONNX.

The exported graph takes the raw field-frame state of one controlled robot and returns its sub-goal
pose; the manager observation (``hier_ssl.manager.observation``, or the relative layout of
``hier_ssl.manager.neighbours``, with the closest-approach columns of ``hier_ssl.manager.encounter`` in
the "encounters" layout, computed by the same function), the actor's deterministic (mean) action and the
action decoding in the run's frame (``hier_ssl.manager.actions``) are all inside it::

    state (B, 11 + 5J) float32 (11 + 6J with teammates), metres, radians, m/s, rad/s, field frame:
        0-4    target x, y, theta, vx, vy
        5-10   robot x, y, theta, vx, vy, w
        11+5j  other robot j: x, y, vx, vy, w (and teammate: 1 for another controlled robot, 0 for an
               obstacle, when the run's task has several controlled robots); J = the task's other robots,
               the paper's obstacles or a scenario's M - 1 teammates and K obstacles
    subgoal (B, 5) float32: x, y, theta in (-pi, pi], vx, vy (0 for pose4 and for the Proposed and
        Obstacle tasks)

A shared scenario manager exports the same way: each robot calls it with its own target and state.
The field's constants come from the run's task (``hier_ssl.envs.make_scenario``).

Normalisation runs in float64, as the numpy observation builder does, and its result is rounded to
float32 for the actor, so the file reproduces the Python policy to float32 rounding. The layout is
also stored in the file (TorchScript extra file ``layout.json``, ONNX metadata ``layout``).
"""

from __future__ import annotations

import json
import logging
import threading
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import torch
from torch import nn
from tqdm import tqdm

from hier_ssl.checkpoints.actor import load_actor, run_config
from hier_ssl.config import TrainConfig
from hier_ssl.envs import Scenario, make_scenario
from hier_ssl.manager.encounter import ENCOUNTER_DIM, encounter_columns
from hier_ssl.policies.actor import load_candidate_manager

FORMATS = {"torchscript": ".pt", "onnx": ".onnx"}
STATE_BASE_DIM = 11  # target 5 + robot 6
OTHER_STATE = ("x", "y", "vx", "vy", "w")  # each other robot's columns, then "teammate" with teammates
OBS_CLIP = 1.2


class ExportedManager(nn.Module):
    """Raw state (B, 11 + 5J), or (B, 11 + 6J) with ``teammate_column``, -> sub-goal (B, 5): observation,
    actor mean, decoding, in one module.

    ``neighbours`` None builds the paper's observation; an int builds the "neighbours" layout with that many
    slots (``hier_ssl.manager.neighbours``: the other robots nearest first, relative to the robot, with
    their teammate flag), followed by the "encounters" columns with ``encounters``. ``target_frame``
    decodes actions as offsets from the target (``hier_ssl.manager.actions``).
    """

    def __init__(
        self,
        actor: nn.Module,
        num_others: int,
        action_form: str,
        zero_velocity: bool,
        half_length: float,
        half_width: float,
        max_pos: float,
        max_v: float,
        max_w: float,
        neighbours: int | None = None,
        target_frame: bool = False,
        teammate_column: bool = False,
        encounters: bool = False,
    ) -> None:
        super().__init__()
        self.actor = actor
        self.num_others = num_others  # J, every other robot
        self.teammate_column = teammate_column
        self.width = len(OTHER_STATE) + int(teammate_column)
        self.pose6 = action_form == "pose6"
        self.zero_velocity = zero_velocity or not self.pose6
        self.half_length, self.half_width = half_length, half_width
        self.max_pos, self.max_v, self.max_w = max_pos, max_v, max_w
        self.clip = OBS_CLIP
        self.neighbours, self.target_frame, self.encounters = neighbours, target_frame, encounters
        self.encounter_dim = ENCOUNTER_DIM  # TorchScript reads attributes, not module constants
        per_obstacle = torch.tensor([max_pos, max_pos, max_v, max_v, max_w], dtype=torch.float64)
        self.register_buffer("obstacle_scale", per_obstacle.repeat(num_others))

    def _neighbour_slots(self, x: torch.Tensor, k: int) -> list[torch.Tensor]:
        """The ``k`` neighbour slots of the "neighbours" layout: relative x, y / max_pos, relative vx, vy /
        max_v (each clipped), teammate, present 1; all-zero padding past the other robots there are. With
        ``encounters``, then the encounter columns of the k slots (zeros for padding)."""
        b, real = x.shape[0], min(k, self.num_others)
        slots: list[torch.Tensor] = []
        extra: list[torch.Tensor] = []
        if real > 0:
            others = x[:, 11:].reshape(b, self.num_others, self.width)
            rel_pos, rel_vel = others[:, :, 0:2] - x[:, None, 5:7], others[:, :, 2:4] - x[:, None, 8:10]
            # Nearest first (ONNX TopK; exact distance ties, which the numpy builder breaks by index, are
            # measure-zero for real positions).
            order = torch.topk(rel_pos.square().sum(dim=2), real, dim=1, largest=False, sorted=True)[1]
            pick = order[:, :, None].expand(b, real, 2)
            if self.teammate_column:
                teammate = torch.gather(others[:, :, 5:6], 1, order[:, :, None])
            else:
                teammate = torch.zeros_like(rel_pos[:, :real, 0:1])
            block = torch.cat(
                [
                    torch.clamp(torch.gather(rel_pos, 1, pick) / self.max_pos, -self.clip, self.clip),
                    torch.clamp(torch.gather(rel_vel, 1, pick) / self.max_v, -self.clip, self.clip),
                    teammate,
                    torch.ones_like(rel_pos[:, :real, 0:1]),
                ],
                dim=2,
            )
            slots.append(block.reshape(b, 6 * real))
            if self.encounters:
                columns = encounter_columns(
                    torch.gather(rel_pos, 1, pick),
                    torch.gather(rel_vel, 1, pick),
                    x[:, None, 8:10],
                    x[:, None, 0:2] - x[:, None, 5:7],
                    max_pos=self.max_pos,
                    clip=self.clip,
                )
                extra.append(torch.stack(columns, dim=2).reshape(b, self.encounter_dim * real))
        if k > real:
            slots.append(torch.zeros(b, 6 * (k - real), dtype=x.dtype, device=x.device))
            if self.encounters:
                extra.append(torch.zeros(b, self.encounter_dim * (k - real), dtype=x.dtype, device=x.device))
        return slots + extra

    def forward(self, state: torch.Tensor) -> torch.Tensor:
        x = state.to(torch.float64)
        parts = [
            x[:, 0:2] / self.max_pos,  # target
            torch.sin(x[:, 2:3]),
            torch.cos(x[:, 2:3]),
            x[:, 3:5] / self.max_v,
            x[:, 5:7] / self.max_pos,  # robot
            torch.sin(x[:, 7:8]),
            torch.cos(x[:, 7:8]),
            x[:, 8:10] / self.max_v,
            x[:, 10:11] / self.max_w,
        ]
        slots: list[torch.Tensor] = []
        if self.neighbours is not None:
            slots = self._neighbour_slots(x, self.neighbours)
        elif self.num_others > 0:  # a (B, 0) slice would make ONNX infer a reshape by dividing by 0
            parts.append(x[:, 11:] / self.obstacle_scale)
        pieces = [torch.clamp(torch.cat(parts, dim=1), -self.clip, self.clip)]
        pieces.extend(slots)
        obs = torch.cat(pieces, dim=1)
        action = torch.clamp(self.actor(obs.to(torch.float32)), -1.0, 1.0)
        xy, sin, cos = action[:, 0:2], action[:, -2:-1], action[:, -1:]
        if self.target_frame:  # offsets cubed, a turn of atan2(sin, 1 + cos) from the target's heading
            xy, cos = xy * xy * xy, cos + 1.0
        xy = torch.cat([xy[:, 0:1] * self.half_length, xy[:, 1:2] * self.half_width], dim=1)
        theta = torch.atan2(sin, cos)
        if self.target_frame:
            target = x[:, 0:2].to(xy.dtype)
            xy = torch.cat(
                [
                    torch.clamp(xy[:, 0:1] + target[:, 0:1], -self.half_length, self.half_length),
                    torch.clamp(xy[:, 1:2] + target[:, 1:2], -self.half_width, self.half_width),
                ],
                dim=1,
            )
            heading = theta + x[:, 2:3].to(theta.dtype)
            theta = torch.atan2(torch.sin(heading), torch.cos(heading))
        vel = action[:, 2:4] * self.max_v if self.pose6 and not self.zero_velocity else torch.zeros_like(xy)
        return torch.cat([xy, theta, vel], dim=1)


def _task(config: TrainConfig) -> Scenario:
    """The run's task as the core runs it: robot counts, field constants, rules."""
    return make_scenario(config.task_config)


def layout(config: TrainConfig) -> dict[str, object]:
    """The exported file's input and output layout, as stored in it and printed by the CLI."""
    task, env = _task(config), config.task_config
    teammates, k = task.num_agents - 1, task.num_obstacles
    columns = OTHER_STATE + (("teammate",) if teammates else ())
    prefix = "other" if teammates else "obstacle"
    others = [f"{prefix}{j}_{name}" for j in range(teammates + k) for name in columns]
    return {
        "input": "state",
        "input_shape": ["batch", STATE_BASE_DIM + len(columns) * (teammates + k)],
        "input_fields": ["target_x", "target_y", "target_theta", "target_vx", "target_vy"]
        + ["robot_x", "robot_y", "robot_theta", "robot_vx", "robot_vy", "robot_w", *others],
        "output": "subgoal",
        "output_shape": ["batch", 5],
        "output_fields": ["x", "y", "theta", "vx", "vy"],
        "units": "m, rad, m/s, rad/s; field frame, origin at the centre, x along the length",
        "dtype": "float32",
        "task": env.scenario_name,
        "field": env.field,
        "teammates": teammates,
        "obstacles": k,
        "action_form": env.action_form,
        "observation": env.observation,
        "action_frame": env.action_frame,
        "frame_skip": env.frame_skip,
    }


def exported_manager(run_dir: str | Path) -> tuple[ExportedManager, TrainConfig]:
    """The manager trained in ``run_dir`` as an ``ExportedManager`` (frozen, eval mode), and its config.
    An ``algo: candidates`` run's actor is its whole decision (``load_candidate_manager``)."""
    config = run_config(run_dir)
    if config.algo == "candidates" and config.candidates.network == "residual":
        raise ValueError(
            f"{run_dir}: a residual candidates manager cannot be exported: every decision adds the sampling "
            "planner's rollouts (numba, numpy), which TorchScript and ONNX do not hold"
        )
    if config.algo == "candidates":
        actor: nn.Module = load_candidate_manager(run_dir)
    else:
        actor, config = load_actor(run_dir)
    if config.kind != "manager":
        raise ValueError(f"{run_dir}: a {config.kind} run; export takes a manager run")
    task, env = _task(config), config.task_config
    if config.algo != "candidates":
        in_dim, out_dim = actor[0].in_features, actor[-2].out_features
        if (in_dim, out_dim) != (task.obs_dim, task.act_dim):
            raise ValueError(
                f"{run_dir}: actor maps {in_dim} -> {out_dim} values; its config needs "
                f"{task.obs_dim} -> {task.act_dim}"
            )
    scales = task.scales
    module = ExportedManager(
        actor,
        num_others=task.num_agents - 1 + task.num_obstacles,
        action_form=env.action_form,
        zero_velocity=task.zero_velocity,
        half_length=scales["half_length"],
        half_width=scales["half_width"],
        max_pos=scales["max_pos"],
        max_v=scales["max_v"],
        max_w=scales["max_w"],
        neighbours=env.neighbours if env.observation != "paper" else None,
        target_frame=env.action_frame == "target",
        teammate_column=task.num_agents > 1,
        encounters=env.observation == "encounters",
    )
    return module.eval(), config


def export_manager(
    run_dir: str | Path, fmt: str, out: str | Path | None = None, progress: bool = False
) -> Path:
    """Write the manager of ``run_dir`` as ``fmt`` ("torchscript" or "onnx") to ``out`` (default:
    ``RUN_DIR/manager.pt`` or ``RUN_DIR/manager.onnx``). Returns the path written. With ``progress`` a
    bar on stderr names the step under way and counts its seconds."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r}; expected one of {sorted(FORMATS)}")
    bar_format = "{desc}: step {n_fmt}/{total_fmt}{postfix} [{elapsed}]"
    with tqdm(total=2, desc=f"export {fmt}", bar_format=bar_format, disable=not progress) as bar:
        bar.set_postfix_str("loading the run")
        module, config = exported_manager(run_dir)
        bar.update()
        out = Path(out) if out is not None else Path(run_dir) / f"manager{FORMATS[fmt]}"
        out.parent.mkdir(parents=True, exist_ok=True)
        example = torch.zeros(2, STATE_BASE_DIM + module.width * module.num_others)
        meta = json.dumps(layout(config))
        bar.set_postfix_str(f"tracing and writing {out.name}")
        with _ticking(bar):
            if fmt == "torchscript":
                with warnings.catch_warnings():  # torch 2.13 deprecates TorchScript; C++ stacks still load it
                    warnings.simplefilter("ignore", DeprecationWarning)
                    torch.jit.save(torch.jit.script(module), str(out), _extra_files={"layout.json": meta})
            else:
                _export_onnx(module, example, out, meta)
        bar.update()
    return out


@contextmanager
def _ticking(bar: tqdm) -> Iterator[None]:
    """Redraw ``bar`` every second while the body runs: the exporter is one call of a minute or more, and
    a bar that redraws only when a step ends would look hung."""
    stop = threading.Event()

    def tick() -> None:
        while not stop.wait(1.0):
            bar.refresh()

    thread = threading.Thread(target=tick, daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def _export_onnx(module: ExportedManager, example: torch.Tensor, out: Path, meta: str) -> None:
    # here, not at the top: onnx, for the ONNX format alone
    import onnx

    # The exporter logs about optional packages (torchvision) and deprecations that concern it, not us.
    onnx_logger = logging.getLogger("torch.onnx")
    level = onnx_logger.level
    onnx_logger.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _torch_onnx_export(module, example, out)
    finally:
        onnx_logger.setLevel(level)
    model = onnx.load(str(out))
    entry = model.metadata_props.add()
    entry.key, entry.value = "layout", meta
    onnx.save(model, str(out))


def _torch_onnx_export(module: ExportedManager, example: torch.Tensor, out: Path) -> None:
    torch.onnx.export(
        module,
        (example,),
        str(out),
        input_names=["state"],
        output_names=["subgoal"],
        dynamic_shapes=({0: torch.export.Dim("batch")},),
        dynamo=True,
        external_data=False,  # one file: the weights inside the graph
        verbose=False,
    )


__all__ = ["FORMATS", "ExportedManager", "export_manager", "exported_manager", "layout"]
