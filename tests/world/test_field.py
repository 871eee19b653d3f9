from __future__ import annotations

import pytest

from hier_ssl.world.field import FIELDS, Field, get_field


def test_hardware_challenge_field_is_the_papers() -> None:
    field = get_field("hardware_challenge")
    assert (field.length, field.width) == (6.0, 4.0)
    assert (field.penalty_width, field.penalty_depth, field.goal_width) == (2.0, 0.8, 0.7)
    assert (field.half_length, field.half_width) == (3.0, 2.0)
    assert field.wall_half_extent == pytest.approx((3.3, 2.3))
    assert field.max_pos == pytest.approx(3.8)  # max(W/2, L/2 + penalty depth), docs/paper.md


@pytest.mark.parametrize(("name", "length", "width"), [("division_b", 9.0, 6.0), ("division_a", 12.0, 9.0)])
def test_ssl_division_presets(name: str, length: float, width: float) -> None:
    field = get_field(name)
    assert (field.name, field.length, field.width, field.boundary) == (name, length, width, 0.3)
    assert field.penalty_width < field.width and field.goal_width < field.penalty_width


def test_unknown_preset_raises_naming_it_and_the_known_ones() -> None:
    with pytest.raises(ValueError, match=r"unknown field preset 'division_c'; known: \['division_a'"):
        get_field("division_c")


def test_fields_are_immutable_data() -> None:
    field = FIELDS["division_b"]
    with pytest.raises(AttributeError):
        field.length = 10.0  # type: ignore[misc]
    assert isinstance(field, Field) and get_field("division_b") is field
