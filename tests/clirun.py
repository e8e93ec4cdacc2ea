"""Run ``cas-freq`` in-process and capture what it prints (usable from module-scoped
fixtures, where pytest's capsys is not available). Imported by the CLI tests as ``clirun``:
pytest puts this folder on sys.path (the tests are not a package)."""

import contextlib
import io

from cas_freq.cli import main
from cas_freq.config import default_config_path

#: What a command that ran says on stderr when CONFIG was omitted (issue 24).
SHIPPED_NOTE = (f"cas-freq: used the shipped config {default_config_path()} (give CONFIG to use "
                "another)\n")


def run_cli(argv):
    """(exit status, stdout, stderr) of ``cas-freq argv``; argparse's usage errors (and
    ``--help``) end in SystemExit, whose code is the exit status as from the command line."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
    return code, out.getvalue(), err.getvalue()
