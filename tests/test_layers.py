"""What import-linter (``lint-imports``, contracts in pyproject.toml) cannot check: modules and functions
stay small, and an environment without learning, once imported and stepped, has brought no torch."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).parents[1] / "hier_ssl"


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
