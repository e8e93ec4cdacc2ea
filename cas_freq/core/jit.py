"""Compiled code in cas_freq: numba's ``njit`` as the kernels use it, and the engine choice.

Every compiled kernel has a numpy reference it is tested against: the simulation loop
(:mod:`cas_freq.simulation.kernel`), the second-order fit's sums
(:mod:`cas_freq.simulation.fit_kernel`), and, for large batches only (:data:`COMPILED_FROM`),
the analysis' grid responses and scans (:mod:`cas_freq.analysis.response_kernel`,
:mod:`cas_freq.analysis.scan_kernel`). ``CAS_FREQ_ENGINE=reference`` (or ``engine="reference"``
where a function takes it) runs the references instead, as does a machine without numba; numba
is imported only by the kernels' modules.

numba caches the machine code next to the kernels' modules (``__pycache__``). Where the
package folder is not writable (a read-only site-packages) and ``NUMBA_CACHE_DIR`` is unset,
:func:`configure_cache` points numba at a per-user folder (:func:`cache_candidates`) on
import of this module, so that the kernels compile once per user, not in every process; a
user's ``NUMBA_CACHE_DIR`` is always respected. The first compilation of a process is told
once (:func:`compile_messages`): the CLI prints it on stderr, the API logs it on the
``cas_freq`` logger (silent unless a handler is configured). What is told is measured, not
estimated (a first run's compiling takes from under 10 s to minutes, with the command, the drive
architecture and the machine's load): the CLI says every :data:`TICK_S` how long it has compiled
so far, and at the end how long it took, wall and CPU (:func:`compile_summary`).
"""

import functools
import logging
import os
import pathlib
import tempfile
import threading
import time

from cas_freq.core.exceptions import ConfigError

#: Environment variable choosing the engine: ``compiled`` (default) or ``reference``.
ENGINE_ENV = "CAS_FREQ_ENGINE"
#: Engines: the numba kernels and the numpy references.
ENGINES = ("compiled", "reference")
#: Array size (points) from which the frequency-domain analysis uses its compiled kernels:
#: below it numpy is about as fast, and a single analysis needs no numba.
COMPILED_FROM = 65_536


def engine_name(requested=None):
    """The engine to use: ``requested``, else ``$CAS_FREQ_ENGINE``, else compiled.

    Parameters
    ----------
    requested : {"compiled", "reference"} or None
        The caller's choice.

    Returns
    -------
    str
        ``"compiled"`` or ``"reference"``.

    Raises
    ------
    ConfigError
        For another name (naming where it came from).
    """
    source = "engine"
    if requested is None:
        requested = os.environ.get(ENGINE_ENV, "").strip().lower() or "compiled"
        source = ENGINE_ENV
    if requested not in ENGINES:
        raise ConfigError(f"{source}: expected one of {', '.join(ENGINES)}, got {requested!r}")
    return requested


def use_compiled():
    """True where the compiled kernels should run: the compiled engine chosen
    (:func:`engine_name`) and numba importable (else the numpy references run, with the same
    results)."""
    return engine_name() == "compiled" and _numba_installed()


def compiled_for(points):
    """:func:`use_compiled`, for an analysis step on ``points`` array points: only from
    :data:`COMPILED_FROM` points."""
    return points >= COMPILED_FROM and use_compiled()


@functools.cache
def _numba_installed():
    """numba imports (an installed numba can fail to, e.g. against a newer numpy)."""
    try:
        import numba  # noqa: F401
    except Exception:  # noqa: BLE001  (any failure to import means: no compiled kernels)
        return False
    return True


#: numba's variable for its cache folder (read when numba is imported).
CACHE_ENV = "NUMBA_CACHE_DIR"
#: The package's folders holding compiled kernels (numba caches in their ``__pycache__``).
KERNEL_DIRS = ("simulation", "analysis")
#: Interval [s] of the CLI's "still compiling" lines while the kernels compile.
TICK_S = 15.0

_PACKAGE = pathlib.Path(__file__).resolve().parent
_LOG = logging.getLogger("cas_freq")


def writable(path):
    """True if a file can be created in folder ``path``, or in its nearest existing parent
    where the folder does not exist yet (numba creates it)."""
    path = pathlib.Path(path)
    while not path.exists() and path.parent != path:
        path = path.parent
    return path.is_dir() and os.access(path, os.W_OK | os.X_OK)


def cache_candidates(environ=None):
    """Per-user cache folders, in order of preference: ``$XDG_CACHE_HOME/cas_freq/numba``
    (default ``~/.cache``), then ``cas_freq-numba-<user id>`` in the temporary folder (for a
    user without a writable home)."""
    environ = os.environ if environ is None else environ
    base = environ.get("XDG_CACHE_HOME", "")
    if not os.path.isabs(base):  # unset, or relative (which the XDG specification ignores)
        base = os.path.join(os.path.expanduser("~"), ".cache")
    user = os.getuid() if hasattr(os, "getuid") else os.environ.get("USERNAME", "user")
    temporary = pathlib.Path(tempfile.gettempdir()) / f"cas_freq-numba-{user}"
    # no home at all: expanduser leaves "~" (never a folder relative to the working one)
    return [pathlib.Path(base) / "cas_freq" / "numba"] * os.path.isabs(base) + [temporary]


def _private_folder(path):
    """Create ``path`` (mode 700) if needed; True if it is then a folder of this user that
    only this user can write (machine code is loaded from it: another user's folder in the
    temporary folder must not be trusted)."""
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = path.stat()
    except OSError:
        return False
    own = not hasattr(os, "getuid") or info.st_uid == os.getuid()
    return own and not info.st_mode & 0o022 and writable(path)


def choose_cache_dir(environ=None, package_writable=None):
    """The folder numba should cache the kernels in, or None to leave numba's choice.

    None where the user set ``NUMBA_CACHE_DIR`` (respected) or where the package's kernel
    folders are writable (numba's ``__pycache__`` next to them); else the first usable of
    :func:`cache_candidates`, or None if there is none (the kernels then compile in each
    process, :func:`cached_jit`).

    Parameters
    ----------
    environ : mapping, optional
        The environment (default ``os.environ``).
    package_writable : callable, optional
        ``path -> bool`` for the kernel folders (default :func:`writable`; a test's stand-in,
        since root writes anywhere).
    """
    environ = os.environ if environ is None else environ
    package_writable = writable if package_writable is None else package_writable
    if environ.get(CACHE_ENV):
        return None
    if all(package_writable(_PACKAGE / name / "__pycache__") for name in KERNEL_DIRS):
        return None
    return next((str(path) for path in cache_candidates(environ) if _private_folder(path)), None)


def configure_cache(environ=None, package_writable=None):
    """Set ``NUMBA_CACHE_DIR`` to :func:`choose_cache_dir`'s folder if it gives one (and
    numba's setting too if numba is already imported); returns that folder or None."""
    import sys

    environ = os.environ if environ is None else environ
    folder = choose_cache_dir(environ, package_writable)
    if folder is not None:
        environ[CACHE_ENV] = folder
        numba = sys.modules.get("numba")
        if numba is not None:
            numba.config.CACHE_DIR = folder
    return folder


configure_cache()

#: Where the first-compilation messages go: a callable taking a line (the CLI's stderr), or
#: None for the ``cas_freq`` logger (:func:`compile_messages`).
_SAY = None
#: Seconds spent compiling in this process (wall, and CPU of the compiling thread), since when
#: the running compilation has been (None when none runs: ``depth``, its nesting, is 0),
#: whether the first-run message was given, whether some kernel could not be cached, and the
#: process that tells (not the report's forked workers, which may compile too). ``ticker``: the
#: thread saying "still compiling", stopped by :func:`compile_summary`.
_COMPILING = {"seconds": 0.0, "cpu_seconds": 0.0, "started": None, "cpu_started": 0.0,
              "depth": 0, "told": False, "uncached": False, "listener": None,
              "pid": os.getpid(), "ticker": None}


def compile_messages(say=None):
    """Send the first-compilation messages to ``say`` (a callable taking one line, e.g. the
    CLI's stderr printer), or to the ``cas_freq`` logger at INFO level with None (the
    default)."""
    global _SAY
    _SAY = say
    _COMPILING["pid"] = os.getpid()


def _tell(text):
    if _SAY is not None:
        _SAY(text)
    else:
        _LOG.info(text)


def compile_summary():
    """The line telling how long kernels compiled since the first-run message (or the last
    summary), wall and CPU, or None if they did not; the next compilation is then told again.

    The CPU time is the compiling thread's: below the wall time where other processes shared
    the machine's cores.
    """
    ticker, _COMPILING["ticker"] = _COMPILING["ticker"], None
    if ticker is not None:
        ticker.set()
    if not _COMPILING["told"]:
        return None
    where = ("no writable cache folder: they compile again in the next run"
             if _COMPILING["uncached"] else
             "runs that need the same kernels load them from the cache")
    seconds, cpu = _compiled_seconds()
    _COMPILING.update(seconds=0.0, cpu_seconds=0.0, told=False)
    return (f"cas-freq: compiled the numerical kernels in {_seconds(seconds)} s "
            f"(CPU {_seconds(cpu)} s; {where})")


def _seconds(value):
    """``value`` [s] as said: whole seconds from 10 s, tenths below."""
    return f"{value:.0f}" if value >= 10 else f"{value:.1f}"


def _compiled_seconds():
    """Wall and CPU seconds compiled so far, the running compilation's wall time included."""
    seconds, started = _COMPILING["seconds"], _COMPILING["started"]
    if started is not None:
        seconds += time.perf_counter() - started
    return seconds, _COMPILING["cpu_seconds"]


def _start_ticker():
    """A thread saying every :data:`TICK_S` of compiling how long it has compiled so far (only
    where the messages go to a callable, the CLI's stderr); :func:`compile_summary` stops it."""
    if _SAY is None or _COMPILING["ticker"] is not None:
        return
    stop = threading.Event()
    _COMPILING["ticker"] = stop

    def tick():
        said = 0.0
        while not stop.wait(min(0.5, TICK_S / 5)):
            seconds = _compiled_seconds()[0]
            if _COMPILING["started"] is not None and seconds >= said + TICK_S:
                said = seconds - seconds % TICK_S
                say = _SAY
                if say is not None and not stop.is_set():
                    say(f"cas-freq: still compiling the numerical kernels ({_seconds(said)} s "
                        "so far) ...")

    threading.Thread(target=tick, daemon=True, name="cas-freq compile ticker").start()


def _listen_to_compilations():
    """Register (once per process) a numba listener that tells the first compilation and
    times them all: numba fires ``numba:compile`` only where the cache has no machine code
    for the function and its argument types (a cache miss)."""
    if _COMPILING["listener"] is not None:
        return
    from numba.core import event

    def module(event_):  # the compiled function's module; numba holds its compiler lock
        return getattr(event_.data["dispatcher"].py_func, "__module__", None) or ""

    class _Listener(event.Listener):
        def on_start(self, event_):
            if not module(event_).startswith("cas_freq."):  # the user's own numba code
                return
            if _COMPILING["depth"] == 0:
                _COMPILING["cpu_started"] = time.thread_time()
                _COMPILING["started"] = time.perf_counter()
                if not _COMPILING["told"] and os.getpid() == _COMPILING["pid"]:
                    _COMPILING["told"] = True
                    _tell("cas-freq: compiling the numerical kernels not in the cache yet (the "
                          f"time so far every {TICK_S:.0f} s) ...")
                    _start_ticker()
            _COMPILING["depth"] += 1

        def on_end(self, event_):
            if not module(event_).startswith("cas_freq."):
                return
            _COMPILING["depth"] -= 1
            if _COMPILING["depth"] == 0:
                _COMPILING["seconds"] += time.perf_counter() - _COMPILING["started"]
                _COMPILING["cpu_seconds"] += time.thread_time() - _COMPILING["cpu_started"]
                _COMPILING["started"] = None

    _COMPILING["listener"] = _Listener()
    event.register("numba:compile", _COMPILING["listener"])


def cached_jit(arguments=None, **options):
    """``numba.njit`` with ``cache=True``; without a cache if no cache directory is usable.

    ``error_model="numpy"``: a division by zero gives inf or nan, as in the numpy code each
    kernel mirrors, instead of raising. The first compilation in a process is told
    (:func:`compile_messages`).

    Parameters
    ----------
    arguments : tuple of numba types, optional
        The kernel's one signature (its argument types, e.g. :func:`array_type`), compiled or
        loaded from the cache when the kernel's module is imported: every call converts to it
        (a C-contiguous or read-only array to an ``array_type`` of any layout), and a call
        that cannot raises ``TypeError`` instead of compiling another machine code. None (an
        inlined helper): numba compiles for each call's types.
    **options
        More ``numba.njit`` options (``nogil``, ``inline``).
    """
    from numba import njit

    _listen_to_compilations()
    signatures = () if arguments is None else [tuple(arguments)]

    def decorate(function):
        try:
            return njit(*signatures, cache=True, error_model="numpy", **options)(function)
        except RuntimeError:  # numba: "cannot cache function ...: no locator available"
            _COMPILING["uncached"] = True
            return njit(*signatures, cache=False, error_model="numpy", **options)(function)

    return decorate


def array_type(dtype, ndim, written=False):
    """numba's type of a numpy array argument of any layout (C-contiguous, Fortran-ordered or
    a strided view), for :func:`cached_jit`'s ``arguments``: one machine code for all layouts.

    Parameters
    ----------
    dtype : str
        The element type by numba's name (``"float64"``, ``"complex128"``, ``"int64"``,
        ``"bool_"``).
    ndim : int
        Number of dimensions.
    written : bool
        The kernel writes into the array; else the array is declared read-only, which accepts
        read-only and writable arrays alike.
    """
    from numba import types

    return types.Array(getattr(types, dtype), ndim, "A", readonly=not written)
