from __future__ import annotations

import pytest

from hier_ssl.world.field import FIELDS, Field, get_field


def test_hardware_challenge_field_is_the_papers() -> None:
    field = get_field("hardware_challenge")
    assert (field.field_length, field.field_width) == (6.0, 4.0)
    assert (field.penalty_area_width, field.penalty_area_depth, field.goal_width) == (2.0, 0.8, 0.7)
    assert (field.half_length, field.half_width) == (3.0, 2.0)
    assert field.wall_half_extent == pytest.approx((3.3, 2.3))
    assert field.max_pos == pytest.approx(3.8)  # max(W/2, L/2 + penalty depth), docs/paper.md


# Rules 2.1.1 (playing area), 2.1.3 "Defense Area" (width along the goal line x depth), 2.1.4 "Goals" (side
# walls 1.8 m / 1 m apart, 0.18 m deep), 2.1.2 "Field Surface" (0.3 m field margins inside the wall).
@pytest.mark.parametrize(
    ("name", "size", "defense", "goal"),
    [("division_b", (9.0, 6.0), (2.0, 1.0), 1.0), ("division_a", (12.0, 9.0), (3.6, 1.8), 1.8)],
)
def test_ssl_division_presets_are_the_rules(
    name: str, size: tuple[float, float], defense: tuple[float, float], goal: float
) -> None:
    field = get_field(name)
    assert (field.name, field.field_length, field.field_width) == (name, *size)
    assert (field.penalty_area_width, field.penalty_area_depth) == defense
    assert (field.goal_width, field.goal_depth, field.boundary_width) == (goal, 0.18, 0.3)
    # The walled area is the field plus its margins: 12 + 2 * 0.3 = 12.6 m long for Division A.
    assert field.wall_half_extent == pytest.approx((size[0] / 2 + 0.3, size[1] / 2 + 0.3))


def test_unknown_preset_raises_naming_it_and_the_known_ones() -> None:
    with pytest.raises(ValueError, match=r"unknown field preset 'division_c'; known: \['division_a'"):
        get_field("division_c")


def test_fields_are_immutable_data() -> None:
    field = FIELDS["division_b"]
    with pytest.raises(AttributeError):
        field.field_length = 10.0  # type: ignore[misc]
    assert isinstance(field, Field) and get_field("division_b") is field
