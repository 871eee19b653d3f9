"""The examples of the README and the user guide (docs/), run as written: the own-controller example (the
controller saved as the file the page names, the command line run by the installed ``hier-ssl`` from that
directory, the Python snippets run there too), the Gymnasium / Stable-Baselines3 / CleanRL snippets and
the multi-agent one."""

from __future__ import annotations

import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

from hier_ssl.cli import build_parser
from hier_ssl.config.files import config_names

ROOT = Path(__file__).parents[1]
GUIDE = ROOT / "docs" / "guide"


def _blocks(page: Path, section: str) -> dict[str, list[str]]:
    """The fenced code blocks of ``page``'s section titled ``section`` (a level-1 or level-2 heading, up to
    the next heading of level 1 or 2), by language."""
    text = page.read_text()
    start = re.search(rf"^##? {re.escape(section)}\n", text, re.MULTILINE).end()
    following = re.search(r"^##? ", text[start:], re.MULTILINE)
    end = len(text) if following is None else start + following.start()
    blocks: dict[str, list[str]] = {}
    for language, code in re.findall(r"```(\w+)\n(.*?)```", text[start:end], re.DOTALL):
        blocks.setdefault(language, []).append(code)
    return blocks


def _environment() -> dict[str, str]:
    # One torch thread: two OpenMP threads stall badly on a busy 2-core CPU (tests/conftest.py).
    return {**os.environ, "PYTHONUNBUFFERED": "1", "OMP_NUM_THREADS": "1"}


def _run(snippet: str, cwd: Path) -> list[list[str]]:
    """The snippet's printed lines, split into words; it must exit 0."""
    done = subprocess.run(
        [sys.executable, "-c", snippet], cwd=cwd, env=_environment(), capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    return [line.split() for line in done.stdout.splitlines()]


def test_the_workers_section_example_runs_as_written(tmp_path: Path) -> None:
    blocks = _blocks(GUIDE / "workers.md", "Workers and your own controller")
    controller, snippet, objects = blocks["python"]
    (command,) = blocks["bash"]
    (tmp_path / "my_controller.py").write_text(controller)
    env = _environment()

    # The console script, not `python -m`: it must find my_controller.py in the directory it runs in.
    script = Path(sys.executable).parent / "hier-ssl"
    argv = shlex.split(command)
    assert argv[0] == "hier-ssl" and script.is_file()
    done = subprocess.run([str(script), *argv[1:]], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    for manager in ("direct", "sampling"):
        for worker in ("my_controller:Proportional", "paper"):
            assert f"| {manager} | {worker} |" in done.stdout

    rows = _run(snippet, tmp_path)
    assert [row[0] for row in rows] == ["my_controller:Proportional", "my_controller:Proportional+latency=4"]
    for _, success, length in rows:
        assert 0.9 <= float(success) <= 1.0 and 0 < float(length) < 1200

    # The controller as an object: labelled module:Class beside the paper's worker, for both planners.
    rows = _run(objects, tmp_path)
    assert [row[:2] for row in rows] == [
        ["direct", "my_controller:Proportional"],
        ["direct", "paper"],
        ["sampling", "my_controller:Proportional"],
        ["sampling", "paper"],
    ]
    assert all(0.9 <= float(row[2]) <= 1.0 for row in rows)


def test_the_gymnasium_section_examples_run_as_written(tmp_path: Path) -> None:
    sb3, vector = _blocks(GUIDE / "environments.md", "Gymnasium, Stable-Baselines3, CleanRL")["python"]
    (row,) = _run(sb3, tmp_path)
    limit, length, success, cpad = row
    assert int(limit) == 75 and 1 <= int(length) <= 75 and success in ("0.0", "1.0") and float(cpad) >= 0
    rows = _run(vector, tmp_path)
    assert len(rows) >= 8  # 150 decisions of 8 fields: every field ends an episode (at most 75 each)
    for words in rows:
        assert words[0] == "field" and 0 <= int(words[1].rstrip(":")) < 8 and words[-1] == "m"


def test_the_subproc_vec_env_example_runs_as_written(tmp_path: Path) -> None:
    (snippet,) = _blocks(GUIDE / "environments.md", "Processes, SuperSuit, TorchRL")["python"]
    assert _run(snippet, tmp_path) == [["(2,", "13)", "(2,)"]]


def test_the_multi_agent_example_runs_as_written(tmp_path: Path) -> None:
    (snippet,) = _blocks(GUIDE / "environments.md", "Multi-agent learners: the global state")["python"]
    ((space, *states, steps),) = _run(snippet, tmp_path)
    assert space == "(80,)"  # 7 x 4 robot columns + 13 x 4 controlled-robot columns
    assert "".join(states) == f"({steps},80)" and int(steps) >= 1


def test_the_getting_started_snippet_runs_as_written(tmp_path: Path) -> None:
    (snippet,) = _blocks(ROOT / "docs" / "getting-started.md", "A first session")["python"]
    (words,) = _run(snippet, tmp_path)
    keys = [word.strip("{'\":") for word in words[::2]]
    assert keys == ["return", "length", "decisions", "success", "collision", "cpad"]


def test_the_readme_tour_runs_as_written(tmp_path: Path) -> None:
    blocks = _blocks(ROOT / "README.md", "A tour")
    (snippet,) = blocks["python"]
    (words,) = _run(snippet, tmp_path)
    assert [word.strip("{'\":") for word in words[::2]][:4] == ["return", "length", "decisions", "success"]
    # The commands parse as the CLI takes them and name what exists: shipped configs, files of the checkout.
    (commands,) = blocks["bash"]
    for line in commands.splitlines():
        argv = shlex.split(line.split("#")[0])
        if argv[0] == "hier-ssl":
            args = build_parser().parse_args(argv[1:])
            assert args.command != "train" or args.config in config_names(), line
        else:
            assert argv[0] == "python" and (ROOT / argv[1]).is_file(), line


def test_every_tour_line_that_needs_an_extra_names_it() -> None:
    (commands,) = _blocks(ROOT / "README.md", "A tour")["bash"]
    for line in commands.splitlines():
        command, _, comment = line.partition("#")
        argv = shlex.split(command)
        # An ONNX file runs on onnxruntime, which only the export extra installs; deploy needs a simulator.
        runs_onnx = any(arg.endswith(".onnx") for arg in argv) and "export" not in argv[:2]
        assert not runs_onnx or '".[export]"' in comment, line
        assert "deploy" not in argv[:2] or "grSim" in comment, line


def test_the_front_pages_commands_paste_into_a_shell_as_they_are() -> None:
    for page in (ROOT / "README.md", ROOT / "docs" / "getting-started.md"):
        for block in re.findall(r"```bash\n(.*?)```", page.read_text(), re.DOTALL):
            for line in block.splitlines():
                command = line.partition("#")[0]
                # `runs/<run>` is a redirection from a file named run.
                assert "<" not in command and ">" not in command, f"{page.name}: {line}"


def test_the_readme_quotes_each_time_as_getting_started_does() -> None:
    readme, guide = (ROOT / "README.md").read_text(), (ROOT / "docs" / "getting-started.md").read_text()
    measured = r"^Measured on a fresh clone, 2 CPU cores.*: the first line takes (\d+ min)"
    first = re.search(measured, readme, re.MULTILINE)
    assert first is not None and first.group() in guide
    index = " ".join((ROOT / "docs" / "index.md").read_text().split())
    assert f"{first.group(1)} on 2 CPU cores" in index
    (tour,) = _blocks(ROOT / "README.md", "A tour")["bash"]
    for command in ("train obstacle/scorer", "export runs/scorer", "render crossing"):
        (line,) = [line for line in tour.splitlines() if command in line]
        time = re.search(r"# ((?:about )?\d[^;:]*)[;:]", line)
        assert time is not None and re.search(r"\d (min|s)\b", time.group(1)), line
        assert time.group(1) in guide, f"getting-started.md does not quote {time.group(1)} for {command}"


def test_the_readme_is_a_front_page_whose_links_resolve() -> None:
    text = (ROOT / "README.md").read_text()
    assert len(text.splitlines()) < 200
    # A front page, not a research log: the long story is in docs/results.md and docs/research-notes.md.
    assert max(map(len, text.splitlines())) <= 400
    results = text[text.index("## Results") : text.index("## Documentation")]
    prose = [part for part in results.split("\n\n") if not part.lstrip().startswith(("|", "```"))]
    assert max(map(len, prose)) <= 400
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", text)
    assert any(link.startswith("docs/") for link in links)
    for link in links:
        assert (ROOT / link).exists(), f"README links {link}, which is not in the repository"
