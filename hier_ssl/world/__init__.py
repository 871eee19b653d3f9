"""The world: field geometry, robot bodies, obstacle behaviours and contacts, N fields stepped together.

A world's fields hold entities of the kinds it simulates (``entities.py``: robots and balls),
added in groups by a scenario. Everything crosses this boundary as arrays with a leading (fields, entities
of one kind) pair of axes. Drawing
(``hier_ssl.world.render``, matplotlib) is imported where it is used.
"""

from __future__ import annotations

from hier_ssl.world.ball import BallSpec, BallState
from hier_ssl.world.entities import KINDS, Entities
from hier_ssl.world.field import FIELDS, Field, get_field
from hier_ssl.world.frames import to_field_frame, to_robot_frame, wrap_angle
from hier_ssl.world.obstacles import (
    OBSTACLE_AGENT_OBS_DIM,
    OBSTACLES,
    PublicCodeRandom,
    RandomWalk,
    Stationary,
    make_obstacle,
    obstacle_observation,
)
from hier_ssl.world.physics import RobotSpec, RobotState, World

__all__ = [
    "FIELDS",
    "KINDS",
    "OBSTACLE_AGENT_OBS_DIM",
    "OBSTACLES",
    "BallSpec",
    "BallState",
    "Entities",
    "Field",
    "PublicCodeRandom",
    "RandomWalk",
    "RobotSpec",
    "RobotState",
    "Stationary",
    "World",
    "get_field",
    "make_obstacle",
    "obstacle_observation",
    "to_field_frame",
    "to_robot_frame",
    "wrap_angle",
]
