"""Frequency grids, and the continuous phase of a response along one.

Crossings are located on such a grid by sign changes and then refined
(:mod:`cas_freq.analysis.roots`), never read off the grid.
"""

import math

import numpy as np

#: Default analysed range [rad/s]: below the slowest mechanical pole (mu_v/J ~ 2.4 rad/s) and
#: far above the fastest loop dynamics.
DEFAULT_RANGE_RAD_S = (1e-2, 1e6)

#: Default log density of the grid [points per decade].
DEFAULT_POINTS_PER_DECADE = 200


def frequency_grid(w_min, w_max, points_per_decade=DEFAULT_POINTS_PER_DECADE, total_delay=0.0):
    """Log-spaced grid, densified where a delay turns the phase faster than the log spacing.

    A delay ``tau`` turns the phase by ``omega * tau``; the grid keeps linear steps below
    ``pi / (8 tau)`` so that no phase crossing (one every ``2 pi / tau``) is stepped over.

    Parameters
    ----------
    w_min, w_max : float
        Range [rad/s], 0 < w_min < w_max.
    points_per_decade : int
        Log density [1/decade].
    total_delay : float
        Largest delay the phase sees [s].

    Returns
    -------
    numpy.ndarray
        Sorted, unique frequencies [rad/s].
    """
    if not (0 < w_min < w_max) or not math.isfinite(w_max):
        raise ValueError(f"frequency range: need 0 < w_min < w_max, got {w_min!r}, {w_max!r}")
    decades = math.log10(w_max / w_min)
    count = max(int(decades * points_per_decade), 2) + 1
    grid = np.logspace(math.log10(w_min), math.log10(w_max), count)
    if total_delay > 0:
        max_step = math.pi / (8.0 * total_delay)
        dense_from = max(w_min, max_step / (10 ** (1 / points_per_decade) - 1))
        if dense_from < w_max:
            count = int(math.ceil((w_max - dense_from) / max_step)) + 1
            grid = np.union1d(grid, np.linspace(dense_from, w_max, count))
    return grid


def continuous_phase(response, omega):
    """Phase [rad] of a response along a grid, unwrapped and on the right branch.

    The branch is set at the lowest frequency by the low-frequency asymptote: a response that
    falls as omega^-k there (k integrators) starts near -k*90°. So a type-2 loop whose phase
    dips just below -180° starts at -180.x°, not at +179.x°, and a phase past a whole turn of
    delay reads -388°, not -28°.

    Parameters
    ----------
    response : numpy.ndarray
        Complex response on ``omega``.
    omega : numpy.ndarray
        Sorted grid [rad/s], fine enough for ``numpy.unwrap`` (see :func:`frequency_grid`).
    """
    phase = np.unwrap(np.angle(response))
    slope = math.log(abs(response[1]) / abs(response[0])) / math.log(omega[1] / omega[0])
    integrators = round(-slope)
    target = -integrators * math.pi / 2
    return phase + 2 * math.pi * round((target - phase[0]) / (2 * math.pi))
