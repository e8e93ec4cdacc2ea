"""Nonlinear fin steps of many variants, with the figures and fit of ``simulate`` for each.

The runs go through :func:`cas_freq.simulation.simulate_batch` in chunks. The batch extends its
horizon until every run of the chunk has settled; each run's figures are then taken over the
horizon the single-variant ``simulate`` would have used for it (0.1 s after the step, doubled
until that run has settled: the simulator's own rule), so figures and the second-order fit
match ``simulate --json`` for the same variant.
"""

import dataclasses
import math

import numpy as np

from cas_freq.simulation.commands import Step
from cas_freq.simulation.second_order import fit_second_order
from cas_freq.simulation.simulator import (
    DEFAULT_HORIZON_S,
    SETTLE_BAND,
    simulate_batch,
)
from cas_freq.simulation.step_figures import step_figures

#: Runs simulated together: memory is about 10 signals x 8 B x samples (up to 80,001) per run.
DEFAULT_STEP_CHUNK = 32

#: Figure names (as in ``simulate --json``: ``step.*`` and ``fit.*``).
STEP_FIGURES = (
    "step.rise_time_s", "step.overshoot_pct", "step.settling_time_s",
    "step.settling_time_5pct_s", "step.peak_time_s", "step.max_current_a", "step.max_voltage_v",
    "step.current_limited", "step.voltage_limited",
)
FIT_FIGURES = (
    "fit.wn_rad_s", "fit.zeta", "fit.td_s", "fit.rms_residual", "fit.bandwidth_closed_form_rad_s",
)


def _own_horizon(t, delta, amplitude, t_total):
    """Horizon [s] the single-run simulator would stop at for this run."""
    horizon = DEFAULT_HORIZON_S
    band = SETTLE_BAND * abs(amplitude)
    while True:
        window = (t >= 0.5 * horizon) & (t <= horizon + 1e-12)
        if np.all(np.abs(delta[window] - amplitude) <= band) or horizon >= t_total * (1 - 1e-9):
            return horizon
        horizon = min(2.0 * horizon, 10.0 * DEFAULT_HORIZON_S)


def batch_steps(params, amplitude_rad, *, fit=True, rates_hz=(None, None),
                chunk_size=DEFAULT_STEP_CHUNK, progress=None):
    """Step figures (and second-order fits) of every run.

    Parameters
    ----------
    params : cas_freq.simulation.LoopParameters
        The runs.
    amplitude_rad : float
        Fin step [rad].
    fit : bool
        Also fit the second-order model to each response (about 0.15 s per run).
    rates_hz : (float or None, float or None)
        Sampled-controller rates (current, position) [Hz], or None for continuous.
    chunk_size : int
        Runs simulated together.
    progress : callable, optional
        ``progress(done, total)`` after each run's figures.

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
    for start in range(0, n, chunk_size):
        stop = min(start + chunk_size, n)
        chunk = _subset(params, start, stop)
        result = simulate_batch(chunk, Step(amplitude_rad), current_rate_hz=current_rate,
                                position_rate_hz=position_rate)
        for index in range(stop - start):
            run = start + index
            horizon = _own_horizon(result.t, result.delta[index], amplitude_rad,
                                   result.t_end_s)
            keep = result.t <= horizon + 0.5 * result.dt_s
            t = result.t[keep]
            figures = step_figures(
                t, result.delta[index, keep], amplitude_rad, current=result.i[index, keep],
                voltage=result.V[index, keep],
                current_limited=result.current_limited[index, keep],
                voltage_limited=result.voltage_limited[index, keep],
            )
            for key, value in dataclasses.asdict(figures).items():
                name = f"step.{key}"
                if name in out:
                    out[name][run] = math.nan if value is None else float(value)
            if fit:
                model = fit_second_order(t, result.delta[index, keep], amplitude_rad)
                for key in FIT_FIGURES:
                    out[key][run] = getattr(model, key.split(".", 1)[1])
            done += 1
            if progress:
                progress(done, n)
    return out


def _subset(params, start, stop):
    names = [field.name for field in dataclasses.fields(params)]
    return dataclasses.replace(params, **{k: getattr(params, k)[start:stop] for k in names})
