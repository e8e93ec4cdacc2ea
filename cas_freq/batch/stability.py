r"""Closed-loop stability of many variants: batched characteristic polynomials (Padé delays).

The single-variant verdict (:func:`cas_freq.analysis.stability.closed_loop_stability`) comes
from the poles of the Padé model of order n. The same poles are the roots of

.. math::
    Q_c(s) = D_{ci}(s)\,D(s\tau_c)\,P(s) + N_{ci}(s)\,D(-s\tau_c)\,(Js + \mu_v)

    Q(s) = D_{cp}(s)\,D(s\tau_p)\,s\,Q_c(s) + K_m N_{cp}(s)\,D(-s\tau_p)\,N_{ci}(s)\,D(-s\tau_c)

with :math:`P = (Ls + R)(Js + \mu_v) + K_e K_m`, :math:`C_i = N_{ci}/D_{ci}`,
:math:`C_p = N_{cp}/D_{cp}` (:mod:`cas_freq.model.transfer`) and the Padé approximant
:math:`e^{-x} \approx D(-x)/D(x)`. :math:`Q_c` decides the current loop alone, :math:`Q` the
whole actuator (either derivative placement: the feedback path is :math:`C_p` in both).
Exact common factors are cancelled as :mod:`cas_freq.analysis.stability` does: Ki = 0 drops a
controller's integrator, Kd = 0 the derivative filter, and with mu_v = 0 the current loop
alone is judged on :math:`C_i Y = J (K_p s + K_i) / P`.

The verdict is read from the Routh array of the scaled polynomial (no root finding, all runs
at once). Where the array is ambiguous (a first-column entry within :data:`ROUTH_TOLERANCE`
of zero, or a root near s = 0) the roots are computed (companion-matrix eigenvalues, stacked)
and judged by :func:`cas_freq.analysis.stability.pole_verdict` like the single path.
"""

import numpy as np

from cas_freq.model.delay import DEFAULT_PADE_ORDER, pade_denominator

#: A Routh first-column entry below this (relative to its row) counts as ambiguous.
ROUTH_TOLERANCE = 1e-8
#: A root |s| below this [rad/s] (estimated -a_N/a_(N-1)) sends the run to the eigenvalues.
NEAR_ZERO_RAD_S = 1e-4


def polymul(a, b):
    """Product of stacks of polynomials (rows, highest power first)."""
    out = np.zeros((a.shape[0], a.shape[1] + b.shape[1] - 1))
    for j in range(b.shape[1]):
        out[:, j : j + a.shape[1]] += a * b[:, j : j + 1]
    return out


def polyadd(a, b):
    """Sum of stacks of polynomials of possibly different degrees."""
    width = max(a.shape[1], b.shape[1])
    out = np.zeros((a.shape[0], width))
    out[:, width - a.shape[1] :] += a
    out[:, width - b.shape[1] :] += b
    return out


def _stack(*columns):
    return np.column_stack([np.broadcast_to(np.asarray(c, float), np.shape(columns[0]))
                            for c in columns])


def pade_polynomials(tau, order):
    """(D(s tau), D(-s tau)) as stacks of polynomials in s, for delays ``tau`` [s] (n,)."""
    d = pade_denominator(order)
    powers = np.arange(order, -1, -1)
    scale = tau[:, None] ** powers
    return d * scale, d * scale * (-1.0) ** powers


def characteristic_polynomials(p, order=DEFAULT_PADE_ORDER):
    """(Q_c, Q): current-loop and whole-loop characteristic polynomials of each run.

    Parameters
    ----------
    p : cas_freq.simulation.LoopParameters
        The runs.
    order : int
        Padé order of both delays.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Stacks of coefficients (highest power first); leading zeros where a delay or Tf is 0.
    """
    jm = _stack(p.J, p.mu_v)
    plant = polyadd(polymul(_stack(p.L, p.R), jm), (p.Ke * p.Km)[:, None])
    dc, nc = pade_polynomials(p.tau_c, order)
    dp, np_ = pade_polynomials(p.tau_p, order)
    zero = np.zeros(p.n_runs)
    one = np.ones(p.n_runs)
    s = _stack(one, zero)
    # C_i = n_ci / d_ci; Ki = 0 drops the integrator (exact cancellation, as the single path)
    integral = p.ci_Ki > 0
    n_ci = np.where(integral[:, None], _stack(p.ci_Kp, p.ci_Ki), _stack(zero, p.ci_Kp))
    d_ci = np.where(integral[:, None], s, _stack(zero, one))
    qc = polyadd(polymul(polymul(d_ci, dc), plant), polymul(polymul(n_ci, nc), jm))
    # C_p = n_cp / d_cp, without the integrator where Ki = 0 and the filter where Kd = 0
    kp, ki, kd, tf = p.cp_Kp, p.cp_Ki, p.cp_Kd, p.Tf
    has_i, has_d = (ki > 0)[:, None], (kd > 0)[:, None]
    n_cp = np.where(has_i, np.where(has_d, _stack(kp * tf + kd, kp + ki * tf, ki),
                                    _stack(zero, kp, ki)),
                    np.where(has_d, _stack(zero, kp * tf + kd, kp), _stack(zero, zero, kp)))
    d_cp = np.where(has_i, np.where(has_d, _stack(tf, one, zero), _stack(zero, one, zero)),
                    np.where(has_d, _stack(zero, tf, one), _stack(zero, zero, one)))
    q = polyadd(
        polymul(polymul(polymul(d_cp, dp), s), qc),
        polymul(polymul(polymul(n_cp, np_), n_ci), nc) * p.Km[:, None],
    )
    # the current loop alone: with mu_v = 0 (and an integrator) the pole at 0 of C_i cancels
    # the zero of Y at 0, C_i Y = J (Kp s + Ki) / P
    cancel = ((p.mu_v == 0) & integral)[:, None]
    reduced = polyadd(polymul(dc, plant), polymul(polymul(n_ci, nc), _stack(p.J)))
    qc = np.where(cancel, polyadd(np.zeros((p.n_runs, qc.shape[1])), reduced), qc)
    return qc, q


def _routh_unstable_count(a):
    """(number of sign changes of the Routh first column, ambiguous flag) per row of ``a``.

    ``a``: stack of polynomials of one degree, leading coefficients nonzero, scaled.
    """
    n_rows, width = a.shape
    degree = width - 1
    cols = degree // 2 + 1
    previous = np.zeros((n_rows, cols))
    current = np.zeros((n_rows, cols))
    even = a[:, 0::2]
    odd = a[:, 1::2]
    previous[:, : even.shape[1]] = even
    current[:, : odd.shape[1]] = odd
    first = [previous[:, 0], current[:, 0]]
    ambiguous = np.zeros(n_rows, dtype=bool)
    for _ in range(degree - 1):
        scale = np.max(np.abs(current), axis=1)
        scale = np.where(scale > 0, scale, 1.0)
        ambiguous |= np.abs(current[:, 0]) <= ROUTH_TOLERANCE * scale
        pivot = np.where(current[:, 0] != 0, current[:, 0], 1.0)
        nxt = np.zeros_like(current)
        nxt[:, :-1] = (
            current[:, :1] * previous[:, 1:] - previous[:, :1] * current[:, 1:]
        ) / pivot[:, None]
        norm = np.max(np.abs(nxt), axis=1)
        norm = np.where(norm > 0, norm, 1.0)
        previous, current = current / scale[:, None], nxt / norm[:, None]
        first.append(current[:, 0])
    column = np.column_stack(first)
    ambiguous |= np.any(column == 0, axis=1)
    signs = np.sign(column)
    return np.sum(signs[:, 1:] != signs[:, :-1], axis=1), ambiguous


def _scaled(a):
    """Coefficients of a(w0 x) / max, with w0 balancing the constant and leading terms."""
    degree = a.shape[1] - 1
    lead, const = np.abs(a[:, 0]), np.abs(a[:, -1])
    w0 = np.where(const > 0, (const / lead) ** (1.0 / max(degree, 1)), 1.0)
    powers = np.arange(degree, -1, -1)
    scaled = a * w0[:, None] ** powers
    scaled /= np.max(np.abs(scaled), axis=1, keepdims=True)
    return scaled, w0


def _eigen_verdicts(a):
    """Verdicts from the roots of each polynomial (companion eigenvalues)."""
    from cas_freq.analysis.stability import pole_verdict

    scaled, w0 = _scaled(a)
    degree = a.shape[1] - 1
    if degree == 0:
        return np.array(["stable"] * a.shape[0], dtype=object)
    companion = np.zeros((a.shape[0], degree, degree))
    companion[:, 0, :] = -scaled[:, 1:] / scaled[:, :1]
    companion[:, np.arange(1, degree), np.arange(degree - 1)] = 1.0
    roots = np.linalg.eigvals(companion) * w0[:, None]
    return np.array([pole_verdict(r) for r in roots], dtype=object)


def verdicts(polynomials):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` for each polynomial (row).

    Parameters
    ----------
    polynomials : numpy.ndarray
        Stack of characteristic polynomials, highest power first (leading zeros allowed).

    Returns
    -------
    numpy.ndarray of str (object)
    """
    n = polynomials.shape[0]
    out = np.empty(n, dtype=object)
    nonzero = polynomials != 0
    leading = np.argmax(nonzero, axis=1)
    for lead in np.unique(leading):
        rows = np.flatnonzero(leading == lead)
        a = polynomials[rows, lead:]
        if a.shape[1] == 1:
            out[rows] = "stable"
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            near_zero = np.abs(a[:, -1]) <= NEAR_ZERO_RAD_S * np.abs(a[:, -2])
        scaled, _ = _scaled(a)
        changes, ambiguous = _routh_unstable_count(scaled)
        ambiguous |= near_zero | ~np.all(np.isfinite(scaled), axis=1)
        out[rows] = np.where(changes > 0, "unstable", "stable")
        hard = np.flatnonzero(ambiguous)
        if hard.size:
            out[rows[hard]] = _eigen_verdicts(a[hard])
    return out


def batch_stability(p, order=DEFAULT_PADE_ORDER):
    """(whole-loop verdicts, current-loop verdicts) of every run, from Padé-model poles."""
    qc, q = characteristic_polynomials(p, order)
    return verdicts(q), verdicts(qc)
