"""BLAS threads in the Python API: one thread inside its calls, the caller's setting restored.

The CLI limits BLAS threads through the environment before numpy loads; a Python user's numpy
is loaded already, so the API limits them with threadpoolctl around its work
(cas_freq.core.threads).
Checked with threadpoolctl's own report of every loaded BLAS library's thread count, the
caller's count set to 2 first (so that "1 inside" cannot be the caller's own setting).
"""

import numpy as np
import scipy.linalg
from threadpoolctl import threadpool_info, threadpool_limits

import cas_freq as cf
import cas_freq.analysis
from cas_freq.simulation import mechanics

CALLER_THREADS = 2


def _blas_threads():
    """Thread count of each loaded BLAS library, by file."""
    return {info["filepath"]: info["num_threads"] for info in threadpool_info()
            if info["user_api"] == "blas"}


def _spy(record, function):
    def spied(*args, **kwargs):
        record.append(_blas_threads())
        return function(*args, **kwargs)
    return spied


def test_api_call_runs_on_one_blas_thread_and_restores_the_callers_count(monkeypatch):
    seen = []
    monkeypatch.setattr(cas_freq.analysis, "analyze", _spy(seen, cas_freq.analysis.analyze))
    act = cf.load()
    with threadpool_limits(limits=CALLER_THREADS, user_api="blas"):
        before = _blas_threads()
        assert before and set(before.values()) == {CALLER_THREADS}
        act.analyze()
        assert _blas_threads() == before  # the caller's setting, unchanged
    assert len(seen) == 1 and seen[0].keys() == before.keys()
    assert set(seen[0].values()) == {1}


def test_the_simulators_exponentials_run_on_one_blas_thread(monkeypatch):
    # scipy's expm as the toolbox's exponential (cas_freq.core.threads.expm) calls it
    seen = []
    monkeypatch.setattr(scipy.linalg, "expm", _spy(seen, scipy.linalg.expm))
    matrices = np.array([[[0.0, 1.0], [-1.0, 0.0]]] * 3)  # three copies of one rotation
    with threadpool_limits(limits=CALLER_THREADS, user_api="blas"):
        before = _blas_threads()
        result = mechanics.distinct_exponentials(matrices)
        assert _blas_threads() == before
    assert [set(threads.values()) for threads in seen] == [{1}]  # one expm: distinct matrices
    # expm of [[0, 1], [-1, 0]] is the rotation [[cos 1, sin 1], [-sin 1, cos 1]]
    rotation = [[np.cos(1.0), np.sin(1.0)], [-np.sin(1.0), np.cos(1.0)]]
    np.testing.assert_allclose(result, [rotation] * 3, rtol=0, atol=1e-14)


def test_where_blas_runs_one_thread_already_nothing_is_limited_or_restored(monkeypatch):
    """The CLI's setting (every BLAS library at one thread): entering only reads the counts.
    threadpoolctl's limit (a set and a restore per call, ~60 us of a single run's ~0.6 ms
    simulation) is refused here, so a call to it fails the test."""
    from cas_freq.core import threads

    controller = threads._controller()

    def refused(*args, **kwargs):
        raise AssertionError("limited although every BLAS library runs one thread")

    with threadpool_limits(limits=1, user_api="blas"):
        monkeypatch.setattr(controller, "limit", refused)
        with threads.one_blas_thread():
            assert set(_blas_threads().values()) == {1}
        monkeypatch.undo()
    with threadpool_limits(limits=CALLER_THREADS, user_api="blas"):  # and otherwise it limits
        with threads.one_blas_thread():
            assert set(_blas_threads().values()) == {1}
        assert set(_blas_threads().values()) == {CALLER_THREADS}

