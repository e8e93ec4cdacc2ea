"""Safe file input, and atomic file output.

:func:`read_input` reads every file a user names (config, recording, command, EPOS4 parameter
file): only a regular file (a symbolic link to one is fine), never more than a stated number of
bytes, so a device (``/dev/zero``), a named pipe or a folder ends the run with one line (exit 2)
instead of exhausting memory or waiting forever.

Output: write to a temporary file in the target's folder, then rename.

A run that fails half-way (or is interrupted) leaves the previous file intact, never half of a
new one, and removes its temporary file.

:func:`check_output_file` (and :func:`cas_freq.report.outdir.check_output_dir`) check an
output path before any work starts: every command calls them first for its ``--csv``,
``--junit`` and ``-o`` options, so a folder where a file is meant, a parent that cannot be
written or a symbolic link ends the run at once with one line (exit 2) instead of after
minutes of work. Symbolic links are refused, not written through: outputs are replaced as a
whole, and replacing a link would silently turn it into a plain file or folder.
"""

import os
import stat
import tempfile
from pathlib import Path

from cas_freq.core.exceptions import CasFreqError, ConfigError

#: Largest data file read [bytes]: a recording or command CSV (about 500,000 rows: 50 s at
#: 10 kHz; the shipped 1 s chirp is 0.2 MB), as for an EPOS4 parameter file.
MAX_DATA_BYTES = 16 << 20


def one_line(text):
    """``text`` with every control character (newlines included) escaped: one line."""
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in str(text))


#: What a file that is not regular is, by its ``stat`` mode.
_FILE_KINDS = ((stat.S_ISDIR, "a folder"), (stat.S_ISFIFO, "a named pipe (FIFO)"),
               (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
               (stat.S_ISSOCK, "a socket"))


def _not_regular(mode):
    """What a file of ``mode`` is if not a regular file ('a folder', ...); None if regular."""
    if stat.S_ISREG(mode):
        return None
    return next((kind for test, kind in _FILE_KINDS if test(mode)), "not a regular file")


def read_input(path, what, limit=None, encoding="utf-8"):
    """The contents of a file a user named, read safely.

    The file (a symbolic link is followed) must be a regular file: its kind is checked with
    ``os.stat`` before it is opened, so a named pipe is refused without waiting for a writer,
    and again on the open descriptor (opened non-blocking), so a file swapped in between is
    refused too. At most ``limit`` bytes are read.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file is, for messages ("config file", "recording", ...).
    limit : int, optional
        Largest size accepted [bytes] (default :data:`MAX_DATA_BYTES`).
    encoding : str or None
        Decode the bytes as this text encoding; None returns the bytes.

    Returns
    -------
    str or bytes

    Raises
    ------
    ConfigError
        One line naming the path and what is wrong: ``"<path>: <what> not found"``, or
        ``"<path>: cannot read <what> (<reason>)"`` for a file that is not regular (a folder,
        a device, a named pipe, ...), larger than ``limit``, unreadable, or not text in
        ``encoding``.
    """
    shown = one_line(path)
    limit = MAX_DATA_BYTES if limit is None else limit

    def refused(reason):
        return ConfigError(f"{shown}: cannot read {what} ({reason})")

    def too_large():
        return refused(f"larger than {limit} bytes, the limit for {what}s")

    try:
        kind = _not_regular(os.stat(path).st_mode)
        if kind:
            raise refused(f"{kind}, not a regular file")
        handle = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0)
                         | getattr(os, "O_CLOEXEC", 0))
        with os.fdopen(handle, "rb") as stream:
            status = os.fstat(stream.fileno())
            kind = _not_regular(status.st_mode)
            if kind:
                raise refused(f"{kind}, not a regular file")
            if status.st_size > limit:
                raise too_large()
            raw = stream.read(limit + 1)
    except ConfigError:
        raise
    except FileNotFoundError:
        raise ConfigError(f"{shown}: {what} not found") from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        reason = getattr(exc, "strerror", None) or one_line(exc)[:200]
        raise refused(reason) from None
    if len(raw) > limit:  # grew since fstat
        raise too_large()
    if encoding is None:
        return raw
    try:
        return raw.decode(encoding)
    except UnicodeDecodeError as exc:
        raise refused(f"not {encoding.upper()} text: byte {exc.start} is "
                      f"0x{raw[exc.start]:02x}") from None


def _writable(path):
    """True if the folder ``path`` lets this process create and remove entries."""
    return os.access(path, os.W_OK | os.X_OK)


def _check_parent(path, option):
    """The nearest existing ancestor of ``path`` must be a folder this process can write: its
    permissions allow it and a file can be created there (an empty probe file, removed at
    once; a read-only or virtual file system such as /proc refuses it whatever the
    permissions say)."""
    parent = path.parent
    while not os.path.lexists(parent):
        if parent == parent.parent:
            break
        parent = parent.parent
    if not parent.is_dir():
        raise CasFreqError(f"{option} {path}: {parent} is not a folder")
    if not _writable(parent):
        raise CasFreqError(f"{option} {path}: the folder {parent} is not writable")
    try:
        handle, probe = tempfile.mkstemp(dir=parent, prefix=".cas-freq-probe.")
    except OSError as exc:
        raise CasFreqError(f"{option} {path}: no file can be created in the folder {parent} "
                           f"({exc.strerror or exc}; a read-only or virtual file system?)"
                           ) from None
    os.close(handle)
    os.unlink(probe)


def csv_row(path, number, line):
    """The cells of one CSV ``line`` (line ``number`` of the file ``path``).

    Raises
    ------
    ConfigError
        Naming the file and the line for what the csv module refuses, e.g. a field longer than
        its limit (131,072 characters; the cells of a CSV of numbers are short).
    """
    import csv

    try:
        return next(csv.reader([line]), [])
    except csv.Error as exc:
        if "field limit" in str(exc):
            reason = (f"a cell longer than {csv.field_size_limit():,} characters "
                      f"(the line has {len(line):,}); cells are numbers")
        else:
            reason = f"not CSV ({one_line(exc)[:200]})"
        raise ConfigError(f"{one_line(path)}: line {number}: {reason}") from None


def check_output_file(path, option):
    """Check that ``path`` can be written as a file (by :func:`write_text_atomic`).

    Raises :class:`~cas_freq.core.exceptions.CasFreqError` (one line naming ``option``, the path and
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
