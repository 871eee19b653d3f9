"""docs/guide/layout.md's "Add a scenario", run as written: its one Python file (a static no-go circle with a
reward term and an ending of its own) and its one YAML make a scenario that the PettingZoo view runs
through ``parallel_api_test``, whose robots pay the circle's penalty and leave where they enter it."""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import hier_ssl
from hier_ssl.envs import SCENARIOS, HierarchicalCore, Scenario, scenario_config

PAGE = Path(__file__).parents[2] / "docs" / "guide" / "layout.md"


@pytest.fixture
def no_go(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The page's two blocks saved as ``no_go.py`` and ``no_go.yaml`` and the module imported, registered
    for this test alone; the YAML's path."""
    section = PAGE.read_text().split("## Add a scenario\n", 1)[1]
    (python,), (yaml,) = (
        re.findall(rf"```{lang}\n(.*?)```", section, re.DOTALL) for lang in ("python", "yaml")
    )
    (tmp_path / "no_go.py").write_text(python)
    (tmp_path / "no_go.yaml").write_text(yaml)
    monkeypatch.setattr("hier_ssl.envs.registry.SCENARIOS", dict(SCENARIOS))
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "no_go", raising=False)
    importlib.import_module("no_go")
    return tmp_path / "no_go.yaml"


def test_the_worked_example_passes_the_parallel_api_test_and_draws_its_circle(
    no_go: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    env = hier_ssl.parallel_env(no_go)
    assert env.core.scenario.name == "no_go_circle"
    assert env.possible_agents == [f"manager_{i}" for i in range(4)]
    parallel_api_test(env, num_cycles=100)
    env = hier_ssl.parallel_env(no_go, render_mode="rgb_array")
    env.reset(seed=0)
    frame = env.render()
    monkeypatch.setattr(type(env.core.scenario), "extra_render", Scenario.extra_render)
    changed = (frame != env.render()).any(axis=-1)
    rows, cols = np.nonzero(changed)
    assert len(rows) and abs(rows.mean() / frame.shape[0] - 0.5) < 0.05
    assert abs(cols.mean() / frame.shape[1] - 0.5) < 0.05  # the circle, at the field's centre


def test_a_robot_inside_the_circle_pays_the_penalty_and_leaves_as_a_collision(no_go: Path) -> None:
    """One control step from the same placement with robot 1 of field 0 moved into the circle: its reward
    is crossing's less the penalty, and it alone leaves, as a collision."""
    same = {"field": "division_b", "num_agents": 4, "neighbours": 3, "frame_skip": 1}
    cores = [
        HierarchicalCore(scenario_config(no_go, frame_skip=1), 2, autoreset=False),
        HierarchicalCore(scenario_config("crossing", **same, options={"radius": 2.0}), 2, autoreset=False),
    ]
    results = []
    for core in cores:
        core.reset(seed=0)
        pos = core.state.pos.copy()
        pos[0, 1] = [0.1, -0.1]
        core.world.set_state([0], pos[:1], core.state.angle[:1])
        results.append(core.step(np.zeros((2, 4, core.act_dim))))
    no_go_result, crossing = results
    penalty = cores[0].scenario.options.penalty
    expected = crossing.reward.astype(np.float64)
    expected[0, 1] -= penalty
    np.testing.assert_allclose(no_go_result.reward, expected, rtol=1e-6)
    left = np.zeros((2, 4), dtype=bool)
    left[0, 1] = True
    np.testing.assert_array_equal(no_go_result.info["collision"], left | crossing.info["collision"])
    np.testing.assert_array_equal(no_go_result.terminated, left | crossing.terminated)
