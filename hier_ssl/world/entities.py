"""What a world's fields hold, by entity kind: robots and balls.

A scenario adds its entities in groups (``Entities.add``): each group is ``count`` entities of one kind,
and takes the next rows of that kind's state arrays, whose leading axes are (fields, entities of the
kind). Every field holds the same entities. More entities of a kind the world simulates need no change to
the world; a new kind is one more entry of ``KINDS`` and its bodies and state in ``World``.
"""

from __future__ import annotations

from dataclasses import dataclass

# The kinds a World simulates, each with its state class: "robot", ``hier_ssl.world.robot.RobotState``;
# "ball", ``hier_ssl.world.ball.BallState``.
KINDS = ("robot", "ball")


@dataclass(frozen=True)
class Group:
    """``rows`` of the ``kind``'s state arrays (axis 1), named ``name`` by the scenario that added them."""

    kind: str
    name: str
    rows: slice

    @property
    def count(self) -> int:
        return self.rows.stop - self.rows.start


class Entities:
    """The groups of entities of every field of a world, in the order they were added."""

    def __init__(self) -> None:
        self.groups: list[Group] = []
        self._counts: dict[str, int] = {}

    def add(self, kind: str, count: int, name: str) -> Group:
        """``count`` more entities of ``kind``, after those of that kind added before; their group."""
        if kind not in KINDS:
            raise ValueError(f"unknown entity kind {kind!r}; a world simulates {list(KINDS)}")
        if not (isinstance(count, int) and count >= 0):
            raise ValueError(f"count of {name!r} must be an integer >= 0, got {count!r}")
        first = self._counts.get(kind, 0)
        group = Group(kind, name, slice(first, first + count))
        self._counts[kind] = first + count
        self.groups.append(group)
        return group

    def count(self, kind: str) -> int:
        """How many entities of ``kind`` every field holds."""
        return self._counts.get(kind, 0)

    def of(self, kind: str) -> list[Group]:
        """The groups of ``kind``, in their rows' order."""
        return [group for group in self.groups if group.kind == kind]


def robots(count: int) -> Entities:
    """``count`` robots, one group: a world's entities when only their number is given."""
    entities = Entities()
    entities.add("robot", count, "robots")
    return entities


__all__ = ["KINDS", "Entities", "Group", "robots"]
