"""Which figures of a study's grid point are shown: the rule of the load envelope and the sweep.

At a grid point where the closed loop is not stable, the figures of the closed loop's own
response (:data:`RUN_FIGURES`: the linear closed loop's, the nonlinear step's and its fit's) are
no figures of the loop (verify never passes them): the step there is a run the limits hold in a
limit cycle or let diverge, whose figures hang on the last bits of the arithmetic (the fit's RMS
residual of the shipped ``loaded`` variant at -20 N*m/rad moved by 3e-4 under another BLAS
kernel), so they are not shown, stored or plotted. Where the loop is stable but the step
diverged (the limits let it run away), the step's and the fit's figures are not shown.
"""

import numpy as np

#: Figures of the closed loop's own response (prefixes).
RUN_FIGURES = ("closed_loop.", "step.", "fit.")

#: :func:`run_figures_not_shown`'s reason at a stable point whose step diverged.
DIVERGED = "step diverged (beyond 1e6 times the step): no step figures or fit"


def run_figures_not_shown(figures, stability):
    """Why each grid point's :data:`RUN_FIGURES` are not shown: None where they are.

    Parameters
    ----------
    figures : dict of str to numpy.ndarray
        Figure -> value per grid point; a diverged step has a NaN ``step.max_current_a``
        (:func:`~cas_freq.simulation.step_figures.diverged`).
    stability : sequence of str
        Stability verdict of the linear closed loop per grid point.

    Returns
    -------
    list of str or None
        Per grid point, e.g. ``"closed loop unstable"``.
    """
    current = figures.get("step.max_current_a")
    diverged = np.zeros(len(stability), dtype=bool) if current is None else np.isnan(current)
    return [f"closed loop {v}" if str(v) != "stable" else DIVERGED if gone else None
            for v, gone in zip(stability, diverged, strict=True)]


def shown_run_figure(values, key, reasons):
    """``values`` of figure ``key`` per grid point, NaN where :func:`run_figures_not_shown`
    gave a reason (the closed loop's own figures stay at a stable point whose step diverged).

    Returns
    -------
    numpy.ndarray
        A copy [the figure's unit].
    """
    values = np.array(values, dtype=float)
    if key.startswith(RUN_FIGURES):
        loop = key.startswith("closed_loop.")
        values[[reason is not None and not (loop and reason == DIVERGED)
                for reason in reasons]] = np.nan
    return values
