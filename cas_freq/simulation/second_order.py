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
ζ = 1, so the fit may cross it. (ωn, ζ, td) are fitted by :func:`scipy.optimize.least_squares`;
their ~95 % confidence intervals are ±t(0.975, m - 3) times the standard errors from
:math:`s^2 (J^T J)^{-1}` at the solution (J the residuals' Jacobian, :math:`s^2` the residual
variance), which assumes independent residuals of equal variance.
"""

import dataclasses
import math

import numpy as np
from scipy import optimize, special

from cas_freq.formulas import second_order_bandwidth


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
        :func:`cas_freq.formulas.second_order_bandwidth` of (wn, zeta) [rad/s].
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


#: Most samples the fit uses (evenly strided). Against the full 5 us data of the shipped
#: variants' 10 deg and 0.5 deg steps (20,001-40,001 samples), wn and zeta move by <= 0.11 %,
#: td by <= 0.06 % (or < 1e-9 s where it fits to ~0), the closed-form bandwidth by <= 0.003 %,
#: at a tenth to a twentieth of the cost.
MAX_FIT_POINTS = 2000


def fit_second_order(t, response, step, initial=None, max_points=MAX_FIT_POINTS):
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

    Returns
    -------
    SecondOrderFit
    """
    t = np.asarray(t, dtype=float)
    y = np.asarray(response, dtype=float)
    if t.shape != y.shape or t.ndim != 1 or t.size < 4:
        raise ValueError("fit_second_order: t and response must be 1-D of the same length (>= 4)")
    if step == 0 or not math.isfinite(step):
        raise ValueError(f"fit_second_order: step must be finite and nonzero, got {step!r}")
    stride = max(1, -(-t.size // max_points))
    t, y = t[::stride], y[::stride]
    unit = y / step
    wn0, zeta0, td0 = initial if initial is not None else _initial_guess(t, unit)
    scale = np.array([wn0, 1.0, max(td0, 1e-3 / wn0)])

    def residuals(p):
        return second_order_step(t, p[0] * scale[0], p[1], p[2] * scale[2]) - unit

    x0 = np.array([1.0, zeta0, td0 / scale[2]])
    lower = [1e-6, 0.0, 0.0]
    upper = [np.inf, np.inf, float(t[-1]) / scale[2]]
    fit = optimize.least_squares(
        residuals, np.clip(x0, lower, upper), bounds=(lower, upper), x_scale="jac",
        xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=2000,
    )
    values = fit.x * np.array([scale[0], 1.0, scale[2]])
    dof = max(t.size - 3, 1)
    variance = 2.0 * fit.cost / dof
    jac = fit.jac / np.array([scale[0], 1.0, scale[2]])
    try:
        cov = np.linalg.inv(jac.T @ jac) * variance
        t_quantile = special.stdtrit(dof, 0.975)  # Student t, two-sided 95 %
        half = t_quantile * np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        half = np.full(3, math.inf)
    ci = [(float(v - h), float(v + h)) for v, h in zip(values, half, strict=True)]
    wn, zeta, td = (float(v) for v in values)
    return SecondOrderFit(
        wn_rad_s=wn, zeta=zeta, td_s=td, wn_ci_rad_s=ci[0], zeta_ci=ci[1], td_ci_s=ci[2],
        rms_residual=float(abs(step) * math.sqrt(2.0 * fit.cost / t.size)),
        bandwidth_closed_form_rad_s=second_order_bandwidth(wn, zeta),
        success=bool(fit.success),
    )
