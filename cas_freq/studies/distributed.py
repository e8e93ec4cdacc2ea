"""Running a study's chunks on a dask.distributed cluster (the optional ``distributed`` extra).

A sweep or a Monte Carlo is a list of independent samples. Locally they are evaluated in one
process; with ``--scheduler`` they are cut into chunks of :data:`CHUNK_SAMPLES` samples, each
chunk is evaluated by :func:`cas_freq.studies.sweep.evaluate_figures` on a worker, and the
chunks are put back in sample order. The cut does not depend on the number of workers, the
samples are drawn before the cut (the seed is used once, here), and every figure of a sample
is computed from that sample alone, so a run gives the same numbers with any number of
workers as it does locally.

Worker loss is dask's to handle: a chunk that was running on a lost worker is rescheduled on
another (up to ``distributed.scheduler.allowed-failures`` times); a chunk that raised is
retried :data:`RETRIES` times before the study fails with its error. Losing every worker at
once loses the config scattered to them (and with it every chunk still to run), as losing the
scheduler loses every chunk: the study then ends with one line saying the cluster was lost
(:class:`~cas_freq.core.exceptions.CasFreqError`, exit 2), not with dask's ``FutureCancelledError``.

``ADDRESS`` is a scheduler address (``tcp://host:8786``, ``host:8786``) or ``local:N`` for a
local cluster of N single-threaded worker processes, started and stopped with the study.
"""

import contextlib
import re

from cas_freq.core.exceptions import CasFreqError

#: Samples per chunk sent to a worker (a multiple of the step batch, so that a chunk's steps
#: run in the same batches as locally).
CHUNK_SAMPLES = 256

#: Times a chunk that raised is submitted again.
RETRIES = 2

#: Seconds to wait for a scheduler address to answer.
CONNECT_TIMEOUT_S = 20.0

#: Most local workers ``local:N`` starts.
MAX_LOCAL_WORKERS = 256

_LOCAL = re.compile(r"local:(\d+)")
_ADDRESS = re.compile(r"((tcp|tls|inproc|ucx|ws|wss)://)?[A-Za-z0-9_.\-\[\]:]+:\d+")


def parse_scheduler(text):
    """Check a ``--scheduler`` value: ``local:N`` or ``[protocol://]host:port``.

    Returns
    -------
    (str, int or str)
        ``("local", N)`` or ``("address", text)``.

    Raises
    ------
    CasFreqError
        For anything else, saying what is accepted.
    """
    text = str(text).strip()
    local = _LOCAL.fullmatch(text)
    if local:
        workers = int(local.group(1))
        if not 1 <= workers <= MAX_LOCAL_WORKERS:
            raise CasFreqError(f"--scheduler: local:N needs 1 <= N <= {MAX_LOCAL_WORKERS} "
                               f"workers, got {text!r}")
        return "local", workers
    if _ADDRESS.fullmatch(text):
        return "address", text
    raise CasFreqError(f"--scheduler: expected local:N (a local cluster of N workers) or a "
                       f"scheduler address such as tcp://10.0.0.5:8786, got {text!r}")


def distributed_module():
    """The ``distributed`` module, or a clear error naming the extra to install."""
    try:
        import distributed
    except ImportError:
        raise CasFreqError(
            "--scheduler needs dask.distributed: pip install \"cas_freq[distributed]\""
        ) from None
    return distributed


#: Clients open in this process, by ``--scheduler`` value (see :func:`session`).
_OPEN = {}


def session(scheduler):
    """A context in which every study on ``scheduler`` shares one client (and one local
    cluster), e.g. around the variants of ``montecarlo --all-variants``; a no-op for None."""
    return contextlib.nullcontext() if scheduler is None else client_for(scheduler)


@contextlib.contextmanager
def client_for(scheduler):
    """A dask Client for a ``--scheduler`` value: the one an enclosing :func:`client_for` of
    the same value opened, else a new one (a local cluster is closed on exit)."""
    if scheduler in _OPEN:
        yield _OPEN[scheduler]
        return
    with _new_client(scheduler) as client:
        _OPEN[scheduler] = client
        try:
            yield client
        finally:
            del _OPEN[scheduler]


@contextlib.contextmanager
def _new_client(scheduler):
    distributed = distributed_module()
    kind, value = parse_scheduler(scheduler)
    if kind == "local":
        with distributed.LocalCluster(n_workers=value, threads_per_worker=1, processes=True,
                                      dashboard_address=None) as cluster, \
                distributed.Client(cluster) as client:
            try:
                yield client
            except KeyboardInterrupt:  # Ctrl-C, SIGTERM: end at once, not in 4 s per worker
                _kill_local_workers(cluster)
                raise
        return
    try:
        client = distributed.Client(value, timeout=f"{CONNECT_TIMEOUT_S}s")
    except (OSError, TimeoutError) as exc:
        raise CasFreqError(f"--scheduler: no dask scheduler answers at {value!r} "
                           f"({type(exc).__name__}: {exc})") from None
    with client:
        yield client


def _kill_local_workers(cluster):
    """Kill a local cluster's worker processes (SIGKILL) and quieten dask's logs, so that an
    interrupted study ends within the second its Ctrl-C promises: closed as usual, each busy
    worker is given 4 s to finish its chunk (the nanny's grace) and dask logs two warnings per
    worker. Each nanny is first marked as closing, so that it does not restart its worker."""
    import logging
    import os
    import signal

    from distributed.core import Status

    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    for nanny in list(cluster.workers.values()):
        pid = getattr(nanny, "pid", None)
        if pid is None:
            continue
        nanny.status = Status.closing_gracefully
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass


def chunk_slices(n_samples, size=CHUNK_SAMPLES):
    """Slices of consecutive samples, ``size`` each (the last one shorter)."""
    return [slice(start, min(start + size, n_samples)) for start in range(0, n_samples, size)]


def cluster_lost(scheduler, exc, done, total):
    """The one-line error of a study whose cluster lost the chunks still to run: every worker
    gone (the config scattered to them with them), the scheduler gone, or a chunk's workers
    dying more often than dask allows."""
    import distributed

    if isinstance(exc, distributed.KilledWorker):
        why = ("a chunk's workers died more often than dask allows "
               "(distributed.scheduler.allowed-failures; out of memory?)")
    else:
        why = (f"every worker (or the scheduler) left, taking the chunks still to run "
               f"(dask: {getattr(exc, 'reason', None) or 'cancelled'})")
    return CasFreqError(f"--scheduler {scheduler}: the dask cluster was lost mid-study after "
                        f"{done:,} of {total:,} samples: {why}; start the workers again and "
                        "rerun, or run without --scheduler")
