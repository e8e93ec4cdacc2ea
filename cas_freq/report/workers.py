"""Worker processes that never outlive the report that forked them.

The report's figures are drawn in forked processes
(:class:`cas_freq.report.rendering.FigureRenderer`).
A worker waits for work on a queue whose pipe it holds both ends of, so on its own it would
never notice its parent's death: a report killed by ``timeout`` (SIGTERM) or SIGKILL would leave
its workers running, re-parented to init, holding the caller's stdout and stderr open (a caller
that captures the output then waits forever). Here each worker:

- asks the kernel for SIGKILL when its parent dies (Linux ``prctl(PR_SET_PDEATHSIG)``), and
  exits at once if the parent died before that took effect (``getppid()`` no longer the parent);
- ignores SIGINT: a Ctrl-C reaches the whole foreground process group, and the parent, which
  handles it, ends the workers (:func:`stop_pool`); a worker interrupted on its own would only
  print a traceback;
- takes SIGTERM and SIGHUP by their default action (the parent's handlers, inherited through
  the fork, raise an exception meant for the parent's clean-up).

The parent forks with these signals blocked (:func:`fork_pool`), so none lands in a worker
before it has set them up; signals that arrive meanwhile are delivered to the parent when the
fork is done. :func:`stop_pool` with ``kill=True`` (an interrupted or failed report) kills the
workers at once instead of waiting for the figures they are drawing.

Linux only: elsewhere the report draws in its own process and nothing is forked.

The workers never compile: :func:`prepare_kernels` has the kernels they run in the report's
process before it forks them (on a first run each worker compiled the envelope's again); it
compiles the frequency-domain ones in a forked helper meanwhile, into numba's cache.
"""

import ctypes
import dataclasses
import functools
import multiprocessing
import os
import signal
import threading
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from cas_freq.analysis import batch_analyze
from cas_freq.core.jit import use_compiled
from cas_freq.core.parameters import LoopParameters
from cas_freq.core.threads import result_of, worker_threads
from cas_freq.report.envelope import envelope_variants
from cas_freq.simulation.simulator import prepare_kernels as prepare_simulation

#: ``prctl`` option that sets the signal a process gets when its parent dies (linux/prctl.h).
PR_SET_PDEATHSIG = 1

#: Signals blocked while the workers are forked and set up in each worker.
WORKER_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

#: Longest wait for a killed worker to be reaped [s] (it is gone within milliseconds).
KILL_WAIT_S = 2.0

#: Period of the parent check where ``prctl`` is unavailable [s].
PARENT_POLL_S = 0.2


def prepare_kernels(variants):
    """Have the compiled kernels of the load envelope in this process, before it forks the
    workers that compute it (compiled where numba's cache has none, else loaded from it).

    For each variant whose envelope the report computes
    (:func:`cas_freq.report.envelope.envelope_variants`): the simulation's kernels
    (:func:`cas_freq.simulation.simulator.prepare_kernels`: steps with and without a load
    spring, fits, step figures) and the frequency-domain batch kernels
    (:func:`cas_freq.analysis.batch_analyze` of two runs, without and with a load spring, on a
    short grid: a batch analysis runs them at any size; the grid scans of
    :mod:`cas_freq.analysis.scan_kernel` run only on larger arrays than an envelope's).
    The kernels take the architecture, the sampling and the load as data, so one variant
    prepares them for every other: the first enveloped one (and, for the frequency-domain
    kernels, the first with continuous controllers: sampled loops are evaluated in numpy).
    Nothing with the reference engine. The frequency-domain kernels are compiled (or loaded) in
    a forked helper process at the same time as the simulation's here, then loaded here from
    numba's cache (compiled here where the helper could not).

    Parameters
    ----------
    variants : list of cas_freq.config.LoadedVariant
        The report's variants (of one config).
    """
    if not use_compiled() or not variants or variants[0].params.load_envelope is None:
        return
    wanted = envelope_variants(variants[0].params)
    enveloped = [loaded for loaded in variants if wanted is None or loaded.variant in wanted]
    if not enveloped:
        return
    continuous = next((loaded for loaded in enveloped
                       if not loaded.params.sampling.sample_rates), None)
    if continuous is None:
        prepare_simulation(enveloped[0].params)
        return
    # the frequency-domain kernels compile in a forked helper while this process compiles the
    # simulation's (numba compiles one function at a time per process: on a first run this
    # takes the longer of the two instead of their sum); afterwards this process loads the
    # helper's from numba's cache
    helper, (prepared,) = fork_pool(
        1, functools.partial(_prepare_frequency_kernels, continuous.params))
    try:
        prepare_simulation(enveloped[0].params)
        prepared.exception()  # waited for; where it failed, this process compiles them below
    finally:
        stop_pool(helper, kill=True)
    prepare_frequency_kernels(continuous.params)


def prepare_frequency_kernels(params):
    """Have the frequency-domain kernels of a batch of ``params`` (an ActuatorConfig) in this
    process (see :func:`prepare_kernels`); nothing with the reference engine.

    In a thread of its own, as :func:`cas_freq.simulation.simulator.prepare_kernels` (see its
    docstring).
    """
    if use_compiled():
        with worker_threads(1, "cas_freq-prepare-kernels") as thread:
            result_of(thread.submit(_prepare_frequency_kernels, params))


def _prepare_frequency_kernels(params):
    """The work of :func:`prepare_frequency_kernels`, in its thread."""
    runs = LoopParameters.from_configs([params]).take([0, 0])
    runs = dataclasses.replace(runs, K_h=np.array([0.0, 1.0]))
    batch_analyze(runs, frequency_range=(1.0, 1e4), points_per_decade=5, workers=1)


def fork_pool(workers, warm_up):
    """A pool of ``workers`` forked processes that end with this one.

    Parameters
    ----------
    workers : int
        Number of processes (forked now).
    warm_up : callable
        A module-level function without arguments, submitted once per worker here (so the
        processes are forked now; e.g. a first import).

    Returns
    -------
    tuple of (concurrent.futures.ProcessPoolExecutor, list of concurrent.futures.Future)
        The pool and the futures of the ``warm_up`` calls.
    """
    parent = os.getpid()
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, WORKER_SIGNALS)
    pool = None
    try:
        pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"),
                                   initializer=_start_worker, initargs=(parent, previous))
        # the first submission forks every worker (the fork start method), here and now,
        # from this thread, which lives as long as the process (PR_SET_PDEATHSIG fires when
        # the forking thread ends)
        futures = [pool.submit(warm_up) for _ in range(workers)]
    except BaseException:
        if pool is not None:
            stop_pool(pool, kill=True)
        raise
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)
    return pool, futures


def stop_pool(pool, kill=False):
    """Shut ``pool`` down: after its work is done, or with ``kill`` at once (its workers
    killed, queued and running work abandoned); returns when no worker is left."""
    if not kill:
        pool.shutdown(wait=True, cancel_futures=True)
        return
    processes = list(pool._processes.values())  # pid -> Process (not public before 3.14)
    for process in processes:
        process.kill()
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.join(KILL_WAIT_S)


def _start_worker(parent, mask):
    """Initializer of each worker: signals as described in the module, then end with
    ``parent``; ``mask`` is the parent's signal mask before :func:`fork_pool` blocked
    :data:`WORKER_SIGNALS`."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.signal(signal.SIGHUP, signal.SIG_DFL)
    _end_with_parent(parent)
    signal.pthread_sigmask(signal.SIG_SETMASK, mask)


def _end_with_parent(parent):
    """Have this process killed when ``parent`` (its parent's pid) dies."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        armed = libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):  # no prctl: not Linux, or a libc without it
        armed = False
    if os.getppid() != parent:  # the parent died before the request took effect
        os._exit(1)
    if not armed:
        threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def _watch_parent(parent):
    """Exit this process once ``parent`` is no longer its parent (it died)."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL_S)
    os._exit(1)
