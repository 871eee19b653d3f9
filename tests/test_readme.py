"""The README's own-controller example, run as written: the controller saved as the file the README
names, the command line run by the installed ``hier-ssl`` from that directory, the Python snippet run
there too."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

README = Path(__file__).parents[1] / "README.md"


def _blocks(section: str) -> dict[str, list[str]]:
    """The fenced code blocks of the README section titled ``section``, by language."""
    text = README.read_text()
    start = text.index(f"## {section}\n")
    end = text.find("\n## ", start + 1)
    blocks: dict[str, list[str]] = {}
    for language, code in re.findall(r"```(\w+)\n(.*?)```", text[start:end], re.DOTALL):
        blocks.setdefault(language, []).append(code)
    return blocks


def test_the_workers_section_example_runs_as_written(tmp_path: Path) -> None:
    blocks = _blocks("Workers")
    controller, snippet = blocks["python"]
    (command,) = blocks["bash"]
    (tmp_path / "my_controller.py").write_text(controller)
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}

    # The console script, not `python -m`: it must find my_controller.py in the directory it runs in.
    script = Path(sys.executable).parent / "hier-ssl"
    argv = shlex.split(command)
    assert argv[0] == "hier-ssl" and script.is_file()
    done = subprocess.run([str(script), *argv[1:]], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    for manager in ("direct", "sampling"):
        for worker in ("my_controller:Proportional", "paper"):
            assert f"| {manager} | {worker} |" in done.stdout

    done = subprocess.run(
        [sys.executable, "-c", snippet], cwd=tmp_path, env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    rows = [line.split() for line in done.stdout.splitlines()]
    assert [row[0] for row in rows] == ["my_controller:Proportional", "my_controller:Proportional+latency=4"]
    for _, success, length in rows:
        assert 0.9 <= float(success) <= 1.0 and 0 < float(length) < 1200
