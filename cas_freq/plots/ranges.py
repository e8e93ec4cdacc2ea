"""Axis ranges and legend layouts of the overlay figures, chosen from the region that matters
(no matplotlib: plain numbers in, limits out).

An overlay of many variants is unreadable when one variant decides an axis: the exact delays
turn the phase of L_p without bound (−2880° at the top of a wide range), and a slow variant's
step stretches the time axis of every other. :func:`phase_window` keeps the phase the curves take
up to a little past the highest gain crossover (where |L| is near 1 and the margins are read);
:func:`time_window` keeps the settling of most variants.
"""

import math

import numpy as np

#: How far past the highest gain crossover the phase axis follows the curves [factor].
PAST_CROSSOVER = 3.0
#: Tick spacings of a phase axis [deg], the first that gives at most MAX_PHASE_TICKS ticks.
PHASE_STEPS_DEG = (45.0, 90.0, 180.0, 360.0)
MAX_PHASE_TICKS = 9
#: The time axis of a step overlay: this many times the median settling time.
SETTLING_FACTOR = 2.5
#: Most entries in one legend column.
LEGEND_ROWS = 6
#: Legend type size of the overlays [pt] (the report's smallest readable).
LEGEND_FONT_PT = 8.0


def phase_window(curves, crossovers_rad_s, past=PAST_CROSSOVER):
    """Phase-axis limits and tick spacing [deg] for overlaid loop phases.

    Parameters
    ----------
    curves : sequence of (numpy.ndarray, numpy.ndarray)
        Each curve's frequencies [rad/s] and continuous phase [deg].
    crossovers_rad_s : sequence of float
        The gain crossovers of every curve [rad/s] (|L| = 1).
    past : float
        The curves are followed up to ``past`` × the highest crossover.

    Returns
    -------
    (float, float, float)
        Bottom, top and tick spacing [deg]: the range the curves take below that frequency
        (and −180°), widened to whole multiples of 45°, the spacing from
        :data:`PHASE_STEPS_DEG`.
    """
    finite = [w for w in crossovers_rad_s if w is not None and math.isfinite(w) and w > 0]
    top = past * max(finite) if finite else math.inf
    values = [-180.0]
    for omega, phase in curves:
        omega, phase = np.asarray(omega, dtype=float), np.asarray(phase, dtype=float)
        shown = (omega <= top) & np.isfinite(phase)
        if shown.any():
            values += [float(phase[shown].min()), float(phase[shown].max())]
    low = 45.0 * math.floor((min(values) - 10.0) / 45.0)
    high = 45.0 * math.ceil((max(values) + 10.0) / 45.0)
    step = next((s for s in PHASE_STEPS_DEG if (high - low) / s <= MAX_PHASE_TICKS - 1),
                PHASE_STEPS_DEG[-1])
    return low, high, step


def time_window(settling_s, windows_s, factor=SETTLING_FACTOR):
    """Time-axis length [s] of a step overlay, and which steps run off it.

    Parameters
    ----------
    settling_s : sequence of float or None
        Each step's settling time [s] (None or not finite: it did not settle, its own window
        is used instead).
    windows_s : sequence of float
        Each step's own window [s] (what its own figure shows).
    factor : float
        The axis is ``factor`` × the median settling time, never longer than the longest window.

    Returns
    -------
    (float, list of int)
        The window [s] and the indices of the steps whose own window is longer.
    """
    settled = [s if s is not None and math.isfinite(s) else w
               for s, w in zip(settling_s, windows_s, strict=True)]
    window = min(max(windows_s), factor * float(np.median(settled)))
    return window, [k for k, w in enumerate(windows_s) if w > window * (1 + 1e-9)]


def legend_columns(entries, rows=LEGEND_ROWS):
    """Columns of a legend of ``entries`` entries: at most ``rows`` per column."""
    return max(1, math.ceil(entries / rows))
