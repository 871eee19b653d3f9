from __future__ import annotations

import os
from pathlib import Path
from typing import BinaryIO

import pytest
import torch

from hier_ssl.checkpoints.files import atomic_write, write_text
from hier_ssl.checkpoints.tensors import load_checkpoint, save_checkpoint


def test_a_write_that_fails_midway_leaves_the_old_file_whole(tmp_path: Path) -> None:
    path = tmp_path / "curve.csv"
    write_text("step\n1\n", path)

    def half_then_fail(f: BinaryIO) -> None:
        f.write(b"step\n1\n2")
        f.flush()
        raise OSError("disk full")

    with pytest.raises(OSError, match="disk full"):
        atomic_write(path, half_then_fail)
    assert path.read_text() == "step\n1\n"
    assert [p.name for p in tmp_path.iterdir()] == ["curve.csv"]


def test_a_failed_first_write_leaves_no_file(tmp_path: Path) -> None:
    def fail(f: BinaryIO) -> None:
        f.write(b"name: run")
        raise KeyboardInterrupt  # a run killed mid-write

    with pytest.raises(KeyboardInterrupt):
        atomic_write(tmp_path / "config.yaml", fail)
    assert list(tmp_path.iterdir()) == []


def test_an_interrupt_just_after_the_rename_is_raised_as_itself(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Ctrl-C handled as the rename returns: `hier-ssl train` must see the interrupt (its resume hint, exit
    # 130), not "no such file" for the temporary file the rename already moved.
    path, replace = tmp_path / "model.pt", os.replace

    def replace_then_interrupt(src: str, dst: Path) -> None:
        replace(src, dst)
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "replace", replace_then_interrupt)
    with pytest.raises(KeyboardInterrupt):
        write_text("new", path)
    assert path.read_text() == "new" and [p.name for p in tmp_path.iterdir()] == ["model.pt"]


def test_a_write_replaces_the_content_and_has_the_mode_of_a_new_file(tmp_path: Path) -> None:
    path, plain = tmp_path / "config.yaml", tmp_path / "plain"
    write_text("name: a\n", path)
    write_text("name: b\n", path)
    assert path.read_text() == "name: b\n"
    plain.write_text("")
    assert path.stat().st_mode == plain.stat().st_mode


def test_a_checkpoint_that_fails_to_pickle_keeps_the_previous_one(tmp_path: Path) -> None:
    path = tmp_path / "model.pt"
    save_checkpoint({"step": 1, "w": torch.ones(3)}, path)
    with pytest.raises(Exception, match="pickle"):
        save_checkpoint({"step": 2, "bad": lambda: None}, path)  # fails halfway through pickling
    saved = load_checkpoint(path)
    assert saved["step"] == 1 and torch.equal(saved["w"], torch.ones(3))
    assert [p.name for p in tmp_path.iterdir()] == ["model.pt"]
