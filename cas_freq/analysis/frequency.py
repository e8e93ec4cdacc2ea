"""Frequency grids and the refinement of crossings found on them.

Crossings are located on a dense grid by sign changes and then refined by root finding
(Brent's method on log frequency), never read off the grid.
"""

import math

import numpy as np
from scipy import optimize

#: Default analysed range [rad/s]: below the slowest mechanical pole (mu_v/J ~ 2.4 rad/s) and
#: far above the fastest loop dynamics.
DEFAULT_RANGE_RAD_S = (1e-2, 1e6)

#: Default log density of the grid [points per decade].
DEFAULT_POINTS_PER_DECADE = 200

#: Refined frequencies are accurate to this relative tolerance.
RELATIVE_TOLERANCE = 1e-12


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


def refine_roots(func, omega, values=None):
    """Roots of a real function of frequency, bracketed by sign changes on a grid.

    Parameters
    ----------
    func : callable
        ``func(omega) -> float`` for scalar ``omega`` [rad/s] (also vectorised if ``values``
        is not given).
    omega : numpy.ndarray
        Sorted grid [rad/s].
    values : numpy.ndarray, optional
        ``func(omega)`` already evaluated.

    Returns
    -------
    numpy.ndarray
        Refined roots [rad/s], ascending. Exact zeros on the grid are returned as they are.
    """
    if values is None:
        values = func(omega)
    roots = [float(w) for w, v in zip(omega, values, strict=True) if v == 0]
    signs = np.sign(values)
    brackets = np.nonzero(signs[:-1] * signs[1:] < 0)[0]
    for k in brackets:
        roots.append(_bracketed_root(func, omega[k], omega[k + 1]))
    return np.sort(np.asarray(roots, dtype=float))


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


def _bracketed_root(func, w_low, w_high):
    """Root of ``func`` between two grid points whose grid values differ in sign."""
    lo, hi = math.log(w_low), math.log(w_high)
    f_lo, f_hi = func(math.exp(lo)), func(math.exp(hi))
    if f_lo == 0 or f_hi == 0 or f_lo * f_hi > 0:
        # The root sits on a grid point to within rounding (the scalar and vectorised
        # evaluations disagree on its sign): that grid point is the root.
        return float(w_low if abs(f_lo) <= abs(f_hi) else w_high)
    root = optimize.brentq(lambda x: func(math.exp(x)), lo, hi, xtol=RELATIVE_TOLERANCE)
    return math.exp(root)


def refine_maximum(func, omega, values):
    """Refine the largest grid value of ``func`` to a local maximum.

    Returns
    -------
    (float, float, bool)
        Frequency [rad/s], value there, and whether the maximum is interior (False when it sits
        on an end of the grid, i.e. the function still rises past the range).
    """
    k = int(np.argmax(values))
    if k == 0 or k == len(omega) - 1:
        return float(omega[k]), float(values[k]), False
    lo, hi = math.log(omega[k - 1]), math.log(omega[k + 1])
    result = optimize.minimize_scalar(
        lambda x: -func(math.exp(x)), bounds=(lo, hi), method="bounded",
        options={"xatol": RELATIVE_TOLERANCE},
    )
    w_best, v_best = math.exp(result.x), -result.fun
    if v_best < values[k]:  # the grid point itself was better
        return float(omega[k]), float(values[k]), True
    return float(w_best), float(v_best), True
