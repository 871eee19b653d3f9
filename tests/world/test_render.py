from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.world.physics import World
from hier_ssl.world.render import BALL, GOAL, TEAM_COLORS, render_fields


def _rgb(color: str) -> np.ndarray:
    return np.array([int(color[i : i + 2], 16) for i in (1, 3, 5)])


def _world() -> World:
    world = World(2, 3)
    world.set_state([0, 1], np.array([[[-1.5, 0.5], [1.0, -1.0], [2.0, 1.2]]] * 2), np.zeros((2, 3)))
    return world


def test_render_returns_an_rgb_image_with_robots_in_team_colours() -> None:
    world = _world()
    image = render_fields(
        world.field,
        world.state,
        targets=np.array([[1.0, 1.0, 0.5, 0.0, 0.0]] * 2),
        subgoals=np.zeros((2, 3, 5)),
        trails=[np.array([[-2.0, -1.0], [-1.5, 0.5]]), np.array([[0.0, -1.5], [1.0, -1.0]])],
        size=(330, 230),
    )
    assert image.shape == (230, 330, 3) and image.dtype == np.uint8
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 10  # not blank
    # The walled area and a 5 cm margin fill the image, origin at its centre, y up. Robot 0 (controlled) is
    # at (-1.5, 0.5), robot 1 (obstacle) at (1.0, -1.0); sample a little off the centre, away from the
    # heading tick along +x.
    hx, hy = world.field.wall_half_extent
    px_per_m = 1 / max(2 * (hx + 0.05) / 330, 2 * (hy + 0.05) / 230)
    for (x, y), team in [((-1.5, 0.5), 0), ((1.0, -1.0), 1)]:
        col, row = round(165 + px_per_m * x), round(115 - px_per_m * y)
        pixel = image[row - 2, col - 2].astype(int)
        assert np.abs(pixel - _rgb(TEAM_COLORS[team])).max() < 40, (team, pixel)


def test_render_picks_the_field_and_checks_its_arguments() -> None:
    world = _world()
    first = render_fields(world.field, world.state, field_index=1, size=(200, 140))
    assert first.shape == (140, 200, 3)
    with pytest.raises(ValueError, match="field_index 2 out of range"):
        render_fields(world.field, world.state, field_index=2)
    with pytest.raises(ValueError, match="team has shape"):
        render_fields(world.field, world.state, team=[0, 1])
    with pytest.raises(ValueError, match="targets must have shape"):
        render_fields(world.field, world.state, targets=np.zeros(3))


def test_several_controlled_robots_each_get_their_own_colour() -> None:
    from hier_ssl.world.render import ROBOT_COLORS

    world = _world()
    image = render_fields(world.field, world.state, team=[0, 0, 1], size=(330, 230))
    hx, hy = world.field.wall_half_extent
    px_per_m = 1 / max(2 * (hx + 0.05) / 330, 2 * (hy + 0.05) / 230)
    for (x, y), color in [
        ((-1.5, 0.5), ROBOT_COLORS[0]),
        ((1.0, -1.0), ROBOT_COLORS[1]),
        ((2.0, 1.2), TEAM_COLORS[1]),
    ]:
        col, row = round(165 + px_per_m * x), round(115 - px_per_m * y)
        pixel = image[row - 2, col - 2].astype(int)
        assert np.abs(pixel - _rgb(color)).max() < 40, (color, pixel)
    assert len(set(ROBOT_COLORS)) == 11 and TEAM_COLORS[1] not in ROBOT_COLORS
    with pytest.raises(ValueError, match="trail_robot"):
        render_fields(world.field, world.state, trails=[np.zeros((2, 2))] * 4)


@pytest.mark.parametrize("team", [[0, 1, 1], [0, 0, 1]])
def test_an_ssl_game_draws_ours_yellow_and_theirs_blue(team: list[int]) -> None:
    from hier_ssl.world.render import GAME_ROBOT_COLORS, SSL_BLUE, SSL_YELLOW

    world = _world()
    image = render_fields(world.field, world.state, team=team, ssl_teams=True, size=(330, 230))
    hx, hy = world.field.wall_half_extent
    px_per_m = 1 / max(2 * (hx + 0.05) / 330, 2 * (hy + 0.05) / 230)
    for (x, y), t in zip([(-1.5, 0.5), (1.0, -1.0), (2.0, 1.2)], team, strict=True):
        col, row = round(165 + px_per_m * x), round(115 - px_per_m * y)
        pixel = image[row - 2, col - 2].astype(int)  # inside the disc, within its ring
        assert np.abs(pixel - _rgb(SSL_YELLOW if t == 0 else SSL_BLUE)).max() < 40, (t, pixel)
    # Several of ours each keep a colour of their own, which the blue team's is not.
    assert SSL_BLUE not in GAME_ROBOT_COLORS and SSL_YELLOW not in GAME_ROBOT_COLORS


def test_render_marks_collisions_in_the_colliding_robots_colours() -> None:
    world = World(1, 3)
    world.set_state([0], np.array([[[-1.5, 0.5], [1.0, -1.0], [2.0, 1.2]]]), np.zeros((1, 3)))
    team = [0, 0, 1]  # two controlled robots: the first blue, the second red (ROBOT_COLORS)
    plain = render_fields(world.field, world.state, team=team, size=(330, 230))
    marked = render_fields(
        world.field,
        world.state,
        team=team,
        size=(330, 230),
        collisions=np.array([[0.0, -1.5]]),
        collision_robot=[1],
    )
    hx, hy = world.field.wall_half_extent
    px_per_m = 1 / max(2 * (hx + 0.05) / 330, 2 * (hy + 0.05) / 230)
    col, row = round(165 + px_per_m * 0.0), round(115 + px_per_m * 1.5)
    changed = np.any(plain != marked, axis=-1)
    assert changed[row - 4 : row + 5, col - 4 : col + 5].sum() > 20 and not changed[:, : col - 20].any()
    assert np.abs(marked[row, col].astype(int) - _rgb("#e03131")).max() < 40  # robot 1's red at the centre
    with pytest.raises(ValueError, match="collision_robot"):
        render_fields(world.field, world.state, team=team, collisions=np.zeros((1, 2)), collision_robot=[2])


def test_render_draws_the_balls_in_orange_and_the_goal_walls() -> None:
    balls = np.array([[[0.5, 0.5], [-2.0, -1.5]], [[0.0, 0.0], [0.0, 0.0]]])
    world = _world()
    size, (hx, hy) = (660, 460), world.field.wall_half_extent
    image = render_fields(world.field, world.state, balls=balls, size=size)
    bare = render_fields(world.field, world.state, size=size)
    px_per_m = 1 / max(2 * (hx + 0.05) / size[0], 2 * (hy + 0.05) / size[1])
    for x, y in balls[0]:
        pixel = image[round(230 - px_per_m * y), round(330 + px_per_m * x)].astype(int)
        assert np.abs(pixel - _rgb(BALL)).max() < 40, pixel
    assert np.count_nonzero((image != bare).any(axis=-1)) < 2 * np.pi * (4 * 0.0215 * px_per_m) ** 2
    # The back wall of the goal at +x, halfway along it, is drawn in the goals' colour.
    back = world.field.half_length + world.field.goal_depth + 0.01
    assert np.abs(image[230, round(330 + px_per_m * back)].astype(int) - _rgb(GOAL)).max() < 40
