"""Report directories of ``sweep`` and ``montecarlo``: results JSON, CSV and SVG plots.

Each file is written atomically (:func:`cas_freq.fileio.write_text_atomic`: temporary file,
then rename), so an interrupted run never leaves half a file; other files in the directory
are left alone.
"""

import json
import re
from pathlib import Path

from cas_freq.fileio import write_text_atomic


def safe_name(text, default="report"):
    """A file-system-safe name from free text (e.g. a config name)."""
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", str(text)).strip("._")
    return name[:80] or default


def write_report(directory, files):
    """Write ``files`` (name -> text) into ``directory``; returns the written paths.

    Names are sanitised with :func:`safe_name` (keeping the extension).
    """
    directory = Path(directory)
    paths = []
    for name, text in files.items():
        stem, dot, extension = name.rpartition(".")
        safe = f"{safe_name(stem)}.{safe_name(extension)}" if dot else safe_name(name)
        paths.append(write_text_atomic(directory / safe, text))
    return paths


def json_text(data):
    """Strict, indented JSON text."""
    return json.dumps(data, indent=2, allow_nan=False) + "\n"
