"""Field geometry as data: the paper's hardware-challenge field and the SSL division presets.

The attribute names are SSL-Vision's geometry message's (``SSL_GeometryFieldSize``: ``field_length``,
``field_width``, ``goal_width``, ``goal_depth``, ``boundary_width``, ``penalty_area_depth``,
``penalty_area_width``), in metres where the wire has millimetres, so that a geometry packet can fill one
in. The numbers of the division presets are the league's rules, "Playing Environment" (docs/guide/ssl-game.md
gives each with its section).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Field:
    """A rectangular SSL field, origin at its centre, x along its length. All lengths in metres.

    ``field_length`` x ``field_width`` is the playing area inside the field lines; ``penalty_area_*`` the
    defense area in front of each goal (width along the goal line, depth into the field); ``goal_width`` the
    distance between the goal's side walls and ``goal_depth`` how far the goal reaches behind the goal line;
    ``boundary_width`` the field margin between the field lines and the walls robots collide with.
    """

    name: str
    field_length: float
    field_width: float
    penalty_area_width: float
    penalty_area_depth: float
    goal_width: float
    # Rules 2.1.4 "Goals": the goal is 0.18 m deep in both divisions.
    goal_depth: float = 0.18
    # Rules 2.1.2 "Field Surface": of the 0.7 m beyond the field lines, the outer 0.4 m lie behind the wall;
    # the 0.3 m inside it are the field margins robots may use.
    boundary_width: float = 0.3

    @property
    def half_length(self) -> float:
        return self.field_length / 2

    @property
    def half_width(self) -> float:
        return self.field_width / 2

    @property
    def wall_half_extent(self) -> tuple[float, float]:
        """Half extents (x, y) of the walled area: the field plus its boundary."""
        return self.half_length + self.boundary_width, self.half_width + self.boundary_width

    @property
    def max_pos(self) -> float:
        """Position normaliser of the paper's observation: max(W/2, L/2 + penalty depth)."""
        return max(self.half_width, self.half_length + self.penalty_area_depth)


FIELDS: dict[str, Field] = {
    # The paper's 6 x 4 m field (docs/paper.md "The world").
    "hardware_challenge": Field("hardware_challenge", 6.0, 4.0, 2.0, 0.8, 0.7),
    # SSL rules 2.1.1 "Dimensions" (playing area), 2.1.3 "Defense Area" (width x depth), 2.1.4 "Goals"
    # (distance between the side walls): Division B 9 x 6 m, 2 x 1 m, 1 m; Division A 12 x 9 m, 3.6 x 1.8 m,
    # 1.8 m.
    "division_b": Field("division_b", 9.0, 6.0, 2.0, 1.0, 1.0),
    "division_a": Field("division_a", 12.0, 9.0, 3.6, 1.8, 1.8),
}


def get_field(name: str) -> Field:
    """The preset called ``name``; a ValueError lists the known presets otherwise."""
    try:
        return FIELDS[name]
    except KeyError:
        raise ValueError(f"unknown field preset {name!r}; known: {sorted(FIELDS)}") from None
