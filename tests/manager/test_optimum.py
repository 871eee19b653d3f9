from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hier_ssl.config import TrainConfig
from hier_ssl.envs import load_config
from hier_ssl.manager import task_reward
from hier_ssl.manager.optimum import finish_value, finishing_wins, hover_value, in_threshold_bonus


def _hover_stream(gamma: float, frame_skip: int, summation: str, decisions: int = 4000) -> float:
    """Hovering played out with the task's own reward: the sub-goal 1 cm and 1 degree off the target,
    the robot parked next to it and never meeting the success test, discounted per decision."""
    target = np.zeros((1, 5))
    subgoal = np.array([[0.01, 0.0, np.deg2rad(1.0), 0.0, 0.0]])
    step, _ = task_reward("proposed", target, np.array([[0.3, 0.0]]), np.zeros(1), subgoal, np.array([False]))
    per_decision = step[0] * (frame_skip if summation == "sum" else 1)
    return float(sum(per_decision * gamma**k for k in range(decisions)))


@pytest.mark.parametrize(
    ("gamma", "frame_skip", "summation", "value"),
    [
        (0.99, 16, "sum", 17_600.0),
        (0.95, 16, "sum", 3_520.0),
        (0.99, 16, "last", 1_100.0),
        (0.99, 1, "sum", 1_100.0),
    ],
)
def test_hover_value_matches_the_discounted_stream_of_the_reward(
    gamma: float, frame_skip: int, summation: str, value: float
) -> None:
    assert hover_value(gamma, frame_skip, summation) == pytest.approx(value)
    assert _hover_stream(gamma, frame_skip, summation) == pytest.approx(value, rel=1e-9)


def test_the_papers_reward_hovers_and_a_large_enough_success_reward_finishes() -> None:
    assert in_threshold_bonus(16, "sum") == 176.0
    # Public code: gamma 0.99, last reward, R_t = 1000: hovering (1,100) beats finishing.
    assert not finishing_wins(0.99, 16, "last", 1.0)
    # Summed over 16 steps at gamma 0.95, R_t must reach 3,520: x3.5 loses, x5 wins.
    assert not finishing_wins(0.95, 16, "sum", 3.5)
    assert finishing_wins(0.95, 16, "sum", 5.0) and finish_value(5.0) == 5000.0
    with pytest.raises(ValueError, match="frame_skip_reward"):
        in_threshold_bonus(16, "mean")


CONFIGS = Path(__file__).parents[2] / "configs"
SHIPPED = sorted(p for p in CONFIGS.rglob("*.yaml") if "paper" not in p.parts and "worker" not in p.parts)


def _same_but_name(a: TrainConfig, b: TrainConfig) -> bool:
    words = {"name", "description"}  # what a config is called and says of itself, not what it trains
    return a.model_dump(exclude=words) == b.model_dump(exclude=words)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_every_default_config_rewards_finishing_over_hovering(path: Path) -> None:
    config = load_config(path)
    task = config.task_config
    if config.algo == "candidates":
        # Its PPO phase pays outcomes alone: no in-threshold bonus, and every decision costs time, so a
        # manager that hovers earns a negative stream where one that finishes earns success_reward.
        ppo = config.candidates.ppo
        assert ppo.success_reward > 0 and ppo.time_cost > 0, path.name
        return
    gamma = config.sac.gamma if config.algo == "sac" else config.ppo.gamma
    hover = hover_value(gamma, task.frame_skip, task.frame_skip_reward)
    twin = CONFIGS / "paper" / path.relative_to(CONFIGS)
    if twin.is_file() and _same_but_name(config, load_config(twin)):
        # A row where nothing cheaper matched the public code ships its settings (issue 31), hover value
        # and all: 1,100 against 1,000 without frame skip, and its runs finish (docs/research-notes.md).
        assert hover == pytest.approx(1_100.0), path.name
        return
    assert finishing_wins(gamma, task.frame_skip, task.frame_skip_reward, task.success_weight), (
        f"{path.name}: R_t = {finish_value(task.success_weight):.0f} < hovering {hover:.0f}"
    )
