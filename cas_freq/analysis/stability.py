r"""Closed-loop stability of one or many variants, from the Padé model (numpy only).

The position closed loop contains the current closed loop, so its poles decide both. A pole
whose real part is within a relative 1e-9 of zero is called marginal: the loop neither grows nor
decays there, and no frequency-domain figure of it is trustworthy.

Verdicts (all variants at once). The poles of the Padé model of order n are the roots of

.. math::
    Q_c(s) = s\,D(s\tau_c)\,(Z_e P_m + K_e K_m) + n_{ci}(s)\,D(-s\tau_c)\,P_m

    Q(s) = s (T_f s + 1)\,D(s\tau_p)\,s\,Q_c(s)
           + K_m\,n_{cp}(s)\,D(-s\tau_p)\,n_{ci}(s)\,D(-s\tau_c)

with the parts of :mod:`cas_freq.model.parts` and the Padé approximant
:math:`e^{-x} \approx D(-x)/D(x)`. :math:`Q_c` decides the current loop alone, :math:`Q` the
whole actuator (either derivative placement: the feedback path is :math:`C_p` in both). The
verdict is read from the Routh array of the scaled polynomial (no root finding). Where the
array is ambiguous (a first-column entry within :data:`ROUTH_TOLERANCE` of zero, or a root near
s = 0) the poles are computed and judged by :func:`pole_verdict`.

Poles (:func:`closed_loop_poles`, :func:`current_loop_poles`): the eigenvalues of the
closed-loop state matrix, assembled from the same blocks as python-control's model
(:func:`cas_freq.model.systems.linear_model`): the plant states (i, omega, theta) of
:func:`cas_freq.model.parts.plant_matrices`, the PI integrator of C_i, the two Padé cascades of
:func:`cas_freq.model.delay.pade_realization` and the two states of C_p (integrator and
derivative filter). Eigenvalues of the block matrix are preferred to polynomial roots: the
polynomial mixes poles from ~10 rad/s to ~1e5 rad/s, so its coefficients span tens of decades,
while the block matrix holds the physical coefficients themselves and LAPACK balances it.

Exact common factors are cancelled before realising, so no spurious pole appears: ``Ki = 0``
in either controller drops its integrator, ``Kd = 0`` drops the derivative filter (even with
``Tf`` set), and with ``mu_v = 0`` the current loop's integrator pole cancels the zero of Y at
s = 0 (the frictionless shaft drifts at constant speed with i = 0, a mode unobservable from i):
the current-loop verdict then uses ``C_i Y = J (K_p s + K_i) / D``. The whole loop observes
that mode through theta and keeps every state.
"""

import dataclasses

import numpy as np

from cas_freq.model import parts
from cas_freq.model.delay import DEFAULT_PADE_ORDER, pade_denominator, pade_realization

#: |Re p| <= MARGINAL_TOLERANCE * max(1, |p|) counts as on the imaginary axis.
MARGINAL_TOLERANCE = 1e-9


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
    p : cas_freq.parameters.LoopParameters
        The runs.
    order : int
        Padé order of both delays.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Stacks of coefficients (highest power first); leading zeros where a delay or Tf is 0.
    """
    n = p.n_runs
    d, n_theta, _ = parts.mechanics(p)
    mech, n_th = parts.stacked(d, n), parts.stacked(n_theta, n)
    dc, nc = pade_polynomials(p.tau_c, order)
    dp, np_ = pade_polynomials(p.tau_p, order)
    zero = np.zeros(p.n_runs)
    one = np.ones(p.n_runs)
    s = _stack(one, zero)
    plant = polyadd(polymul(parts.stacked(parts.electrical(p), n), mech),
                    polymul(s, n_th) * parts.back_emf_coupling(p)[:, None])
    # C_i = n_ci / d_ci; Ki = 0 drops the integrator (exact cancellation)
    integral = p.ci_Ki > 0
    n_ci = np.where(integral[:, None], _stack(p.ci_Kp, p.ci_Ki), _stack(zero, p.ci_Kp))
    d_ci = np.where(integral[:, None], s, _stack(zero, one))
    qc = polyadd(polymul(polymul(d_ci, dc), plant), polymul(polymul(n_ci, nc), mech))
    # C_p = n_cp / d_cp, without the integrator where Ki = 0 and the filter where Kd = 0
    kp, ki, kd, tf = p.cp_Kp, p.cp_Ki, p.cp_Kd, p.Tf
    has_i, has_d = (ki > 0)[:, None], (kd > 0)[:, None]
    n_cp = np.where(has_i, np.where(has_d, _stack(kp * tf + kd, kp + ki * tf, ki),
                                    _stack(zero, kp, ki)),
                    np.where(has_d, _stack(zero, kp * tf + kd, kp), _stack(zero, zero, kp)))
    d_cp = np.where(has_i, np.where(has_d, _stack(tf, one, zero), _stack(zero, one, zero)),
                    np.where(has_d, _stack(zero, tf, one), _stack(zero, zero, one)))
    q = polyadd(
        polymul(polymul(d_cp, dp), qc),
        polymul(polymul(polymul(polymul(n_cp, np_), n_ci), nc), n_th) * p.Km[:, None],
    )
    # The current loop alone: where D(0) = 0 (no hinge stiffness) the shaft's position is not
    # seen from i, a factor s common to both terms; with mu_v = 0 as well (and an integrator)
    # the pole at 0 of C_i cancels the zero of Y at 0 (C_i Y = J (Kp s + Ki) / P, unloaded).
    qc = _deflated(qc, mech[:, -1] == 0)
    qc = _deflated(qc, (mech[:, -1] == 0) & (mech[:, -2] == 0) & integral)
    return qc, q


def _deflated(polynomials, rows):
    """The polynomials with one factor s divided out in ``rows`` (their last coefficient 0)."""
    out = polynomials.copy()
    out[rows, 1:] = polynomials[rows, :-1]
    out[rows, 0] = 0.0
    return out


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


def verdicts(polynomials, fallback):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` for each polynomial (row).

    Parameters
    ----------
    polynomials : numpy.ndarray
        Stack of characteristic polynomials, highest power first (leading zeros allowed).
    fallback : callable
        ``fallback(rows) -> verdicts`` from the poles, for rows whose Routh array is ambiguous.

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
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            changes, ambiguous = _routh_unstable_count(scaled)
        ambiguous |= near_zero | ~np.all(np.isfinite(scaled), axis=1)
        out[rows] = np.where(changes > 0, "unstable", "stable")
        hard = np.flatnonzero(ambiguous)
        if hard.size:
            out[rows[hard]] = fallback(rows[hard])
    return out


def stability_verdicts(p, order=DEFAULT_PADE_ORDER):
    """(whole-loop verdicts, current-loop verdicts) of every run of ``p`` (Padé order n).

    Parameters
    ----------
    p : cas_freq.parameters.LoopParameters
        The runs.
    order : int
        Padé order of both delays.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``"stable"``, ``"marginal"`` or ``"unstable"`` per run (object arrays).
    """
    qc, q = characteristic_polynomials(p, order)

    def whole(rows):
        return [pole_verdict(closed_loop_poles(p.run(r), order)) for r in rows]

    def current(rows):
        return [pole_verdict(current_loop_poles(p.run(r), order)) for r in rows]

    return verdicts(q, whole), verdicts(qc, current)


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
    params : cas_freq.parameters.LoopParameters or cas_freq.config.ActuatorConfig
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


def _scalars(p):
    """The one run of ``p`` with every parameter a Python float."""
    return {name: getattr(p, name)[0].item() for name in (
        "R", "L", "Km", "Ke", "J", "mu_v", "ci_Kp", "ci_Ki", "tau_c", "cp_Kp", "cp_Ki",
        "cp_Kd", "Tf", "tau_p", "ratio", "K_g", "c_g", "K_h", "J_L", "b_L", "eta")}


def closed_loop_poles(params, pade_order):
    """Poles [rad/s] of T = theta/theta_cmd with Padé delays, sorted by real part, largest first.

    Parameters
    ----------
    params : cas_freq.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order n >= 1 of both delays.

    Returns
    -------
    numpy.ndarray
        Complex poles [rad/s]; 2n + 6 of them unless a controller term is zero.
    """
    params = parts.one_variant(params)
    v = _scalars(params)
    # i_cmd -> (i, theta): PI, current delay, plant (states i, omega, theta[, omega_L, delta])
    states = parts.plant_matrices(params)[0].shape[1]
    output = np.zeros((2, states))
    output[0, 0] = output[1, 2] = 1.0
    plant = _plant(params, output, states=states)
    forward = _series(
        _series(_current_controller(v), pade_realization(v["tau_c"], pade_order)),
        plant,
    )
    inner = _close_loop(forward, feedback_row=0, output_row=1)
    # position controller -> position delay -> inner loop, closed on theta
    loop = _series(
        _series(_position_controller(v), pade_realization(v["tau_p"], pade_order)),
        inner,
    )
    return _sorted(np.linalg.eigvals(_close_loop(loop, 0, 0)[0]))


def current_loop_poles(params, pade_order):
    """Poles [rad/s] of T_i = i/i_cmd with a Padé current delay (exact cancellations removed).

    Parameters
    ----------
    params : cas_freq.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order n >= 1 of the current-loop delay.

    Returns
    -------
    numpy.ndarray
        Complex poles [rad/s], sorted by real part, largest first.
    """
    params = parts.one_variant(params)
    v = _scalars(params)
    delay = pade_realization(v["tau_c"], pade_order)
    rigid_free = v["K_g"] == 0 and v["K_h"] == 0  # the shaft's position is not seen from i
    if rigid_free and v["mu_v"] == 0 and v["b_L"] == 0 and v["ci_Ki"] > 0:
        # C_i Y = (Kp s + Ki) J_eff / D: with mu_eff = 0, J_eff omega' = Km i, so i = (J_eff/Km)
        # s omega and the plant (i, omega) read out as Kp i + (J_eff Ki/Km) omega has exactly
        # this transfer.
        j_eff = v["J"] + v["J_L"] / (v["eta"] * v["ratio"] ** 2)
        output = np.array([[v["ci_Kp"], j_eff * v["ci_Ki"] / v["Km"]]])
        forward = _series(delay, _plant(params, output, states=2))
    else:
        forward = _series(
            _series(_current_controller(v), delay),
            (*parts.current_plant_matrices(params), np.zeros((1, 1))),
        )
    return _sorted(np.linalg.eigvals(_close_loop(forward, 0, 0)[0]))


def _sorted(poles):
    return poles[np.argsort(-poles.real, kind="stable")]


def _plant(params, output, states=3):
    """The plant of :func:`cas_freq.model.parts.plant_matrices`, input V [V], states
    (i, omega[, theta]), outputs ``output @ x``."""
    a, b = parts.plant_matrices(params)
    return (a[0, :states, :states], b[0, :states, :1], np.asarray(output, dtype=float),
            np.zeros((output.shape[0], 1)))


def _current_controller(v):
    """C_i = Kp + Ki/s [V/A]; no state when Ki = 0."""
    kp, ki = v["ci_Kp"], v["ci_Ki"]
    if ki == 0:
        return np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.array([[kp]])
    return np.zeros((1, 1)), np.ones((1, 1)), np.array([[ki]]), np.array([[kp]])


def _position_controller(v):
    """C_p = Kp + Ki/s + Kd s/(Tf s + 1) [A/rad]: integrator (if Ki > 0), filter (if Kd > 0).

    The derivative term is (Kd/Tf) (1 - 1/(Tf s + 1)): a filter state x' = (e - x)/Tf.
    """
    diagonal, b, c = [], [], []
    d = v["cp_Kp"]
    if v["cp_Ki"] > 0:
        diagonal.append(0.0)
        b.append(1.0)
        c.append(v["cp_Ki"])
    if v["cp_Kd"] > 0:
        tf = v["Tf"]
        diagonal.append(-1.0 / tf)
        b.append(1.0 / tf)
        c.append(-v["cp_Kd"] / tf)
        d += v["cp_Kd"] / tf
    m = len(diagonal)
    return (np.diag(np.asarray(diagonal, dtype=float)).reshape(m, m),
            np.asarray(b, dtype=float).reshape(m, 1), np.asarray(c, dtype=float).reshape(1, m),
            np.array([[d]]))


def _series(first, second):
    """``first`` then ``second`` (single input; ``first`` single output)."""
    a1, b1, c1, d1 = first
    a2, b2, c2, d2 = second
    m1, m2 = a1.shape[0], a2.shape[0]
    a = np.zeros((m1 + m2, m1 + m2))
    a[:m1, :m1] = a1
    a[m1:, :m1] = b2 @ c1
    a[m1:, m1:] = a2
    return a, np.vstack([b1, b2 @ d1]), np.hstack([d2 @ c1, c2]), d2 @ d1


def _close_loop(system, feedback_row, output_row):
    """Unity negative feedback u = r - y[feedback_row]; returns (A, B, C, D) for y[output_row].

    The fed-back output must be strictly proper (zero feedthrough), as every loop here is.
    """
    a, b, c, d = system
    if np.any(d[feedback_row] != 0):
        raise AssertionError("feedback through a direct term")  # pragma: no cover
    a_closed = a - b @ c[feedback_row:feedback_row + 1]
    return a_closed, b, c[output_row:output_row + 1], d[output_row:output_row + 1]
