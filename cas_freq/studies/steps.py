"""Nonlinear output steps of many variants, with the figures and fit of ``simulate`` for each.

The runs go through :func:`cas_freq.simulation.simulate_batch` in chunks. The batch extends its
horizon until every run of the chunk has settled; each run stops at the horizon it would have
had alone (``stop_settled``) and its figures and fit are taken there, so they match
``simulate --json`` for the same variant. The chunk records only what the figures and the fit
need (:data:`STEP_SIGNALS`), and its step figures are computed in one compiled pass
(:func:`chunk_step_figures`).
"""

import collections
import dataclasses
import math

import numpy as np

from cas_freq.core.jit import use_compiled
from cas_freq.core.threads import result_of, worker_threads
from cas_freq.simulation.commands import Step
from cas_freq.simulation.figure_kernel import FIGURE_COLUMNS, step_figures_batch
from cas_freq.simulation.second_order import fit_second_order_batch
from cas_freq.simulation.simulator import RecordingBuffers, simulate_batch
from cas_freq.simulation.step_figures import simulation_step_figures

#: Runs simulated together: memory is about 10 signals x 8 B x samples (up to 80,001) per run
#: (the kernel writes only :data:`STEP_SIGNALS` of them).
DEFAULT_STEP_CHUNK = 32

#: Threads fitting the second-order model (the machine's two cores, shared with the
#: simulation of the next chunks), and the chunks whose fits may wait at once (memory: each
#: holds its output angles, 32 x 40,001 x 8 B = 10 MB).
FIT_THREADS = 2
FITS_IN_FLIGHT = 2

#: Figure names (as in ``simulate --json``: ``step.*`` and ``fit.*``).
STEP_FIGURES = (
    "step.rise_time_s", "step.overshoot_pct", "step.settling_time_s",
    "step.settling_time_5pct_s", "step.peak_time_s", "step.max_current_a", "step.max_voltage_v",
    "step.current_limited", "step.voltage_limited",
)
#: The signals a step batch records: what the step figures need.
STEP_SIGNALS = ("theta", "i", "V", "current_limited", "voltage_limited")
FIT_FIGURES = (
    "fit.wn_rad_s", "fit.zeta", "fit.td_s", "fit.rms_residual", "fit.bandwidth_closed_form_rad_s",
)


def batch_steps(params, amplitude_rad, *, fit=True, rates_hz=(None, None),
                chunk_size=DEFAULT_STEP_CHUNK, progress=None, buffers=None):
    """Step figures (and second-order fits) of every run.

    Parameters
    ----------
    params : cas_freq.simulation.LoopParameters
        The runs.
    amplitude_rad : float
        Output step [rad].
    fit : bool
        Also fit the second-order model to each response, all runs of a chunk at once
        (:func:`~cas_freq.simulation.second_order.fit_second_order_batch`: the estimates of
        ``simulate``'s :func:`~cas_freq.simulation.second_order.fit_second_order` to ~1e-12;
        1.2-1.7 ms of CPU per run on a loaded 2-core machine, against 25-35 ms for one
        :func:`scipy.optimize.least_squares` per run).
    rates_hz : (float or None, float or None)
        Sampled-controller rates (current, position) [Hz], or None for continuous.
    chunk_size : int
        Runs simulated together.
    progress : callable, optional
        ``progress(done, total)`` for each run once its chunk's figures and fits are done.
    buffers : cas_freq.simulation.simulator.RecordingBuffers, optional
        Memory the chunks record into, kept by the caller between calls (a bisection's many
        small batches); default: new for this call.

    Returns
    -------
    dict of str to numpy.ndarray
        :data:`STEP_FIGURES` (and :data:`FIT_FIGURES`), each (n,), NaN where undefined; the
        limit flags are 1.0 or 0.0.
    """
    n = params.n_runs
    names = STEP_FIGURES + (FIT_FIGURES if fit else ())
    out = {name: np.full(n, np.nan) for name in names}
    current_rate, position_rate = rates_hz
    done = 0
    # Every chunk records into the same memory; its figures are taken before the next starts,
    # and its fits get the output angle and times, arrays of their own (BatchResult.delta, .t).
    buffers = RecordingBuffers() if buffers is None else buffers
    # The fits of a chunk run in background threads while the next chunks are simulated
    # (their compiled work releases the GIL, as the simulation kernel does): each chunk's
    # runs in :data:`FIT_THREADS` parts, so that the fits, the larger share of the work, use
    # both cores while the main thread waits or Python holds the GIL. A fit does not depend on
    # the other runs fitted with it, so neither the parts nor the threads change a number.
    with worker_threads(FIT_THREADS) as fitter:
        pending = collections.deque()
        for start in range(0, n, chunk_size):
            stop = min(start + chunk_size, n)
            chunk = params.take(slice(start, stop))
            result = simulate_batch(chunk, Step(amplitude_rad), current_rate_hz=current_rate,
                                    position_rate_hz=position_rate, buffers=buffers,
                                    signals=STEP_SIGNALS, stop_settled=True)
            sizes = result.sizes()  # each run cut at the horizon it would have had alone
            for name, values in chunk_step_figures(result, amplitude_rad, sizes).items():
                out[name][start:stop] = values
            if not fit:
                done = _count(done, stop - start, n, progress)
                continue
            # result.t and result.delta are arrays of their own, not the buffers
            times = [result.t[:size] for size in sizes]
            outputs = [result.delta[run, :size] for run, size in enumerate(sizes)]
            part = -(-len(sizes) // FIT_THREADS)
            pending.extend((start + first, fitter.submit(
                fit_second_order_batch, times[first:first + part],
                outputs[first:first + part], amplitude_rad))
                for first in range(0, len(sizes), part))
            while len(pending) > FIT_THREADS * FITS_IN_FLIGHT:
                done = _store_fits(out, *pending.popleft(), done, n, progress)
        while pending:
            done = _store_fits(out, *pending.popleft(), done, n, progress)
    return out


def chunk_step_figures(result, amplitude_rad, sizes):
    """The :data:`STEP_FIGURES` of every run of a step batch, each run cut at ``sizes``.

    Compiled (:func:`~cas_freq.simulation.figure_kernel.step_figures_batch`) with the compiled
    engine, else run by run by :func:`~cas_freq.simulation.step_figures.step_figures`: the
    same numbers.

    Parameters
    ----------
    result : cas_freq.simulation.simulator.BatchResult
        The batch, with at least the signals of :data:`STEP_SIGNALS` recorded.
    amplitude_rad : float
        Output step [rad].
    sizes : numpy.ndarray
        Samples of each run (:meth:`BatchResult.sizes`).

    Returns
    -------
    dict of str to numpy.ndarray
        Each figure of :data:`STEP_FIGURES`, shape (n_runs,).
    """
    if use_compiled():
        table = step_figures_batch(result.t, np.ascontiguousarray(result.delta), sizes,
                                   float(amplitude_rad), result.i, result.V,
                                   result.current_limited, result.voltage_limited)
        return {f"step.{name}": table[:, column] for column, name in enumerate(FIGURE_COLUMNS)}
    out = {name: np.full(len(sizes), np.nan) for name in STEP_FIGURES}
    for run in range(len(sizes)):
        figures = simulation_step_figures(result.run(run), amplitude_rad)
        for key, value in dataclasses.asdict(figures).items():
            name = f"step.{key}"
            if name in out:
                out[name][run] = math.nan if value is None else float(value)
    return out


def _store_fits(out, start, future, done, n, progress):
    """Write a chunk's fits (from ``future``) into ``out`` from run ``start``; count them."""
    models = result_of(future)
    for run, model in enumerate(models, start):
        for key in FIT_FIGURES:
            out[key][run] = getattr(model, key.split(".", 1)[1])
    return _count(done, len(models), n, progress)


def _count(done, count, n, progress):
    """Report ``count`` more runs done."""
    for _ in range(count):
        done += 1
        if progress:
            progress(done, n)
    return done

