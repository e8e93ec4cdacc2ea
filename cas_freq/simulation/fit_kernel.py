r"""The normal equations of the second-order step fit, compiled with numba.

:func:`normal_equations` gives, for each of k runs, the sum of squares
:math:`r^T r`, :math:`J^T J` (3 x 3) and :math:`J^T r` (3) of the residuals of the
second-order-plus-delay unit step at the scaled variables p, in one pass over the samples and
without the (k, 3, m) Jacobian. It is the scalar form of the numpy reference
:func:`~cas_freq.simulation.second_order._residuals_and_jacobian` followed by
:func:`~cas_freq.simulation.second_order._normal_equations` (the same closed forms, the same
power series where :math:`|(1 - \zeta^2) s^2| < 1`, each product in the same order), and
agrees with it to ~1e-15 relative (the sums are accumulated in another order, and libm's exp,
sin and cos may differ from numpy's in the last bit); ``tests/test_second_order_batch.py``
compares them. The Levenberg-Marquardt iteration and the Newton refinement of
:mod:`~cas_freq.simulation.second_order` need nothing else from the samples, and spend most of
their time here: 3-4 times less than in the numpy form (32 runs x 2,000 samples: 1.6 against
5.1 ms on a 2-core machine). Each run is computed alone, so its result does not depend on the
other runs of the batch.
"""

import math

import numpy as np

from cas_freq.jit import cached_jit
from cas_freq.simulation.second_order import C_SERIES, D_SERIES, S_SERIES


@cached_jit(inline="always")
def _series(x, coefficients):
    """Horner evaluation of sum coefficients[k] (-x)^k."""
    total = coefficients[-1]
    for k in range(coefficients.size - 2, -1, -1):
        total = total * -x + coefficients[k]
    return total


@cached_jit(nogil=True)
def normal_equations(t, unit, p, scale):
    """Sum of squares, J^T J and J^T r of the unit-step residuals of k runs
    (:func:`normal_equations_of` of every row of ``t`` and ``unit``)."""
    return normal_equations_of(t, unit, np.arange(t.shape[0]), p, scale)


@cached_jit(nogil=True)
def normal_equations_of(t, unit, rows, p, scale):
    """Sum of squares, J^T J and J^T r of the unit-step residuals of k runs, run i on the
    data of row ``rows[i]`` (no copy of the data of the runs still iterating).

    Parameters
    ----------
    t, unit : numpy.ndarray
        As in :func:`~cas_freq.simulation.second_order._residuals_and_jacobian`: times [s] and
        unit responses, shape (rows, m).
    rows : numpy.ndarray
        The data row of each run, shape (k,).
    p, scale : numpy.ndarray
        Scaled variables and their scales (k, 3).

    Returns
    -------
    cost : numpy.ndarray
        Sum of squared residuals (model - unit), shape (k,).
    normal : numpy.ndarray
        J^T J of the Jacobian in the scaled variables, shape (k, 3, 3).
    gradient : numpy.ndarray
        J^T r, shape (k, 3).
    """
    k, m = rows.shape[0], t.shape[1]
    cost = np.zeros(k)
    normal = np.zeros((k, 3, 3))
    gradient = np.zeros((k, 3))
    for run in range(k):
        wn = p[run, 0] * scale[run, 0]
        zeta = p[run, 1]
        td = p[run, 2] * scale[run, 2]
        q = 1.0 - zeta * zeta
        root = math.sqrt(abs(q))
        d_wn = scale[run, 0]
        d_td = -(wn * scale[run, 2])
        rr = a00 = a01 = a02 = a11 = a12 = a22 = g0 = g1 = g2 = 0.0
        row = rows[run]
        for j in range(m):
            tau = max(t[row, j] - td, 0.0)
            s = wn * tau
            x = q * s * s
            if abs(x) < 1.0:  # near s = 0 (all of a run at zeta = 1): the series
                decay = math.exp(-zeta * s)
                ec = decay * _series(x, C_SERIES)
                es = decay * s * _series(x, S_SERIES)
                ed = decay * s**3 * _series(x, D_SERIES)
            elif q > 0.0:  # underdamped
                decay = math.exp(-zeta * s)
                ws = root * s
                ec = decay * math.cos(ws)
                es = decay * math.sin(ws) / root
                ed = (s * ec - es) / q
            else:  # overdamped, without overflow for large s: e^{(beta - zeta) s} exactly
                slow = math.exp(s * (-1.0 / (root + zeta)))
                fast = math.exp(-(root + zeta) * s)
                ec = 0.5 * (slow + fast)
                es = (0.5 / root) * (slow - fast)
                ed = (s * ec - es) / q
            r = (1.0 - (ec + zeta * es)) - unit[row, j]
            j0 = es * tau * d_wn
            j1 = ed
            j2 = es * d_td
            rr += r * r
            a00 += j0 * j0
            a01 += j0 * j1
            a02 += j0 * j2
            a11 += j1 * j1
            a12 += j1 * j2
            a22 += j2 * j2
            g0 += j0 * r
            g1 += j1 * r
            g2 += j2 * r
        cost[run] = rr
        normal[run, 0, 0] = a00
        normal[run, 0, 1] = normal[run, 1, 0] = a01
        normal[run, 0, 2] = normal[run, 2, 0] = a02
        normal[run, 1, 1] = a11
        normal[run, 1, 2] = normal[run, 2, 1] = a12
        normal[run, 2, 2] = a22
        gradient[run, 0] = g0
        gradient[run, 1] = g1
        gradient[run, 2] = g2
    return cost, normal, gradient
