r"""Second-order-plus-delay model of a step response (ARL-TR-9136 §7, docs/model.md).

.. math::
    \ddot x = -\omega_n^2 x - 2\zeta\omega_n \dot x + \omega_n^2 u(t - t_d)

For a step of size A at t = 0 and :math:`\tau = t - t_d \ge 0`, with :math:`\sigma = \zeta\omega_n`,

.. math::
    x = A \left[1 - e^{-\sigma\tau}\left(C(\tau) + \sigma S(\tau)\right)\right]

where :math:`C = \cos\omega_d\tau`, :math:`S = \sin(\omega_d\tau)/\omega_d`,
:math:`\omega_d = \omega_n\sqrt{1 - \zeta^2}` (underdamped); :math:`C = 1`, :math:`S = \tau`
(critically damped); :math:`C = \cosh\beta\tau`, :math:`S = \sinh(\beta\tau)/\beta`,
:math:`\beta = \omega_n\sqrt{\zeta^2 - 1}` (overdamped), and x = 0 before :math:`t_d`
(Ogata, *Modern Control Engineering*, 5th ed., §5-3). The three cases join continuously at
ζ = 1, so the fit may cross it. (ωn, ζ, td) are fitted by a bounded Levenberg-Marquardt
iteration with an analytic Jacobian, many responses at once (:func:`fit_second_order_batch`; one
response is a batch of one), or by :func:`scipy.optimize.least_squares` as a cross-check; both
finish with Newton steps on the gradient, which pin the minimum to ~1e-12 (the sum of squares
alone is flat to rounding over ~1e-8 of the variables there). The ~95 % confidence intervals
are ±t(0.975, m - 3) times the standard errors from :math:`s^2 (J^T J)^{-1}` at the solution (J
the residuals' analytic Jacobian, :math:`s^2` the residual variance), which assumes independent
residuals of equal variance.
"""

import dataclasses
import math

import numpy as np

from cas_freq.core.formulas import (
    _FTOL,
    _LOWER,
    _MOVE,
    C_SERIES,
    D_SERIES,
    S_SERIES,
    second_order_bandwidth,
)
from cas_freq.core.jit import use_compiled
from cas_freq.simulation.step_figures import diverged

# scipy.optimize (the cross-check only) and scipy.special are imported inside the functions that
# use them: importing scipy.optimize costs 0.4-0.7 s, which every CLI start paid through
# ``cas_freq.simulation``.


def second_order_step(t, natural_frequency, damping_ratio, delay, step=1.0):
    """Step response of the second-order-plus-delay model, in closed form.

    Parameters
    ----------
    t : array_like
        Times [s] (the step at t = 0).
    natural_frequency : float
        ωn [rad/s], > 0.
    damping_ratio : float
        ζ [-], >= 0.
    delay : float
        td [s].
    step : float
        Step size A (the response's unit).

    Returns
    -------
    numpy.ndarray
        x(t).
    """
    t = np.asarray(t, dtype=float)
    wn, zeta = float(natural_frequency), float(damping_ratio)
    tau = t - delay
    on = tau > 0
    tau = np.where(on, tau, 0.0)
    sigma = zeta * wn
    q = zeta * zeta - 1.0
    if q < 0:
        wd = wn * math.sqrt(-q)
        decay = np.exp(-sigma * tau)
        shape = decay * (np.cos(wd * tau) + sigma * tau * np.sinc(wd * tau / math.pi))
    elif q == 0:
        shape = np.exp(-sigma * tau) * (1.0 + sigma * tau)
    else:
        beta = wn * math.sqrt(q)
        slow = np.exp((beta - sigma) * tau)  # e^{-sigma tau} e^{beta tau}, beta < sigma
        fast = np.exp(-(beta + sigma) * tau)
        cosh = 0.5 * (slow + fast)
        # e^{-sigma tau} sinh(beta tau) / beta without cancellation for small beta tau.
        sinh = np.where(beta * tau < 1.0, 0.5 * fast * np.expm1(np.minimum(2 * beta * tau, 2.0)),
                        0.5 * (slow - fast)) / beta
        shape = cosh + sigma * sinh
    return step * np.where(on, 1.0 - shape, 0.0)


@dataclasses.dataclass(frozen=True)
class SecondOrderFit:
    """A second-order-plus-delay model fitted to a step response.

    Attributes
    ----------
    wn_rad_s, zeta, td_s : float
        Natural frequency [rad/s], damping ratio [-], delay [s].
    wn_ci_rad_s, zeta_ci, td_ci_s : tuple of float
        ~95 % confidence intervals (low, high) of each.
    rms_residual : float
        RMS of response - model (the response's unit).
    bandwidth_closed_form_rad_s : float
        :func:`cas_freq.core.formulas.second_order_bandwidth` of (wn, zeta) [rad/s].
    success : bool
        Whether the optimiser reported convergence.
    """

    wn_rad_s: float
    zeta: float
    td_s: float
    wn_ci_rad_s: tuple
    zeta_ci: tuple
    td_ci_s: tuple
    rms_residual: float
    bandwidth_closed_form_rad_s: float
    success: bool


def _initial_guess(t, y):
    """(wn, zeta, td) from overshoot, peak and the first 5 % crossing of the unit-step y."""
    moved = np.flatnonzero(y > 0.05)
    td = float(t[moved[0]]) * 0.5 if moved.size else 0.0
    k = int(np.argmax(y))
    overshoot = y[k] - 1.0
    if overshoot > 1e-3 and t[k] > td:
        log = math.log(overshoot)
        zeta = -log / math.sqrt(math.pi**2 + log**2)
        wn = math.pi / ((t[k] - td) * math.sqrt(1.0 - zeta**2))
    else:
        zeta = 1.0
        rise = np.flatnonzero(y > 0.5)
        half = float(t[rise[0]]) - td if rise.size else float(t[-1]) / 2
        wn = 1.68 / max(half, 1e-12)  # a critically damped step reaches 50 % at wn t = 1.68
    return wn, max(zeta, 0.05), td


def _strided_unit_step(t, response, step, max_points, caller):
    """Checked (t, response / step), strided evenly to at most ``max_points`` samples."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(response, dtype=float)
    if t.shape != y.shape or t.ndim != 1 or t.size < 4:
        raise ValueError(f"{caller}: t and response must be 1-D of the same length (>= 4)")
    if step == 0 or not math.isfinite(step):
        raise ValueError(f"{caller}: step must be finite and nonzero, got {step!r}")
    stride = max(1, -(-t.size // max_points))
    return t[::stride], y[::stride] / step


#: Most samples the fit uses (evenly strided). Against the full 5 us data of the shipped
#: variants' 10 deg and 0.5 deg steps (20,001-40,001 samples), wn and zeta move by <= 0.11 %,
#: td by <= 0.06 % (or < 1e-9 s where it fits to ~0), the closed-form bandwidth by <= 0.003 %,
#: at a tenth to a twentieth of the cost.
MAX_FIT_POINTS = 2000


def fit_second_order(t, response, step, initial=None, max_points=MAX_FIT_POINTS, method="lm"):
    """Least-squares fit of (ωn, ζ, td) to a step response.

    Parameters
    ----------
    t : array_like
        Times [s], the step at t = 0.
    response : array_like
        The measured or simulated response (any unit).
    step : float
        Step size (the response's unit), nonzero.
    initial : tuple of float, optional
        Starting (wn [rad/s], zeta, td [s]); default estimated from overshoot and peak time.
    max_points : int
        Longer data is strided evenly down to at most this many samples (the confidence
        intervals then count those samples only).
    method : {"lm", "least_squares"}
        ``"lm"``: the bounded Levenberg-Marquardt iteration of :func:`fit_second_order_batch`
        (this fit is a batch of one); ``"least_squares"``:
        :func:`scipy.optimize.least_squares` (trf, 2-point Jacobian, tolerances 1e-14), the
        independent cross-check of the tests. Both end with the same Newton steps on the
        gradient (:func:`_refine`) and agree to about 1e-12.

    Returns
    -------
    SecondOrderFit
    """
    t, unit = _strided_unit_step(t, response, step, max_points, "fit_second_order")
    if method == "lm":
        return _fit_block([(t, unit)], np.array([float(step)]), _MAX_ITERATIONS, [initial])[0]
    if method != "least_squares":
        raise ValueError(f"fit_second_order: method must be 'lm' or 'least_squares', "
                         f"got {method!r}")
    from scipy import optimize

    x0, scale, upper = _start(t, unit, initial)

    def residuals(p):
        return second_order_step(t, p[0] * scale[0], p[1], p[2] * scale[2]) - unit

    fit = optimize.least_squares(
        residuals, np.clip(x0, _LOWER, upper), bounds=(_LOWER, upper), x_scale="jac",
        xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=2000,
    )
    return _summaries(t[None], unit[None], fit.x[None], scale[None], upper[None],
                      np.array([float(step)]), np.array([fit.success]))[0]


def _start(t, unit, initial=None):
    """Starting point, scales and upper bounds of the scaled variables of one fit.

    Parameters
    ----------
    t, unit : numpy.ndarray
        Times [s] and unit-step response (strided).
    initial : tuple of float, optional
        Starting (wn [rad/s], zeta, td [s]); default :func:`_initial_guess`.

    Returns
    -------
    x0, scale, upper : numpy.ndarray
        Each (3,): the scaled start (1, zeta0, td0 / scale_td), the scales (wn0 [rad/s], 1,
        scale_td [s]) and the upper bounds (inf, inf, t_end / scale_td); the lower bounds are
        :data:`_LOWER`.
    """
    wn0, zeta0, td0 = initial if initial is not None else _initial_guess(t, unit)
    scale = np.array([wn0, 1.0, max(td0, 1e-3 / wn0)])
    x0 = np.array([1.0, zeta0, td0 / scale[2]])
    upper = np.array([np.inf, np.inf, float(t[-1]) / scale[2]])
    return x0, scale, upper


# --- Many fits at once -------------------------------------------------------------------------
#
# fit_second_order_batch (and fit_second_order, a batch of one) runs a bounded
# Levenberg-Marquardt iteration on every unconverged response together (_levenberg_marquardt),
# then Newton steps on the gradient (_refine), then the intervals (_summaries), with the analytic
# Jacobian below; the variables, bounds and starting guess are those least_squares gets in
# fit_second_order(method="least_squares").
#
# In dimensionless time s = wn (t - td) the unit step is g(s, zeta) = 1 - E (C + zeta S),
# E = exp(-zeta s), C = cos(w s), S = sin(w s) / w, w = sqrt(1 - zeta^2) (cosh / sinh of
# sqrt(zeta^2 - 1) s when overdamped), and
#
#     dg/ds = E S                     (the impulse response),
#     dg/dzeta = E (s C - S) / (1 - zeta^2),
#
# so dx/dwn = E S (t - td), dx/dtd = -E S wn. Near zeta = 1 (|(1 - zeta^2) s^2| < 1) C, S and
# (s C - S) / (1 - zeta^2) come from their power series in (1 - zeta^2) s^2, which are exact at
# zeta = 1 and free of the cancellation of the closed forms there.

#: Most Levenberg-Marquardt trial steps per run (found: 10-45).
_MAX_ITERATIONS = 500

#: Runs iterated together in one block of fit_second_order_batch (memory: about 12 arrays of
#: block x max_points floats, 2 MB each at 128 x 2000, three times that in _refine's Hessian).
_BATCH_BLOCK = 128

#: Newton steps of _refine.
_REFINE_STEPS = 4



def _series(x, coefficients):
    """Horner evaluation of sum coefficients[k] (-x)^k."""
    total = np.full_like(x, coefficients[-1])
    for c in coefficients[-2::-1]:
        total = total * -x + c
    return total


def _unit_step_terms(s, zeta):
    """E C, E S and E D = E (s C - S) / (1 - zeta^2) of the unit step at dimensionless times s.

    Parameters
    ----------
    s : numpy.ndarray
        wn (t - td) >= 0 [-], shape (k, m).
    zeta : numpy.ndarray
        Damping ratios [-], shape (k, 1).

    Returns
    -------
    tuple of numpy.ndarray
        (E C, E S, E D), each shape (k, m); the unit step is 1 - (E C + zeta E S).
    """
    q = 1.0 - zeta * zeta
    root = np.sqrt(np.abs(q))
    ec, es, ed = np.empty_like(s), np.empty_like(s), np.empty_like(s)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        for rows, closed_form in ((q[:, 0] > 0, _underdamped), (q[:, 0] < 0, _overdamped)):
            if rows.all():
                rows = slice(None)  # a view, not a copy
            elif not rows.any():
                continue
            ec[rows], es[rows] = closed_form(s[rows], zeta[rows], root[rows])
            ed[rows] = (s[rows] * ec[rows] - es[rows]) / q[rows]
    # Where |(1 - zeta^2) s^2| < 1 (all of a run at zeta = 1), the series instead.
    x = q * s * s
    near = np.abs(x) < 1.0
    if near.any():
        sn, xn = s[near], x[near]
        decay = np.exp(-np.broadcast_to(zeta, s.shape)[near] * sn)
        ec[near] = decay * _series(xn, C_SERIES)
        es[near] = decay * sn * _series(xn, S_SERIES)
        ed[near] = decay * sn**3 * _series(xn, D_SERIES)
    return ec, es, ed


def _underdamped(s, zeta, w):
    """E C and E S for zeta < 1, w = sqrt(1 - zeta^2) (shapes as in _unit_step_terms)."""
    decay = np.exp(-zeta * s)
    ws = w * s
    return decay * np.cos(ws), decay * np.sin(ws) / w


def _overdamped(s, zeta, beta):
    """E C and E S for zeta > 1, beta = sqrt(zeta^2 - 1), without overflow for large s."""
    slow = np.exp(s * (-1.0 / (beta + zeta)))  # e^{(beta - zeta) s}, exactly beta - zeta
    fast = np.exp(-(beta + zeta) * s)
    return 0.5 * (slow + fast), (0.5 / beta) * (slow - fast)


def _residuals_and_jacobian(t, unit, p, scale):
    """Residuals (model - unit) and their Jacobian in the scaled variables, for k runs.

    Parameters
    ----------
    t, unit : numpy.ndarray
        Times [s] and unit responses, shape (k, m); padding is t = 0, unit = 0 (its residual
        and Jacobian are then 0 for any td >= 0).
    p : numpy.ndarray
        Scaled variables (wn / scale_wn, zeta, td / scale_td), shape (k, 3).
    scale : numpy.ndarray
        (scale_wn [rad/s], 1, scale_td [s]), shape (k, 3).

    Returns
    -------
    residuals : numpy.ndarray
        Shape (k, m).
    jacobian : numpy.ndarray
        d residuals / d p, shape (k, 3, m).
    """
    wn = (p[:, 0] * scale[:, 0])[:, None]
    zeta = p[:, 1:2]
    td = (p[:, 2] * scale[:, 2])[:, None]
    tau = np.maximum(t - td, 0.0)
    ec, es, ed = _unit_step_terms(wn * tau, zeta)
    residuals = (1.0 - (ec + zeta * es)) - unit
    jacobian = np.empty((t.shape[0], 3, t.shape[1]))
    jacobian[:, 0] = es * tau * scale[:, 0:1]
    jacobian[:, 1] = ed
    jacobian[:, 2] = es * -(wn * scale[:, 2:3])
    return residuals, jacobian


def _normal_equations(residuals, jacobian):
    """Sum of squares (k,), J J^T (k, 3, 3) and J r (k, 3) of residuals (k, m), J (k, 3, m)."""
    return (np.einsum("km,km->k", residuals, residuals),
            np.einsum("kim,kjm->kij", jacobian, jacobian),
            np.einsum("kim,km->ki", jacobian, residuals))


def _normal_equations_at(t, unit, p, scale, rows=None):
    """Sum of squares (k,), J^T J (k, 3, 3) and J^T r (k, 3) at the scaled variables ``p``.

    Computed by the compiled :func:`cas_freq.simulation.fit_kernel.normal_equations_of`, in
    one pass over the samples; ``_normal_equations(*_residuals_and_jacobian(...))`` is its
    numpy reference (the same to ~1e-15 relative), used with ``CAS_FREQ_ENGINE=reference`` or
    without numba (:func:`cas_freq.core.jit.use_compiled`). Arguments as in
    :func:`_residuals_and_jacobian`; with ``rows`` (k,), run i is fitted to the data of row
    ``rows[i]`` of ``t`` and ``unit`` (default: row i).
    """
    if not use_compiled():
        if rows is not None:
            t, unit = t[rows], unit[rows]
        return _normal_equations(*_residuals_and_jacobian(t, unit, p, scale))
    from cas_freq.simulation.fit_kernel import normal_equations_of

    t, unit, p, scale = (np.ascontiguousarray(a, dtype=float) for a in (t, unit, p, scale))
    rows = np.arange(t.shape[0]) if rows is None else np.asarray(rows, dtype=np.int64)
    return normal_equations_of(t, unit, rows, p, scale)


def _levenberg_marquardt(t, unit, p, scale, upper, max_iterations):
    """Bounded Levenberg-Marquardt on k runs at once; each run stops when it has converged.

    The step solves :math:`(J^T J + \\lambda\\,\\mathrm{diag}(J^T J))\\,\\delta = -J^T r` over the
    variables not held at a bound (a variable at a bound whose gradient points outward is held
    there), and is projected onto the bounds; λ follows Nielsen's rule (Madsen, Nielsen &
    Tingleff, *Methods for Non-Linear Least Squares Problems*, 2004, §3.2). A run has converged
    when a step it tried is below 1e-14 of the variables, an accepted step lowers the sum of
    squares by less than :data:`_FTOL` of it, or its projected gradient is 0; :func:`_refine`
    then pins the minimum.

    Parameters
    ----------
    t, unit : numpy.ndarray
        Padded times [s] and unit responses, shape (k, m).
    p : numpy.ndarray
        Starting scaled variables, shape (k, 3), within the bounds.
    scale : numpy.ndarray
        Variable scales, shape (k, 3).
    upper : numpy.ndarray
        Upper bounds of the scaled variables, shape (k, 3).
    max_iterations : int
        Most trial steps per run.

    Returns
    -------
    p : numpy.ndarray
        Scaled estimates, shape (k, 3).
    converged : numpy.ndarray
        Bool, shape (k,).
    """
    k = t.shape[0]
    p = np.clip(p, _LOWER, upper)
    # Per run only what a step needs: the sum of squares, J J^T (3 x 3) and J r (3).
    cost, normal, gradient = _normal_equations_at(t, unit, p, scale)
    damping = np.full(k, 1e-3)
    growth = np.full(k, 2.0)
    converged = np.zeros(k, dtype=bool)
    active = np.arange(k)
    eye = np.eye(3)
    for _ in range(max_iterations):
        if active.size == 0:
            break
        A, g, x, hi = normal[active], gradient[active], p[active], upper[active]
        held = ((x <= _LOWER) & (g > 0)) | ((x >= hi) & (g < 0))
        free = ~held
        diag = np.diagonal(A, axis1=1, axis2=2)
        diag = np.maximum(diag, 1e-30 * diag.max(axis=1, keepdims=True) + 1e-300)
        system = A + damping[active, None, None] * (diag[:, :, None] * eye)
        system = system * (free[:, :, None] & free[:, None, :]) + held[:, :, None] * eye
        delta, stuck = _solve_steps(system, np.where(held, 0.0, -g))
        trial = np.clip(x + delta, _LOWER, hi)
        step = trial - x
        cost_new, normal_new, gradient_new = _normal_equations_at(t, unit, trial, scale[active],
                                                                  rows=active)
        predicted = -(2.0 * np.einsum("ki,ki->k", g, step)
                      + np.einsum("ki,kij,kj->k", step, A, step))
        old = cost[active]
        accept = cost_new < old
        positive = predicted > 0
        ratio = np.where(positive, (old - cost_new) / np.where(positive, predicted, 1.0), -1.0)
        # Nielsen's update of the damping.
        good = accept & (ratio > 0)
        lam = damping[active]
        lam = np.where(good, lam * np.maximum(1.0 / 3.0, 1.0 - (2.0 * ratio - 1.0) ** 3),
                       lam * growth[active])
        growth[active] = np.where(good, 2.0, growth[active] * 2.0)
        damping[active] = np.minimum(lam, 1e300)
        done = np.linalg.norm(step, axis=1) <= 1e-14 * (1e-14 + np.linalg.norm(x, axis=1))
        done |= accept & (old - cost_new <= _FTOL * old)
        done |= ~np.any(free & (g != 0), axis=1)
        done |= damping[active] >= 1e300  # no step lowers the sum of squares any more
        accept &= ~stuck
        taken = active[accept]
        p[taken], cost[taken], normal[taken], gradient[taken] = (
            trial[accept], cost_new[accept], normal_new[accept], gradient_new[accept])
        converged[active[done & ~stuck]] = True
        active = active[~(done | stuck)]  # a stuck run stops, not converged
    return p, converged


def _levenberg_marquardt_compiled(t, unit, p, scale, upper, max_iterations):
    """:func:`_levenberg_marquardt` with each iteration's work compiled
    (:func:`cas_freq.simulation.fit_kernel.lm_trials` and
    :func:`~cas_freq.simulation.fit_kernel.lm_update`, run by run): the same estimates to
    the last bit, at a seventh of the cost of the iteration's numpy operations.

    Arguments as in :func:`_levenberg_marquardt`. Returns ``(p, converged, cost, normal,
    gradient)``: the estimates and convergence, and the sum of squares (k,), J^T J (k, 3, 3)
    and J^T r (k, 3) at the estimates (which :func:`_refine` would compute again).
    """
    from cas_freq.simulation.fit_kernel import lm_trials, lm_update

    k = t.shape[0]
    t, unit, scale, upper = (np.ascontiguousarray(a, dtype=float) for a in (t, unit, scale, upper))
    p = np.clip(p, _LOWER, upper)
    cost, normal, gradient = _normal_equations_at(t, unit, p, scale)
    damping, growth = np.full(k, 1e-3), np.full(k, 2.0)
    converged = np.zeros(k, dtype=bool)
    active = np.arange(k)
    trial, step, normal_new, gradient_new = (np.empty((k, 3)), np.empty((k, 3)),
                                             np.empty((k, 3, 3)), np.empty((k, 3)))
    for _ in range(max_iterations):
        if active.size == 0:
            break
        cost_new, ratio, accept, stuck, flat = lm_trials(
            t, unit, active, p, cost, normal, gradient, damping, scale, upper, trial, step,
            normal_new, gradient_new)
        # numpy's power, as in _levenberg_marquardt: its last bit differs from libm's pow
        cube = (2.0 * ratio - 1.0) ** 3
        active = lm_update(active, p, cost, normal, gradient, damping, growth, converged,
                           trial, step, cost_new, normal_new, gradient_new, ratio, cube, accept,
                           stuck, flat)
    return p, converged, cost, normal, gradient


#: Largest condition number of the normalised J^T J (unit diagonal) at which the three
#: parameters are still told apart; beyond it the data determine only a combination of them
#: (a heavily overdamped step fixes wn / (2 zeta), not wn and zeta), and each interval is
#: reported as unbounded rather than computed from a matrix that rounding has made singular.
_MAX_CONDITION = 1e12


def _standard_errors(normal, variance):
    """Standard errors from s^2 (J^T J)^-1, or inf for each when J^T J is (nearly) singular."""
    diagonal = np.diag(normal)
    if not (np.isfinite(normal).all() and np.all(diagonal > 0) and np.isfinite(variance)):
        return np.full(3, math.inf)
    norm = np.sqrt(diagonal)
    correlation = normal / np.outer(norm, norm)
    if np.linalg.cond(correlation) > _MAX_CONDITION:
        return np.full(3, math.inf)
    cov = np.linalg.inv(correlation) / np.outer(norm, norm) * variance
    errors = np.sqrt(np.diag(cov))
    return np.where(np.isfinite(errors) & (np.diag(cov) >= 0), errors, math.inf)


def _solve_steps(system, rhs):
    """Batched solve of the damped normal equations: (steps (k, 3), stuck (k,)).

    A run whose system is not finite or is singular (extreme data: a Jacobian that overflows
    or vanishes) gets a zero step and is reported stuck, so that the others go on and it ends
    as not converged (``success`` False), never as an exception.
    """
    steps = np.zeros(rhs.shape)
    stuck = ~(np.isfinite(system).all(axis=(1, 2)) & np.isfinite(rhs).all(axis=1))
    good = np.flatnonzero(~stuck)
    try:
        steps[good] = np.linalg.solve(system[good], rhs[good][:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:  # one singular system fails the stack: solve one by one
        for i in good:
            try:
                steps[i] = np.linalg.solve(system[i], rhs[i])
            except np.linalg.LinAlgError:
                stuck[i] = True
    stuck |= ~np.isfinite(steps).all(axis=1)
    steps[stuck] = 0.0
    return steps, stuck


def fit_second_order_batch(times, responses, steps, max_points=MAX_FIT_POINTS,
                           max_iterations=_MAX_ITERATIONS):
    """Least-squares fits of (ωn, ζ, td) to many step responses at once.

    Each fit is that of :func:`fit_second_order` (a batch of one): the same strided samples,
    starting guess, scaled variables, bounds, confidence intervals, RMS residual and
    closed-form bandwidth. The runs, strided each to at most ``max_points`` samples, are padded
    to a common length (the padding has no residual) and iterated together in blocks of
    :data:`_BATCH_BLOCK` by a bounded Levenberg-Marquardt iteration with an analytic Jacobian;
    a run that has converged stops iterating. The estimates equal those of one
    :func:`scipy.optimize.least_squares` per run (``fit_second_order(method="least_squares")``)
    to ~1e-12 and do not depend on the other runs of the batch. A td that fits to its bound is
    exactly 0 (least_squares alone, which keeps inside the bounds, leaves ~1e-48 s).

    Parameters
    ----------
    times : sequence of array_like
        Each run's times [s], the step at t = 0; the runs may differ in length.
    responses : sequence of array_like
        Each run's measured or simulated response (any unit), as long as its times.
    steps : float or array_like
        Step size of every run or of each (the response's unit), nonzero.
    max_points : int
        Longer data is strided evenly down to at most this many samples, per run as
        :func:`fit_second_order` does.
    max_iterations : int
        Most Levenberg-Marquardt trial steps per run (a run that reaches it has
        ``success`` False).

    Returns
    -------
    list of SecondOrderFit
        One per run, in order.
    """
    times, responses = list(times), list(responses)
    if len(times) != len(responses):
        raise ValueError(f"fit_second_order_batch: {len(times)} time arrays but "
                         f"{len(responses)} responses")
    steps = np.broadcast_to(np.asarray(steps, dtype=float), (len(times),))
    runs = [_strided_unit_step(t, y, float(a), max_points, "fit_second_order_batch")
            for t, y, a in zip(times, responses, steps, strict=True)]
    fits = []
    for start in range(0, len(runs), _BATCH_BLOCK):
        block = runs[start:start + _BATCH_BLOCK]
        fits += _fit_block(block, steps[start:start + _BATCH_BLOCK], max_iterations)
    return fits


def _fit_block(runs, steps, max_iterations, initials=None):
    """fit_second_order_batch of one block of (t, unit response) runs (optional starts).

    A response that diverged (:func:`~cas_freq.simulation.step_figures.diverged`) has no fit
    (NaN, ``success`` False); a flat zero response stands in for it in the iteration.
    """
    lost = [diverged(t, unit, 1.0) is not None for t, unit in runs]
    runs = [(t, np.zeros_like(unit) if gone else unit)
            for (t, unit), gone in zip(runs, lost, strict=True)]
    k = len(runs)
    sizes = np.array([t.size for t, _ in runs])
    t_pad, unit_pad = np.zeros((k, sizes.max())), np.zeros((k, sizes.max()))
    x0, scale, upper = np.empty((k, 3)), np.empty((k, 3)), np.empty((k, 3))
    initials = [None] * k if initials is None else initials
    for i, ((t, unit), initial) in enumerate(zip(runs, initials, strict=True)):
        t_pad[i, :t.size], unit_pad[i, :t.size] = t, unit
        x0[i], scale[i], upper[i] = _start(t, unit, initial)
    if use_compiled():
        p, converged, cost, normal, gradient = _levenberg_marquardt_compiled(
            t_pad, unit_pad, x0, scale, upper, max_iterations)
        from cas_freq.simulation.fit_kernel import refine

        refined = refine(t_pad, unit_pad, p, scale, upper, cost, normal, gradient,
                         _REFINE_STEPS)
        fits = _summaries(t_pad, unit_pad, p, scale, upper, steps, converged, sizes, refined)
    else:
        p, converged = _levenberg_marquardt(t_pad, unit_pad, x0, scale, upper, max_iterations)
        fits = _summaries(t_pad, unit_pad, p, scale, upper, steps, converged, sizes)
    nan = math.nan
    return [SecondOrderFit(
        wn_rad_s=nan, zeta=nan, td_s=nan, wn_ci_rad_s=(nan, nan), zeta_ci=(nan, nan),
        td_ci_s=(nan, nan), rms_residual=nan, bandwidth_closed_form_rad_s=nan, success=False)
        if gone else fit for fit, gone in zip(fits, lost, strict=True)]


def _refine(t, unit, p, scale, upper, iterations=_REFINE_STEPS):
    """Newton steps on the gradient of the sum of squares, from a converged fit.

    Near the minimum the sum of squares is flat to rounding over ~1e-8 of the variables (its
    change there is 1e-16 of it), so optimisers that stop on it (least_squares' ftol, a
    rejected Levenberg-Marquardt step) stop anywhere in that flat: two of them, or one on
    differently padded data, differ by up to ~1e-7 relative. The gradient
    :math:`J^T r` is known to rounding much more finely; a few Newton steps on
    :math:`J^T r = 0` (Hessian by forward differences of the analytic gradient, computed once)
    bring any start within that flat to the same point to ~1e-12. Variables held at a bound
    (at it, the gradient pointing outward) stay there. A run whose Hessian is not positive
    definite, or that the steps would move by more than :data:`_MOVE` of its variables or whose
    sum of squares they would raise by more than 1e-12 of it, keeps its start.

    Parameters
    ----------
    t, unit : numpy.ndarray
        Padded times [s] and unit responses, shape (k, m).
    p : numpy.ndarray
        Scaled variables of the converged fits, shape (k, 3).
    scale, upper : numpy.ndarray
        Scales and upper bounds of the variables, shape (k, 3).
    iterations : int
        Newton steps (each one evaluation of the gradient).

    Returns
    -------
    numpy.ndarray
        Refined scaled variables, shape (k, 3).
    """
    k = p.shape[0]
    before, _, gradient = _normal_equations_at(t, unit, p, scale)
    # Hessian of half the sum of squares: column j from the gradient at p + h e_j, all at once
    # (forward differences, ~1e-6 relative: enough for Newton steps whose fixed point is set by
    # the gradient alone).
    h = 1e-6 * np.maximum(np.abs(p), 1.0)
    probes = (p[:, None, :] + np.eye(3)[None] * h[:, None, :]).reshape(3 * k, 3)
    _, _, g3 = _normal_equations_at(t, unit, probes, np.repeat(scale, 3, axis=0),
                                    rows=np.repeat(np.arange(k), 3))
    g3 = g3.reshape(k, 3, 3)  # [run, probe j, component i]
    hessian = ((g3 - gradient[:, None, :]) / h[:, :, None]).transpose(0, 2, 1)
    hessian = 0.5 * (hessian + hessian.transpose(0, 2, 1))
    eye = np.eye(3)
    usable = np.ones(k, dtype=bool)
    finite = np.isfinite(upper)
    ceiling = np.where(finite, upper - 1e-10 * np.maximum(np.abs(np.where(finite, upper, 0.0)),
                                                          1.0), np.inf)
    q = p.copy()
    for _ in range(iterations):
        # At a bound (within 1e-10 of the scaled variable: least_squares, which keeps inside
        # the bounds, leaves td at ~1e-48) with the gradient pointing outward: held there.
        at_lower = (q <= _LOWER + 1e-10) & (gradient > 0)
        at_upper = (q >= ceiling) & (gradient < 0)
        q = np.where(at_lower, _LOWER, np.where(at_upper, upper, q))
        free = ~(at_lower | at_upper)
        system = np.where(free[:, :, None] & free[:, None, :], hessian, 0.0)
        system = system + (~free)[:, :, None] * eye
        # a run whose data or fit is not finite (a diverging simulation) keeps its start
        usable &= np.isfinite(system).all(axis=(1, 2))
        system = np.where(usable[:, None, None], system, eye)
        usable &= np.linalg.eigvalsh(system)[:, 0] > 0
        system = np.where(usable[:, None, None], system, eye)
        delta = np.linalg.solve(system, -np.where(free, gradient, 0.0)[:, :, None])[:, :, 0]
        q = np.where(usable[:, None], np.clip(q + delta, _LOWER, upper), q)
        after, _, gradient = _normal_equations_at(t, unit, q, scale)
    moved = np.linalg.norm(q - p, axis=1) <= _MOVE * np.linalg.norm(p, axis=1)
    keep = usable & moved & (after <= before * (1.0 + 1e-12))
    return np.where(keep[:, None], q, p)


def _summaries(t, unit, p, scale, upper, steps, success, sizes=None, refined=None):
    """SecondOrderFit of each run from its converged scaled variables (refined first).

    The confidence intervals are those of :func:`fit_second_order`'s docstring, from the
    analytic Jacobian at the refined estimates.

    Parameters
    ----------
    t, unit : numpy.ndarray
        Padded times [s] and unit responses, shape (k, m).
    p, scale, upper : numpy.ndarray
        Scaled estimates, scales and upper bounds, shape (k, 3).
    steps : numpy.ndarray
        Step sizes (the responses' unit), shape (k,).
    success : numpy.ndarray
        Whether each fit converged, shape (k,).
    sizes : numpy.ndarray, optional
        Samples of each run (default: all m).
    refined : tuple of numpy.ndarray, optional
        The refined variables (k, 3) with their sums of squares (k,) and J^T J (k, 3, 3),
        when already computed (:func:`cas_freq.simulation.fit_kernel.refine`); default:
        :func:`_refine` of ``p``.

    Returns
    -------
    list of SecondOrderFit
    """
    from scipy import special

    sizes = np.full(t.shape[0], t.shape[1]) if sizes is None else sizes
    if refined is None:
        p = _refine(t, unit, p, scale, upper)
        sum_squares, normal, _ = _normal_equations_at(t, unit, p, scale)
    else:
        p, sum_squares, normal = refined
    values = p * scale
    # In the unscaled variables (wn [rad/s], zeta, td [s]).
    normal = normal / (scale[:, :, None] * scale[:, None, :])
    dof = np.maximum(sizes - 3, 1)
    t_quantile = special.stdtrit(dof, 0.975)  # Student t, two-sided 95 %
    fits = []
    for i in range(t.shape[0]):
        half = t_quantile[i] * _standard_errors(normal[i], sum_squares[i] / dof[i])
        ci = [(float(v - h), float(v + h)) for v, h in zip(values[i], half, strict=True)]
        wn, zeta, td = (float(v) for v in values[i])
        fits.append(SecondOrderFit(
            wn_rad_s=wn, zeta=zeta, td_s=td, wn_ci_rad_s=ci[0], zeta_ci=ci[1], td_ci_s=ci[2],
            rms_residual=float(abs(steps[i]) * math.sqrt(sum_squares[i] / sizes[i])),
            bandwidth_closed_form_rad_s=second_order_bandwidth(wn, zeta),
            success=bool(success[i]),
        ))
    return fits
