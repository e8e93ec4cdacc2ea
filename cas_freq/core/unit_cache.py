"""A disk cache of pint's conversion factors, so that a CLI start need not import pint.

Importing pint and building its registry costs 0.2-0.3 s, a quarter of a short command such as
``cas-freq simulate`` or ``verify``; a config converts only a dozen distinct units. The factor
pint gives for each (unit text, SI unit) pair is kept in a small JSON file in the user's cache
folder (``platformdirs.user_cache_dir("cas_freq")``, e.g. ``~/.cache/cas_freq``), named by
pint's version and :data:`FORMAT`, and the next process multiplies by it without importing pint.

Only what pint itself computed is stored, and only when it is exactly a factor: the conversion
of 0 must give 0 (no offset unit such as degC) and pint's conversion of the magnitude at hand
must equal ``magnitude * factor`` to the bit, which is how pint converts multiplicative units.
Failed conversions are never stored (they go to pint every time, for its error). A missing,
unreadable or malformed file is ignored and rewritten; a folder that cannot be written leaves
the cache in memory only. Nothing here changes a value: a hit returns what pint would return.
"""

import functools
import json
import math
import os

from cas_freq.core.fileio import write_text_atomic

#: Version of the rules a stored factor passed (part of the file name): 2 since an angle must
#: match (``min^-1`` is no longer read as ``rad/min``), 3 since a torque per current counts as
#: per radian (``V*s`` is no longer read as ``N*m/A``), so a factor stored under older rules
#: is never read.
FORMAT = 3

#: Environment variable: a folder to keep the cache in instead of the user's cache folder, or
#: ``off`` to keep it in memory only.
CACHE_ENV = "CAS_FREQ_UNIT_CACHE"


def cache_file():
    """Path of the cache file for the installed pint, or None (cache in memory only)."""
    folder = os.environ.get(CACHE_ENV, "").strip()
    if folder.lower() == "off":
        return None
    try:
        import importlib.metadata

        version = importlib.metadata.version("pint")
        if not folder:
            import platformdirs  # a dependency of pint

            folder = platformdirs.user_cache_dir("cas_freq")
    except Exception:  # noqa: BLE001 - no version or folder: no disk cache, never an error
        return None
    return os.path.join(folder, f"unit-factors-{FORMAT}-pint-{version}.json")


@functools.cache
def _table():
    """The factors read from :func:`cache_file`: dict (unit text, SI unit) -> factor."""
    path = cache_file()
    try:
        with open(path, encoding="utf-8") as stream:
            rows = json.load(stream)
        return {(unit, target): float(factor) for unit, target, factor in rows
                if isinstance(unit, str) and isinstance(target, str)
                and isinstance(factor, float) and math.isfinite(factor) and factor != 0.0}
    except Exception:  # noqa: BLE001 - missing, unreadable or malformed: start afresh
        return {}


def cached_factor(unit, target):
    """The factor from ``unit`` (text as written) to ``target`` stored earlier, or None."""
    return _table().get((unit, target))


def store_factor(unit, target, factor):
    """Remember a factor pint computed (and write the file, if it can be written)."""
    table = _table()
    if table.get((unit, target)) == factor:
        return
    table[(unit, target)] = factor
    path = cache_file()
    if path is None:
        return

    rows = [[unit, target, value] for (unit, target), value in sorted(table.items())]
    try:
        write_text_atomic(path, json.dumps(rows, indent=0))
    except Exception:  # noqa: BLE001 - a cache that cannot be written stays in memory
        pass
