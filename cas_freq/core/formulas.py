"""Closed-form relations quoted by ARL-TR-9136, as plain functions of SI values.

This module sits at the bottom of the package: it imports nothing from cas_freq, so both the
parameter table (:mod:`cas_freq.core.parameters`, which derives the viscous friction for a config
and
for a batch of samples alike) and the analysis layer (which reports the second-order bandwidth)
can use it.
"""

import math

import numpy as np

#: |T| at the bandwidth relative to |T(0)| (docs/model.md: 3.01 dB below): 1/sqrt(2) = -3.0103 dB.
HALF_POWER = 1.0 / math.sqrt(2.0)


def viscous_friction_from_no_load(torque_constant, no_load_speed, no_load_current):
    r"""Viscous friction coefficient from the motor's no-load point.

    At no load the motor torque only overcomes friction, so :math:`K_m I_0 = \mu_v \omega_0`:

    .. math:: \mu_v = \frac{K_m I_0}{\omega_0}, \qquad \omega_0 = n_0 \frac{2\pi}{60}

    (ARL-TR-9136 §6; the report prints :math:`n_0` = 16,300 "rad/s" but the formula and its
    result 1.341e-6 N·m·s/rad hold only for rpm, see docs/model.md.)

    Parameters
    ----------
    torque_constant : float or numpy.ndarray
        Motor torque constant :math:`K_m` [N*m/A].
    no_load_speed : float or numpy.ndarray
        No-load speed :math:`\omega_0` [rad/s] (already converted from rpm), > 0.
    no_load_current : float or numpy.ndarray
        No-load current :math:`I_0` [A].

    Returns
    -------
    float or numpy.ndarray
        Viscous friction :math:`\mu_v` [N*m*s/rad]: a float for floats, else an array of the
        arguments' broadcast shape.
    """
    if not np.all(np.greater(no_load_speed, 0)):
        raise ValueError(f"no_load_speed: must be > 0 rad/s, got {no_load_speed!r}")
    return torque_constant * no_load_current / no_load_speed


def worm_efficiencies(lead_angle, friction_coefficient, pressure_angle):
    r"""Forward and backdrive efficiencies of a worm gear from its geometry and friction.

    With the lead angle :math:`\lambda`, the normal pressure angle :math:`\phi_n` and the
    friction coefficient :math:`f` of the mesh (Shigley's Mechanical Engineering Design, the
    worm-gear efficiency), the worm driving the wheel and the wheel driving the worm give

    .. math::
        \eta = \frac{\cos\phi_n - f \tan\lambda}{\cos\phi_n + f \cot\lambda}, \qquad
        \eta_b = \frac{\cos\phi_n - f \cot\lambda}{\cos\phi_n + f \tan\lambda}

    and a worm whose :math:`\eta_b \le 0` is self-locking: the wheel cannot drive it
    (:math:`\eta_b` = 0 then).

    Parameters
    ----------
    lead_angle : float
        Lead angle :math:`\lambda` of the worm [rad], in (0, pi/2).
    friction_coefficient : float
        Friction coefficient :math:`f` of the mesh [-], >= 0.
    pressure_angle : float
        Normal pressure angle :math:`\phi_n` [rad], in [0, pi/2).

    Returns
    -------
    tuple of float
        (:math:`\eta`, :math:`\eta_b`) [-], each in [0, 1].
    """
    cos_n, tan_l = math.cos(pressure_angle), math.tan(lead_angle)
    f = friction_coefficient
    forward = (cos_n - f * tan_l) / (cos_n + f / tan_l)
    back = (cos_n - f / tan_l) / (cos_n + f * tan_l)
    return max(forward, 0.0), max(back, 0.0)


def disc_inertia(diameter, thickness, density, bore=0.0):
    r"""Moment of inertia of a solid disc (a cylinder, optionally bored) about its axis.

    .. math:: J = \frac{\pi \rho t}{32} (D^4 - d^4)

    (:math:`\frac{1}{2} m (R^2 + r^2)` with :math:`m = \rho \pi t (R^2 - r^2)`).

    Parameters
    ----------
    diameter, thickness, bore : float
        Outer diameter D, thickness t and bore d [m].
    density : float
        Density :math:`\rho` [kg/m^3].

    Returns
    -------
    float
        J [kg*m^2].
    """
    return math.pi * density * thickness * (diameter**4 - bore**4) / 32.0


def second_order_bandwidth(natural_frequency, damping_ratio):
    r"""-3 dB bandwidth of the standard second-order closed loop.

    For :math:`T(s) = \omega_n^2 / (s^2 + 2\zeta\omega_n s + \omega_n^2)` the frequency where
    :math:`|T(j\omega)|^2 = 1/2` is

    .. math::
        \omega_{BW} = \omega_n \sqrt{(1 - 2\zeta^2) + \sqrt{4\zeta^4 - 4\zeta^2 + 2}}

    (ARL-TR-9136 §7, its ref. 5). A pure delay :math:`t_d` in front does not change the magnitude,
    so the formula also holds for the report's second-order-plus-delay model.

    Parameters
    ----------
    natural_frequency : float
        Natural frequency :math:`\omega_n` [rad/s], > 0.
    damping_ratio : float
        Damping ratio :math:`\zeta` [-], >= 0.

    Returns
    -------
    float
        Bandwidth :math:`\omega_{BW}` [rad/s].

    Examples
    --------
    >>> round(second_order_bandwidth(462.0, 0.54))
    566
    """
    if not natural_frequency > 0:
        raise ValueError(f"natural_frequency: must be > 0 rad/s, got {natural_frequency!r}")
    if not damping_ratio >= 0:
        raise ValueError(f"damping_ratio: must be >= 0, got {damping_ratio!r}")
    # wn^2 (a + sqrt(a^2 + 1)) with a = 1 - 2 zeta^2 (4 zeta^4 - 4 zeta^2 + 2 = a^2 + 1); for
    # a < 0 (zeta > 0.707) the sum cancels, so it is written 1 / (sqrt(a^2 + 1) - a), which
    # does not (at zeta = 1e4 the direct form rounds to 0 or below)
    a = 1.0 - 2.0 * damping_ratio * damping_ratio  # inf, not OverflowError, at 1e200
    root = math.hypot(a, 1.0)
    return natural_frequency * math.sqrt(a + root if a >= 0 else 1.0 / (root - a))


# --- the second-order step fit (cas_freq.simulation.second_order, its compiled kernels in
# cas_freq.simulation.fit_kernel) ---------------------------------------------------------

#: Terms of the power series in x = (1 - zeta^2) s^2 (|x| < 1): the 12th is below 1e-20.
SERIES_TERMS = 12
#: Coefficients of C = sum c_k (-x)^k, S / s = sum s_k (-x)^k, D / s^3 = sum d_k (-x)^k.
C_SERIES = np.array([1.0 / math.factorial(2 * k) for k in range(SERIES_TERMS)])
S_SERIES = np.array([1.0 / math.factorial(2 * k + 1) for k in range(SERIES_TERMS)])
D_SERIES = np.array([-(2 * k + 2) / math.factorial(2 * k + 3) for k in range(SERIES_TERMS)])

#: Lower bounds of the scaled variables (wn / wn0, zeta, td / td_scale); the upper bound of the
#: third is t_end / td_scale, of the others infinity (as in fit_second_order).
_LOWER = np.array([1e-6, 0.0, 0.0])

#: Levenberg-Marquardt stops a run when an accepted step lowers its sum of squares by less than
#: this fraction (least_squares in fit_second_order: 1e-14). Within ~1e-7 of the minimum then,
#: where _refine's Newton steps take over; stopping at 1e-12 saves a fifth of the iterations
#: but can leave a slowly zigzagging overdamped fit 1e-4 short.
_FTOL = 1e-15

#: Most relative move of the variables that _refine accepts (larger: the start was not near a
#: minimum, and it is kept).
_MOVE = 1e-4
