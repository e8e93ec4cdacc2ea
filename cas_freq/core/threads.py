"""Threads: one BLAS thread around the toolbox's small dense linear algebra, the caller's
setting kept; and worker threads that an interrupt does not wait for (:func:`worker_threads`,
:func:`result_of`).

The toolbox's linear algebra is many small matrices (5 x 5 exponentials, eigenvalues of loop
matrices, 3 x 3 solves), where BLAS's threads only contend: on a loaded machine a 5 x 5
``expm`` took 2.8-6.8 ms with the default threads against 0.021 ms with one. The CLI sets the
``*_NUM_THREADS`` variables before numpy loads (:func:`cas_freq.cli.limit_blas_threads`); the
Python API cannot (numpy is loaded already), so its entry points and the simulator's
exponentials run inside :func:`one_blas_thread`, which limits every loaded BLAS library with
threadpoolctl and restores the caller's thread counts on exit. :func:`expm` is the toolbox's
matrix exponential, on one BLAS thread.
"""

import concurrent.futures
import contextlib

_CONTROLLER = None

#: The longest a wait of the main thread for a worker thread lasts before Python code runs
#: again [s]: the next wait starts after it (:func:`result_of`).
WAIT_SLICE_S = 0.05


def _controller():
    """threadpoolctl's controller of the BLAS libraries numpy and scipy.linalg load, made once
    (making one scans the process's libraries, ~3 ms; entering its limit costs ~10 us)."""
    global _CONTROLLER
    if _CONTROLLER is None:
        import numpy  # noqa: F401 - the BLAS libraries the toolbox calls, loaded first
        import scipy.linalg  # noqa: F401
        from threadpoolctl import ThreadpoolController

        _CONTROLLER = ThreadpoolController()
    return _CONTROLLER


@contextlib.contextmanager
def one_blas_thread():
    """Context manager (and function decorator): every BLAS library of numpy and scipy limited
    to one thread inside, the previous thread counts restored on exit.

    Where every BLAS library already runs one thread (the CLI's setting), there is nothing to
    limit or restore: entering then only reads their counts (~2 us against ~10 us for the
    limit, whose set and restore also cost a single run's simulation ~60 us in all).
    """
    controller = _controller()
    if all(lib.num_threads == 1 for lib in controller.lib_controllers
           if lib.user_api == "blas"):
        yield
        return
    with controller.limit(limits=1, user_api="blas"):
        yield


@contextlib.contextmanager
def worker_threads(max_workers, thread_name_prefix=""):
    """Context manager: a ``concurrent.futures.ThreadPoolExecutor`` whose tasks are waited for
    only when the block ends normally.

    ``with ThreadPoolExecutor()`` waits on leaving the block for every task submitted, also
    when an interrupt leaves it: Ctrl-C while the threads compiled the kernels (a first run:
    minutes on a loaded machine) or analysed a large batch acted only once they were done.
    Here an exception (Ctrl-C, SIGTERM, an error) leaves at once: the tasks not started are
    cancelled, the running ones end on their own, their results unused (the CLI then ends the
    process). Where it ends normally, the threads are waited for in slices, as :func:`result_of`
    waits (which the block should use for the tasks' results), so that a Ctrl-C then acts at
    once too.

    Parameters
    ----------
    max_workers : int
        The number of threads.
    thread_name_prefix : str, optional
        Their names' prefix.
    """
    pool = concurrent.futures.ThreadPoolExecutor(max_workers=max_workers,
                                                 thread_name_prefix=thread_name_prefix)
    try:
        yield pool
        pool.shutdown(wait=False)  # the threads end once the tasks submitted are done
        for thread in list(pool._threads):  # waited for in slices, as in result_of()
            while thread.is_alive():
                thread.join(WAIT_SLICE_S)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise


def result_of(future):
    """``future.result()``, waited for in slices of :data:`WAIT_SLICE_S`, so that a Ctrl-C
    acts within one slice: call it, not ``future.result()``, for a worker's result in the main
    thread (``pool.map``'s results are such waits too).

    A wait without a timeout acts on a signal only if the signal interrupts it: one that
    arrives just before the wait blocks (the main thread has passed the last point where
    Python runs a pending handler, in the few instructions between
    ``Condition.wait`` and its lock's acquire) is handled only once the wait ends, when the
    task has returned. A Ctrl-C sent just as a worker started was so held for the worker's
    whole task about one time in ten (tests/test_lost_interrupts.py); a real one during a
    first run's compiling would have been held for minutes.

    Parameters
    ----------
    future : concurrent.futures.Future
        A task's future.

    Returns
    -------
    object
        The task's result; its exception is raised.
    """
    while not future.done():
        concurrent.futures.wait((future,), timeout=WAIT_SLICE_S)
    return future.result()


def expm(matrices):
    """``scipy.linalg.expm`` of a matrix or a stack (..., m, m) on one BLAS thread
    (:func:`one_blas_thread`); scipy.linalg is imported at the first call, not with the
    toolbox (about 0.3 s of a process's start that a continuous analysis does not need)."""
    from scipy.linalg import expm as exponential

    with one_blas_thread():
        return exponential(matrices)
