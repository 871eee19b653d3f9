"""The package's layers hold: what each may import (README "Layout"), and that an environment without
learning brings no torch."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).parents[1] / "hier_ssl"
# Layer (a path under hier_ssl/) -> packages it must not import, anywhere in its modules.
FORBIDDEN = {
    "config.py": ("hier_ssl",),
    "learner_config.py": ("hier_ssl",),
    "world": ("hier_ssl.manager", "hier_ssl.worker", "hier_ssl.policies", "hier_ssl.envs"),
    "worker": ("hier_ssl.manager", "hier_ssl.envs"),
    "manager": ("hier_ssl.policies", "hier_ssl.envs"),
    "policies": ("hier_ssl.world",),
}
# Exceptions to FORBIDDEN: the config data assembles the learners' sections.
ALLOWED = {"config.py": ("hier_ssl.config.learners",)}


def _imports(path: Path, top_level_only: bool = False) -> list[str]:
    """Modules ``path`` imports (every ``import`` and ``from`` statement, or the module-level ones)."""
    tree = ast.parse(path.read_text())
    nodes = tree.body if top_level_only else ast.walk(tree)
    names = []
    for node in nodes:
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.append(node.module)
    return names


@pytest.mark.parametrize("layer", sorted(FORBIDDEN))
def test_layers_import_only_what_they_may(layer: str) -> None:
    root = PACKAGE / layer
    files = [root] if root.is_file() else sorted(root.rglob("*.py"))
    bad = [
        (path.relative_to(PACKAGE).as_posix(), name)
        for path in files
        for name in _imports(path)
        if any(name == f or name.startswith(f + ".") for f in FORBIDDEN[layer])
        and name not in ALLOWED.get(layer, ())
    ]
    assert not bad, bad


def test_modules_and_functions_stay_small() -> None:
    """A module reads in one sitting (at most 400 lines), a function on one screen (at most 80)."""
    too_long = []
    for path in sorted(PACKAGE.rglob("*.py")):
        text, name = path.read_text(), path.relative_to(PACKAGE).as_posix()
        if len(text.splitlines()) > 400:
            too_long.append((name, len(text.splitlines())))
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > 80:
                    too_long.append((f"{name}:{node.name}", lines))
    assert not too_long, too_long


def test_a_worker_loads_a_learned_network_only_on_first_use() -> None:
    # The policies' loader (and torch with it) comes with a learned worker, not with the package.
    bad = [
        (path.name, name)
        for path in sorted((PACKAGE / "worker").glob("*.py"))
        for name in _imports(path, top_level_only=True)
        if name.startswith("hier_ssl.policies") or (name == "torch" and path.name != "learned.py")
    ]
    assert not bad, bad


_ENV_WITHOUT_TORCH = """
import sys
import hier_ssl
from hier_ssl.world import World
env = hier_ssl.parallel_env(task="proposed", frame_skip=1)
env.reset(seed=0)
env.step({"manager_0": env.action_space("manager_0").sample()})
scenario = hier_ssl.scenario_env("crossing", num_agents=2)
scenario.reset(seed=0)
scenario.state()
import gymnasium
gym_env = gymnasium.make("hier_ssl/Obstacle-v0", frame_skip=16)  # registered by importing hier_ssl
gym_env.reset(seed=0)
gym_env.step(gym_env.action_space.sample())
vec = gymnasium.make_vec("hier_ssl/Proposed-v0", num_envs=2)
vec.reset(seed=0)
vec.step(vec.action_space.sample())
heavy = sorted(m for m in ("torch", "rsl_rl", "tensorboard", "tensordict") if m in sys.modules)
assert not heavy, heavy
"""


def test_an_environment_without_learning_imports_no_torch() -> None:
    subprocess.run([sys.executable, "-c", _ENV_WITHOUT_TORCH], check=True, cwd=PACKAGE.parent)
