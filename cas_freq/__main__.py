"""``python -m cas_freq`` and the ``cas-freq`` command (:func:`run`).

:func:`run` is the process around :func:`cas_freq.cli.main`: it catches a Ctrl-C that lands while
the CLI is being imported (before :func:`~cas_freq.cli.main` handles it), and after an interrupted
run (Ctrl-C, SIGTERM, SIGHUP) it ends the process at once: the clean-up is done by then
(outputs, workers), while tearing down the interpreter with a report's ~1,200 modules loaded
(numba, matplotlib, python-control) takes another 0.5-1.3 s on the project's 2-core machine.
"""

import sys


def run():
    """Run ``cas-freq`` with the process's arguments; returns the exit status (after an
    interrupt the process ends here)."""
    try:
        from cas_freq.cli import main
    except KeyboardInterrupt:  # the import is kept small (cas_freq.cli), so this is rare
        print("cas-freq: interrupted", file=sys.stderr)
        _exit_now(130)
    status = main()
    if status > 128:  # 128 + a signal's number: interrupted (cas_freq.cli)
        _exit_now(status)
    return status


def _exit_now(status):
    """End the process with ``status``: exit handlers run and stdout and stderr are flushed,
    the interpreter is not torn down."""
    import atexit
    import os

    try:
        atexit._run_exitfuncs()  # e.g. weakref.finalize's clean-ups (temporary folders)
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError, AttributeError):
                pass
        os._exit(status)


if __name__ == "__main__":
    raise SystemExit(run())
