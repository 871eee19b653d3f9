"""The SSL game as rules: the referee's state, the zones and speed limits it sets, the fouls it calls.

Pure functions of arrays with a leading N (fields), like the world's poses, so that the environments, the
planners and the deploy bridge call one implementation of the rules. This layer sits between ``manager |
worker`` and ``world``: it imports the world's field and nothing above it. docs/guide/ssl-game.md gives
every number with its section of the league's rules.
"""

from __future__ import annotations

from hier_ssl.game.fouls import KINDS, FoulClocks, FoulReport, Motion, crash_verdicts, new_clocks, step_fouls
from hier_ssl.game.referee import (
    BALL_PLACEMENT_BLUE,
    BALL_PLACEMENT_YELLOW,
    BLUE,
    COMMANDS,
    DIRECT_FREE_BLUE,
    DIRECT_FREE_YELLOW,
    FORCE_START,
    HALT,
    NO_KEEPER,
    NORMAL_START,
    STOP,
    YELLOW,
    Lineup,
    RefereeState,
    ball_in_play,
    check_keepers,
    lineup,
    referee_state,
)
from hier_ssl.game.zones import (
    ROBOT_RADIUS,
    SLOTS,
    Zones,
    forbidden_zones,
    signed_distance,
    speed_limit,
    violates,
)

__all__ = [
    "BALL_PLACEMENT_BLUE",
    "BALL_PLACEMENT_YELLOW",
    "BLUE",
    "COMMANDS",
    "DIRECT_FREE_BLUE",
    "DIRECT_FREE_YELLOW",
    "FORCE_START",
    "HALT",
    "KINDS",
    "NORMAL_START",
    "NO_KEEPER",
    "ROBOT_RADIUS",
    "SLOTS",
    "STOP",
    "YELLOW",
    "FoulClocks",
    "FoulReport",
    "Lineup",
    "Motion",
    "RefereeState",
    "Zones",
    "ball_in_play",
    "check_keepers",
    "crash_verdicts",
    "forbidden_zones",
    "lineup",
    "new_clocks",
    "referee_state",
    "signed_distance",
    "speed_limit",
    "violates",
    "step_fouls",
]
