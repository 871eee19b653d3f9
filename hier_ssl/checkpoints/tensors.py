"""Checkpoints: written whole or not at all (``save_checkpoint``), read as plain tensors only, through
``torch.load(weights_only=True)`` (``load_checkpoint``).

A file holding anything else (pickled Python objects, which run code as they are unpickled) is refused
with an error that names the file and what it holds and says that hier_ssl will not load it. torch's own
message would go on to suggest loading it with ``weights_only=False``, which is the unsafe thing a
reader may take for the fix; it is not passed on.
"""

from __future__ import annotations

import pickle
import re
from pathlib import Path
from typing import Any

import torch

from hier_ssl.checkpoints.files import atomic_write
from hier_ssl.config import ConfigError


class UnsafeCheckpointError(ConfigError):
    """A checkpoint that holds more than plain tensors (a ``ConfigError``: the command ends with it)."""


def save_checkpoint(obj: Any, path: str | Path) -> None:
    """``torch.save(obj)`` into ``path`` through ``atomic_write``: a run killed mid-save keeps its previous
    checkpoint."""
    atomic_write(path, lambda f: torch.save(obj, f))


def load_checkpoint(path: str | Path, map_location: str | torch.device | None = None) -> Any:
    """The tensors (state dicts, in nested dicts and lists) saved in ``path``. UnsafeCheckpointError when
    it holds pickled objects; a ``pickle.UnpicklingError`` saying what the unpickler met when it is no
    checkpoint at all (the loaders name the file)."""
    try:
        return torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as err:
        message = str(err)
        names = sorted(set(re.findall(r"GLOBAL ([\w.]+)", message)))
        if names:
            raise UnsafeCheckpointError(
                f"{path}: not a checkpoint of plain tensors: it holds pickled Python objects "
                f"({', '.join(names)}), which run code when they are loaded. hier_ssl reads tensors only "
                "and will not load this file."
            ) from None
        # Not a pickle torch can read at all (a damaged or foreign file): what the unpickler met, only.
        found = re.search(r"WeightsUnpickler error:(.*?)(?:Check the documentation|$)", message, re.DOTALL)
        detail = " ".join(found.group(1).split()) if found else type(err).__name__
        raise pickle.UnpicklingError(f"not a file of plain tensors ({detail})") from None


__all__ = ["UnsafeCheckpointError", "load_checkpoint", "save_checkpoint"]
