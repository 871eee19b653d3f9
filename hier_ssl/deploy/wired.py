"""A wired run of ``hier-ssl bench deploy``: a field server in its own process (``hier-ssl field``) and the
controller loop of a manager in this one, over 127.0.0.1."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
from typing import Any

from hier_ssl.deploy.assemble import DeploySettings, build_loop
from hier_ssl.deploy.loop import PRIORITY, LoopStats
from hier_ssl.envs.planners import is_planner


class WiredRun:
    """A field server process on ``task`` and the controller loop of ``manager`` here, over 127.0.0.1,
    both free-running or both in ``lockstep``, the controlled robots of ``team``; with a ``referee`` (a
    game scenario's own) or a referee ``script`` the field server plays referee to the loop's referee port
    (``hier-ssl field --referee-script``)."""

    def __init__(
        self,
        manager: str,
        task: str,
        robots: int,
        episodes: int | None,
        seed: int = 0,
        priority: int = PRIORITY,
        field_options: tuple[str, ...] = (),
        lockstep: bool = False,
        script: str | None = None,
        referee: bool = False,
        team: str = "blue",
    ) -> None:
        settings = DeploySettings(
            manager, "127.0.0.1:0", "grsim:127.0.0.1:9", team, list(range(robots)), {}, control_port=0
        )
        settings.priority, settings.lockstep = priority, lockstep
        settings.task = task if takes_task(manager) else None
        referee = referee or script is not None
        settings.referee = "127.0.0.1:0" if referee else None
        self.loop = build_loop(settings)
        field_options = (*field_options, "--team", team)
        if referee:
            field_options += ("--referee-port", str(self.loop.referee.sock.getsockname()[1]))
        if script is not None:
            field_options += ("--referee-script", script)
        command = [
            sys.executable,
            "-m",
            "hier_ssl.cli",
            "field",
            task,
            "--vision-port",
            str(self.loop.vision.getsockname()[1]),
            "--control",
            str(self.loop.control.port),
            "--grsim-port",
            "0",
            "--simulation-port",
            "0",
            "--seed",
            str(seed),
        ]
        command += ["--episodes", str(episodes)] if episodes else []
        command += [*field_options, "--lockstep"] if lockstep else field_options
        self.field = subprocess.Popen(command, stdout=subprocess.PIPE, text=True)
        ports = json.loads(self.field.stdout.readline())
        self.loop.sender.address = ("127.0.0.1", ports["grsim_port"])

    def run(self, seconds: float | None) -> tuple[LoopStats, list[dict[str, Any]]]:
        """Run for ``seconds`` (None: until the field server's episodes end); stats and its records."""
        stop = threading.Event()
        thread = threading.Thread(target=self.loop.run, args=(stop, seconds))
        thread.start()
        try:
            lines = [json.loads(line) for line in self.field.stdout] if seconds is None else []
            records = [line for line in lines if "episode" in line]  # not the fouls' summary at its exit
        finally:
            if seconds is None:
                stop.set()
            thread.join()
            self.field.terminate()
            self.field.wait()
            self.loop.close()
        return self.loop.stats, records


def takes_task(manager: str) -> bool:
    """Whether the manager takes its task from the command line (a planner) rather than its own files."""
    return is_planner(manager)
