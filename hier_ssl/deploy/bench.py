"""``hier-ssl bench deploy``: the tracker's error, the loop's latency and the tasks through the wire.

- ``tracking``: a robot driven by the paper worker to random sub-goals in hier_ssl's world, seen by two
  overlapping 60 Hz cameras (2 mm and 0.5 deg noise, 10 % of detections dropped, 20 ms from capture to
  send): the tracker's velocity and position error at the time each control period acts, against
  the truth, and the position error of the newest detection for comparison.
- ``latency``: a field server in its own process publishing over 127.0.0.1, the controller loop here;
  from a camera frame's arrival to the command's send, p50 / p99 over ``seconds`` of running, for an
  exported network manager (TorchScript, and ONNX where onnxruntime is installed; untrained: the time does
  not depend on the weights) and the sampling planner, with 1 robot (Obstacle task), 6 (formation: 6
  controlled robots, 6 moving obstacles) or 11 (formation on the Division A field, 11 and 11), each
  decision one batched call for all of them; and the controller's compute time of the ticks that decide.
- ``task``: success, collisions and median episode length (control steps) of the Obstacle task and of
  crossing driven through field server -> packets -> tracker -> manager -> commands -> field server (the
  field server and the loop in lockstep: one world step per command, as the direct loop steps),
  against the same manager played directly by ``hier_ssl.envs.play`` (what ``hier-ssl eval`` runs) on
  the same episodes (``direct_episodes``), and a run's own task for ``run``; ``success_gap_points`` is
  through the wire minus direct.
- ``game``: the ``task`` row's comparison on ``GAME_TASK`` (the SSL game's STOP), whose referee the field
  server plays to the loop (its own schedule: the command at a random time of each episode), with the
  share of robot-episodes ended by a foul through the wire and directly.
"""

from __future__ import annotations

import importlib.util
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from hier_ssl.checkpoints.files import write_text
from hier_ssl.config import TaskConfig
from hier_ssl.deploy.cameras import Cameras, camera_frames, camera_strips
from hier_ssl.deploy.field import STEP
from hier_ssl.deploy.loop import PRIORITY
from hier_ssl.deploy.tracker import Tracker
from hier_ssl.deploy.view import DeployView, manager_task
from hier_ssl.deploy.wired import WiredRun, takes_task
from hier_ssl.envs import make_scenario
from hier_ssl.envs.core import HierarchicalCore
from hier_ssl.envs.game import GameScenario
from hier_ssl.envs.play import play
from hier_ssl.envs.scenarios import SCENARIOS

# Robots -> the field server's task of a latency row and the settings that differ from its defaults.
LATENCY_TASKS: dict[int, tuple[str, dict[str, Any]]] = {
    1: ("obstacle", {}),
    6: ("formation", {}),
    11: ("formation", {"field": "division_a", "num_agents": 11, "num_obstacles": 11}),
}
# The exported network is timed in each format the machine can run: ONNX Runtime is the `export` extra.
EXPORT_FORMATS = ("torchscript", "onnx") if importlib.util.find_spec("onnxruntime") else ("torchscript",)
# The tracking row's cameras: vision's processing (capture to send) as a real field's SSL-Vision has it.
NOISY = Cameras(pos_noise=0.002, angle_noise=float(np.deg2rad(0.5)), drop=0.1, latency=0.02)


def tracking_error(
    seconds: float = 60.0,
    seed: int = 0,
    cameras: Cameras = NOISY,
    commands: bool = False,
    tracker: Tracker | None = None,
) -> dict[str, Any]:
    """RMS errors of the tracker predicted to each control period's time (velocity m/s, position m) and
    of the newest detection's position, over ``seconds`` of a robot driving to random sub-goals; with
    ``commands`` the tracker is told each command (an own robot), without it sees a robot of the others."""
    from hier_ssl.worker.scripted import PaperGoToPoint
    from hier_ssl.world.physics import World

    rng = np.random.default_rng(seed)
    world = World(1, 1)
    hx, hy = world.field.half_length - 0.3, world.field.half_width - 0.3
    worker, subgoal = PaperGoToPoint(dt=STEP), np.zeros((1, 1, 5))
    tracker = Tracker() if tracker is None else tracker
    strips = camera_strips(cameras, world.field.wall_half_extent[0])
    queue: list = []  # (arrival, frame)
    errors: dict[str, list[float]] = {"vel": [], "pos": [], "detection": []}
    next_frame, t, newest = 0.0, 0.0, None
    for k in range(round(seconds / STEP)):
        if k % 80 == 0:  # a new sub-goal every 2 s: the robot accelerates, brakes and turns
            subgoal[0, 0] = [*rng.uniform((-hx, -hy), (hx, hy)), rng.uniform(-np.pi, np.pi), 0.0, 0.0]
        command = worker(world.state, subgoal)
        if commands:
            tracker.command(("blue", 0), t, tuple(command[0, 0]))
        state = world.step(command)
        t += STEP
        while next_frame <= t:  # frames of this step's state, captured at its time
            queue += [
                (t + cameras.latency, f)
                for f in camera_frames(state.pos[0], state.angle[0], [("blue", 0)], cameras, strips, t, rng)
            ]
            next_frame += 1.0 / cameras.rate
        for arrival, frame in [q for q in queue if q[0] <= t]:
            tracker.update(frame, arrival)
            newest = frame.robots[0] if frame.robots else newest
        queue = [q for q in queue if q[0] > t]
        if k > 40 and newest is not None:  # after the filter's first second
            x, y, _, vx, vy, _ = tracker.state([("blue", 0)], tracker.vision_time(t))[0]
            errors["vel"].append(float(np.hypot(vx - state.vel[0, 0, 0], vy - state.vel[0, 0, 1])))
            errors["pos"].append(float(np.hypot(x - state.pos[0, 0, 0], y - state.pos[0, 0, 1])))
            errors["detection"].append(
                float(np.hypot(newest.x - state.pos[0, 0, 0], newest.y - state.pos[0, 0, 1]))
            )
    rms = {key: float(np.sqrt(np.mean(np.square(v)))) for key, v in errors.items()}
    return {
        "bench": "deploy tracking",
        "robot": "own (commands known)" if commands else "other",
        "latency_ms": round(cameras.latency * 1e3, 1),
        "velocity_rmse_m_s": round(rms["vel"], 4),
        "position_rmse_m": round(rms["pos"], 4),
        "detection_rmse_m": round(rms["detection"], 4),
    }


def untrained_export(folder: Path, task: str = "obstacle", fmt: str = "torchscript", **settings: Any) -> Path:
    """An exported manager (``fmt``: torchscript or onnx) for ``task`` (a paper task or a scenario, with
    ``settings`` changing its keys) of the size training gives (SAC, 2 x 256 units), with random weights."""
    from hier_ssl.checkpoints.tensors import save_checkpoint
    from hier_ssl.config import dump_config
    from hier_ssl.envs import parse_config
    from hier_ssl.policies.export import export_manager
    from hier_ssl.policies.networks import SquashedGaussianActor

    config = parse_config({"algo": "sac", **_section(task, settings)})
    scenario = make_scenario(config.task_config)
    run = folder / f"untrained-{task}-{scenario.num_agents}"
    run.mkdir(parents=True, exist_ok=True)
    write_text(dump_config(config), run / "config.yaml")
    actor = SquashedGaussianActor(scenario.obs_dim, scenario.act_dim)
    save_checkpoint({"actor": actor.state_dict(), "step": 0}, run / "best_actor.pt")
    return export_manager(run, fmt)


def _section(task: str, settings: dict[str, Any]) -> dict[str, Any]:
    """A training config's section of ``task`` (a paper task or a scenario) with ``settings``."""
    if task in SCENARIOS:
        return {"scenario": {"scenario": task, **settings}}
    return {"env": {"task": task, "frame_skip": 16, **settings}}


def latency_task(robots: int, folder: Path) -> str:
    """The field server's task of a latency row of ``robots`` (``LATENCY_TASKS``): its name, or a YAML file
    in ``folder`` where its settings differ from the defaults."""
    if robots not in LATENCY_TASKS:
        raise ValueError(f"latency rows of {robots} robots: expected one of {sorted(LATENCY_TASKS)}")
    task, settings = LATENCY_TASKS[robots]
    if not settings:
        return task
    path = folder / f"{task}-{robots}.yaml"
    write_text(yaml.safe_dump({"scenario": {"scenario": task, **settings}}), path)
    return str(path)


WARM_UP_S = 1.0  # s: the latency rows' untimed first run


def latency_row(
    manager: str, label: str, robots: int, seconds: float, priority: int = PRIORITY, task: str | None = None
) -> dict[str, Any]:
    """From a camera frame's arrival to the command's send (``p50_ms``, ``p99_ms``), and the controller's
    compute time of the ticks that decided (``decision_...``), over ``seconds`` of the loop driving
    ``robots`` robots of ``task`` (default: ``LATENCY_TASKS``'s, which needs no file)."""
    task = LATENCY_TASKS[robots][0] if task is None else task
    # An untimed first run builds this process's compiled kernels (seconds on a cold cache).
    WiredRun(manager, task, robots, None, priority=priority).run(WARM_UP_S)
    stats, _ = WiredRun(manager, task, robots, None, priority=priority).run(seconds)
    if not stats.latencies or not stats.decisions:
        raise RuntimeError(f"latency of {label!r}: no command sent in {seconds} s (is the field server up?)")
    p50, p99 = np.percentile(stats.latencies, [50, 99]) * 1e3
    d50, d99 = np.percentile(stats.decisions, [50, 99]) * 1e3
    return {
        "bench": "deploy latency",
        "manager": label,
        "robots": robots,
        "field": LATENCY_TASKS[robots][0] if robots in LATENCY_TASKS else task,
        "samples": len(stats.latencies),
        "p50_ms": round(float(p50), 3),
        "p99_ms": round(float(p99), 3),
        "decisions": len(stats.decisions),
        "decision_p50_ms": round(float(d50), 3),
        "decision_p99_ms": round(float(d99), 3),
        "scheduling": stats.scheduling,
    }


def _outcomes(success: np.ndarray, collision: np.ndarray, length: np.ndarray) -> dict[str, float]:
    return {
        "success": float(np.mean(success)),
        "collision": float(np.mean(collision)),
        "median_length": float(np.median(length)),
    }


def direct_episodes(
    policy: Callable[[np.ndarray], np.ndarray],
    config: TaskConfig,
    episodes: int,
    seed: int,
    keys: tuple[str, ...] = ("success", "collision", "length"),
) -> tuple[np.ndarray, ...]:
    """Success, collision and length (or other ``keys`` of ``play``'s ends; (episodes, M) each) of
    ``policy`` played directly (``hier_ssl.envs.play``, as ``hier-ssl eval`` plays) on the field server's
    episodes: episode e in a one-field core reset with seed ``seed + e``. (A core of ``episodes`` fields
    draws its starts in one batch from ``seed``: other episodes, and the wire's and the direct loop's figures
    would differ by the episodes drawn.)"""
    core = HierarchicalCore(config, num_fields=1, autoreset=False)
    ends = [play(core, policy, seed + e) for e in range(episodes)]
    return tuple(np.concatenate([end[key] for end in ends]) for key in keys)


def _gap(wired: float, direct: float, samples: int) -> tuple[float, float]:
    """Wire minus direct, in points, and its standard error with the two as independent samples."""
    variance = sum(p * (1 - p) for p in (wired, direct)) / samples
    return round(100 * (wired - direct), 1), round(100 * float(np.sqrt(variance)), 1)


def task_row(
    manager: str,
    label: str,
    task: str,
    episodes: int,
    seed: int = 0,
    noise: tuple[float, float] = (2.0, 0.5),
    script: str | None = None,
) -> dict[str, Any]:
    """Through the wire (field server in lockstep) against ``direct_episodes``; the field server's vision
    ``noise`` (mm, deg) and referee ``script`` (None: none; a game scenario plays its own referee). The
    gaps' standard error treats the wire's and the direct loop's robots as independent samples (a chaotic
    episode's two plays part early); robots of one episode are not. Under a referee, ``wire_fouls``: the
    share of robot-episodes with a foul (a game scenario's: ended by one, as ``eval_fouls`` counts them;
    a script's: any the field server called, and ``eval_fouls`` None, as the direct loop has no referee)."""
    config = manager_task(manager, task if takes_task(manager) else None)
    scenario = make_scenario(config)
    robots, game = scenario.num_agents, isinstance(scenario, GameScenario)
    options = ("--noise-mm", str(noise[0]), "--noise-deg", str(noise[1]))
    team = "yellow" if game else "blue"  # the game scenarios' own team
    wired_run = WiredRun(
        manager,
        task,
        robots,
        episodes,
        seed,
        lockstep=True,
        field_options=options,
        script=script,
        referee=game,
        team=team,
    )
    _, records = wired_run.run(None)
    wired = _outcomes(*(np.array([r[k] for r in records]) for k in ("success", "collision", "length")))
    keys = ("success", "collision", "length") + (("foul",) if game else ())
    direct = direct_episodes(DeployView(manager, robots, config).policy, config, episodes, seed, keys)
    direct_out = _outcomes(*direct[:3])
    samples = episodes * robots
    gap, gap_se = _gap(wired["success"], direct_out["success"], samples)
    row = {
        "bench": "deploy task" if script is None and not game else "deploy game",
        "manager": label,
        "task": task,
        "episodes": episodes,
        "robot_samples": samples,
        "field_clock": "lockstep",
        "noise_mm": noise[0],
        "noise_deg": noise[1],
        **{f"wire_{k}": round(v, 3) for k, v in wired.items()},
        **{f"eval_{k}": round(v, 3) for k, v in direct_out.items()},
        "success_gap_points": gap,
        "success_gap_se_points": gap_se,
    }
    if game:
        fouled, direct_fouled = float(np.mean([r["foul"] for r in records])), float(np.mean(direct[3] > 0))
        foul_gap, foul_se = _gap(fouled, direct_fouled, samples)
        row |= {"wire_fouls": round(fouled, 3), "eval_fouls": round(direct_fouled, 3)}
        row |= {"foul_gap_points": foul_gap, "foul_gap_se_points": foul_se}
    elif script is not None:
        fouled = float(np.mean([bool(r["fouls"]) for r in records]))
        row |= {"referee_script": script, "wire_fouls": round(fouled, 3), "eval_fouls": None}
    return row


GAME_TASK = "game_stop"  # the game row's scenario: it plays its own referee, the field server sends it


ROWS = ("tracking", "latency", "task", "game")


def deploy_rows(
    run: str | None,
    seconds: float,
    episodes: int,
    priority: int = PRIORITY,
    noise: tuple[float, float] = (2.0, 0.5),
    rows: tuple[str, ...] = ROWS[:3],
    robots: tuple[int, ...] = (1, 6),
) -> Iterator[dict[str, Any]]:
    """The ``rows`` (of ``ROWS``) of ``hier-ssl bench deploy``, yielded as each finishes; the latency rows
    of ``robots`` robots each (``LATENCY_TASKS``)."""
    if "tracking" in rows:
        yield tracking_error()
        yield tracking_error(commands=True)
    if "latency" in rows:
        with tempfile.TemporaryDirectory() as folder:
            for count in robots:
                task = latency_task(count, Path(folder))
                name, settings = LATENCY_TASKS[count]
                for fmt in EXPORT_FORMATS:
                    network = str(untrained_export(Path(folder), name, fmt, **settings))
                    label = f"network (untrained, {fmt})"
                    yield latency_row(network, label, count, seconds, priority, task)
                yield latency_row("sampling", "sampling", count, seconds, priority, task)
    if "task" in rows:
        for task in ("obstacle", "crossing"):
            yield task_row("sampling", "sampling", task, episodes, noise=noise)
        if run is not None:
            yield task_row(run, Path(run).name, manager_task(run).scenario_name, episodes, noise=noise)
    if "game" in rows:
        yield task_row("sampling", "sampling", GAME_TASK, episodes, noise=noise)


__all__ = [
    "LATENCY_TASKS",
    "ROWS",
    "deploy_rows",
    "direct_episodes",
    "latency_row",
    "latency_task",
    "task_row",
    "tracking_error",
    "untrained_export",
]
