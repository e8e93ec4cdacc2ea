r"""The normal equations of the second-order step fit, compiled with numba.

:func:`normal_equations_of` gives, for each of k runs, the sum of squares
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
5.1 ms on a 2-core machine; 0.74 ms for the shipped config's overdamped steps since the
negligible fast decay is left out, :data:`FAST_NEGLIGIBLE`). Each run is computed alone, so its
result does not depend on the other runs of the batch.

The iteration is compiled too (:func:`lm_trials`, :func:`lm_update`, :func:`refine`): the numpy
iteration's operations run by run, which give its estimates to the last bit
(``tests/test_second_order_compiled.py``).
"""

import math

import numpy as np
from numba import types

from cas_freq.core.formulas import _FTOL, _LOWER, _MOVE, C_SERIES, D_SERIES, S_SERIES
from cas_freq.core.jit import array_type, cached_jit

try:  # numba's own helper for LAPACK's dgesv (what its np.linalg.solve calls): not public API
    from numba.np.linalg import _LAPACK, F_INT_nptype

    #: LAPACK's dgesv for doubles, or None where this numba has no such helper.
    _GESV = _LAPACK().numba_xgesv(types.float64)
except (ImportError, AttributeError):  # pragma: no cover (another numba)
    _GESV = F_INT_nptype = None
_DOUBLE = ord("d")

# The kernels' argument types (one signature each, arrays of any layout: cached_jit): read-only
# (R) and written (W) float arrays of 1, 2 and 3 dimensions, index and flag arrays.
_R1, _R2, _R3 = (array_type("float64", ndim) for ndim in (1, 2, 3))
_W1, _W2, _W3 = (array_type("float64", ndim, written=True) for ndim in (1, 2, 3))
_INDEX, _FLAGS = array_type("int64", 1), array_type("bool_", 1)
_F, _I = types.float64, types.int64

#: Exponent gap beyond which the fast decay of the overdamped step is below 2^-54 of the slow
#: one (e^-40 = 4e-18 < 2^-54 = 5.6e-17, with room for the rounding of the exponents and of
#: exp): adding or subtracting it rounds to the slow one, so it is left out, exactly.
FAST_NEGLIGIBLE = 40.0


@cached_jit((_F, _R1))
def _series(x, coefficients):
    """Horner evaluation of sum coefficients[k] (-x)^k (at x = 0 exactly coefficients[0],
    as Horner's steps give it: every product is then a zero: all of a run at zeta = 1, as
    the fit's starting guess often is, and the samples before the delay)."""
    if x == 0.0:
        return coefficients[0]
    total = coefficients[-1]
    for k in range(coefficients.size - 2, -1, -1):
        total = total * -x + coefficients[k]
    return total


@cached_jit((_R2, _R2, _I, _R1, _R1, _W2, _W1))
def _run_sums(t, unit, row, p, scale, normal, gradient):
    """Sum of squares of one run (returned), its J^T J into ``normal`` (3, 3) and J^T r into
    ``gradient`` (3), at the scaled variables ``p`` (3) with scales ``scale`` (3), on the data
    of row ``row`` of ``t`` and ``unit`` (see :func:`normal_equations_of`)."""
    m = t.shape[1]
    wn = p[0] * scale[0]
    zeta = p[1]
    td = p[2] * scale[2]
    q = 1.0 - zeta * zeta
    root = math.sqrt(abs(q))
    d_wn = scale[0]
    d_td = -(wn * scale[2])
    # overdamped: the exponents of e^{-(beta + zeta) s} and e^{(beta - zeta) s} differ by
    # `apart` s; from FAST_NEGLIGIBLE on, the first is below 2^-54 of the second and cannot
    # change their sum or difference in any bit, and is not computed
    sum_rate = root + zeta
    apart = sum_rate - 1.0 / sum_rate
    rr = a00 = a01 = a02 = a11 = a12 = a22 = g0 = g1 = g2 = 0.0
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
            fast = math.exp(-(root + zeta) * s) if apart * s < FAST_NEGLIGIBLE else 0.0
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
    normal[0, 0] = a00
    normal[0, 1] = normal[1, 0] = a01
    normal[0, 2] = normal[2, 0] = a02
    normal[1, 1] = a11
    normal[1, 2] = normal[2, 1] = a12
    normal[2, 2] = a22
    gradient[0] = g0
    gradient[1] = g1
    gradient[2] = g2
    return rr


@cached_jit((_R2, _R2, _INDEX, _R2, _R2), nogil=True)
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
    k = rows.shape[0]
    cost = np.zeros(k)
    normal = np.zeros((k, 3, 3))
    gradient = np.zeros((k, 3))
    for run in range(k):
        cost[run] = _run_sums(t, unit, rows[run], p[run], scale[run], normal[run], gradient[run])
    return cost, normal, gradient


# --- The iteration of the fit, compiled ---------------------------------------------------------
#
# The Levenberg-Marquardt iteration and the Newton refinement of
# cas_freq.simulation.second_order (_levenberg_marquardt, _refine), run by run: each run's
# operations are those of the numpy iteration, in the same order and with numpy's rounding
# (np.clip's and np.maximum's NaN rules, einsum's and np.linalg.norm's order of summation,
# LAPACK's dgesv and dsyevd for np.linalg.solve and eigvalsh), so the fits are the numpy
# iteration's to the last bit. The one operation left to numpy is the cube of Nielsen's
# damping update: numpy's power uses a vectorised pow whose last bit differs from libm's in
# ~3 % of cases (second_order._levenberg_marquardt_compiled computes it between lm_trials and
# lm_update).


@cached_jit((_F, _F))
def _maximum(a, b):
    """np.maximum of two floats (NaN if either is NaN)."""
    if a != a or b != b:
        return a + b
    return a if a >= b else b


@cached_jit((_F, _F))
def _minimum(a, b):
    """np.minimum of two floats (NaN if either is NaN)."""
    if a != a or b != b:
        return a + b
    return a if a <= b else b


@cached_jit((_F, _F, _F))
def _clip(x, low, high):
    """np.clip of a float between array bounds: min(max(x, low), high), NaN kept."""
    if x != x:
        return x
    x = x if x > low else low
    return x if x < high else high


def _solve_by_helper(system, rhs, out):
    """np.linalg.solve of a 3 x 3 system into ``out`` (3,): LAPACK's dgesv, as numpy and numba
    call it (the same solution to the bit), without numba's np.linalg.solve, which takes ~3 s
    to compile. Returns dgesv's info: 0, or > 0 where the system is singular."""
    a = np.empty((3, 3))  # column-major copy: a[j, i] = system[i, j]
    for i in range(3):
        for j in range(3):
            a[j, i] = system[i, j]
        out[i] = rhs[i]
    pivots = np.empty(3, dtype=F_INT_nptype)
    return _GESV(_DOUBLE, 3, 1, a.ctypes, 3, pivots.ctypes, out.ctypes, 3)


def _solve_by_numpy(system, rhs, out):
    """:func:`_solve_by_helper` through numba's public np.linalg.solve (the same dgesv; slower
    to compile): for a numba without the helper."""
    try:
        out[:] = np.linalg.solve(system, rhs)
    except Exception:  # noqa: BLE001 (numba: LinAlgError of a singular system)
        return 1
    return 0


#: ``_solve(system, rhs, out)``: ``out`` C-contiguous (dgesv writes its memory).
_solve = cached_jit((_R2, _R1, types.float64[::1]), nogil=True)(
    _solve_by_numpy if _GESV is None else _solve_by_helper)


@cached_jit((_R1,))
def _norm(v):
    """np.linalg.norm of a 3-vector (its sum of squares in numpy's order)."""
    return math.sqrt((v[0] * v[0] + v[1] * v[1]) + v[2] * v[2])


@cached_jit((_R2, _R2, _INDEX, _R2, _R1, _R3, _R2, _R1, _R2, _R2, _W2, _W2, _W3, _W2),
            nogil=True)
def lm_trials(t, unit, active, p, cost, normal, gradient, damping, scale, upper,
              trial, step, normal_new, gradient_new):
    """One Levenberg-Marquardt trial step of each active run (the first half of an iteration
    of :func:`~cas_freq.simulation.second_order._levenberg_marquardt`).

    Parameters
    ----------
    t, unit : numpy.ndarray
        Padded times [s] and unit responses, shape (k, m).
    active : numpy.ndarray
        The runs still iterating (int, shape (n,)).
    p, cost, normal, gradient : numpy.ndarray
        Each run's scaled variables (k, 3), sum of squares (k,), J^T J (k, 3, 3) and J^T r
        (k, 3) there.
    damping : numpy.ndarray
        Each run's λ (k,).
    scale, upper : numpy.ndarray
        Scales and upper bounds of the scaled variables (k, 3); the lower bounds are
        ``cas_freq.core.formulas._LOWER``.
    trial, step, normal_new, gradient_new : numpy.ndarray
        Written, row a for active run a: the trial point, the step to it (n, 3), J^T J
        (n, 3, 3) and J^T r (n, 3) there.

    Returns
    -------
    cost_new, ratio : numpy.ndarray
        Sum of squares at the trial point and the ratio of its actual to predicted decrease
        (-1 where none is predicted), shape (n,).
    accept, stuck, flat : numpy.ndarray
        Bool (n,): the trial lowers the sum of squares; the damped system was not finite or
        singular (a zero step); no free variable has a nonzero gradient.
    """
    n = active.size
    cost_new, ratio = np.empty(n), np.empty(n)
    accept, stuck, flat = (np.zeros(n, dtype=np.bool_), np.zeros(n, dtype=np.bool_),
                           np.zeros(n, dtype=np.bool_))
    held = np.zeros(3, dtype=np.bool_)
    diag, rhs, delta = np.empty(3), np.empty(3), np.empty(3)
    system = np.empty((3, 3))
    for a in range(n):
        r = active[a]
        A, g, x, hi = normal[r], gradient[r], p[r], upper[r]
        flat[a] = True
        for i in range(3):
            held[i] = (x[i] <= _LOWER[i] and g[i] > 0) or (x[i] >= hi[i] and g[i] < 0)
            flat[a] = flat[a] and not (not held[i] and g[i] != 0)
            diag[i] = A[i, i]
        floor = 1e-30 * _maximum(_maximum(diag[0], diag[1]), diag[2]) + 1e-300
        finite = True
        for i in range(3):
            diag[i] = _maximum(diag[i], floor)
        for i in range(3):
            for j in range(3):
                e = 1.0 if i == j else 0.0
                value = A[i, j] + damping[r] * (diag[i] * e)
                both_free = 1.0 if not held[i] and not held[j] else 0.0
                value = value * both_free + (1.0 if held[i] else 0.0) * e
                system[i, j] = value
                finite = finite and math.isfinite(value)
            rhs[i] = 0.0 if held[i] else -g[i]
            finite = finite and math.isfinite(rhs[i])
        stuck[a] = not finite
        if finite:
            stuck[a] = _solve(system, rhs, delta) != 0  # singular
            for i in range(3):
                stuck[a] = stuck[a] or not math.isfinite(delta[i])
        if stuck[a]:
            delta[0] = delta[1] = delta[2] = 0.0
        for i in range(3):
            trial[a, i] = _clip(x[i] + delta[i], _LOWER[i], hi[i])
            step[a, i] = trial[a, i] - x[i]
        cost_new[a] = _run_sums(t, unit, r, trial[a], scale[r], normal_new[a], gradient_new[a])
        # einsum("ki,ki->k") and einsum("ki,kij,kj->k") in numpy's order of summation
        dot = 0.0 + ((g[0] * step[a, 0] + g[2] * step[a, 2]) + g[1] * step[a, 1])
        quad = 0.0
        for i in range(3):
            for j in range(3):
                quad += (step[a, i] * A[i, j]) * step[a, j]
        predicted = -(2.0 * dot + quad)
        accept[a] = cost_new[a] < cost[r]
        ratio[a] = (cost[r] - cost_new[a]) / predicted if predicted > 0 else -1.0
    return cost_new, ratio, accept, stuck, flat


@cached_jit((_INDEX, _W2, _W1, _W3, _W2, _W1, _W1, array_type("bool_", 1, written=True), _R2,
             _R2, _R1, _R3, _R2, _R1, _R1, _FLAGS, _FLAGS, _FLAGS), nogil=True)
def lm_update(active, p, cost, normal, gradient, damping, growth, converged, trial, step,
              cost_new, normal_new, gradient_new, ratio, cube, accept, stuck, flat):
    """The second half of an iteration: Nielsen's update of λ, the convergence tests and the
    accepted steps (arguments as in :func:`lm_trials`, with ``growth`` (k,), ``converged``
    (k,) and ``cube`` = (2 ratio - 1)^3 (n,)); updates the per-run arrays in place and
    returns the runs still iterating."""
    n = active.size
    going = np.empty(n, dtype=active.dtype)  # (loops, not fancy indexing: 3 s less to compile)
    kept = 0
    for a in range(n):
        r = active[a]
        good = accept[a] and ratio[a] > 0
        if good:
            lam = damping[r] * _maximum(1.0 / 3.0, 1.0 - cube[a])
        else:
            lam = damping[r] * growth[r]
        growth[r] = 2.0 if good else growth[r] * 2.0
        damping[r] = _minimum(lam, 1e300)
        done = _norm(step[a]) <= 1e-14 * (1e-14 + _norm(p[r]))
        done = done or (accept[a] and cost[r] - cost_new[a] <= _FTOL * cost[r])
        done = done or flat[a] or damping[r] >= 1e300
        if accept[a] and not stuck[a]:
            cost[r] = cost_new[a]
            for i in range(3):
                p[r, i] = trial[a, i]
                gradient[r, i] = gradient_new[a, i]
                for j in range(3):
                    normal[r, i, j] = normal_new[a, i, j]
        if done and not stuck[a]:
            converged[r] = True
        if not (done or stuck[a]):
            going[kept] = r
            kept += 1
    return going[:kept]


@cached_jit((_R2, _R2, _R2, _R2, _R2, _R1, _R3, _R2, _I), nogil=True)
def refine(t, unit, p, scale, upper, cost, normal, gradient, iterations):
    """:func:`~cas_freq.simulation.second_order._refine`, run by run, from the converged fits.

    Parameters
    ----------
    t, unit : numpy.ndarray
        Padded times [s] and unit responses, shape (k, m).
    p, scale, upper : numpy.ndarray
        Scaled variables of the converged fits, their scales and upper bounds (k, 3).
    cost, normal, gradient : numpy.ndarray
        Sum of squares (k,), J^T J (k, 3, 3) and J^T r (k, 3) at ``p`` (the iteration's).
    iterations : int
        Newton steps.

    Returns
    -------
    p, cost, normal : numpy.ndarray
        The refined scaled variables (k, 3), and the sum of squares and J^T J there.
    """
    k = p.shape[0]
    out, out_cost, out_normal = p.copy(), cost.copy(), normal.copy()
    g, h, probe, rhs, ceiling, q, delta = (np.empty(3), np.empty(3), np.empty(3), np.empty(3),
                                           np.empty(3), np.empty(3), np.empty(3))
    free = np.zeros(3, dtype=np.bool_)
    g3, raw, hessian = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    system, scratch, normal_q = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
    for r in range(k):
        x, hi = p[r], upper[r]
        for i in range(3):  # (element loops here: slices take seconds longer to compile)
            g[i] = gradient[r, i]
        for i in range(3):
            h[i] = 1e-6 * _maximum(abs(x[i]), 1.0)
        # Hessian by forward differences: column j from the gradient at x + h_j e_j
        for j in range(3):
            for i in range(3):
                probe[i] = x[i] + (1.0 if i == j else 0.0) * h[i]
            _run_sums(t, unit, r, probe, scale[r], scratch, g3[j])
        for i in range(3):
            for j in range(3):
                raw[i, j] = (g3[j, i] - g[i]) / h[j]
        for i in range(3):
            for j in range(3):
                hessian[i, j] = 0.5 * (raw[i, j] + raw[j, i])
            if math.isfinite(hi[i]):
                ceiling[i] = hi[i] - 1e-10 * _maximum(abs(hi[i]), 1.0)
            else:
                ceiling[i] = math.inf
        usable = True
        for i in range(3):
            q[i] = x[i]
        after = cost[r]
        for _ in range(iterations):
            for i in range(3):
                at_lower = q[i] <= _LOWER[i] + 1e-10 and g[i] > 0
                at_upper = q[i] >= ceiling[i] and g[i] < 0
                if at_lower:
                    q[i] = _LOWER[i]
                elif at_upper:
                    q[i] = hi[i]
                free[i] = not (at_lower or at_upper)
            for i in range(3):
                for j in range(3):
                    e = 1.0 if i == j else 0.0
                    value = hessian[i, j] if free[i] and free[j] else 0.0
                    system[i, j] = value + (0.0 if free[i] else 1.0) * e
                    usable = usable and math.isfinite(system[i, j])
                rhs[i] = -(g[i] if free[i] else 0.0)
            if usable:
                usable = np.linalg.eigvalsh(system)[0] > 0
            if usable:
                if _solve(system, rhs, delta) != 0:  # (positive definite: not singular)
                    delta[0] = delta[1] = delta[2] = math.nan  # (numpy would raise) p kept
                for i in range(3):
                    q[i] = _clip(q[i] + delta[i], _LOWER[i], hi[i])
            after = _run_sums(t, unit, r, q, scale[r], normal_q, g)
        for i in range(3):
            delta[i] = q[i] - x[i]
        moved = _norm(delta) <= _MOVE * _norm(x)
        if usable and moved and after <= cost[r] * (1.0 + 1e-12):
            out_cost[r] = after
            for i in range(3):
                out[r, i] = q[i]
                for j in range(3):
                    out_normal[r, i, j] = normal_q[i, j]
    return out, out_cost, out_normal
