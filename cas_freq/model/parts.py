r"""The parts of the actuator loop, each written once, as arrays over variants (numpy only).

Every consumer of the model (frequency responses, characteristic polynomials, the closed-loop
state matrix, python-control systems and the nonlinear simulator) takes the plant and the
controllers from here, so a new term of the plant is added in this module only.

All in motor-shaft coordinates and SI (docs/model.md). A *polynomial* is a tuple of
coefficients, highest power of s first, each coefficient a float or an array that broadcasts
over variants (and frequencies):

.. math::
    Z_e(s) = L s + R, \qquad P_m(s) = J s + \mu_v, \qquad
    Y(s) = \frac{i}{V} = \frac{P_m}{Z_e P_m + K_e K_m}, \qquad
    M(s) = \frac{\theta}{i} = \frac{K_m}{s P_m}

    C_i(s) = \frac{K_{p,i} s + K_{i,i}}{s}, \qquad
    C_p(s) = \frac{(K_p T_f + K_d) s^2 + (K_p + K_i T_f) s + K_i}{s (T_f s + 1)}

With the derivative on the measurement, the command sees only :math:`K_p + K_i/s`.
"""

import numpy as np

#: Below this many frequencies the plain Horner rule is faster (less Python overhead).
_REAL_ARITHMETIC_FROM = 512


def one_variant(params):
    """One variant as :class:`~cas_freq.parameters.LoopParameters` of one run.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig or cas_freq.parameters.LoopParameters
        A validated config, or loop parameters of exactly one run.
    """
    from cas_freq.parameters import LoopParameters

    if not isinstance(params, LoopParameters):
        params = LoopParameters.from_config(params)
    if params.n_runs != 1:
        raise ValueError(f"one variant expected, got {params.n_runs}")
    return params


def polyval(coefficients, s):
    """Value of a polynomial (tuple of broadcastable coefficients) at ``s``.

    Horner's rule in complex arithmetic; on the imaginary axis (``s = j omega``, every
    frequency response) the real and imaginary parts are summed in real arithmetic instead,
    about twice as fast for the same value.
    """
    s = np.asarray(s)
    if s.size >= _REAL_ARITHMETIC_FROM and np.iscomplexobj(s) and not s.real.any():
        return _polyval_imaginary(coefficients, s.imag)
    value = coefficients[0]
    for coefficient in coefficients[1:]:
        value = value * s + coefficient
    return value


def _polyval_imaginary(coefficients, w):
    """sum c_k (j w)^k: even powers give the real part (signs + - + ...), odd the imaginary."""
    parts = [0.0, 0.0]  # real, imaginary
    power = None
    for k, coefficient in enumerate(reversed(coefficients)):
        term = coefficient if power is None else coefficient * power
        sign = 1.0 if k % 4 < 2 else -1.0
        parts[k % 2] = parts[k % 2] + (term if sign > 0 else -term)
        power = w if power is None else power * w
    real, imaginary = parts
    out = np.empty(np.broadcast_shapes(np.shape(real), np.shape(imaginary)), dtype=complex)
    out.real = real
    out.imag = imaginary
    return out


def stacked(coefficients, n):
    """A polynomial as an (n, degree + 1) array of coefficient rows, one row per variant."""
    return np.column_stack([np.broadcast_to(np.asarray(c, dtype=float), (n,))
                            for c in coefficients])


def electrical(p):
    """Winding impedance Z_e(s) = L s + R [ohm]."""
    return (p.L, p.R)


def mechanical(p):
    """Shaft impedance divided by s, P_m(s) = J s + mu_v [N*m*s/rad]: torque / speed."""
    return (p.J, p.mu_v)


def back_emf_coupling(p):
    """K_e K_m [V*N*m*s/(rad*A)]: what the back-EMF adds to Z_e P_m in Y's denominator."""
    return p.Ke * p.Km


def current_controller(p):
    """Numerator of C_i(s) = (Kp s + Ki) / s [V/A]."""
    return (p.ci_Kp, p.ci_Ki)


def position_controller(p):
    """Numerator of C_p(s) over s (Tf s + 1) [A/rad] (filtered derivative on the error)."""
    return (p.cp_Kp * p.Tf + p.cp_Kd, p.cp_Kp + p.cp_Ki * p.Tf, p.cp_Ki)


def position_filter(p):
    """The derivative filter T_f s + 1 [-] (C_p's denominator is s times this)."""
    return (p.Tf, 1.0)


def reference_path(p):
    """Numerator over s of what acts on the command with the derivative on the measurement:
    K_p + K_i/s = (Kp s + Ki)/s [A/rad]."""
    return (p.cp_Kp, p.cp_Ki)


def plant_matrices(p):
    r"""State-space plant of every variant: states (i, omega, theta), input the voltage.

    .. math::
        L \dot i = V - R i - K_e \omega, \qquad J \dot\omega = K_m i - \mu_v \omega, \qquad
        \dot\theta = \omega

    Parameters
    ----------
    p : LoopParameters or namespace
        Parameters as arrays of shape (n,).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        A of shape (n, 3, 3) [1/s] and B of shape (n, 3, 1) [A/(V*s)].
    """
    n = np.broadcast(p.R, p.L, p.Ke, p.Km, p.J, p.mu_v).shape
    n = n[0] if n else 1
    a = np.zeros((n, 3, 3))
    a[:, 0, 0] = -p.R / p.L
    a[:, 0, 1] = -p.Ke / p.L
    a[:, 1, 0] = p.Km / p.J
    a[:, 1, 1] = -p.mu_v / p.J
    a[:, 2, 1] = 1.0
    b = np.zeros((n, 3, 1))
    b[:, 0, 0] = 1.0 / p.L
    return a, b
