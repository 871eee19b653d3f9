from __future__ import annotations

import pickle

import numpy as np
import pytest

from hier_ssl.world import blocks
from hier_ssl.world.blocks import FIELDS_PER_SPACE, block_bounds
from hier_ssl.world.physics import World


@pytest.mark.parametrize("num_fields", [1, FIELDS_PER_SPACE, FIELDS_PER_SPACE + 1, 1000, 4096])
def test_blocks_cover_the_fields_in_order_as_few_and_as_even_as_allowed(num_fields: int) -> None:
    bounds = block_bounds(num_fields)
    assert bounds[0][0] == 0 and bounds[-1][1] == num_fields
    assert all(stop == start for (_, stop), (start, _) in zip(bounds, bounds[1:], strict=False))
    sizes = [stop - start for start, stop in bounds]
    assert max(sizes) <= FIELDS_PER_SPACE and max(sizes) - min(sizes) <= 1
    assert len(bounds) == -(-num_fields // FIELDS_PER_SPACE)


def _contact_run(world: World, steps: int = 30) -> list[np.ndarray]:
    """Every field: robot 0 driving head-on into robot 1 (fields of odd index: also into a wall)."""
    n = world.num_fields
    limit = world.field.wall_half_extent[0] - world.robot.radius
    pos = np.zeros((n, 2, 2))
    pos[:, 0, 0], pos[:, 1, 0] = -0.3, 0.3
    pos[1::2, 1, 0] = limit - 0.2
    pos[:, :, 1] = np.linspace(-1.0, 1.0, n)[:, None]
    world.set_state(np.arange(n), pos, np.zeros((n, 2)))
    command = np.zeros((n, 2, 3))
    command[:, 0, 0], command[:, 1, 2] = 2.0, 3.0
    command[1::2, 1, 0] = 2.0
    out = []
    for t in range(steps):
        state = world.step(command + 0.01 * t)
        out += [state.pos, state.angle, state.vel, state.ang_vel, world.robot_contacts.copy()]
        out.append(world.wall_contacts.copy())
    return out


def test_a_world_in_blocks_steps_bit_for_bit_as_one_space(monkeypatch: pytest.MonkeyPatch) -> None:
    # Each robot touches one body at a time, so no contact order is left to the broad phase.
    monkeypatch.setattr(blocks, "FIELDS_PER_SPACE", 7)
    split = World(30, 2)
    monkeypatch.setattr(blocks, "FIELDS_PER_SPACE", 30)
    whole = World(30, 2)
    assert (len(split.blocks), len(whole.blocks)) == (5, 1)
    a, b = _contact_run(split), _contact_run(whole)
    assert any(x.any() for x in a[4::6]) and any(x.any() for x in a[5::6])  # robots touched robots, walls
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def test_set_state_of_fields_across_blocks_leaves_the_others(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(blocks, "FIELDS_PER_SPACE", 2)
    world = World(5, 1)
    before = world.state
    world.set_state([4, 1], np.array([[[0.5, 0.25]], [[-1.0, 0.75]]]), np.array([[0.5], [-0.5]]))
    np.testing.assert_array_equal(world.state.pos[[4, 1], 0], [[0.5, 0.25], [-1.0, 0.75]])
    np.testing.assert_array_equal(world.state.angle[[4, 1], 0], [0.5, -0.5])
    np.testing.assert_array_equal(world.state.pos[[0, 2, 3]], before.pos[[0, 2, 3]])


def test_a_copied_world_in_blocks_steps_as_its_original(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(blocks, "FIELDS_PER_SPACE", 3)
    world = World(8, 2)
    _contact_run(world, steps=10)
    copied = pickle.loads(pickle.dumps(world))
    assert len(copied.blocks) == 3
    command = np.full((8, 2, 3), 0.5)
    for _ in range(10):
        a, b = world.step(command), copied.step(command)
        np.testing.assert_array_equal(a.pos, b.pos)
        np.testing.assert_array_equal(copied.robot_contacts, world.robot_contacts)


def test_blocks_stepped_in_threads_step_bit_for_bit_as_in_one(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(blocks, "FIELDS_PER_SPACE", 4)
    alone, threaded = World(30, 2), World(30, 2)
    threaded.use_threads(3)
    a, b = _contact_run(alone), _contact_run(threaded)
    assert any(x.any() for x in b[4::6]) and any(x.any() for x in b[5::6])  # robots touched robots, walls
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    command = np.full((30, 2, 3), 0.5)
    copied = pickle.loads(pickle.dumps(threaded))  # the pool is made again, not pickled
    assert copied.threads == 3
    np.testing.assert_array_equal(copied.step(command).pos, threaded.step(command).pos)
    alone.step(command)
    threaded.use_threads(1)
    np.testing.assert_array_equal(threaded.step(command).pos, alone.step(command).pos)
    with pytest.raises(ValueError, match="count must be an integer >= 1, got 0"):
        alone.use_threads(0)
