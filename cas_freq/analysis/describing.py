r"""Describing functions of the actuator's nonlinearities and the linear parts they see
(docs/model.md, "15. What the flight-control system sees", "Limit cycles").

A nonlinearity y = f(x) driven by x = A sin(ωt) has the first harmonic N(A)·A sin(ωt) of its
output (all three below are odd, single-valued and memoryless, so N is real). The rest of the
loop, all of it linear, gives x = −G(s) y, and a limit cycle of amplitude A and frequency ω
satisfies the harmonic balance 1 + N(A) G(jω) = 0.

The three nonlinearities of the model (docs/model.md §5, §3, §4) and where they sit:

- **backlash** (``gear.backlash`` b): the gear's spring and damper carry no torque inside the
  play. With the twist x = θ/N − δ and the dead zone y = dz(x) of half-width d = b/2, the
  spring and damper torque is exactly τ_g = (K_g + c_g s) y (in contact ẏ = ẋ, inside the play
  y and ẏ are 0), so the nonlinearity is the dead zone and G is the loop with the gear's
  spring removed, seen from the twist;
- **Coulomb friction** (``motor.coulomb_friction`` F_c): the torque −F_c sign(ω) on the motor
  shaft, a relay on the motor speed; G is the speed per unit torque applied to the motor shaft
  with every loop closed;
- **saturation** of a controller's output (the clamps ±V_max, ±I_max, ±ω_max): G is the loop
  broken at that controller's output with every other loop closed (L_k,aat of §13).
"""

import numpy as np

from cas_freq.model import parts
from cas_freq.model.structure import build


def dead_zone(amplitude, half_width):
    r"""Describing function of a unit-slope dead zone of half-width d [-].

    .. math:: N(A) = 1 - \frac{2}{\pi}\left(\arcsin\frac{d}{A}
              + \frac{d}{A}\sqrt{1 - \frac{d^2}{A^2}}\right), \quad A > d

    and 0 for A ≤ d (Gelb and Vander Velde, *Multiple-input describing functions*, 1968,
    App. B; Slotine and Li, *Applied nonlinear control*, 1991, §5.3).

    Parameters
    ----------
    amplitude : array_like
        Input amplitude A [unit of the input].
    half_width : float
        d = b/2 for a total play b [same unit].
    """
    a = np.asarray(amplitude, dtype=float)
    return np.where(a > half_width, 1.0 - saturation(a, half_width), 0.0)


def saturation(amplitude, limit):
    r"""Describing function of a unit-slope saturation at ±a [-].

    .. math:: N(A) = \frac{2}{\pi}\left(\arcsin\frac{a}{A}
              + \frac{a}{A}\sqrt{1 - \frac{a^2}{A^2}}\right), \quad A > a

    and 1 for A ≤ a (the same references; a dead zone of half-width a is 1 minus it).
    """
    a = np.asarray(amplitude, dtype=float)
    r = np.clip(limit / np.where(a > 0, a, np.inf), 0.0, 1.0)
    return np.where(a > limit, (2.0 / np.pi) * (np.arcsin(r) + r * np.sqrt(1.0 - r * r)), 1.0)


def relay(amplitude, level):
    r"""Describing function of an ideal relay ±F [output unit per input unit]:
    N(A) = 4F/(πA) (the first Fourier coefficient of a square wave of height F)."""
    return 4.0 * level / (np.pi * np.asarray(amplitude, dtype=float))


def _inverse(function, target, low, high, increasing):
    """The A in [low, high] where ``function(A) = target``, by bisection on a log scale
    (vectorised over ``target``)."""
    low = np.full(np.shape(target), float(low))
    high = np.full(np.shape(target), float(high))
    for _ in range(200):
        mid = np.sqrt(low * high)
        above = function(mid) > target
        if increasing:
            high, low = np.where(above, mid, high), np.where(above, low, mid)
        else:
            low, high = np.where(above, mid, low), np.where(above, high, mid)
    return np.sqrt(low * high)


def dead_zone_amplitude(n, half_width):
    """The amplitude A > d where the dead zone's N(A) = n (0 < n < 1)."""
    return _inverse(lambda a: dead_zone(a, half_width), n, half_width, half_width * 1e12,
                    increasing=True)


def saturation_amplitude(n, limit):
    """The amplitude A > a where the saturation's N(A) = n (0 < n < 1)."""
    return _inverse(lambda a: saturation(a, limit), n, limit, limit * 1e12, increasing=False)


# --- the linear parts ------------------------------------------------------------------------

def controller_law(p, s, structure=None):
    r"""The loops as one law V = −(C_i i + C_θ θ + C_y N δ) at the complex frequencies ``s``.

    From the declared structure (:func:`cas_freq.model.structure.build`): loop k's forward path
    from its error to the voltage is :math:`P_k = \prod_{j \le k} C_j \cdot path_j \cdot
    e^{-s\tau_j}`, and it measures its plant signal through its sensor filters H_k, so
    V = −Σ_k P_k H_k z_k. The current adds to C_i, the motor angle (and the motor speed s θ)
    to C_θ, the output angle N δ to C_y.

    Parameters
    ----------
    p : types.SimpleNamespace
        One run's parameters, scalars (:class:`cas_freq.model.loops.Selector`).
    s : numpy.ndarray
        Complex frequencies [rad/s].
    structure : cas_freq.model.structure.Structure, optional
        ``build(p)``, if already built (a search evaluates the law many times).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray, numpy.ndarray)
        C_i [V/A], C_θ [V/rad], C_y [V/rad].
    """
    law = {"current": 0j, "motor_angle": 0j, "output_angle": 0j}
    path = 1.0 + 0j
    for loop in (structure or build(p)).loops:
        for block in (loop.controller, *loop.path):
            path = path * parts.polyval(block.numerator, s) / parts.polyval(block.denominator, s)
        path = path * np.exp(-s * loop.delay)
        sensed = path
        for block in loop.sensor:
            sensed = sensed * parts.polyval(block.numerator, s) / parts.polyval(
                block.denominator, s)
        if loop.feedback == "motor_velocity":
            law["motor_angle"] = law["motor_angle"] + sensed * s
        else:
            law[loop.feedback] = law[loop.feedback] + sensed
    return law["current"], law["motor_angle"], law["output_angle"]


def _motor_side(p, s, structure=None):
    r"""The motor shaft with the loops closed through the winding: Q_θ = P_m + C_e (K_e s + C_θ)
    and C_e C_y, with C_e = K_m/(Z_e + C_i), P_m = J s² + μ_v s (the torque per motor angle
    the shaft needs, the loops' share included; the output-angle feedback's share separate)."""
    c_i, c_theta, c_y = controller_law(p, s, structure)
    c_e = p.Km / (p.L * s + p.R + c_i)
    q_theta = p.J * s * s + p.mu_v * s + c_e * (p.Ke * s + c_theta)
    return q_theta, c_e * c_y


def twist_loop(p, s, structure=None):
    r"""G of the backlash: the twist x = θ/N − δ per unit dead-zone output y, negated, with the
    gear's spring and damper acting only through y (τ_g = (K_g + c_g s) y) and every loop
    closed. With P_L = J_L s² + b_L s + K_h, the motor shaft :func:`_motor_side`, η the gear's
    efficiency and y_p = N δ the position loop's output measurement (or θ):

    .. math::
        \delta = \frac{\tau_g}{P_L}, \qquad
        \theta = -\frac{\tau_g/(\eta N) + C_e C_y N \delta}{Q_\theta}, \qquad
        G = -\frac{\theta/N - \delta}{y}

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        G [-] and the output per unit dead-zone output δ/y [-].
    """
    q_theta, c_ey = _motor_side(p, s, structure)
    n = p.ratio
    gear = p.K_g + p.c_g * s
    delta = gear / (p.J_L * s * s + p.b_L * s + p.K_h)
    theta = -(gear / (p.eta * n) + c_ey * n * delta) / q_theta
    return -(theta / n - delta), delta


def speed_loop(p, s, structure=None):
    r"""G of the Coulomb friction: the motor speed per unit torque applied to the motor shaft,
    every loop closed (the friction −F_c sign ω is that torque, so x = ω = −G y).

    Rigid gear (the load reflected into P_eff = P_m + P_L/(η N²), y_p = θ):
    :math:`\theta/\tau = 1/(Q_\theta + P_L/(\eta N^2) + C_e C_y)`. Compliant gear (K = K_g +
    c_g s; the fin δ = K θ/(N (P_L + K))):

    .. math::
        \frac{\theta}{\tau} = 1 \Big/ \left(Q_\theta + \frac{K}{\eta N^2}
        + \left(C_e C_y N - \frac{K}{\eta N}\right)\frac{K}{N (P_L + K)}\right)

    and G = s θ/τ. Returns G [rad/(s·N·m)] and the output per unit torque δ/τ [rad/(N·m)].
    """
    q_theta, c_ey = _motor_side(p, s, structure)
    n = p.ratio
    load = p.J_L * s * s + p.b_L * s + p.K_h
    if p.K_g > 0:
        gear = p.K_g + p.c_g * s
        follows = gear / (n * (load + gear))  # delta per theta
        theta = 1.0 / (q_theta + gear / (p.eta * n * n)
                       + (c_ey * n - gear / (p.eta * n)) * follows)
        return s * theta, follows * theta
    theta = 1.0 / (q_theta + load / (p.eta * n * n) + c_ey)
    return s * theta, theta / n


def clamp_to_output(p, s, loop_at_a_time):
    r"""The output per unit of the outermost controller's (clamped) output, every loop closed
    but that one: :math:`\delta/u = (L_{top}/C_{top}) (N\delta/y_p)/N`, with L_top the loop
    broken at that controller's output (``loop_at_a_time``, evaluated at ``s``), C_top the
    controller and y_p what it measures (N δ, or θ with N δ/θ = n_out/n_θ of the compliant
    gear) [rad per unit of the clamped signal]."""
    loop = build(p).loops[-1]
    controller = (parts.polyval(loop.controller.numerator, s)
                  / parts.polyval(loop.controller.denominator, s))
    seen = 1.0
    if loop.feedback == "motor_angle" and p.K_g > 0:
        _, n_theta, n_out = parts.mechanics(p)
        seen = parts.polyval(n_out, s) / parts.polyval(n_theta, s)
    return loop_at_a_time / controller * seen / p.ratio
