"""The SSL game as rules: the referee's state, the zones and speed limits it sets.

Pure functions of arrays with a leading N (fields), like the world's poses, so that the environments, the
planners and the deploy bridge call one implementation of the rules. This layer sits between ``manager |
worker`` and ``world``: it imports the world's field and nothing above it. docs/guide/ssl-game.md gives
every number with its section of the league's rules.
"""

from __future__ import annotations

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
    "NORMAL_START",
    "NO_KEEPER",
    "ROBOT_RADIUS",
    "SLOTS",
    "STOP",
    "YELLOW",
    "Lineup",
    "RefereeState",
    "Zones",
    "check_keepers",
    "forbidden_zones",
    "lineup",
    "referee_state",
    "signed_distance",
    "speed_limit",
    "violates",
]
