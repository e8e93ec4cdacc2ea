"""SIGTERM and SIGHUP end a ``cas-freq`` run as Ctrl-C does, and no interrupt is lost.

By default SIGTERM (``kill``, ``timeout``, a CI runner cancelling a job) and SIGHUP (the
terminal closed) end Python at once: no clean-up runs, a staging folder stays behind. Within
:func:`terminate_as_interrupt` they raise :class:`Terminated` instead, a
:class:`KeyboardInterrupt`, so every clean-up written for Ctrl-C runs (the report's figure
workers killed, the staging folder removed, the previous output left as it was) and the CLI
ends with one line and exit 128 + the signal's number (143 for SIGTERM, 129 for SIGHUP).

A signal the caller set to be ignored stays ignored (``nohup`` ignores SIGHUP), as does SIGINT
where it is ignored: a non-interactive shell starts background jobs so, to shield them from the
Ctrl-C meant for the script; SIGTERM still stops them.

Python runs a signal's handler at the next instruction of Python code, and where that code was
called from C through ctypes (llvmlite's callbacks while numba compiles a kernel: one Ctrl-C in
six during a first report landed in its ``_raw_object_cache_notify``) or is a finaliser, the
:class:`KeyboardInterrupt` cannot propagate: Python prints it as "Exception ignored" and goes
on. Within :func:`interrupts_not_lost` such an interrupt is held instead of printed and raised
again as soon as the Python code called from C has returned (:func:`raise_again`), so the run
ends with its one line and exit status as after any other interrupt.
"""

import _thread
import contextlib
import signal
import sys
import threading

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


#: The interrupt held until it can propagate (:func:`raise_again`): the exception, the handler
#: SIGINT had before it was set to :func:`_deliver`, and whether the main thread is inside
#: :func:`_unraisable` (a handler run there cannot raise either). ``_LOCK`` orders a helper
#: thread's setting SIGINT pending against the interrupt's release (re-entrant: the handler
#: may run within :func:`_release`, at one of its instructions).
_HELD = {"interrupt": None, "previous": None, "in_hook": False}
_LOCK = threading.RLock()


def _unraisable(previous_hook, unraisable):
    """``sys.unraisablehook`` within :func:`interrupts_not_lost`: an interrupt of the main
    thread is held and raised again (:func:`raise_again`); anything else goes to
    ``previous_hook``."""
    if (isinstance(unraisable.exc_value, KeyboardInterrupt)
            and threading.current_thread() is threading.main_thread()):
        _HELD["in_hook"] = True
        try:
            raise_again(unraisable.exc_value)
        finally:
            _HELD["in_hook"] = False
        return
    previous_hook(unraisable)


def raise_again(interrupt):
    """Raise ``interrupt`` in the main thread at its next instruction outside the Python code
    C is running now; call from the main thread.

    Python's own signal mechanism does it: SIGINT's handler becomes :func:`_deliver` until it
    raises, and a helper thread sets SIGINT pending (``_thread.interrupt_main``). The helper
    runs once the main thread lets go of the interpreter, at the latest when the code called
    from C returns to C; if the handler still runs inside the unraisable hook it defers to a
    new helper, and if the interrupt is lost again, it comes back here.

    Parameters
    ----------
    interrupt : KeyboardInterrupt
        The interrupt to raise (a :class:`Terminated` for SIGTERM or SIGHUP).
    """
    with _LOCK:
        if not isinstance(_HELD["interrupt"], Terminated):  # a SIGTERM is not made a Ctrl-C
            _HELD["interrupt"] = interrupt
        if signal.getsignal(signal.SIGINT) is not _deliver:
            _HELD["previous"] = signal.signal(signal.SIGINT, _deliver)
    _interrupt_main_soon()


def _interrupt_main_soon():
    # a bare thread: threading.Thread.start waits for it to run, and the handler would then run
    # (and defer again) inside that wait, without end
    _thread.start_new_thread(_set_pending, ())


def _set_pending():
    with _LOCK:
        if _HELD["interrupt"] is not None:  # not released meanwhile
            _thread.interrupt_main(signal.SIGINT)


def _release():
    """The held interrupt, or None; SIGINT's previous handler restored."""
    with _LOCK:
        interrupt, _HELD["interrupt"] = _HELD["interrupt"], None
        if signal.getsignal(signal.SIGINT) is _deliver:
            signal.signal(signal.SIGINT, _HELD["previous"])
        _HELD["previous"] = None
    return interrupt


def _deliver(signum, frame):
    """SIGINT's handler while an interrupt is held: raises it (a real Ctrl-C meanwhile is the
    same interrupt)."""
    if _HELD["in_hook"]:  # raised here it would be lost again: once the hook has returned
        _interrupt_main_soon()
        return
    interrupt = _release()
    raise interrupt if interrupt is not None else KeyboardInterrupt


@contextlib.contextmanager
def interrupts_not_lost():
    """Within the block, an interrupt Python cannot propagate (in code called from C, in a
    finaliser) is not printed and lost but raised again (:func:`raise_again`); one still held
    when the block ends is raised there. Main thread only (elsewhere the block does nothing:
    Python runs signal handlers in the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous_hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: _unraisable(previous_hook, unraisable)
    try:
        yield
    finally:
        sys.unraisablehook = previous_hook
        interrupt = _release()
        if interrupt is not None:
            raise interrupt
