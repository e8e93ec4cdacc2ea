"""Report folders: safe names from config names, and the atomic swap of a whole folder."""

import pytest

from cas_freq.core.exceptions import CasFreqError
from cas_freq.report.outdir import (
    MARKER,
    MARKER_TEXT,
    MAX_NAME_LENGTH,
    sanitise_name,
    write_directory_atomic,
)

MARKED = {MARKER: MARKER_TEXT.encode()}


@pytest.mark.parametrize(
    ("name", "expected"),
    [
        ("qt_cas", "qt_cas"),
        ("../../etc/passwd", "_.._etc_passwd"),  # no separator survives: one plain name
        ("..", "report"),
        (".hidden", "hidden"),
        ("", "report"),
        ("a b/c\\d", "a_b_c_d"),
        ("fin-2.v3", "fin-2.v3"),
        ("/abs", "_abs"),
        ("ünïcode", "_n_code"),
    ],
)
def test_sanitise_name(name, expected):
    assert sanitise_name(name) == expected


def test_sanitise_name_is_cut():
    assert len(sanitise_name("x" * 500)) == MAX_NAME_LENGTH


def _files(root):
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_writes_a_new_folder(tmp_path):
    target = tmp_path / "reports" / "r"
    write_directory_atomic(target, [("a.txt", "A\n"), ("sub/b.bin", b"\x00\x01")])
    assert _files(target) == {**MARKED, "a.txt": b"A\n", "sub/b.bin": b"\x00\x01"}
    assert sorted(p.name for p in target.parent.iterdir()) == ["r"]  # no staging left


def test_replaces_the_whole_folder(tmp_path):
    target = tmp_path / "r"
    write_directory_atomic(target, [("old.txt", "old"), ("keep/x.txt", "x")])
    write_directory_atomic(target, [("new.txt", "new")])
    assert _files(target) == {**MARKED, "new.txt": b"new"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


def test_failure_midway_leaves_the_previous_folder_intact(tmp_path):
    target = tmp_path / "r"
    write_directory_atomic(target, [("index.html", "previous"), ("figures/a.svg", "<svg/>")])
    before = _files(target)

    def files():
        yield "index.html", "half of a new one"
        raise RuntimeError("a figure failed")

    with pytest.raises(RuntimeError, match="a figure failed"):
        write_directory_atomic(target, files())
    assert _files(target) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]


@pytest.mark.parametrize("bad", ["../escape.txt", "/abs.txt", "a/../../b", "a//b", "./a"])
def test_rejects_paths_outside_the_folder(tmp_path, bad):
    with pytest.raises(CasFreqError, match="relative path inside the report"):
        write_directory_atomic(tmp_path / "r", [(bad, "x")])
    assert not (tmp_path / "r").exists()
    assert not (tmp_path / "escape.txt").exists()


def test_rejects_a_file_as_target(tmp_path):
    target = tmp_path / "file"
    target.write_text("not a folder")
    with pytest.raises(CasFreqError, match="not a folder"):
        write_directory_atomic(target, [("a", "b")])
    assert target.read_text() == "not a folder"


def test_never_replaces_a_folder_it_did_not_write(tmp_path):
    """A non-empty folder without the marker (a home folder, the project, ``-o .``) is refused,
    and left as it was; an empty folder is fine."""
    precious = tmp_path / "victim"
    (precious / "sub").mkdir(parents=True)
    (precious / "precious.txt").write_text("keep me")
    with pytest.raises(CasFreqError, match=r"was not written by cas-freq"):
        write_directory_atomic(precious, [("index.html", "x")])
    assert (precious / "precious.txt").read_text() == "keep me" and (precious / "sub").is_dir()
    empty = tmp_path / "empty"
    empty.mkdir()
    write_directory_atomic(empty, [("index.html", "x")])
    assert (empty / "index.html").read_text() == "x"
