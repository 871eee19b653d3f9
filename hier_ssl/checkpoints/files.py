"""The files a run resumes from or is read back by (checkpoints, its config, its curve, eval.json) go
through ``atomic_write``: a run killed mid-write leaves the previous file whole, never a truncated one
that a resume or a reader would then fail on."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO


def atomic_write(path: str | os.PathLike[str], write: Callable[[BinaryIO], object]) -> None:
    """``write(f)`` writes the new content to ``f``, a temporary file beside ``path`` open for binary
    writing; once it returns the content is synced to the disk and the file renamed over ``path`` in one
    step. If ``write`` raises, the temporary file is removed and ``path`` keeps its old content (or stays
    absent)."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        # mkstemp's file is private (0600); the result reads like any file the process creates.
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            # The rename is durable only once the data it points to has reached the disk.
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        # An interrupt can land once the rename is done: the file is then whole and the temporary gone,
        # and the interrupt, not a missing temporary file, is what the caller must see.
        Path(tmp).unlink(missing_ok=True)
        raise


def _umask() -> int:
    """The process's umask (only settable, so set and put back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text(text: str, path: str | os.PathLike[str]) -> None:
    """``text`` (UTF-8) into ``path`` through ``atomic_write``."""
    atomic_write(path, lambda f: f.write(text.encode()))


__all__ = ["atomic_write", "write_text"]
