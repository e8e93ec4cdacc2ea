r"""Rational factors of the actuator loops and their frequency responses (numpy only).

All in motor-shaft coordinates and SI (MODEL.md):

.. math::
    Y(s) = \frac{i}{V} = \frac{Js + \mu_v}{(Ls + R)(Js + \mu_v) + K_e K_m}, \qquad
    M(s) = \frac{\theta}{i} = \frac{K_m}{s (Js + \mu_v)}

    C_i(s) = K_{p,i} + \frac{K_{i,i}}{s}, \qquad
    C_p(s) = K_p + \frac{K_i}{s} + \frac{K_d s}{T_f s + 1}

    L_i = C_i e^{-s\tau_c} Y, \quad T_i = \frac{L_i}{1 + L_i}, \quad
    L_p = C_p e^{-s\tau_p} T_i M, \quad S = \frac{1}{1 + L_p}, \quad T = \frac{L_p}{1 + L_p}

With the derivative on the measurement, only the reference path changes:
:math:`T = (K_p + K_i/s) e^{-s\tau_p} T_i M / (1 + L_p)`; :math:`L_p` and :math:`S` are the
same. Feed-forward :math:`F(s) = FF_v s + FF_a s^2` is not part of T (MODEL.md: zero for the
report's tests); ``closed_loop(s, feedforward=True)`` gives
:math:`(C_r + F) e^{-s\tau_p} T_i M / (1 + L_p)` for commands with a usable rate.

Evaluating the factors separately keeps every polynomial at degree <= 3, so the responses stay
accurate at any frequency, with exact delays or Padé delays of any order.
"""

import dataclasses

import numpy as np

from cas_freq.model.delay import EXACT


@dataclasses.dataclass(frozen=True)
class Rational:
    """A ratio of polynomials in s, coefficients highest power first."""

    num: tuple
    den: tuple

    def __call__(self, s):
        """Value at complex frequencies ``s`` [rad/s]."""
        s = np.asarray(s, dtype=complex)
        return np.polyval(self.num, s) / np.polyval(self.den, s)

    def trimmed(self):
        """(num, den) as arrays without leading zeros, for building systems."""
        return np.trim_zeros(np.asarray(self.num, float), "f"), np.trim_zeros(
            np.asarray(self.den, float), "f"
        )


def current_plant(motor):
    """Y(s) = i/V [A/V] of the motor with back-EMF."""
    mu = motor.viscous_friction
    return Rational(
        (motor.J, mu),
        (motor.L * motor.J, motor.L * mu + motor.R * motor.J, motor.R * mu + motor.Ke * motor.Km),
    )


def mechanics(motor):
    """M(s) = theta/i [rad/A]: torque constant into the rotor inertia and viscous friction."""
    return Rational((motor.Km,), (motor.J, motor.viscous_friction, 0.0))


def current_controller(loop):
    """C_i(s) = Kp + Ki/s [V/A]."""
    return Rational((loop.Kp, loop.Ki), (1.0, 0.0))


def position_controller(loop):
    """C_p(s) = Kp + Ki/s + Kd s/(Tf s + 1) [A/rad], on one denominator s (Tf s + 1)."""
    tf = loop.filter_time_constant
    return Rational(
        (loop.Kp * tf + loop.Kd, loop.Kp + loop.Ki * tf, loop.Ki),
        (tf, 1.0, 0.0),
    )


def position_reference_path(loop):
    """Controller acting on the command: C_p, or Kp + Ki/s with the derivative on measurement."""
    if loop.derivative_on == "measurement":
        return Rational((loop.Kp, loop.Ki), (1.0, 0.0))
    return position_controller(loop)


class ActuatorLoops:
    """Frequency responses of every loop of one actuator, for one delay model.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        Validated parameters (SI).
    delay : DelayModel, optional
        Exact delays (default) or Padé of some order.

    Notes
    -----
    Each method takes complex frequencies ``s`` [rad/s] (use ``1j * omega``) and returns the
    complex response, vectorised over ``s``.
    """

    def __init__(self, params, delay=EXACT):
        self.params = params
        self.delay = delay
        self._y = current_plant(params.motor)
        self._m = mechanics(params.motor)
        self._ci = current_controller(params.current_loop)
        self._cp = position_controller(params.position_loop)
        self._cr = position_reference_path(params.position_loop)
        self._ff = Rational(
            (params.position_loop.ff_a, params.position_loop.ff_v, 0.0), (1.0,)
        )
        self._tau_c = params.current_loop.delay
        self._tau_p = params.position_loop.delay

    def current_loop(self, s):
        """L_i(s) = C_i(s) e^(-s tau_c) Y(s), broken at the voltage [-]."""
        return self._ci(s) * self.delay.response(s, self._tau_c) * self._y(s)

    def current_closed_loop(self, s):
        """T_i(s) = L_i/(1 + L_i) = i/i_cmd [-]."""
        loop = self.current_loop(s)
        return loop / (1.0 + loop)

    def _plant_seen_by_position(self, s):
        """e^(-s tau_p) T_i(s) M(s) = theta / (position controller output) [rad/A]."""
        return self.delay.response(s, self._tau_p) * self.current_closed_loop(s) * self._m(s)

    def position_loop(self, s):
        """L_p(s) = C_p(s) e^(-s tau_p) T_i(s) M(s), broken at the current command [-]."""
        return self._cp(s) * self._plant_seen_by_position(s)

    def sensitivity(self, s):
        """S(s) = 1/(1 + L_p) [-]."""
        return 1.0 / (1.0 + self.position_loop(s))

    def closed_loop(self, s, feedforward=False):
        """T(s) = theta/theta_cmd = delta/delta_cmd [-].

        With ``feedforward=True`` the command also drives i_ff = ff_v s + ff_a s^2 (added before
        the clamp, so it goes through tau_p like the controller output).
        """
        plant = self._plant_seen_by_position(s)
        reference = self._cr(s) + (self._ff(s) if feedforward else 0.0)
        return reference * plant / (1.0 + self._cp(s) * plant)

    @property
    def total_delay(self):
        """Sum of both transport delays [s] (sets how finely a grid must sample the phase)."""
        return self._tau_c + self._tau_p
