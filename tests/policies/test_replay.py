from __future__ import annotations

import io

import pytest
import torch

from hier_ssl.policies.replay import ReplayBuffer

OBS_DIM, ACT_DIM = 3, 2


def _transitions(ids: range) -> tuple[torch.Tensor, ...]:
    """Transitions whose every field encodes its id, so rows can be traced through the ring."""
    i = torch.tensor(list(ids), dtype=torch.float32)
    return (
        i[:, None].expand(-1, OBS_DIM).clone(),
        -i[:, None].expand(-1, ACT_DIM).clone(),
        10 * i,
        i[:, None].expand(-1, OBS_DIM) + 0.5,
        (i.long() % 2) == 1,
    )


def _ids(buffer: ReplayBuffer) -> list[int]:
    return buffer.obs[: buffer.size, 0].long().tolist()


def _build_buffer(capacity: int = 5, filled: int = 0) -> ReplayBuffer:
    buffer = ReplayBuffer(capacity, OBS_DIM, ACT_DIM)
    if filled:
        buffer.add(*_transitions(range(filled)))
    return buffer


def test_add_fills_in_order_and_keeps_fields_aligned() -> None:
    buffer = _build_buffer(capacity=5, filled=3)
    assert len(buffer) == 3 and buffer.pos == 3
    assert _ids(buffer) == [0, 1, 2]
    assert buffer.actions[:3, 0].tolist() == [0.0, -1.0, -2.0]
    assert buffer.rewards[:3].tolist() == [0.0, 10.0, 20.0]
    assert buffer.next_obs[:3, 0].tolist() == [0.5, 1.5, 2.5]
    assert buffer.terminated[:3].tolist() == [0.0, 1.0, 0.0]  # stored as float for the Bellman target


def test_add_wraps_around_overwriting_the_oldest() -> None:
    buffer = _build_buffer(capacity=5, filled=3)
    buffer.add(*_transitions(range(3, 7)))  # rows 3, 4 then wraps to rows 0, 1
    assert len(buffer) == 5 and buffer.pos == 2
    assert _ids(buffer) == [5, 6, 2, 3, 4]
    assert buffer.rewards.tolist() == [50.0, 60.0, 20.0, 30.0, 40.0]


def test_add_more_than_capacity_keeps_the_newest() -> None:
    buffer = _build_buffer(capacity=5, filled=2)
    buffer.add(*_transitions(range(2, 9)))  # 7 rows into 5: 4..8 survive, written from row 2 on
    assert len(buffer) == 5 and buffer.pos == 2
    assert sorted(_ids(buffer)) == [4, 5, 6, 7, 8]
    assert _ids(buffer) == [7, 8, 4, 5, 6]


def test_sample_draws_only_filled_rows_reproducibly() -> None:
    buffer = _build_buffer(capacity=100, filled=4)
    a = buffer.sample(64, torch.Generator().manual_seed(3))
    b = buffer.sample(64, torch.Generator().manual_seed(3))
    assert a.obs.shape == (64, OBS_DIM) and a.actions.shape == (64, ACT_DIM)
    assert a.rewards.shape == a.terminated.shape == (64,)
    assert set(a.obs[:, 0].long().tolist()) <= {0, 1, 2, 3}
    assert a.teacher_actions is None  # a buffer without a teacher keeps no labels
    for x, y in zip(a[:-1], b[:-1], strict=True):
        assert torch.equal(x, y)
    assert torch.equal(a.rewards, 10 * a.obs[:, 0])  # fields of one sample come from one row


def test_a_teacher_buffer_keeps_labels_aligned_and_through_a_round_trip() -> None:
    buffer = ReplayBuffer(4, OBS_DIM, ACT_DIM, teacher=True)
    transitions = _transitions(range(6))
    rows = (*transitions, 100 + transitions[0][:, :ACT_DIM])  # labels: 100 + id
    buffer.add(*rows)  # 6 rows into 4: ids 2..5 survive
    batch = buffer.sample(32, torch.Generator().manual_seed(0))
    assert torch.equal(batch.teacher_actions[:, 0], 100 + batch.obs[:, 0])
    restored = ReplayBuffer(4, OBS_DIM, ACT_DIM, teacher=True)
    restored.load_state_dict(_round_trip(buffer.state_dict()))
    assert torch.equal(restored.teacher_actions, buffer.teacher_actions)
    with pytest.raises(ValueError, match="teacher_actions: this replay buffer keeps them"):
        buffer.add(*_transitions(range(1)))
    with pytest.raises(ValueError, match="teacher_actions: this replay buffer does not keep them"):
        _build_buffer().add(*rows)
    with pytest.raises(ValueError, match="disagree on keeping teacher_actions"):
        _build_buffer().load_state_dict(buffer.state_dict())


def test_sample_from_empty_buffer_raises() -> None:
    with pytest.raises(RuntimeError, match="empty"):
        _build_buffer().sample(4)


def _round_trip(state: dict) -> dict:
    """Through torch.save / torch.load(weights_only=True), as checkpoints are."""
    blob = io.BytesIO()
    torch.save(state, blob)
    blob.seek(0)
    return torch.load(blob, weights_only=True)


def test_state_dict_saves_only_the_filled_part() -> None:
    state = _build_buffer(capacity=1000, filled=7).state_dict()
    assert state["obs"].shape == (7, OBS_DIM) and state["rewards"].shape == (7,)
    assert state["pos"] == 7


def test_state_dict_round_trip_of_a_wrapped_buffer() -> None:
    buffer = _build_buffer(capacity=5, filled=3)
    buffer.add(*_transitions(range(3, 7)))
    restored = _build_buffer(capacity=5)
    restored.load_state_dict(_round_trip(buffer.state_dict()))
    assert restored.size == buffer.size and restored.pos == buffer.pos
    for name in ("obs", "actions", "rewards", "next_obs", "terminated"):
        assert torch.equal(getattr(restored, name), getattr(buffer, name))
    # Both continue identically: the next write overwrites the same oldest row.
    for b in (buffer, restored):
        b.add(*_transitions(range(7, 8)))
    assert _ids(restored) == _ids(buffer) == [5, 6, 7, 3, 4]


def test_load_into_a_larger_buffer_appends_after_the_restored_rows() -> None:
    restored = _build_buffer(capacity=10)
    restored.load_state_dict(_build_buffer(capacity=5, filled=5).state_dict())
    restored.add(*_transitions(range(5, 6)))
    assert _ids(restored) == [0, 1, 2, 3, 4, 5]


def test_load_into_a_smaller_buffer_raises() -> None:
    with pytest.raises(ValueError, match="capacity"):
        _build_buffer(capacity=2).load_state_dict(_build_buffer(capacity=5, filled=3).state_dict())
