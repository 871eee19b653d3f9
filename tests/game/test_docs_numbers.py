"""The numbers docs/guide/ssl-game.md gives are the code's: the field table and the referee's commands."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from hier_ssl.game.referee import COMMANDS
from hier_ssl.world.field import get_field

PAGE = (Path(__file__).parents[2] / "docs" / "guide" / "ssl-game.md").read_text()


def _rows(heading: str) -> list[list[str]]:
    """The cells of the first table under ``heading``, header and rule left out."""
    section = PAGE.split(f"## {heading}\n", 1)[1].split("\n## ", 1)[0]
    lines = [line for line in section.splitlines() if line.startswith("|")]
    return [[cell.strip() for cell in line.strip("|").split("|")] for line in lines[2:]]


def test_the_field_table_is_the_presets() -> None:
    rows = _rows("The field")
    assert len(rows) == 5
    for names, *values, _rule in rows:
        attributes = re.findall(r"`(\w+)`", names)
        for division, cell in zip(("division_a", "division_b"), values, strict=True):
            numbers = [float(v) for v in cell.removesuffix(" m").split(" x ")]
            field = get_field(division)
            assert [getattr(field, a) for a in attributes] == pytest.approx(numbers), (names, division)


def test_the_command_table_is_the_game_controllers_numbering() -> None:
    documented = {}
    for names, numbers, *_ in _rows("The referee's state"):
        documented.update(zip(re.findall(r"`(\w+)`", names), map(int, numbers.split(", ")), strict=True))
    assert documented == {name: number for number, name in COMMANDS.items()}
