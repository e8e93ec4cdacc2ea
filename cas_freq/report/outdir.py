"""Report folders: safe names, and writing a whole folder atomically.

:func:`write_directory_atomic` writes every file into a fresh temporary folder beside the target
and only then swaps it in (old folder renamed away, new one renamed in, old one removed). A run
that fails midway removes its temporary folder and leaves the previous report as it was, never
half of a new one.

Only a folder cas-freq wrote (it holds the :data:`MARKER` file) or an empty one is ever
replaced: ``-o ~`` or ``-o .`` is refused instead of wiping what is there.
"""

import os
import re
import shutil
import tempfile
from pathlib import Path, PurePosixPath

from cas_freq.exceptions import CasFreqError

#: Longest folder name made from a config name.
MAX_NAME_LENGTH = 100

#: File in every folder cas-freq writes; a folder without it is never replaced.
MARKER = ".cas-freq-output"
MARKER_TEXT = ("Written by cas-freq. The next run that writes here replaces this folder as a "
               "whole.\n")


def sanitise_name(name, fallback="report"):
    """A folder name from free text: only ``[A-Za-z0-9._-]``, no leading dots, never ``..``.

    Every other character (``/``, ``\\``, spaces, ...) becomes ``_``; the result is cut to
    :data:`MAX_NAME_LENGTH` characters; an empty result is ``fallback``.
    """
    text = re.sub(r"[^A-Za-z0-9._-]", "_", str(name))
    text = text.lstrip(".")[:MAX_NAME_LENGTH].rstrip(".")
    return text if text and text not in (".", "..") else fallback


def _relative(path):
    """Check a file path inside the report: relative, no ``..``, no empty parts."""
    parts = str(path).split("/")
    if not str(path) or any(p in ("..", ".", "") or "\\" in p for p in parts):
        raise CasFreqError(f"report file {path!r}: must be a relative path inside the report")
    return PurePosixPath(*parts)


def write_directory_atomic(target, files):
    """Write ``files`` as the whole content of folder ``target``, atomically.

    Parameters
    ----------
    target : str or Path
        The report folder; replaced as a whole if it exists (it must then be a folder).
    files : iterable of (str, str or bytes)
        (path relative to ``target`` with '/' separators, content). Text is written as UTF-8
        with '\\n' line ends. May be a generator: a failure while it produces the files leaves
        ``target`` untouched.

    Returns
    -------
    Path
        ``target``.
    """
    target = Path(target)
    if target.exists() and not target.is_dir():
        raise CasFreqError(f"-o {target}: exists and is not a folder")
    if target.is_dir() and any(target.iterdir()) and not (target / MARKER).is_file():
        raise CasFreqError(
            f"-o {target}: the folder exists and was not written by cas-freq (no {MARKER} "
            "file); give a new or empty folder, it would be replaced as a whole"
        )
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CasFreqError(f"-o {target}: cannot create the parent folder ({exc})") from None
    staging = Path(tempfile.mkdtemp(dir=parent, prefix=f".{target.name}.", suffix=".new"))
    try:
        (staging / MARKER).write_text(MARKER_TEXT, encoding="utf-8")
        for relative, content in files:
            path = staging.joinpath(*_relative(relative).parts)
            path.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(content, bytes):
                path.write_bytes(content)
            else:
                with open(path, "w", encoding="utf-8", newline="\n") as stream:
                    stream.write(content)
        os.chmod(staging, 0o755)
        _swap_in(staging, target)
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        raise CasFreqError(f"-o {target}: cannot write the folder ({exc})") from None
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    return target


def _swap_in(staging, target):
    """Rename ``staging`` to ``target``, moving an existing ``target`` away first."""
    if not target.exists():
        os.rename(staging, target)
        return
    old = Path(tempfile.mkdtemp(dir=target.parent, prefix=f".{target.name}.", suffix=".old"))
    os.rmdir(old)
    os.rename(target, old)
    try:
        os.rename(staging, target)
    except BaseException:
        os.rename(old, target)  # put the previous report back
        raise
    shutil.rmtree(old, ignore_errors=True)
