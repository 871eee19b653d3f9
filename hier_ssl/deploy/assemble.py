"""The deploy pieces put together from command-line values: targets, robots, the controller loop."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from hier_ssl.deploy.controller import Controller
from hier_ssl.deploy.game import RefereeInput
from hier_ssl.deploy.loop import PRIORITY, DeployLoop
from hier_ssl.deploy.net import CommandSender, ControlServer, command_target, open_vision, parse_address
from hier_ssl.deploy.tracker import Tracker
from hier_ssl.deploy.view import DeployView, manager_task
from hier_ssl.deploy.wire import MAX_ROBOT_ID


def parse_robots(text: str) -> list[int]:
    """``0,1,2``, ``0-10`` or both (``0-3,7``) as robot ids in the order given; ValueError naming the
    part of the text that is wrong."""
    robots: list[int] = []
    for part in text.split(","):
        first, dash, last = part.strip().partition("-")
        try:
            ids = range(int(first), int(last) + 1) if dash else [int(first)]
        except ValueError:
            raise ValueError(f"robots {text!r}: {part!r} is not an id or a range like 0-10") from None
        if not ids or ids[0] < 0 or ids[-1] > MAX_ROBOT_ID:
            raise ValueError(f"robots {text!r}: {part!r} is not in 0..{MAX_ROBOT_ID} (low to high)")
        robots += ids
    if len(set(robots)) != len(robots):
        raise ValueError(f"robots {text!r}: an id is named twice")
    return robots


def parse_targets(text: str | None) -> dict[Any, Any]:
    """Targets by robot id from a YAML file (``{0: [x, y, theta], 1: [...]}``) or inline text
    (``0:1.5,0.5,0;1:-1,0,1.57``); checked when given to the controller."""
    if text is None:
        return {}
    if text.endswith((".yaml", ".yml")):
        data = yaml.safe_load(Path(text).read_text())
        if not isinstance(data, dict):
            raise ValueError(f"targets {text}: expected a mapping of robot id to [x, y, theta]")
        return data
    targets: dict[Any, Any] = {}
    for part in filter(None, text.split(";")):
        robot, sep, values = part.partition(":")
        try:
            targets[int(robot)] = [float(v) for v in values.split(",")]
        except ValueError:
            raise ValueError(f"targets {part!r}: expected ID:x,y,theta[,vx,vy]") from None
        if not sep:
            raise ValueError(f"targets {part!r}: expected ID:x,y,theta[,vx,vy]")
    return targets


@dataclass
class DeploySettings:
    """What ``hier-ssl deploy`` takes (its --help says each)."""

    manager: str
    vision: str
    commands: str
    team: str
    robots: list[int]
    targets: dict[Any, Any]
    source: str = "127.0.0.1"
    control_port: int | None = None
    vision_interface: str | None = None
    task: str | None = None
    worker: str | None = None
    frame_skip: int | None = None
    feedback: str = "model"
    priority: int = PRIORITY
    lockstep: bool = False
    referee: str | None = None
    referee_source: str | None = None  # None: ``source``


def build_loop(settings: DeploySettings) -> DeployLoop:
    """The controller loop, its sockets open (vision bound, control socket listening on 127.0.0.1)."""
    config = manager_task(settings.manager, settings.task, settings.frame_skip, settings.worker)
    view = DeployView(settings.manager, len(settings.robots), config)
    controller = Controller(view, Tracker(), settings.team, settings.robots, feedback=settings.feedback)
    for robot, target in settings.targets.items():
        controller.set_target(robot, target)
    kind, address = command_target(settings.commands, settings.team)
    host, port = parse_address(settings.vision, any_port=True)
    sender = CommandSender(kind, address, settings.team)
    vision = open_vision(host, port, settings.vision_interface)
    control = None
    if settings.control_port is not None:
        control = ControlServer(settings.control_port, controller.set_target)
    referee = None
    if settings.referee is not None:
        ref_host, ref_port = parse_address(settings.referee, any_port=True)
        referee = RefereeInput(
            open_vision(ref_host, ref_port, settings.vision_interface),
            settings.referee_source or settings.source,
            view.field,
        )
    return DeployLoop(
        controller,
        vision,
        settings.source,
        sender,
        control,
        priority=settings.priority,
        lockstep=settings.lockstep,
        referee=referee,
    )


__all__ = ["DeploySettings", "build_loop", "parse_robots", "parse_targets"]
