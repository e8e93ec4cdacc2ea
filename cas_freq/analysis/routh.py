"""Stability verdicts of many characteristic polynomials at once from their Routh arrays,
each entry carried with a running bound on its rounding error (docs/model.md, section 6).

Where a first-column sign is not clear of its bound, or a root lies near s = 0, the row is
handed to a fallback that judges it by its poles
(:func:`cas_freq.analysis.stability.loop_verdicts` supplies the eigenvalues).
"""

import numpy as np

#: Unit roundoff of float64 (half the machine epsilon).
UNIT_ROUNDOFF = np.finfo(float).eps / 2
#: A characteristic-polynomial coefficient's rounding error, in unit roundoffs of the sum of
#: the absolute values of its terms: products and sums of polynomials of degree up to ~40
#: nested a few times per loop (each coefficient at most ~2 x 40 x 4 roundings deep: 320; a
#: factor 3 beyond).
COEFFICIENT_ROUNDOFFS = 1000.0
#: A Routh first-column entry not farther from zero than this many times its running error
#: bound counts as ambiguous (the bound is first order: a factor for what it leaves out).
ROUTH_SAFETY = 10.0
#: A root |s| below this [rad/s] (estimated -a_N/a_(N-1)) sends the run to the eigenvalues.
NEAR_ZERO_RAD_S = 1e-4


def _routh_unstable_count(a, error):
    """(number of sign changes of the Routh first column, ambiguous flag) per row of ``a``.

    ``a``: stack of polynomials of one degree, leading coefficients nonzero, scaled;
    ``error``: a bound on each coefficient's absolute error. The bound is carried through
    every entry of the array to first order (a running error bound: the perturbation of each
    new entry by its operands' bounds, plus a unit roundoff for each of its operations), and a
    row is ambiguous where a first-column entry is not farther from zero than its bound times
    :data:`ROUTH_SAFETY`: its sign, and so the count, could be rounding's.
    """
    n_rows, width = a.shape
    degree = width - 1
    cols = degree // 2 + 1
    previous, current = np.zeros((2, n_rows, cols))
    previous_error, current_error = np.zeros((2, n_rows, cols))
    previous[:, : (degree + 2) // 2] = a[:, 0::2]
    current[:, : (degree + 1) // 2] = a[:, 1::2]
    previous_error[:, : (degree + 2) // 2] = error[:, 0::2]
    current_error[:, : (degree + 1) // 2] = error[:, 1::2]
    first, bound = [previous[:, 0], current[:, 0]], [previous_error[:, 0], current_error[:, 0]]
    for _ in range(degree - 1):
        pivot = current[:, :1]
        size = np.abs(np.where(pivot != 0, pivot, 1.0))
        ratio = previous[:, :1] * current[:, 1:] / np.where(pivot != 0, pivot, 1.0)
        nxt = np.zeros_like(current)
        nxt_error = np.zeros_like(current)
        # entry j: p_(j+1) - p_0 c_(j+1) / c_0, perturbed by each operand's bound
        nxt[:, :-1] = previous[:, 1:] - ratio
        nxt_error[:, :-1] = (
            previous_error[:, 1:]
            + (np.abs(current[:, 1:]) * previous_error[:, :1]
               + np.abs(previous[:, :1]) * current_error[:, 1:]
               + np.abs(ratio) * current_error[:, :1]) / size
            + 4 * UNIT_ROUNDOFF * (np.abs(previous[:, 1:]) + np.abs(ratio))
        )
        norm = np.max(np.abs(nxt), axis=1)
        norm = np.where(norm > 0, norm, 1.0)[:, None]
        previous, previous_error = current, current_error
        current, current_error = nxt / norm, nxt_error / norm + UNIT_ROUNDOFF * np.abs(nxt / norm)
        first.append(current[:, 0])
        bound.append(current_error[:, 0])
    column, bound = np.column_stack(first), np.column_stack(bound)
    ambiguous = np.any(np.abs(column) <= ROUTH_SAFETY * bound, axis=1)
    ambiguous |= np.any(column == 0, axis=1)
    signs = np.sign(column)
    return np.sum(signs[:, 1:] != signs[:, :-1], axis=1), ambiguous


def _scaled(a):
    """Coefficients of a(w0 x) / max, with w0 balancing the constant and leading terms, and
    the multipliers applied (per coefficient: w0^power / max)."""
    degree = a.shape[1] - 1
    lead, const = np.abs(a[:, 0]), np.abs(a[:, -1])
    w0 = np.where(const > 0, (const / lead) ** (1.0 / max(degree, 1)), 1.0)
    powers = np.arange(degree, -1, -1)
    multipliers = w0[:, None] ** powers
    scaled = a * multipliers
    multipliers /= np.max(np.abs(scaled), axis=1, keepdims=True)
    return a * multipliers, multipliers


def verdicts(polynomials, fallback, magnitudes=None):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` for each polynomial (row).

    Parameters
    ----------
    polynomials : numpy.ndarray
        Stack of characteristic polynomials, highest power first (leading zeros allowed).
    fallback : callable
        ``fallback(rows) -> verdicts`` from the poles, for rows whose Routh array is ambiguous.
    magnitudes : numpy.ndarray, optional
        Per coefficient, the sum of the absolute values of the terms it was computed from
        (:func:`loop_polynomial_bounds`): each coefficient's error is taken as at most
        :data:`COEFFICIENT_ROUNDOFFS` unit roundoffs of it. Without it, of the coefficient.

    Returns
    -------
    numpy.ndarray of str (object)
    """
    n = polynomials.shape[0]
    out = np.empty(n, dtype=object)
    nonzero = polynomials != 0
    leading = np.argmax(nonzero, axis=1)
    if magnitudes is None:
        magnitudes = np.abs(polynomials)
    for lead in np.unique(leading):
        rows = np.flatnonzero(leading == lead)
        a = polynomials[rows, lead:]
        if a.shape[1] == 1:
            out[rows] = "stable"
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            near_zero = np.abs(a[:, -1]) <= NEAR_ZERO_RAD_S * np.abs(a[:, -2])
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            scaled, multipliers = _scaled(a)
            error = (COEFFICIENT_ROUNDOFFS * UNIT_ROUNDOFF * magnitudes[rows, lead:] * multipliers
                     + UNIT_ROUNDOFF * np.abs(scaled))
            changes, ambiguous = _routh_unstable_count(scaled, error)
        ambiguous |= near_zero | ~np.all(np.isfinite(scaled), axis=1)
        ambiguous |= ~np.all(np.isfinite(error), axis=1)
        out[rows] = np.where(changes > 0, "unstable", "stable")
        hard = np.flatnonzero(ambiguous)
        if hard.size:
            out[rows[hard]] = fallback(rows[hard])
    return out
