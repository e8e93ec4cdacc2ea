"""SIGTERM and SIGHUP end a ``cas-freq`` run as Ctrl-C does.

By default SIGTERM (``kill``, ``timeout``, a CI runner cancelling a job) and SIGHUP (the
terminal closed) end Python at once: no clean-up runs, a staging folder stays behind. Within
:func:`terminate_as_interrupt` they raise :class:`Terminated` instead, a
:class:`KeyboardInterrupt`, so every clean-up written for Ctrl-C runs (the report's figure
workers killed, the staging folder removed, the previous output left as it was) and the CLI
ends with one line and exit 128 + the signal's number (143 for SIGTERM, 129 for SIGHUP).

A signal the caller set to be ignored stays ignored (``nohup`` ignores SIGHUP), as does SIGINT
where it is ignored: a non-interactive shell starts background jobs so, to shield them from the
Ctrl-C meant for the script; SIGTERM still stops them.
"""

import contextlib
import signal

#: Signals turned into :class:`Terminated`.
TERMINATING = (signal.SIGTERM, signal.SIGHUP)


class Terminated(KeyboardInterrupt):
    """The run received ``signum`` (SIGTERM or SIGHUP); handled as Ctrl-C.

    Parameters
    ----------
    signum : int
        The signal's number.
    """

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


def _terminate(signum, frame):
    # once only: a second SIGTERM (``timeout -k``, an impatient caller) must not interrupt the
    # clean-up the first one started; SIGKILL still ends the process
    for number in TERMINATING:
        signal.signal(number, signal.SIG_IGN)
    raise Terminated(signum)


@contextlib.contextmanager
def terminate_as_interrupt():
    """Within the block, :data:`TERMINATING` signals raise :class:`Terminated` (where their
    action is the default one: not where the caller ignores them, not outside the main thread,
    where Python cannot set handlers); the previous handlers are restored after it."""
    previous = {}
    try:
        for number in TERMINATING:
            if signal.getsignal(number) == signal.SIG_DFL:
                previous[number] = signal.signal(number, _terminate)
    except ValueError:  # not the main thread
        pass
    try:
        yield
    finally:
        for number, handler in previous.items():
            signal.signal(number, handler)
