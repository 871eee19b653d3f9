"""Reading checkpoints: plain tensors only, through ``torch.load(weights_only=True)``.

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

from hier_ssl.config import ConfigError


class UnsafeCheckpointError(ConfigError):
    """A checkpoint that holds more than plain tensors (a ``ConfigError``: the command ends with it)."""


def load_checkpoint(path: str | Path, map_location: str | torch.device | None = None) -> Any:
    """The tensors (state dicts, in nested dicts and lists) saved in ``path``; UnsafeCheckpointError when
    it holds anything else."""
    try:
        return torch.load(path, map_location=map_location, weights_only=True)
    except pickle.UnpicklingError as err:
        names = sorted(set(re.findall(r"GLOBAL ([\w.]+)", str(err))))
        what = f"pickled Python objects ({', '.join(names)})" if names else "pickled Python objects"
        raise UnsafeCheckpointError(
            f"{path}: not a checkpoint of plain tensors: it holds {what}, which run code when they are "
            "loaded. hier_ssl reads tensors only and will not load this file."
        ) from None


__all__ = ["UnsafeCheckpointError", "load_checkpoint"]
