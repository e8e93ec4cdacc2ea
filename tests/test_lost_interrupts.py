"""Ctrl-C (and SIGTERM) is neither lost nor held up: not where it lands in Python code Python
cannot interrupt, not while worker threads compile the kernels or analyse a batch.

Python runs a signal's handler at the next instruction of Python code; where that code was
called from C (llvmlite's object-cache callback while numba compiles a kernel, any ctypes
callback) or is a finaliser, the KeyboardInterrupt is printed as "Exception ignored" and the
run goes on: a first ``cas-freq report`` interrupted ~2 s in ended with exit 0, a complete
report and a traceback one time in six. Each case below sends the real signal from inside
such code, so its handler runs there, as when the signal arrives during the compiler's C code.

A first report compiles its simulation kernels in a worker thread (prepare_kernels) and the
frequency-domain batch runs its chunks in worker threads; ``with ThreadPoolExecutor()`` waited
for them on leaving the block, so a Ctrl-C there acted only once a first run's compiling was
done (minutes on a loaded machine). A wait without a timeout also held a Ctrl-C that arrived
just before it blocked until the task returned (one test run in ten here): the main thread
waits in slices (cas_freq.core.threads.result_of).
"""

import _thread
import ctypes
import importlib
import signal
import sys
import threading
import time
from types import SimpleNamespace

import pytest

import cas_freq.core.jit as jit
import cas_freq.simulation.simulator as simulator
from cas_freq.cli import main
from cas_freq.config import load_variant
from cas_freq.core.parameters import LoopParameters
from cas_freq.core.threads import result_of, worker_threads

# the module (cas_freq.analysis exports its function analyze under the same name)
analyze = importlib.import_module("cas_freq.analysis.analyze")

#: Work the command goes on with after the signal was lost: 500 ticks of 10 ms (5 s).
TICKS = 500
#: Ticks allowed after the signal: the interrupt is raised again once the code called from C
#: returns (at once, 0 ticks, when the machine is idle); 50 ticks (0.5 s) leave room for a
#: loaded 2-core machine scheduling the helper thread late, and are 10 % of the work.
TICKS_ALLOWED = 50


@pytest.fixture(autouse=True)
def sigint_as_from_a_terminal():
    """Python's own SIGINT handler during each test, as in a terminal: a suite started as a
    script's background job (``pytest &``) inherits SIGINT ignored, where no Ctrl-C arrives
    (and cas-freq rightly keeps it so); the handler it had is put back after the test."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def _in_llvmlite_callback(signum):
    """Compile a tiny LLVM module with llvmlite's MCJIT; the signal is raised inside its
    object-cache notification, the ctypes callback numba's compiler goes through."""
    llvm = pytest.importorskip("llvmlite.binding")
    llvm.initialize_native_target()
    llvm.initialize_native_asmprinter()
    module = llvm.parse_assembly("define i32 @f(i32 %x) {\n  ret i32 %x\n}\n")
    machine = llvm.Target.from_default_triple().create_target_machine()
    engine = llvm.create_mcjit_compiler(module, machine)

    def notify(module, buffer):
        signal.raise_signal(signum)
        for _ in range(3):  # the handler runs at one of these instructions: in the callback
            pass

    engine.set_object_cache(notify_func=notify)
    engine.finalize_object()
    return engine


def _in_ctypes_callback(signum):
    def callback():
        signal.raise_signal(signum)
        for _ in range(3):
            pass

    ctypes.CFUNCTYPE(None)(callback)()


def _in_finaliser(signum):
    class Finalised:
        def __del__(self):
            signal.raise_signal(signum)
            for _ in range(3):
                pass

    Finalised()  # no reference kept: its __del__ runs at once


PLACES = {"llvmlite callback": _in_llvmlite_callback, "ctypes callback": _in_ctypes_callback,
          "finaliser": _in_finaliser}


def _command(place, signum, progress):
    def run(args):
        PLACES[place](signum)
        for _ in range(TICKS):
            time.sleep(0.01)
            progress.append(1)
        return 0

    return run


@pytest.mark.parametrize("place", PLACES)
@pytest.mark.parametrize("signum, status, line", [
    (signal.SIGINT, 130, "cas-freq verify: interrupted\n"),
    (signal.SIGTERM, 143, "cas-freq verify: terminated (SIGTERM)\n")])
def test_a_signal_in_code_called_from_c_ends_the_run(place, signum, status, line, monkeypatch,
                                                      capsys):
    if signum == signal.SIGTERM and signal.getsignal(signal.SIGTERM) != signal.SIG_DFL:
        pytest.skip("SIGTERM is handled by the test runner here")
    progress = []
    hook = sys.unraisablehook
    monkeypatch.setattr("cas_freq.cli.verify.run", _command(place, signum, progress))
    assert main(["verify"]) == status
    assert len(progress) <= TICKS_ALLOWED, len(progress)
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err == line  # one line, no "Exception ignored"
    # the handlers are the caller's again, and no second interrupt is on its way
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL
    assert sys.unraisablehook is hook
    time.sleep(0.05)


def test_other_lost_exceptions_still_reach_the_callers_hook(monkeypatch):
    lost = []
    monkeypatch.setattr(sys, "unraisablehook", lambda unraisable: lost.append(unraisable))

    def run(args):
        def callback():
            raise ValueError("a callback's own error")

        ctypes.CFUNCTYPE(None)(callback)()
        return 0

    monkeypatch.setattr("cas_freq.cli.verify.run", run)
    assert main(["verify"]) == 0
    assert [str(unraisable.exc_value) for unraisable in lost] == ["a callback's own error"]


#: How long a blocked worker thread would hold the caller up [s], and how soon after the
#: signal the interrupt must reach the caller [s]: at once on an idle machine; 2 s leave room
#: for a loaded one and are a fifth of the wait.
BLOCKED_S, ACTED_WITHIN_S = 10.0, 2.0


class Blocked:
    """A worker thread's task that waits (at most :data:`BLOCKED_S`) until released; ``running``
    is set once one runs."""

    def __init__(self):
        self.running, self.release = threading.Event(), threading.Event()

    def __call__(self, *args, **kwargs):
        self.running.set()
        self.release.wait(BLOCKED_S)


@pytest.fixture
def blocked():
    task = Blocked()
    yield task
    task.release.set()


def _interrupted_while(call, blocked):
    """Run ``call()`` in the main thread with SIGINT sent to it once a worker runs ``blocked``
    (a real signal, as from a terminal: it wakes the main thread's wait for the worker); the
    seconds from the signal until its KeyboardInterrupt left ``call``."""
    main_thread = threading.main_thread().ident
    sent = []

    def send():
        if blocked.running.wait(BLOCKED_S):
            sent.append(time.perf_counter())
            signal.pthread_kill(main_thread, signal.SIGINT)

    threading.Thread(target=send, daemon=True).start()
    with pytest.raises(KeyboardInterrupt):
        call()
    assert sent, "no worker ran the blocked task"
    return time.perf_counter() - sent[0]


def test_worker_threads_are_not_waited_for_after_an_interrupt(blocked):
    def work():
        with worker_threads(2) as pool:
            futures = [pool.submit(blocked) for _ in range(4)]  # two run, two wait
            futures[0].result()

    assert _interrupted_while(work, blocked) < ACTED_WITHIN_S
    with worker_threads(1) as pool:  # ended normally, the tasks are waited for
        future = pool.submit(time.sleep, 0.2)
    assert future.done()


@pytest.mark.parametrize("wait", ["result_of", "leaving the block"])
def test_an_interrupt_pending_while_the_main_thread_waits_acts_at_once(wait, blocked):
    # _thread.interrupt_main sets SIGINT pending as a signal does, without interrupting the
    # main thread's wait: the state a Ctrl-C leaves where it arrives just before the wait blocks
    # (Python runs the handler where Python code runs next, or where the signal interrupts a
    # wait); a wait without a timeout held it until the task returned
    def task():
        time.sleep(0.2)  # the main thread waiting meanwhile
        _thread.interrupt_main()
        blocked()

    start = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        with worker_threads(1) as pool:
            future = pool.submit(task)
            if wait == "result_of":
                result_of(future)
    assert time.perf_counter() - start < 0.2 + ACTED_WITHIN_S


def test_ctrl_c_while_a_first_run_compiles_the_kernels_in_their_thread(blocked, monkeypatch):
    monkeypatch.setattr(jit, "use_compiled", lambda: True)
    monkeypatch.setattr(simulator, "_prepare_kernels", blocked)  # the compiling, held
    assert _interrupted_while(lambda: simulator.prepare_kernels(None), blocked) < ACTED_WITHIN_S


def test_ctrl_c_while_worker_threads_analyse_a_batch(blocked, monkeypatch):
    params = LoopParameters.from_configs([load_variant().params] * 4)
    monkeypatch.setattr(analyze, "_chunk_figures", blocked)  # each chunk's work, held
    took = _interrupted_while(lambda: analyze.batch_analyze(params, chunk_size=1, workers=2),
                              blocked)
    assert took < ACTED_WITHIN_S


def test_an_interrupted_compilation_ends_with_the_one_line(monkeypatch, capsys):
    # the compile summary ("compiled ... in N s; runs that need the same kernels load them from
    # the cache") is not said after Ctrl-C: the compiling was cut short
    from numba.core import event

    kernel = SimpleNamespace(py_func=SimpleNamespace(__module__="cas_freq.simulation.kernel"))

    def run(args):
        with event.trigger_event("numba:compile", data={"dispatcher": kernel}):
            raise KeyboardInterrupt

    jit._listen_to_compilations()  # as on importing a kernel's module
    jit.compile_summary()  # nothing left over from an earlier test
    said = []  # the CLI's compilation lines (silenced in the tests' process by conftest)
    monkeypatch.setattr("cas_freq.cli._say", said.append)
    monkeypatch.setattr("cas_freq.cli.verify.run", run)
    assert main(["verify"]) == 130
    assert capsys.readouterr().err == "cas-freq verify: interrupted\n"
    assert len(said) == 1 and said[0].startswith("cas-freq: compiling the numerical kernels")
