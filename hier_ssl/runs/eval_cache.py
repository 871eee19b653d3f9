"""Evaluation records cached on disk (``OUT/evals/`` of ``hier-ssl reproduce``): a 1000-episode evaluation
costs minutes, so a rerun evaluates only what has no record yet, or whose record is older than its run."""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from hier_ssl.config import TaskConfig


def cached_record(
    path: Path, compute: Callable[[], dict[str, Any]], newer_than: float | None = None
) -> dict[str, Any]:
    """The record at ``path`` if it is there and was written at or after ``newer_than`` (a modification
    time; None: any age), else ``compute()``'s, written there first. Both come back as read from the file
    (NaN as None), so a table is the same whether its records were cached or not."""
    if path.is_file() and (newer_than is None or path.stat().st_mtime >= newer_than):
        return json.loads(path.read_text())
    record = compute()
    path.parent.mkdir(parents=True, exist_ok=True)
    # NaN (a figure of a manager that never succeeds) as null: strict JSON.
    text = json.dumps({k: None if v != v else v for k, v in record.items()}, indent=2) + "\n"
    path.write_text(text)
    return json.loads(text)


def config_digest(config: TaskConfig) -> str:
    """Ten hex digits naming everything ``config`` sets: a cached record of a scenario whose YAML has
    changed since is not found again."""
    return hashlib.sha256(config.model_dump_json().encode()).hexdigest()[:10]


__all__ = ["cached_record", "config_digest"]
