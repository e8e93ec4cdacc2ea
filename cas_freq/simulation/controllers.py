r"""The loops' controllers, vectorised over runs: PI(D), output clamp, anti-windup.

.. math::
    u = K_p e + K_i \int e \, dt + K_d \dot x_f + u_{ff}, \qquad
    T_f \dot x_f = y - x_f, \qquad u_{out} = \mathrm{clip}(u, -u_{max}, u_{max})

so the derivative term :math:`K_d (y - x_f)/T_f` is :math:`K_d s/(T_f s + 1)` applied to
:math:`y` (the error, or :math:`-\theta` for derivative on measurement; docs/model.md). Each update
over a period T, from the inputs' right limits :math:`(e^-, y^-)` at the previous update to their
left limits :math:`(e^+, y^+)` now (they differ where a step passes through):

- the integral by the trapezoidal rule, :math:`T (e^- + e^+)/2` (a sampled controller's by its
  method, below);
- continuous controllers (updated every simulation step): the filter state exactly for an
  input linear between updates, :math:`x_f^+ = a x_f + (1 - a) y^- + c (y^+ - y^-)`,
  :math:`a = e^{-T/T_f}`, :math:`c = 1 - T_f (1 - a)/T`; together with the plant's exact
  discretisation this makes the loop second order in the step;
- sampled controllers (zero-order hold, docs/model.md "Sampled controllers"): the continuous
  controller with :math:`s` replaced by the method's map, so that the simulated controller is
  the frequency domain's digital one. ``backward`` (:math:`s \to (1 - z^{-1})/T`): the
  integral :math:`I_n = I_{n-1} + T e_n` (:math:`K_i T z/(z-1)`), the filter
  :math:`a = T_f/(T_f + T)`, :math:`c = 1 - a` (:math:`K_d (z-1)/((T_f+T) z - T_f)`);
  ``tustin`` (:math:`s \to (2/T)(z-1)/(z+1)`): the trapezoidal integral
  (:math:`K_i (T/2)(z+1)/(z-1)`), the filter :math:`a = (2T_f - T)/(2T_f + T)`,
  :math:`c = (1 - a)/2` (:math:`2K_d (z-1)/((2T_f+T) z - (2T_f - T))`). Both are stable for
  any :math:`T_f/T` and give a step's derivative kick the area :math:`K_d \Delta e` of the
  continuous filter (Åström & Wittenmark, *Computer-Controlled Systems*, 3rd ed., ch. 8). At
  2.5 kHz, :math:`T` = 0.4 ms is close to :math:`T_f` = 0.6 ms, so the choice matters: the
  exact filter held for a period gives a 37 % larger kick;
- anti-windup by conditional integration (docs/model.md): the integrator holds while the output
  would be clamped and the integration step pushes it further out; an update in which the output
  reaches the limit integrates up to it (:func:`integrate_with_anti_windup`).
"""

import numpy as np

from cas_freq.core.sampling_config import ALPHA


def integrate_with_anti_windup(
    integral, e_start, e_end, rest_start, rest_end, ki, limit, period, locate=True,
    backward=False,
):
    """Advance the integral over one update unless that drives the output beyond its limit.

    Conditional integration (docs/model.md): the integral holds while the output is clamped and the
    error pushes it further out. With ``locate`` (continuous controllers) the instants within
    the update where the clamp starts or ends are located by linear interpolation of the output
    with the integral held, and only the part of the interval outside the clamp is integrated
    (trapezoidal rule on the linear error); then, if the integral itself would carry the output
    beyond the limit, it integrates only up to the limit. Both keep the integral continuous in
    the instant the clamp starts or ends; an all-or-nothing update would add an error of up to
    one increment, first order in the step. Without ``locate`` (sampled controllers) the rule is
    applied at the update instant only.

    :meth:`Controller.update` calls this only when some run's output is beyond its limit
    somewhere in the update; elsewhere the result is the plain trapezoidal step, which this
    function returns too.

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
    backward : bool
        The increment is ``period * e_end`` (a sampled controller discretised by the backward
        difference; only without ``locate``) instead of the trapezoidal rule.

    Returns
    -------
    numpy.ndarray
        The new integral.
    """
    increment = period * e_end if backward else 0.5 * period * (e_start + e_end)
    trial = integral + increment
    u_trial = rest_end + ki * trial
    if locate:
        held = ki * integral
        held_start = rest_start + held
        held_end = rest_end + held
        near = (np.abs(u_trial) > limit) | (np.abs(held_start) > limit)
        near |= np.abs(held_end) > limit
        if not np.count_nonzero(near):
            return trial
        side = np.sign(e_start + e_end)  # the direction the integral moves the output
        u_start, u_end = side * held_start, side * held_end
        over_start, over_end = u_start > limit, u_end > limit
        with np.errstate(divide="ignore", invalid="ignore"):
            cross = _unit_interval((limit - u_start) / (u_end - u_start))
        steady = e_start * e_end >= 0  # else: the error changes sign; decide at the end only
        s0 = np.where(steady & over_start & ~over_end, cross, 0.0)
        s1 = np.where(steady & over_end, np.where(over_start, 0.0, cross), 1.0)
        s0 = np.minimum(s0, s1)
        slope = e_end - e_start
        increment = 0.5 * period * (s1 - s0) * (2 * e_start + slope * (s0 + s1))
        trial = integral + increment
        u_trial = rest_end + ki * trial
    outward = (np.abs(u_trial) > limit) & (increment * u_trial > 0)
    if not np.count_nonzero(outward):
        return trial
    # Fraction of the increment that brings the output to the limit (0 if already beyond).
    edge = np.sign(u_trial) * limit
    step = ki * increment
    with np.errstate(divide="ignore", invalid="ignore"):
        fraction = _unit_interval((edge - rest_end - ki * integral) / step)
    fraction = np.where(step != 0, fraction, 0.0)
    return np.where(outward, integral + fraction * increment, trial)


#: The methods that discretise a sampled controller, and the weight alpha of the generalised
#: bilinear transform each is (:data:`cas_freq.core.sampling_config.ALPHA`).
METHODS = ALPHA


def check_method(method):
    """``method`` if it is one of :data:`METHODS`, else a ValueError naming it."""
    if method not in METHODS:
        raise ValueError(f"sampling method: expected one of {', '.join(METHODS)}, got "
                         f"{method!r}")
    return method


def derivative_filter(kd, tf, period, sampled=False, method="backward"):
    r"""Gain and update coefficients of the filtered derivative (module notes).

    The term is :math:`K_d (y - x_f)/T_f` with :math:`x_f^+ = a x_f + b y^- + c (y^+ - y^-)`.

    Parameters
    ----------
    kd : numpy.ndarray
        Derivative gain [output unit * s / input unit], shape (n_runs,).
    tf : numpy.ndarray
        Filter time constant [s] (ignored where kd = 0).
    period : float
        Update period T [s].
    sampled : bool
        A sampled controller, discretised by ``method`` (module notes), instead of the exact
        update for an input linear between updates.
    method : {"backward", "tustin"}
        The sampled controller's discretisation.

    Returns
    -------
    tuple of numpy.ndarray
        :math:`K_d/T_f` (0 where kd = 0) [output unit / input unit], and a, b, c [-].
    """
    safe_tf = np.where(kd > 0, tf, 1.0)
    gain_d = np.where(kd > 0, kd / safe_tf, 0.0)
    if sampled and check_method(method) == "tustin":
        a = (2.0 * safe_tf - period) / (2.0 * safe_tf + period)
        c = 0.5 * (1.0 - a)
    elif sampled:  # backward difference
        a = safe_tf / (safe_tf + period)
        c = 1.0 - a
    else:  # exact for an input linear between updates
        a = np.exp(-period / safe_tf)
        c = 1.0 - safe_tf * (1.0 - a) / period
    return gain_d, a, 1.0 - a, c


def _unit_interval(x):
    """``x`` clipped to [0, 1] (NaN stays NaN), cheaper than np.clip on small arrays."""
    return np.minimum(np.maximum(x, 0.0), 1.0)


class Controller:
    """PID with filtered derivative, clamp and anti-windup, for n_runs runs at once.

    Inputs may jump at an update instant (a step command): each update takes the inputs' left
    limits (the end of the interval just integrated) and right limits (the values from now on),
    and returns the output's left and right limits. Where the right limits are the left ones
    (the same array objects: the usual case, away from a jump of the command) each output is
    computed once and returned as the same array for both limits.

    Parameters
    ----------
    kp, ki, kd, tf, limit : numpy.ndarray
        Gains (proportional, integral [per s], derivative [s]), derivative filter time constant
        [s] (ignored where kd = 0) and output limit, shape (n_runs,).
    period : float
        Update period T [s].
    sampled : bool
        A sampled controller (discretised by ``method``, first update from zero samples
        before t = 0) instead of a continuous one.
    method : {"backward", "tustin"}
        A sampled controller's discretisation (module notes).
    """

    def __init__(self, kp, ki, kd, tf, limit, period, sampled=False, method="backward"):
        self.kp, self.ki, self.limit, self.period = kp, ki, limit, period
        self.sampled = sampled
        #: The integral's increment is T e_n (a sampled controller's backward difference).
        self.backward = sampled and check_method(method) == "backward"
        self.has_derivative = bool(np.any(kd > 0))
        n = kp.shape[0]
        if self.has_derivative:
            self._gain_d, self._a, self._b, self._c = derivative_filter(kd, tf, period, sampled,
                                                                        method)
        self._half_period = 0.5 * period
        self._lower = -limit
        self._unlimited = np.zeros(n, dtype=bool)
        self._unlimited.setflags(write=False)
        #: Whether some run's last right-limit output was clamped.
        self.clamped = False
        self.integral = np.zeros(n)
        self._ki_integral = ki * self.integral  # kept with the integral: ki * integral
        self._filter = np.zeros(n)
        self._e = np.zeros(n)
        self._y = np.zeros(n)
        self._rest = np.zeros(n)

    def start(self, e_left, e_right, y_left=None, y_right=None, ff_left=None, ff_right=None):
        """First outputs, at t = 0, from rest.

        A continuous controller starts with integral and filter state 0 (they are continuous
        states, the inputs' jump passes through the proportional and derivative terms); a sampled
        one makes its first update from zero samples before t = 0.

        Returns
        -------
        tuple of numpy.ndarray
            Clamped output's left and right limits, and where the right limit was clamped.
        """
        return self.update(e_left, e_right, y_left, y_right, ff_left, ff_right, self.sampled)

    def update(
        self, e_left, e_right, y_left=None, y_right=None, ff_left=None, ff_right=None,
        advance=True,
    ):
        """Advance one period, to error ``e`` and derivative input ``y`` (default ``e``).

        ``ff`` is the feed-forward term added to the output (None: none). With ``advance``
        False the states stay (the first outputs of a continuous controller, :meth:`start`).

        Returns
        -------
        tuple of numpy.ndarray
            Clamped output's left and right limits, and where the right limit was clamped.
        """
        jump = e_right is not e_left or y_right is not y_left or ff_right is not ff_left
        kp, ki = self.kp, self.ki
        rest_left = kp * e_left
        rest_right = kp * e_right if jump else None
        if self.has_derivative:
            y_left = e_left if y_left is None else y_left
            y_right = e_right if y_right is None else y_right
            state, y_before = self._filter, self._y
            if advance:
                state = self._a * state + self._b * y_before + self._c * (y_left - y_before)
                self._filter = state
            gain_d = self._gain_d
            rest_left = rest_left + gain_d * (y_left - state)
            if jump:
                rest_right = rest_right + gain_d * (y_right - state)
            self._y = y_right
        if ff_left is not None:
            rest_left = rest_left + ff_left
        if not jump:
            rest_right = rest_left
        elif ff_right is not None:
            rest_right = rest_right + ff_right
        within = False
        if advance:
            integral, e_before = self.integral, self._e
            if self.backward:
                trial = integral + self.period * e_left
            else:
                trial = integral + self._half_period * (e_before + e_left)
            ki_trial = ki * trial
            u_trial = rest_left + ki_trial
            # Where no run's output reaches its limit during the update,
            # integrate_with_anti_windup returns the trapezoidal step ``trial``: its tests are
            # |u_trial| > limit and, when locating clamp instants, the same for the output held
            # at the start (the previous right-limit output: ``clamped``) and at the end.
            if self.sampled:
                within = not np.count_nonzero(np.abs(u_trial) > self.limit)
            elif not self.clamped:
                held_end = rest_left + self._ki_integral
                largest = np.maximum(np.abs(u_trial), np.abs(held_end))
                within = not np.count_nonzero(largest > self.limit)
            if within:  # skip integrate_with_anti_windup's work
                self.integral, self._ki_integral = trial, ki_trial
            else:
                self.integral = integrate_with_anti_windup(
                    integral, e_before, e_left, self._rest, rest_left, ki, self.limit,
                    self.period, locate=not self.sampled, backward=self.backward,
                )
                self._ki_integral = ki * self.integral
        self._e = e_right
        self._rest = rest_right
        if within and not jump:  # the output is u_trial on both sides, inside the limits
            self.clamped = False
            return u_trial, u_trial, self._unlimited
        ki_integral = self._ki_integral
        u_left = u_trial if within else self._clamp(rest_left + ki_integral)
        u_right = rest_right + ki_integral
        limited = np.abs(u_right) > self.limit
        self.clamped = bool(np.count_nonzero(limited))
        if self.clamped:
            u_right = self._clamp(u_right)
        return u_left, u_right, limited

    def _clamp(self, u):
        return np.minimum(np.maximum(u, self._lower), self.limit)
