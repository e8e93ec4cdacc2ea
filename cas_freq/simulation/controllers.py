r"""The loops' controllers, vectorised over runs: PI(D), output clamp, anti-windup.

.. math::
    u = K_p e + K_i \int e \, dt + K_d \dot x_f + u_{ff}, \qquad
    T_f \dot x_f = y - x_f, \qquad u_{out} = \mathrm{clip}(u, -u_{max}, u_{max})

so the derivative term :math:`K_d (y - x_f)/T_f` is :math:`K_d s/(T_f s + 1)` applied to
:math:`y` (the error, or :math:`-\theta` for derivative on measurement; MODEL.md). Each update
over a period T, from the inputs' right limits :math:`(e^-, y^-)` at the previous update to their
left limits :math:`(e^+, y^+)` now (they differ where a step passes through):

- the integral by the trapezoidal rule, :math:`T (e^- + e^+)/2`;
- continuous controllers (updated every simulation step): the filter state exactly for an
  input linear between updates, :math:`x_f^+ = a x_f + (1 - a) y^- + c (y^+ - y^-)`,
  :math:`a = e^{-T/T_f}`, :math:`c = 1 - T_f (1 - a)/T`; together with the plant's exact
  discretisation this makes the loop second order in the step;
- sampled controllers (zero-order hold): the filter by backward difference,
  :math:`a = T_f/(T_f + T)`, :math:`c = 1 - a`, stable for any :math:`T_f/T` and giving a
  step's derivative kick the same area :math:`K_d \Delta e` as the continuous filter (the usual
  choice: Åström & Wittenmark, *Computer-Controlled Systems*, 3rd ed., ch. 8). At 2.5 kHz,
  :math:`T` = 0.4 ms is close to :math:`T_f` = 0.6 ms, so the choice matters: the exact filter
  held for a period gives a 37 % larger kick;
- anti-windup by conditional integration (MODEL.md): the integrator holds while the output would
  be clamped and the integration step pushes it further out; an update in which the output
  reaches the limit integrates up to it (:func:`integrate_with_anti_windup`).
"""

import numpy as np


def integrate_with_anti_windup(
    integral, e_start, e_end, rest_start, rest_end, ki, limit, period, locate=True
):
    """Advance the integral over one update unless that drives the output beyond its limit.

    Conditional integration (MODEL.md): the integral holds while the output is clamped and the
    error pushes it further out. With ``locate`` (continuous controllers) the instants within
    the update where the clamp starts or ends are located by linear interpolation of the output
    with the integral held, and only the part of the interval outside the clamp is integrated
    (trapezoidal rule on the linear error); then, if the integral itself would carry the output
    beyond the limit, it integrates only up to the limit. Both keep the integral continuous in
    the instant the clamp starts or ends; an all-or-nothing update would add an error of up to
    one increment, first order in the step. Without ``locate`` (sampled controllers) the rule is
    applied at the update instant only.

    Parameters
    ----------
    integral : numpy.ndarray
        Integral of the error before the update.
    e_start, e_end : numpy.ndarray
        Error at the start (right limit) and end (left limit) of the update interval.
    rest_start, rest_end : numpy.ndarray
        The output's other terms (proportional, derivative, feed-forward) at both ends.
    ki : numpy.ndarray
        Integral gain (>= 0).
    limit : numpy.ndarray
        Output limit (> 0).
    period : float
        Length of the interval [s].
    locate : bool
        Locate clamp instants within the interval.

    Returns
    -------
    numpy.ndarray
        The new integral.
    """
    increment = 0.5 * period * (e_start + e_end)
    trial = integral + increment
    u_trial = rest_end + ki * trial
    if locate:
        held_start = rest_start + ki * integral
        held_end = rest_end + ki * integral
        near = (np.abs(u_trial) > limit) | (np.abs(held_start) > limit)
        if not np.any(near | (np.abs(held_end) > limit)):
            return trial
        side = np.sign(e_start + e_end)  # the direction the integral moves the output
        u_start, u_end = side * held_start, side * held_end
        over_start, over_end = u_start > limit, u_end > limit
        with np.errstate(divide="ignore", invalid="ignore"):
            cross = np.clip((limit - u_start) / (u_end - u_start), 0.0, 1.0)
        steady = e_start * e_end >= 0  # else: the error changes sign; decide at the end only
        s0 = np.where(steady & over_start & ~over_end, cross, 0.0)
        s1 = np.where(steady & over_end, np.where(over_start, 0.0, cross), 1.0)
        s0 = np.minimum(s0, s1)
        slope = e_end - e_start
        increment = 0.5 * period * (s1 - s0) * (2 * e_start + slope * (s0 + s1))
        trial = integral + increment
        u_trial = rest_end + ki * trial
    outward = (np.abs(u_trial) > limit) & (increment * u_trial > 0)
    if not np.any(outward):
        return trial
    # Fraction of the increment that brings the output to the limit (0 if already beyond).
    edge = np.sign(u_trial) * limit
    with np.errstate(divide="ignore", invalid="ignore"):
        fraction = np.clip((edge - rest_end - ki * integral) / (ki * increment), 0.0, 1.0)
    fraction = np.where(ki * increment != 0, fraction, 0.0)
    return np.where(outward, integral + fraction * increment, trial)


class Controller:
    """PID with filtered derivative, clamp and anti-windup, for n_runs runs at once.

    Inputs may jump at an update instant (a step command): each update takes the inputs' left
    limits (the end of the interval just integrated) and right limits (the values from now on),
    and returns the output's left and right limits.

    Parameters
    ----------
    kp, ki, kd, tf, limit : numpy.ndarray
        Gains (proportional, integral [per s], derivative [s]), derivative filter time constant
        [s] (ignored where kd = 0) and output limit, shape (n_runs,).
    period : float
        Update period T [s].
    sampled : bool
        A sampled controller (backward-difference derivative, first update from zero samples
        before t = 0) instead of a continuous one.
    """

    def __init__(self, kp, ki, kd, tf, limit, period, sampled=False):
        self.kp, self.ki, self.limit, self.period = kp, ki, limit, period
        self.sampled = sampled
        self.has_derivative = bool(np.any(kd > 0))
        n = kp.shape[0]
        if self.has_derivative:
            safe_tf = np.where(kd > 0, tf, 1.0)
            self._gain_d = np.where(kd > 0, kd / safe_tf, 0.0)
            if sampled:  # backward difference
                a = safe_tf / (safe_tf + period)
                self._c = 1.0 - a
            else:  # exact for an input linear between updates
                a = np.exp(-period / safe_tf)
                self._c = 1.0 - safe_tf * (1.0 - a) / period
            self._a = a
            self._b = 1.0 - a
        self.integral = np.zeros(n)
        self._filter = np.zeros(n)
        self._e = np.zeros(n)
        self._y = np.zeros(n)
        self._rest = np.zeros(n)

    def start(self, e_left, e_right, y_left=None, y_right=None, ff_left=0.0, ff_right=0.0):
        """First outputs, at t = 0, from rest.

        A continuous controller starts with integral and filter state 0 (they are continuous
        states, the inputs' jump passes through the proportional and derivative terms); a sampled
        one makes its first update from zero samples before t = 0.

        Returns
        -------
        tuple of numpy.ndarray
            Clamped output's left and right limits, and where the right limit was clamped.
        """
        return self._outputs(
            e_left, e_right, y_left, y_right, ff_left, ff_right, advance=self.sampled
        )

    def update(self, e_left, e_right, y_left=None, y_right=None, ff_left=0.0, ff_right=0.0):
        """Advance one period, to error ``e`` and derivative input ``y`` (default ``e``).

        Returns
        -------
        tuple of numpy.ndarray
            Clamped output's left and right limits, and where the right limit was clamped.
        """
        return self._outputs(e_left, e_right, y_left, y_right, ff_left, ff_right, advance=True)

    def _outputs(self, e_left, e_right, y_left, y_right, ff_left, ff_right, advance):
        y_left = e_left if y_left is None else y_left
        y_right = e_right if y_right is None else y_right
        d_left = d_right = 0.0
        if self.has_derivative:
            if advance:
                self._filter = (
                    self._a * self._filter + self._b * self._y + self._c * (y_left - self._y)
                )
            d_left = self._gain_d * (y_left - self._filter)
            d_right = self._gain_d * (y_right - self._filter)
            self._y = y_right
        rest_left = self.kp * e_left + d_left + ff_left
        if advance:
            self.integral = integrate_with_anti_windup(
                self.integral, self._e, e_left, self._rest, rest_left, self.ki, self.limit,
                self.period, locate=not self.sampled,
            )
        self._e = e_right
        rest_right = self.kp * e_right + d_right + ff_right
        self._rest = rest_right
        u_left = np.clip(rest_left + self.ki * self.integral, -self.limit, self.limit)
        u_right = rest_right + self.ki * self.integral
        limited = np.abs(u_right) > self.limit
        return u_left, np.clip(u_right, -self.limit, self.limit), limited
