"""Atomic text output (cas_freq.core.fileio)."""

import os
import stat

import pytest

from cas_freq.core.fileio import json_ready, write_text_atomic


def test_writes_and_replaces(tmp_path):
    path = tmp_path / "sub" / "out.txt"
    write_text_atomic(path, "one")
    write_text_atomic(path, "two")
    assert path.read_text() == "two"
    assert [p.name for p in path.parent.iterdir()] == ["out.txt"]  # no temporary left


def test_permissions_follow_the_umask(tmp_path):
    """As a plain open() would: 0o666 less the umask (mkstemp alone gives 0o600)."""
    old = os.umask(0o022)
    try:
        path = write_text_atomic(tmp_path / "f.txt", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


def test_failure_keeps_the_previous_file(tmp_path):
    path = write_text_atomic(tmp_path / "f.txt", "old")

    with pytest.raises(TypeError):
        write_text_atomic(path, 42)  # not text: fails while writing
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["f.txt"]


def test_json_ready():
    import numpy as np

    assert json_ready({"a": (np.float64(1.5), float("nan")), "b": np.bool_(True)}) == {
        "a": [1.5, None], "b": True,
    }
