r"""Step figures and settling checks of a whole batch, compiled with numba.

:func:`step_figures_batch` gives, for each run of a batch, the figures of
:func:`~cas_freq.simulation.step_figures.step_figures` (rise time, overshoot, settling times at
2 % and 5 %, peak time, largest current and voltage, the limit flags) from the batch's recorded
signals, each run cut at its own number of samples; :func:`settled_runs` is the settling check
of the simulator's horizon (:func:`~cas_freq.simulation.simulator._settled`). Both are the
scalar form of their numpy references, with the same operations in the same order, so they
give the same numbers to the bit (``tests/test_simulation_step_figures.py`` compares them on a
nominal, an overshooting, an unsettled and an unstable run). Per 32-run chunk of a Monte Carlo
they take well under a millisecond, against ~10 ms for the per-run numpy figures and ~10 ms
for the numpy settling check over the whole horizon (which scans every sample; this one scans
each run backwards from its end and stops at its first sample outside the band).

Each kernel has one signature (:func:`~cas_freq.core.jit.cached_jit`'s ``arguments``): arrays of any
layout, read-only or not, so that a batch's whole buffers and views of their first columns
share one machine code.
"""

import math

import numpy as np
from numba import types

from cas_freq.core.jit import array_type, cached_jit
from cas_freq.simulation.step_figures import DIVERGED

#: Columns of :func:`step_figures_batch`'s table (the ``step.*`` figures of ``simulate``).
FIGURE_COLUMNS = (
    "rise_time_s", "overshoot_pct", "settling_time_s", "settling_time_5pct_s", "peak_time_s",
    "max_current_a", "max_voltage_v", "current_limited", "voltage_limited",
)


@cached_jit(inline="always")
def _first_crossing(t, y, size, level):
    """:func:`~cas_freq.simulation.step_figures._first_crossing` of y[:size]."""
    for k in range(size):
        if y[k] >= level:
            if k == 0:
                return t[0]
            return t[k - 1] + (level - y[k - 1]) / (y[k] - y[k - 1]) * (t[k] - t[k - 1])
    return math.nan


@cached_jit(inline="always")
def _settling_time(t, y, size, band):
    """:func:`~cas_freq.simulation.step_figures.settling_time` of y[:size]."""
    for k in range(size - 1, -1, -1):
        if abs(y[k] - 1.0) > band:
            if k == size - 1:
                return math.nan
            edge = 1.0 + band if y[k] > 1.0 else 1.0 - band
            return t[k] + (edge - y[k]) / (y[k + 1] - y[k]) * (t[k + 1] - t[k])
    return t[0]


@cached_jit(inline="always")
def _largest_magnitude(x, size):
    """np.max(np.abs(x[:size])), NaN if any sample is NaN."""
    top = abs(x[0])
    for k in range(size):
        value = abs(x[k])
        if math.isnan(value):
            return math.nan
        if value > top:
            top = value
    return top


@cached_jit((array_type("float64", 1), array_type("float64", 2), array_type("int64", 1),
             types.float64, array_type("float64", 2), array_type("float64", 2),
             array_type("bool_", 2), array_type("bool_", 2)), nogil=True)
def step_figures_batch(t, response, sizes, final, current, voltage, current_limited,
                       voltage_limited):
    """Step figures of every run (:func:`~cas_freq.simulation.step_figures.step_figures`).

    Parameters
    ----------
    t : numpy.ndarray
        Sample times [s], shape (m,), the step at t = 0.
    response : numpy.ndarray
        Output angle of each run [rad], shape (n, m).
    sizes : numpy.ndarray
        Samples of each run (its first ``sizes[r]`` columns), shape (n,), each >= 1.
    final : float
        The final value (the step) [rad], nonzero.
    current, voltage : numpy.ndarray
        Motor current [A] and voltage [V], shape (n, m).
    current_limited, voltage_limited : numpy.ndarray
        Where each limit was active (bool), shape (n, m).

    Returns
    -------
    numpy.ndarray
        Shape (n, 9), the columns :data:`FIGURE_COLUMNS`; the flags 1.0 or 0.0; NaN where a
        figure is undefined (all but the flags where the response diverged).
    """
    n = response.shape[0]
    out = np.full((n, 9), np.nan)
    y = np.empty(response.shape[1])
    for r in range(n):
        size = sizes[r]
        out[r, 7] = 0.0
        out[r, 8] = 0.0
        for k in range(size):
            if current_limited[r, k]:
                out[r, 7] = 1.0
                break
        for k in range(size):
            if voltage_limited[r, k]:
                out[r, 8] = 1.0
                break
        gone = False
        for k in range(size):
            y[k] = response[r, k] / final
            if not abs(y[k]) <= DIVERGED:
                gone = True
        if gone:  # diverged: no figures but the flags
            continue
        # the peak (the first largest sample), refined by a parabola through its neighbours
        top = 0
        for k in range(1, size):
            if y[k] > y[top]:
                top = k
        peak_time, peak = t[top], y[top]
        if 0 < top < size - 1:
            after, before = t[top + 1] - t[top], t[top] - t[top - 1]
            if abs(after - before) <= 1e-8 + 1e-6 * abs(before):  # numpy.isclose, rtol 1e-6
                a, b, c = y[top - 1], y[top], y[top + 1]
                curvature = a - 2 * b + c
                if curvature < 0:
                    shift = 0.5 * (a - c) / curvature
                    peak_time = t[top] + shift * after
                    peak = b - 0.25 * (a - c) * shift
        out[r, 0] = _first_crossing(t, y, size, 0.9) - _first_crossing(t, y, size, 0.1)
        out[r, 1] = max(0.0, 100.0 * (peak - 1.0))
        out[r, 2] = _settling_time(t, y, size, 0.02)
        out[r, 3] = _settling_time(t, y, size, 0.05)
        out[r, 4] = peak_time
        out[r, 5] = _largest_magnitude(current[r], size)
        out[r, 6] = _largest_magnitude(voltage[r], size)
    return out


@cached_jit((array_type("float64", 2), array_type("float64", 2), array_type("float64", 1),
             types.int64, types.float64), nogil=True)
def settled_runs(delta, command, final, start, band_fraction):
    """Per run: ``delta`` within ``band_fraction`` times the largest |command| of ``final``
    at every sample from column ``start`` on (the simulator's settling check).

    Parameters
    ----------
    delta, command : numpy.ndarray
        Output angle and its command [rad], shape (n, m).
    final : numpy.ndarray
        Final command per run [rad], shape (n,).
    start : int
        First column of the window (m or more: an empty window, never settled).
    band_fraction : float
        The band, relative to the largest |command| of the run.

    Returns
    -------
    numpy.ndarray
        Bool, shape (n,).
    """
    n, m = delta.shape
    out = np.zeros(n, dtype=np.bool_)
    if start >= m:
        return out
    for r in range(n):
        band = band_fraction * _largest_magnitude(command[r], m)
        inside = True
        for k in range(m - 1, start - 1, -1):
            if not abs(delta[r, k] - final[r]) <= band:
                inside = False
                break
        out[r] = inside
    return out
