"""Report folders: safe names, and writing a whole folder atomically.

:func:`write_directory_atomic` writes every file into a fresh temporary folder beside the target
and only then swaps it in (old folder renamed away, new one renamed in, old one removed). A run
that fails midway removes its temporary folder and leaves the previous report as it was, never
half of a new one.

Only a folder cas-freq wrote (it holds the :data:`MARKER` file) or an empty one is ever
replaced: ``-o ~`` or ``-o .`` is refused instead of wiping what is there. A symbolic link given
as the folder is refused (not replaced by a folder, not written through).

Interruption: the staging folder ``.DIR.<random>.new`` is removed when the run fails or is
interrupted (Ctrl-C). A run killed outright (SIGKILL, power loss) may leave it, or may be killed
between the swap's two renames (``DIR`` -> ``.DIR.<random>.old``, staging -> ``DIR``); the next
run that writes ``DIR`` (:func:`recover`, called by :func:`check_output_dir` and
:func:`write_directory_atomic`) removes leftover staging folders and, if ``DIR`` is missing,
renames the newest ``.DIR.*.old`` back to ``DIR`` first, so a report is never lost.
"""

import glob
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path, PurePosixPath

from cas_freq.core.exceptions import CasFreqError

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


def _leftovers(target, suffix):
    """Leftover ``.NAME.*<suffix>`` folders of ``target`` written by cas-freq (or empty),
    newest first."""
    target = Path(os.path.abspath(target))  # '.' and '..' have no name of their own
    parent = target.parent
    if not parent.is_dir():
        return []
    found = []
    for path in parent.glob(f".{glob.escape(target.name)}.*{suffix}"):
        # tempfile.mkdtemp's names: the prefix, 8 random characters, the suffix
        if not re.fullmatch(r"[a-z0-9_]{8}", path.name[len(target.name) + 2:-len(suffix)]):
            continue
        if path.is_symlink() or not path.is_dir():
            continue
        if (path / MARKER).is_file() or not any(path.iterdir()):
            found.append(path)
    return sorted(found, key=lambda p: p.stat().st_mtime, reverse=True)


def recover(target):
    """Clean up after a run of ``target`` that was killed: restore ``target`` from the newest
    ``.NAME.*.old`` if it is missing, then remove leftover ``.new`` and ``.old`` folders.
    Returns ``target``."""
    target = Path(target)
    try:
        old = _leftovers(target, ".old")
        if old and not os.path.lexists(target):
            os.rename(old.pop(0), target)
        for path in old + _leftovers(target, ".new"):
            _remove_tree(path)
    except OSError as exc:
        raise CasFreqError(f"-o {target}: cannot clean up after an earlier run ({exc})") from None
    return target


def _remove_tree(path):
    """Remove a folder tree, making read-only subfolders writable first."""
    def retry(function, name, _info):
        os.chmod(os.path.dirname(name) or ".", 0o700)
        if os.path.isdir(name) and not os.path.islink(name):
            os.chmod(name, 0o700)
        function(name)

    if sys.version_info >= (3, 12):
        shutil.rmtree(path, onexc=retry)
    else:
        shutil.rmtree(path, onerror=retry)


def _writable(path):
    return os.access(path, os.W_OK | os.X_OK)


def check_output_dir(target, option="-o"):
    """Check before any work that ``target`` can be written as a report folder.

    Cleans up after a killed earlier run (:func:`recover`), then raises
    :class:`~cas_freq.core.exceptions.CasFreqError` (one line naming ``option``, the folder and the
    problem) for: a symbolic link, a file, a non-empty folder cas-freq did not write, an existing
    report with a read-only folder inside (it could not be removed), and a parent that is not a
    folder or not writable. Returns ``target`` as a Path.
    """
    if not str(target).strip():
        raise CasFreqError(f"{option}: expected a folder name, got {str(target)!r}")
    target = Path(target)
    if target.is_symlink():
        raise CasFreqError(f"{option} {target}: is a symbolic link (a report folder is replaced "
                           f"as a whole, not written through a link); give the folder it points "
                           f"to, {os.path.realpath(target)}")
    if os.path.lexists(target) and not target.is_dir():
        raise CasFreqError(f"{option} {target}: exists and is not a folder")
    parent = target.parent
    while not os.path.lexists(parent) and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise CasFreqError(f"{option} {target}: {parent} is not a folder")
    if not _writable(parent):
        raise CasFreqError(f"{option} {target}: the folder {parent} is not writable")
    recover(target)
    if target.is_dir():
        if any(target.iterdir()) and not (target / MARKER).is_file():
            raise CasFreqError(
                f"{option} {target}: the folder exists and was not written by cas-freq (no "
                f"{MARKER} file); give a new or empty folder, it would be replaced as a whole"
            )
        for folder, _, _ in os.walk(target):
            if not _writable(folder):
                raise CasFreqError(f"{option} {target}: the existing report cannot be replaced, "
                                   f"{folder} is read-only")
    return target


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
    target = check_output_dir(target)
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CasFreqError(f"-o {target}: cannot create the parent folder ({exc})") from None
    staging = None
    try:
        staging = Path(tempfile.mkdtemp(dir=parent, prefix=f".{target.name}.", suffix=".new"))
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
    except BaseException as exc:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
        if isinstance(exc, OSError):
            raise CasFreqError(f"-o {target}: cannot write the folder ({exc})") from None
        raise
    return target


def _swap_in(staging, target):
    """Rename ``staging`` to ``target``, moving an existing ``target`` away first.

    Killed between the two renames, ``target`` is missing and ``.NAME.*.old`` holds it:
    :func:`recover` puts it back on the next run.
    """
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
    try:
        _remove_tree(old)
    except OSError:
        pass  # the new report is in place; recover() removes the leftover on the next run
