"""Field geometry as data: the paper's hardware-challenge field and the SSL division presets."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Field:
    """A rectangular SSL field, origin at its centre, x along its length. All lengths in metres.

    ``boundary`` is the run-off area between the field lines and the walls robots collide with.
    """

    name: str
    length: float
    width: float
    penalty_width: float
    penalty_depth: float
    goal_width: float
    boundary: float = 0.3

    @property
    def half_length(self) -> float:
        return self.length / 2

    @property
    def half_width(self) -> float:
        return self.width / 2

    @property
    def wall_half_extent(self) -> tuple[float, float]:
        """Half extents (x, y) of the walled area: the field plus its boundary."""
        return self.half_length + self.boundary, self.half_width + self.boundary

    @property
    def max_pos(self) -> float:
        """Position normaliser of the paper's observation: max(W/2, L/2 + penalty depth)."""
        return max(self.half_width, self.half_length + self.penalty_depth)


FIELDS: dict[str, Field] = {
    # The paper's 6 x 4 m field (docs/paper.md "The world").
    "hardware_challenge": Field("hardware_challenge", 6.0, 4.0, 2.0, 0.8, 0.7),
    # SSL rules: Division B 9 x 6 m with a 2 x 1 m defense area, Division A 12 x 9 m with 3.6 x 1.8 m.
    "division_b": Field("division_b", 9.0, 6.0, 2.0, 1.0, 1.0),
    "division_a": Field("division_a", 12.0, 9.0, 3.6, 1.8, 1.8),
}


def get_field(name: str) -> Field:
    """The preset called ``name``; a ValueError lists the known presets otherwise."""
    try:
        return FIELDS[name]
    except KeyError:
        raise ValueError(f"unknown field preset {name!r}; known: {sorted(FIELDS)}") from None
