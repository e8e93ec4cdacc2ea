"""Atomic file output: write to a temporary file in the target's folder, then rename.

A run that fails half-way (or is interrupted) leaves the previous file intact, never half of a
new one, and removes its temporary file.

:func:`check_output_file` and :func:`check_output_dir` check an output path before any work
starts: every command calls them first for its ``--csv``, ``--junit`` and ``-o`` options, so a
folder where a file is meant, a parent that cannot be written or a symbolic link ends the run
at once with one line (exit 2) instead of after minutes of work. Symbolic links are refused,
not written through: outputs are replaced as a whole, and replacing a link would silently turn
it into a plain file or folder.
"""

import os
import tempfile
from pathlib import Path

from cas_freq.exceptions import CasFreqError


def _writable(path):
    """True if the folder ``path`` lets this process create and remove entries."""
    return os.access(path, os.W_OK | os.X_OK)


def _check_parent(path, option):
    """The nearest existing ancestor of ``path`` must be a folder this process can write."""
    parent = path.parent
    while not os.path.lexists(parent):
        if parent == parent.parent:
            break
        parent = parent.parent
    if not parent.is_dir():
        raise CasFreqError(f"{option} {path}: {parent} is not a folder")
    if not _writable(parent):
        raise CasFreqError(f"{option} {path}: the folder {parent} is not writable")


def check_output_file(path, option):
    """Check that ``path`` can be written as a file (by :func:`write_text_atomic`).

    Raises :class:`~cas_freq.exceptions.CasFreqError` (one line naming ``option``, the path and
    the problem) for an empty path, a folder, a symbolic link, a special file (device, pipe)
    or a parent folder that does not exist and cannot be created or is not writable. A missing
    parent folder is created when the file is written.

    Returns
    -------
    Path
    """
    if not str(path).strip():
        raise CasFreqError(f"{option}: expected a file name, got {str(path)!r}")
    path = Path(path)
    if path.is_symlink():
        raise CasFreqError(f"{option} {path}: is a symbolic link (outputs are replaced as a "
                           f"whole, not written through links); give the file it points to, "
                           f"{os.path.realpath(path)}")
    if path.is_dir():
        raise CasFreqError(f"{option} {path}: is a folder, a file name is expected")
    if path.exists() and not path.is_file():
        raise CasFreqError(f"{option} {path}: exists and is not a regular file")
    _check_parent(path, option)
    return path


def check_output_dir(path, option="-o"):
    """Check that ``path`` can be written as a report folder; see
    :func:`cas_freq.report.outdir.check_output_dir`."""
    from cas_freq.report.outdir import check_output_dir as check

    return check(path, option)


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_text_atomic(path, text):
    """Write ``text`` (UTF-8) to ``path`` atomically; returns the path.

    The file gets the permissions a plain ``open(path, "w")`` would give (0o666 less the umask),
    not the 0o600 of the temporary file.
    """
    path = Path(path)
    temporary = None
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.",
                                             suffix=".tmp")
        with os.fdopen(handle, "w", encoding="utf-8", newline="") as stream:
            stream.write(text)
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, path)
    except BaseException as exc:
        if temporary is not None:
            Path(temporary).unlink(missing_ok=True)
        if isinstance(exc, OSError):
            raise CasFreqError(f"{path}: cannot write the file ({exc.strerror or exc})") from None
        raise
    return path


def json_ready(value):
    """Plain JSON data from nested dicts/lists/tuples of numbers, with numpy scalars made plain
    and non-finite floats made None (JSON has no NaN or Infinity)."""
    import math

    import numpy as np

    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    return value
