"""The CLI's process settings (issue 12): BLAS thread pools limited to one thread and numpy's
huge pages off, unless the user chose otherwise, set before numpy loads."""

import os
import subprocess
import sys

from cas_freq.cli import BLAS_THREAD_VARIABLES, HUGE_PAGES_VARIABLE, limit_blas_threads


def test_unset_blas_threads_become_one_and_a_users_choice_is_kept():
    environ = {"OPENBLAS_NUM_THREADS": "4"}
    limit_blas_threads(environ)
    assert environ["OPENBLAS_NUM_THREADS"] == "4"
    assert all(environ[name] == "1" for name in BLAS_THREAD_VARIABLES[1:])
    assert environ[HUGE_PAGES_VARIABLE] == "0"
    environ = {HUGE_PAGES_VARIABLE: "1"}
    limit_blas_threads(environ)
    assert environ[HUGE_PAGES_VARIABLE] == "1"


def test_the_cli_process_sets_them_before_numpy_is_imported():
    """In a fresh interpreter, main() runs before any numpy import: the variables it sets are
    the ones OpenBLAS reads when numpy loads."""
    script = ("import contextlib, io, os, sys\n"
              "from cas_freq.cli import main\n"
              "assert 'numpy' not in sys.modules\n"
              "with contextlib.redirect_stdout(io.StringIO()):\n"
              "    assert main(['analyze', '-q']) == 0\n"
              "import numpy\n"
              "print(os.environ['OPENBLAS_NUM_THREADS'],\n"
              "      numpy._core.multiarray._get_madvise_hugepage())\n")
    environ = {k: v for k, v in os.environ.items()
               if k not in (*BLAS_THREAD_VARIABLES, HUGE_PAGES_VARIABLE)}
    out = subprocess.run([sys.executable, "-c", script], env=environ, capture_output=True,
                         text=True, check=True).stdout
    assert out.split() == ["1", "False"]  # numpy read the variable when it loaded
