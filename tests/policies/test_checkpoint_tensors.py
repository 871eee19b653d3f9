"""Checkpoints are read as plain tensors; anything else is refused, saying what the file holds, and the
error suggests nothing unsafe."""

from __future__ import annotations

import pickle
from pathlib import Path

import pytest
import torch

from hier_ssl.checkpoints.tensors import UnsafeCheckpointError, load_checkpoint
from hier_ssl.cli import main
from hier_ssl.config import ConfigError


class Payload:
    """Stands for whatever a pickled checkpoint may carry: an object of some class, not tensors."""


def test_plain_tensors_load(tmp_path: Path) -> None:
    torch.save({"actor": {"w": torch.ones(2)}, "step": 3}, tmp_path / "model.pt")
    assert load_checkpoint(tmp_path / "model.pt")["step"] == 3


def test_a_checkpoint_of_pickled_objects_is_refused_saying_what_it_holds(tmp_path: Path) -> None:
    path = tmp_path / "best_actor.pt"
    torch.save({"actor": Payload()}, path)
    with pytest.raises(UnsafeCheckpointError) as caught:
        load_checkpoint(path)
    message = str(caught.value)
    assert str(path) in message and "pickled Python objects" in message and "Payload" in message
    assert "will not load this file" in message
    assert "weights_only" not in message and "safe_globals" not in message  # no unsafe advice passed on
    assert isinstance(caught.value, ConfigError)


def test_a_file_that_is_no_checkpoint_says_what_the_unpickler_met(tmp_path: Path) -> None:
    (tmp_path / "model.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(
        pickle.UnpicklingError, match=r"^not a file of plain tensors \(Unsupported operand"
    ) as caught:
        load_checkpoint(tmp_path / "model.pt")
    assert "weights_only" not in str(caught.value)


def test_eval_of_a_run_with_an_unsafe_checkpoint_is_one_line_without_unsafe_advice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from hier_ssl.config import TrainConfig, dump_config

    (tmp_path / "config.yaml").write_text(dump_config(TrainConfig()))
    torch.save({"actor": Payload()}, tmp_path / "best_actor.pt")
    assert main(["export", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    # Beside export's progress bar (its redrawn line), one line says what is wrong.
    said = [line for line in err.replace("\r", "\n").splitlines() if line and not line.startswith("export ")]
    assert len(said) == 1 and "will not load this file" in said[0] and "weights_only" not in err
