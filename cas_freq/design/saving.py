"""Where the design page may write: one folder, files directly in it, no surprise overwrite."""

import re
from pathlib import Path

from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.fileio import check_output_file
from cas_freq.design.guard import Refused

#: The endings of a config file the page may write.
SUFFIXES = (".yaml", ".yml")
#: A file name the page may write: letters, digits, ``._-`` (no folder, no leading dot).
SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9._-]{0,199}")


def save_target(file, save_dir, config, default_name, overwrite=False):
    """The file a save writes.

    Parameters
    ----------
    file : str or None
        What the page asked for: a file name in ``save_dir`` (or a path naming a file
        directly in it); None for ``default_name``.
    save_dir : Path
        The one folder the page writes into (the config's, or ``--save-dir``).
    config : Path
        The input config, never written.
    default_name : str
        The file name when ``file`` is None.
    overwrite : bool
        Whether an existing file may be replaced (the page asked the user first).

    Returns
    -------
    Path
        The resolved path, directly in ``save_dir``.

    Raises
    ------
    Refused
        403 for a file outside ``save_dir``, a folder that would have to be made, a link, a
        folder or special file (:func:`cas_freq.core.fileio.check_output_file`), a name that is
        not a config file's; 409 for an existing file without ``overwrite``
        and for the input config itself.
    """
    folder = Path(save_dir).resolve()
    asked = default_name if file is None else str(file).strip()
    path = Path(asked)
    if not path.is_absolute():
        path = folder / path
    outside = Refused(403, f"file {asked!r}: the design page saves only directly into "
                           f"{folder} (a file name such as 'mine.yaml'; start cas-freq design "
                           "with --save-dir to choose another folder)")
    if path.parent.resolve() != folder:  # checked first: nothing is probed outside
        raise outside
    try:  # a link, a folder, a special file: refused as every output file is
        check_output_file(path, "file")
    except CasFreqError as exc:
        raise Refused(403, str(exc)) from None
    resolved = path.resolve()
    if resolved.parent != folder:
        raise outside
    if not SAFE_NAME.fullmatch(resolved.name) or resolved.suffix.lower() not in SUFFIXES:
        raise Refused(403, f"file {asked!r}: expected a file name of letters, digits and "
                           f"._- ending in {' or '.join(SUFFIXES)}")
    if resolved == Path(config).resolve():
        raise Refused(409, f"{resolved}: is the input config; the design page never "
                           "overwrites it (choose another file)")
    if resolved.exists() and not overwrite:
        raise Refused(409, f"{resolved}: exists; the page replaces it only when you confirm "
                           "(overwrite)")
    return resolved


__all__ = ["SAFE_NAME", "SUFFIXES", "save_target"]
