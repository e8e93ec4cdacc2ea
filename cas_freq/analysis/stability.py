r"""Closed-loop stability of one or many variants, from the Padé model (numpy only).

The position closed loop contains the current closed loop, so its poles decide both. A pole
whose real part is within a relative 1e-9 of zero is called marginal: the loop neither grows nor
decays there, and no frequency-domain figure of it is trustworthy.

Verdicts (all variants at once). The poles of the Padé model of order n of loops 0..k closed
are the roots of :math:`E_k`, the recurrence of :mod:`cas_freq.model.structure` in polynomial
arithmetic (:func:`loop_polynomials`) with the Padé approximant
:math:`e^{-x} \approx D(-x)/D(x)`. For the report's drive:

.. math::
    Q_c(s) = s\,D(s\tau_c)\,(Z_e P_m + K_e K_m) + n_{ci}(s)\,D(-s\tau_c)\,P_m

    Q(s) = s (T_f s + 1)\,D(s\tau_p)\,s\,Q_c(s)
           + K_m\,n_{cp}(s)\,D(-s\tau_p)\,n_{ci}(s)\,D(-s\tau_c)

:math:`Q_c` decides the current loop alone, :math:`Q` the whole actuator (either derivative
placement: the feedback path is :math:`C_p` in both). The verdict is read from the Routh array
of the scaled polynomial (no root finding), with a running bound on each entry's rounding error
(from the coefficients' own, :func:`loop_polynomial_bounds`). Where the array is ambiguous (a
first-column entry not clear of zero by :data:`~cas_freq.analysis.routh.ROUTH_SAFETY` times its
bound, or a root near s = 0: :func:`~cas_freq.analysis.routh.verdicts`) the poles are computed
and judged by :func:`pole_verdict`.

Poles (:func:`closed_loop_poles`): the eigenvalues of the closed-loop state matrix that
:func:`cas_freq.model.state_space.closings` assembles from the declared structure: the plant
states (i, omega, theta) of :func:`cas_freq.model.parts.plant_matrices`, each controller in its
minimal form, the filters and the Padé cascades of
:func:`cas_freq.model.delay.pade_realization`. Eigenvalues of the block matrix are preferred to
polynomial roots: the polynomial mixes poles from ~10 rad/s to ~1e5 rad/s, so its coefficients
span tens of decades, while the block matrix holds the physical coefficients themselves and
LAPACK balances it. The current loop alone (:func:`current_loop_poles`) drops the modes the
current does not see.

Exact common factors are cancelled before realising, so no spurious pole appears: ``Ki = 0``
in a controller drops its integrator, ``Kd = 0`` drops the derivative filter (even with
``Tf`` set), and with ``mu_v = 0`` the current loop's integrator pole cancels the zero of Y at
s = 0 (the frictionless shaft drifts at constant speed with i = 0, a mode unobservable from i):
the current loop's poles leave that one out. The whole loop observes that mode through theta
and keeps every state.
"""

import dataclasses

import numpy as np

from cas_freq.analysis.routh import verdicts
from cas_freq.model import parts
from cas_freq.model.delay import DEFAULT_PADE_ORDER
from cas_freq.model.state_space import closings, run_groups
from cas_freq.model.structure import build
from cas_freq.model.table import Polynomials, table, walk

#: |Re p| <= MARGINAL_TOLERANCE * max(1, |p|) counts as on the imaginary axis.
MARGINAL_TOLERANCE = 1e-9


def loop_polynomials(p, order=DEFAULT_PADE_ORDER):
    """Characteristic polynomials of loops 0..k closed, for every k, of each run.

    The recurrence :math:`E_k = b_k f_k E_{k-1} + c_k` of :mod:`cas_freq.model.structure` in
    polynomial arithmetic, with each delay its Padé approximant :math:`D(-s\tau)/D(s\tau)`
    and each controller in its minimal form. An inner loop's polynomial (k below the top) is
    divided by its factors s: those are modes its loops do not see (the shaft's position,
    unless a hinge stiffness acts on it) or exact cancellations (the frictionless shaft's zero
    of Y at 0 against the current integrator), never closed-loop poles of those loops.

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters
        The runs.
    order : int
        Padé order of every delay.

    Returns
    -------
    dict of str to numpy.ndarray
        Loop name (innermost first) -> stack of coefficients (highest power first; leading
        zeros where a delay or Tf is 0): that loop closed with every loop inside it.
    """
    return {name: e for name, (e, _) in _loop_recurrence(p, order, magnitudes=False).items()}


def loop_polynomial_bounds(p, order=DEFAULT_PADE_ORDER):
    """:func:`loop_polynomials` with, beside each stack, the same recurrence in the absolute
    values of every coefficient: each coefficient of that magnitude polynomial bounds the sum
    of the absolute values of the terms its coefficient was summed from, so a coefficient's
    rounding error is at most a few unit roundoffs per operation times it (Higham, *Accuracy
    and Stability of Numerical Algorithms*, 2nd ed., section 5.1 and problem 3.7).

    Returns
    -------
    dict of str to (numpy.ndarray, numpy.ndarray)
        Loop name -> (coefficients, magnitudes), both deflated alike.
    """
    return _loop_recurrence(p, order, magnitudes=True)


def _loop_recurrence(p, order, magnitudes):
    n = p.n_runs
    rows = table(build(p), minimal=True)
    results = []
    for transform in (None, np.abs) if magnitudes else (None,):
        algebra = Polynomials(n, order, transform)
        results.append({name: np.column_stack(e)
                        for name, e in walk(rows, algebra).characteristic.items()})
    names = rows.names
    paired = {}
    for k, name in enumerate(names):
        e = results[0][name]
        m = results[1][name] if magnitudes else None
        if k < len(names) - 1:
            e, m = _without_roots_at_zero(e, m)
        paired[name] = (e, m)
    return paired


def characteristic_polynomials(p, order=DEFAULT_PADE_ORDER):
    """(Q_c, Q): current-loop and whole-loop characteristic polynomials of each run
    (the first and last of :func:`loop_polynomials`).

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters
        The runs.
    order : int
        Padé order of every delay.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Stacks of coefficients (highest power first); leading zeros where a delay or Tf is 0.
    """
    polynomials = list(loop_polynomials(p, order).values())
    return polynomials[0], polynomials[-1]


def _without_roots_at_zero(polynomials, magnitudes=None):
    """The polynomials with every factor s divided out (trailing zero coefficients), and
    ``magnitudes`` (if given) shifted alike."""
    out = polynomials.copy()
    bounds = None if magnitudes is None else magnitudes.copy()
    for _ in range(polynomials.shape[1] - 1):
        rows = (out[:, -1] == 0) & np.any(out != 0, axis=1)
        if not rows.any():
            break
        out = _deflated(out, rows)
        if bounds is not None:
            bounds = _deflated(bounds, rows)
    return out, bounds


def _deflated(polynomials, rows):
    """The polynomials with one factor s divided out in ``rows`` (their last coefficient 0)."""
    out = polynomials.copy()
    out[rows, 1:] = polynomials[rows, :-1]
    out[rows, 0] = 0.0
    return out


def loop_verdicts(p, order=DEFAULT_PADE_ORDER):
    """Verdicts of every loop closed with the loops inside it, for every run of ``p``.

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters
        The runs.
    order : int
        Padé order of every delay.

    Returns
    -------
    dict of str to numpy.ndarray
        Loop name (innermost first) -> ``"stable"``, ``"marginal"`` or ``"unstable"`` per run
        (object arrays); the last is the whole actuator's.
    """
    bounded = loop_polynomial_bounds(p, order)
    polynomials = {name: e for name, (e, _) in bounded.items()}
    names = list(polynomials)

    def fallback(name):
        if name == names[-1]:
            return lambda rows: [pole_verdict(poles) for poles in
                                 closed_loop_poles_of_runs(p.take(rows), order)]
        if name == names[0]:
            return lambda rows: [pole_verdict(current_loop_poles(p.run(r), order)) for r in rows]
        return lambda rows: [pole_verdict(poles) for poles in
                             _roots_of_rows(polynomials[name][rows])]

    return {name: verdicts(polynomial, fallback(name), bounded[name][1])
            for name, polynomial in polynomials.items()}


def stability_verdicts(p, order=DEFAULT_PADE_ORDER):
    """(whole-loop verdicts, current-loop verdicts) of every run of ``p`` (Padé order n).

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters
        The runs.
    order : int
        Padé order of every delay.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``"stable"``, ``"marginal"`` or ``"unstable"`` per run (object arrays).
    """
    every = list(loop_verdicts(p, order).values())
    return every[-1], every[0]


@dataclasses.dataclass(frozen=True)
class Stability:
    """Closed-loop stability verdict.

    Attributes
    ----------
    verdict : str
        ``"stable"``, ``"marginal"`` or ``"unstable"``.
    pade_order : int
        Padé order of the delays in the model whose poles were computed.
    current_loop_verdict : str
        The same verdict for the current loop T_i alone.
    poles : tuple of (float, float)
        Closed-loop poles of T as (real, imaginary) [rad/s], sorted by real part, largest first.
    """

    verdict: str
    pade_order: int
    current_loop_verdict: str
    poles: tuple

    @property
    def stable(self):
        """True only for a strictly stable closed loop."""
        return self.verdict == "stable"


def pole_verdict(poles):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` for continuous-time poles [rad/s]."""
    poles = np.asarray(poles, dtype=complex)
    if poles.size == 0:
        return "stable"
    tolerance = MARGINAL_TOLERANCE * np.maximum(1.0, np.abs(poles))
    if np.any(poles.real > tolerance):
        return "unstable"
    if np.any(np.abs(poles.real) <= tolerance):
        return "marginal"
    return "stable"


def closed_loop_stability(params, pade_order=DEFAULT_PADE_ORDER):
    """Stability of the current loop and of the whole actuator of one variant.

    The verdicts are those of :func:`stability_verdicts` (the same for every variant of a
    batch); the poles are listed too.

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order of the delays.

    Returns
    -------
    Stability
    """
    params = parts.one_variant(params)
    verdict, current = stability_verdicts(params, pade_order)
    poles = closed_loop_poles(params, pade_order)
    return Stability(
        verdict=str(verdict[0]),
        pade_order=pade_order,
        current_loop_verdict=str(current[0]),
        poles=tuple((float(p.real), float(p.imag)) for p in poles),
    )


def closed_loop_poles(params, pade_order):
    """Poles [rad/s] of T = theta/theta_cmd with Padé delays, sorted by real part, largest first.

    The eigenvalues of the closed-loop state matrix of
    :func:`cas_freq.model.state_space.closings`.

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order n >= 1 of every delay.

    Returns
    -------
    numpy.ndarray
        Complex poles [rad/s]; 2n + 6 of them for the report's drive unless a controller
        term is zero.
    """
    p = parts.one_variant(params)
    top = closings(p, pade_order)[build(p).names[-1]]
    return _sorted(np.linalg.eigvals(top.closed[0]))


def closed_loop_poles_of_runs(p, pade_order):
    """:func:`closed_loop_poles` of every run of ``p`` (unsorted), the state matrices built
    and their eigenvalues found a group of runs at a time
    (:func:`cas_freq.model.state_space.run_groups`): the same matrices, so the same
    eigenvalues, as run by run, without its cost in Python (about 3 ms a run for the cascade;
    a few microseconds here).

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters
        The runs.
    pade_order : int
        Padé order n >= 1 of every delay.

    Returns
    -------
    list of numpy.ndarray
        Complex poles [rad/s] of each run.
    """
    n = p.n_runs
    structure = build(p)
    if structure.loops[-1].reference is not None:  # the command's own path: run by run
        return [closed_loop_poles(p.run(r), pade_order) for r in range(n)]
    out = [None] * n
    for rows in run_groups(p):
        top = closings(p.take(rows), pade_order, n=rows.size)[structure.names[-1]]
        for r, poles in zip(rows, np.linalg.eigvals(top.closed[0]), strict=True):
            out[r] = poles
    return out


def _roots_of_rows(polynomials):
    """``np.roots`` of each row (leading zeros allowed), the companion matrices of rows with
    the same leading and trailing zeros stacked for one eigenvalue call (the matrices
    ``np.roots`` builds, so the same roots); rows that are equal (an inner loop that a sweep
    of an outer loop's gains leaves alone) are solved once."""
    distinct, inverse = np.unique(polynomials, axis=0, return_inverse=True)
    roots = _distinct_roots(distinct)
    return [roots[i] for i in inverse.reshape(-1)]


def _distinct_roots(polynomials):
    """:func:`_roots_of_rows` of rows without repeats."""
    nonzero = polynomials != 0
    width = polynomials.shape[1]
    first = np.argmax(nonzero, axis=1)
    last = width - 1 - np.argmax(nonzero[:, ::-1], axis=1)
    out = [None] * polynomials.shape[0]
    keys = np.column_stack([first, last])
    for key in np.unique(keys, axis=0):
        rows = np.flatnonzero(np.all(keys == key, axis=1))
        start, stop = int(key[0]), int(key[1])
        kept = polynomials[rows, start:stop + 1]
        size = kept.shape[1]
        if size > 1:
            companion = np.zeros((rows.size, size - 1, size - 1))
            companion[:, 1:, :-1] = np.eye(size - 2)
            companion[:, 0, :] = -kept[:, 1:] / kept[:, :1]
            roots = np.linalg.eigvals(companion)
        else:
            roots = np.zeros((rows.size, 0), dtype=complex)
        zeros = np.zeros((rows.size, width - 1 - stop), dtype=roots.dtype)
        for r, value in zip(rows, np.hstack((roots, zeros)), strict=True):
            out[r] = value
    return out


def current_loop_poles(params, pade_order):
    """Poles [rad/s] of T_i = i/i_cmd with a Padé current delay (exact cancellations removed).

    The current loop of :func:`cas_freq.model.state_space.closings` on the plant without the
    modes the current does not see (:func:`cas_freq.model.parts.current_plant_matrices`),
    without the poles that exact cancellations leave at s = 0 (:func:`_at_zero`).

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order n >= 1 of the current-loop delay.

    Returns
    -------
    numpy.ndarray
        Complex poles [rad/s], sorted by real part, largest first.
    """
    p = parts.one_variant(params)
    current = closings(p, pade_order, loops=1, reduced=True)[build(p).names[0]]
    poles = np.linalg.eigvals(current.closed[0])
    return _sorted(poles[~_at_zero(poles)])


def _at_zero(poles):
    r"""The poles within :data:`MARGINAL_TOLERANCE` of the largest one's magnitude of s = 0:
    exact cancellations, not poles of the current loop. With :math:`\mu_v = 0` (and no load
    friction, hinge stiffness or compliance) the current integrator's pole cancels the zero of
    :math:`Y = i/V` at 0: the shaft drifts at constant speed with i = 0, a mode unobservable
    from i, as the polynomials' factors s (:func:`loop_polynomials`)."""
    return np.abs(poles) <= MARGINAL_TOLERANCE * np.max(np.abs(poles), initial=0.0)


def _sorted(poles):
    return poles[np.argsort(-poles.real, kind="stable")]
