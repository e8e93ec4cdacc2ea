"""Report directories of ``sweep`` and ``montecarlo``: results JSON, CSV and SVG plots.

The folder is written as a whole, atomically, like ``cas-freq report``'s
(:func:`cas_freq.report.outdir.write_directory_atomic`): a failed run leaves the previous one
intact, and a folder cas-freq did not write is never replaced.
"""

import json

from cas_freq.report.outdir import write_directory_atomic


def write_report(directory, files):
    """Write ``files`` (name -> text) as the whole content of ``directory``; returns its path."""
    return write_directory_atomic(directory, files.items())


def json_text(data):
    """Strict, indented JSON text."""
    return json.dumps(data, indent=2, allow_nan=False) + "\n"
