"""A decision's compiled book-keeping (``hier_ssl.envs.decisions``) against the array operations it stands
for."""

from __future__ import annotations

import numpy as np
import pytest

from hier_ssl.envs.decisions import tally_control_step


@pytest.mark.parametrize("frame_skip, summed", [(1, True), (4, True), (4, False)])
def test_tally_control_step_is_the_array_operations_it_replaces(frame_skip: int, summed: bool) -> None:
    rng, shape, max_steps = np.random.default_rng(frame_skip), (40, 3), 6
    start = rng.random(shape) < 0.8
    steps = rng.integers(0, max_steps, shape[0])
    # Expected: the operations of the core's decision loop before it was compiled.
    live, reward, elapsed = start.copy(), np.zeros(shape), start.astype(np.int64)
    success, collision = np.zeros(shape, bool), np.zeros(shape, bool)
    # Got: the compiled loop, in place.
    running = (start.copy(), np.zeros(shape), np.zeros(shape, bool), np.zeros(shape, bool))
    running += (start.astype(np.int64), np.zeros(shape, bool))
    for k in range(frame_skip):
        steps = steps + 1
        r = rng.normal(size=shape)
        succ, hit = (rng.random(shape) < 0.1) & live, (rng.random(shape) < 0.1) & live
        add, count = k > 0 and summed, k + 1 < frame_skip
        remaining = tally_control_step(r, succ, hit, steps, max_steps, add, count, start, *running)
        if add:
            np.add(reward, r, out=reward, where=live)
        else:
            np.copyto(reward, r, where=live)
        success, collision = success | succ, collision | hit
        live = live > (succ | hit)
        live = live > (steps >= max_steps)[:, None]
        if count:
            elapsed = elapsed + live.astype(np.int64)
        assert remaining == np.count_nonzero(live)
        timeout = start > (live | success | collision)
        for want, got in zip((live, reward, success, collision, elapsed, timeout), running, strict=True):
            np.testing.assert_array_equal(got, want)
        if not remaining:
            break
