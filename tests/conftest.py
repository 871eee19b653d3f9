from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest
import torch


@pytest.fixture
def one_thread() -> Iterator[None]:
    """Tiny networks run fastest on one thread, and two OpenMP threads stall badly on a busy 2-core CPU."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


@pytest.fixture
def torch_threads_seen() -> Iterator[tuple[dict[str, set[int]], Callable[..., Any]]]:
    """``(seen, counted)``: ``counted(name, function)`` wraps ``function`` to record, under ``name`` in
    ``seen``, torch's thread count at each call. torch runs at two threads meanwhile (a learner's run with
    ``threads: 2``), and at its own count again after."""
    seen: dict[str, set[int]] = {}

    def counted(name: str, function: Callable[..., Any]) -> Callable[..., Any]:
        def run(*args: Any, **kwargs: Any) -> Any:
            seen.setdefault(name, set()).add(torch.get_num_threads())
            return function(*args, **kwargs)

        return run

    threads = torch.get_num_threads()
    torch.set_num_threads(2)
    yield seen, counted
    torch.set_num_threads(threads)
