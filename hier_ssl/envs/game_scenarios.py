"""The four game scenarios (docs/guide/ssl-game.md, "The game scenarios"), each a ``GameScenario`` with
its own defaults, boxes and referee's command:

- ``game_stop`` (Division B, 6 v 6): the game runs with a rolling ball; STOP comes at a random time and our
  robots take their role positions, legally, for the ball where it will come to rest.
- ``game_free_kick``: the opponent's free kick in our half; our robots take defending positions.
- ``game_ball_placement``: an opponent carries the ball to the placement position; our robots cross the
  field around the stadium the rules forbid.
- ``game_match`` (Division A, 11 v 11): the game runs; the ball lost, our robots fall back from the half
  we attack into ours, through 21 other robots and a rolling ball.
"""

from __future__ import annotations

import numpy as np

from hier_ssl.config import ScenarioConfig
from hier_ssl.envs.game import GameOptions, GameScenario
from hier_ssl.envs.registry import register_scenario
from hier_ssl.game import BALL_PLACEMENT_BLUE, referee_state

# Every game scenario's defaults: Division B, 6 v 6, the opponents' rows "stationary" (their team moves them).
GAME_DEFAULTS = {
    "field": "division_b",
    "num_agents": 6,
    "num_obstacles": 6,
    "obstacles": {"behaviour": "stationary"},
    "max_steps": 800,
}


class StopOptions(GameOptions):
    command: str = "STOP"
    command_at: tuple[float, float] = (1.0, 4.0)
    ball_speed: tuple[float, float] = (0.5, 2.5)


@register_scenario
class GameStop(GameScenario):
    """Division B, 6 v 6: the game runs with a rolling ball; STOP comes at a random time and our robots take
    role positions in our half, legally for the ball where it will come to rest, under STOP's speed
    limit."""

    name = "game_stop"
    Options = StopOptions
    defaults = GAME_DEFAULTS
    target_box = ((-1.0, -1.0), (0.0, 1.0))


class FreeKickOptions(GameOptions):
    command: str = "DIRECT_FREE_BLUE"


@register_scenario
class GameFreeKick(GameScenario):
    """The opponent's free kick in our half (Division B, 6 v 6): our robots take defending positions in our
    half, 0.5 m from the ball, half of them marking an attacker goal-side, while the opponents move."""

    name = "game_free_kick"
    Options = FreeKickOptions
    defaults = GAME_DEFAULTS
    start_box = ((-1.0, -1.0), (0.5, 1.0))
    target_box = ((-1.0, -1.0), (-0.1, 1.0))
    ball_box = ((-0.7, -0.8), (-0.1, 0.8))
    mark_share = 0.5  # half the defenders mark an attacker goal-side, as a defence does at a free kick


class PlacementOptions(GameOptions):
    command: str = "BALL_PLACEMENT_BLUE"
    # m, field frame: where the ball is to be placed; None: drawn per episode across the field's middle.
    placement: tuple[float, float] | None = None


@register_scenario
class GameBallPlacement(GameScenario):
    """The opponents place the ball (Division B, 6 v 6): one of them carries it along the field's middle to
    the placement position while our robots cross the field, from one side to the other, around the
    stadium the rules forbid them (0.5 m from the segment ball -> placement position)."""

    name = "game_ball_placement"
    Options = PlacementOptions
    defaults = GAME_DEFAULTS
    start_box = ((-0.9, 0.45), (0.9, 1.0))
    target_box = ((-0.9, -1.0), (0.9, -0.45))
    ball_box = ((-0.8, -0.25), (-0.15, 0.25))
    placement_box = ((0.15, -0.25), (0.8, 0.25))

    def __init__(self, config: ScenarioConfig) -> None:
        super().__init__(config)
        fixed = self.options.placement
        if fixed is not None:
            try:
                referee_state(BALL_PLACEMENT_BLUE, self.field, placement=np.array(fixed))
            except ValueError as err:
                raise ValueError(f"options.placement: {err}") from None

    def placement_position(self, rng: np.random.Generator, mirror: np.ndarray) -> np.ndarray:
        drawn = super().placement_position(rng, mirror)
        fixed = self.options.placement
        return drawn if fixed is None else np.broadcast_to(np.array(fixed, float), drawn.shape).copy()


class MatchOptions(GameOptions):
    ball_speed: tuple[float, float] = (1.0, 3.0)


@register_scenario
class GameMatch(GameScenario):
    """Division A, 11 v 11, the game running (FORCE_START): the ball lost, our robots fall back from the
    half we attack to positions in ours, half of them marking an opponent goal-side, through the 21 other
    robots and a rolling ball."""

    name = "game_match"
    Options = MatchOptions
    # Moves anywhere were solved by ``sampling`` at 96 % (frame skip 1), falling back across the field
    # alone at 97 %: the team falls back to mark, half of it goal-side of an opponent that moves on.
    start_box = ((0.0, -1.0), (1.0, 1.0))
    target_box = ((-1.0, -1.0), (0.0, 1.0))
    mark_share = 0.5
    defaults = GAME_DEFAULTS | {
        "field": "division_a",
        "num_agents": 11,
        "num_obstacles": 11,
        "max_steps": 1200,
    }
    ball_box = ((-0.8, -0.8), (0.8, 0.8))


__all__ = [
    "GAME_DEFAULTS",
    "GameBallPlacement",
    "GameFreeKick",
    "GameMatch",
    "GameStop",
]
