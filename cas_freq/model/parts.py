r"""The parts of the actuator loop, each written once, as arrays over variants (numpy only).

Every consumer of the model (frequency responses, characteristic polynomials, the closed-loop
state matrix, python-control systems and the nonlinear simulator) takes the plant and the
controllers from here, so a new term of the plant is added in this module only.

All in motor-shaft coordinates and SI (docs/model.md). A *polynomial* is a tuple of
coefficients, highest power of s first, each coefficient a float or an array that broadcasts
over variants (and frequencies):

.. math::
    Z_e(s) = L s + R, \qquad
    Y(s) = \frac{i}{V} = \frac{D}{Z_e D + K_e K_m s\, n_\theta}, \qquad
    M(s) = \frac{\theta}{i} = \frac{K_m n_\theta}{D}

with the drivetrain's polynomials :math:`D, n_\theta` of :func:`mechanics` (unloaded:
:math:`D = s (J s + \mu_v)`, :math:`n_\theta = 1`, the report's Fig. 5);

    C_i(s) = \frac{K_{p,i} s + K_{i,i}}{s}, \qquad
    C_p(s) = \frac{(K_p T_f + K_d) s^2 + (K_p + K_i T_f) s + K_i}{s (T_f s + 1)}

With the derivative on the measurement, the command sees only :math:`K_p + K_i/s`.
"""

import numpy as np

from cas_freq.core.parameters import LoopParameters

#: Below this many frequencies the plain Horner rule is faster (less Python overhead).
_REAL_ARITHMETIC_FROM = 512


def one_variant(params):
    """One variant as :class:`~cas_freq.core.parameters.LoopParameters` of one run.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig or cas_freq.core.parameters.LoopParameters
        A validated config, or loop parameters of exactly one run.
    """
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


def polymul(a, b):
    """Product of two polynomials (sequences of coefficients, highest power first, each a
    float or an array broadcasting over runs)."""
    out = [0.0] * (len(a) + len(b) - 1)
    for i, x in enumerate(a):
        for j, y in enumerate(b):
            out[i + j] = out[i + j] + x * y
    return tuple(out)


def polyadd(a, b):
    """Sum of two polynomials of possibly different degrees."""
    width = max(len(a), len(b))
    a = (0.0,) * (width - len(a)) + tuple(a)
    b = (0.0,) * (width - len(b)) + tuple(b)
    return tuple(x + y for x, y in zip(a, b, strict=True))


def product(polynomials):
    """Product of any number of polynomials ((1.0,) for none)."""
    out = (1.0,)
    for polynomial in polynomials:
        out = polymul(out, polynomial)
    return out


def stacked(coefficients, n):
    """A polynomial as an (n, degree + 1) array of coefficient rows, one row per variant."""
    return np.column_stack([np.broadcast_to(np.asarray(c, dtype=float), (n,))
                            for c in coefficients])


def electrical(p):
    """Winding impedance Z_e(s) = L s + R [ohm]."""
    return (p.L, p.R)


def compliance(p):
    """Gear compliance 1/K_g at the fin [rad/(N*m)], 0 for a rigid gear (K_g = 0 in a config)."""
    k_g = np.asarray(p.K_g, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(k_g > 0, 1.0 / np.where(k_g > 0, k_g, 1.0), 0.0)


def mechanics(p):
    r"""The drivetrain as three polynomials: :math:`\theta/i = K_m n_\theta / D` and the fin
    output :math:`N \delta / \theta = n_{out} / n_\theta` (docs/model.md, "Load and drivetrain").

    With the gear compliance :math:`c = 1/K_g` (0 for a rigid gear), the mesh damping
    :math:`c_g` in parallel with the spring, :math:`g = c\,c_g s + 1` (the gear's impedance
    :math:`K_g + c_g s` over :math:`K_g`) and :math:`e = 1/\eta`:

    .. math::
        D = (J s^2 + \mu_v s)\, n_\theta + \frac{e}{N^2}\, g\, (J_L s^2 + b_L s + K_h),
        \qquad n_\theta = c J_L s^2 + c b_L s + c K_h + g, \qquad n_{out} = g

    (the two-mass equations times c). For a rigid gear (c = 0), D is
    :math:`J_{eff} s^2 + \mu_{eff} s + k_{eff}` and :math:`n_\theta = 1`; without a load it is
    :math:`s (J s + \mu_v)`, the report's motor.

    Returns
    -------
    tuple of tuple
        (D [N*m*s^2/rad ...], n_theta [-], n_out [-]): coefficients, highest power first,
        each a float or an array broadcasting over runs. D has degree 4 where any run is
        compliant, else 2; n_theta degree 2, else 0.
    """
    e_n2 = 1.0 / (p.eta * p.ratio * p.ratio)
    if not np.any(np.asarray(p.K_g) > 0):
        return (p.J + e_n2 * p.J_L, p.mu_v + e_n2 * p.b_L, e_n2 * p.K_h), (1.0,), (1.0,)
    c = compliance(p)
    g1 = c * p.c_g  # the gear's impedance over K_g: g = (K_g + c_g s)/K_g = g1 s + 1
    q2, q1, q0 = c * p.J_L, c * p.b_L + g1, c * p.K_h + 1.0
    d = (p.J * q2,
         p.J * q1 + p.mu_v * q2 + e_n2 * g1 * p.J_L,
         p.J * q0 + p.mu_v * q1 + e_n2 * (p.J_L + g1 * p.b_L),
         p.mu_v * q0 + e_n2 * (p.b_L + g1 * p.K_h),
         e_n2 * p.K_h)
    return d, (q2, q1, q0), (g1, 1.0)


def back_emf_coupling(p):
    """K_e K_m [V*N*m*s/(rad*A)]: what the back-EMF adds to Z_e P_m in Y's denominator."""
    return p.Ke * p.Km


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


def plant_matrices(p, states=None, backdrive=False, engaged=True):
    r"""State-space plant of every variant, input the voltage and two external torques.

    Rigid gear (3 states :math:`(i, \omega, \theta)`), with the load reflected through the
    gear (:math:`e = 1/\eta` while the motor drives the fin, :math:`e = \eta_b` while the fin
    drives the motor, ``backdrive``):

    .. math::
        L \dot i = V - R i - K_e \omega, \qquad
        (J + e J_L/N^2) \dot\omega = K_m i - (\mu_v + e b_L/N^2) \omega
            - e K_h/N^2 \, \theta + \tau_m + e \tau_L / N, \qquad
        \dot\theta = \omega

    Compliant gear (5 states, adding the fin's :math:`(\omega_L, \delta)`), the gear's torque
    :math:`\tau_g = K_g (\theta/N - \delta) + c_g (\omega/N - \omega_L)` (spring and mesh
    damping) on the fin and :math:`e/N` of it braking the motor:

    .. math::
        J \dot\omega = K_m i - \mu_v \omega - \frac{e}{N}\tau_g + \tau_m,
        \qquad
        J_L \dot\omega_L = \tau_g - b_L \omega_L - K_h \delta + \tau_L,
        \qquad \dot\delta = \omega_L

    Without ``engaged`` the gear carries no torque (inside its backlash). In a batch
    with any compliant run every run has 5 states; a rigid run's fin states then follow the
    motor (:math:`\dot\omega_L = \dot\omega/N`, :math:`\dot\delta = \omega/N`).

    Parameters
    ----------
    p : LoopParameters or namespace
        Parameters as arrays of shape (n,).
    states : int, optional
        3 or 5; default 5 where any run is compliant, else 3.
    backdrive : bool
        Use the backdrive efficiency (power flowing from the fin to the motor).
    engaged : bool
        The gear's spring carries torque (False: inside the backlash).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        A of shape (n, states, states) [1/s] and B of shape (n, states, 3), inputs
        (V [V], tau_m [N*m] on the motor shaft, tau_L [N*m] on the fin).
    """
    n = np.broadcast(p.R, p.L, p.Ke, p.Km, p.J, p.mu_v, p.J_L, p.K_g, p.c_g).shape
    n = n[0] if n else 1
    compliant = np.broadcast_to(np.asarray(p.K_g) > 0, (n,))
    if states is None:
        states = 5 if compliant.any() else 3
    e = p.eta_b if backdrive else 1.0 / p.eta
    ratio = p.ratio
    rigid = ~compliant
    # rigid: the load reflected onto the motor shaft (zero load terms where compliant)
    j_l, b_l, k_h = (np.where(rigid, v, 0.0) for v in np.broadcast_arrays(p.J_L, p.b_L, p.K_h))
    j = p.J + e * j_l / ratio**2
    a = np.zeros((n, states, states))
    b = np.zeros((n, states, 3))
    a[:, 0, 0] = -p.R / p.L
    a[:, 0, 1] = -p.Ke / p.L
    a[:, 1, 0] = p.Km / j
    a[:, 1, 1] = -(p.mu_v + e * b_l / ratio**2) / j
    a[:, 1, 2] = -e * k_h / ratio**2 / j
    a[:, 2, 1] = 1.0
    b[:, 0, 0] = 1.0 / p.L
    b[:, 1, 1] = 1.0 / j
    b[:, 1, 2] = np.where(rigid, e / ratio / j, 0.0)
    if states == 3:
        if compliant.any():
            raise ValueError("a compliant gear needs 5 states")
        return a, b
    k_g = np.where(compliant & engaged, p.K_g, 0.0)
    c_g = np.where(compliant & engaged, p.c_g, 0.0)
    j_load = np.where(compliant, p.J_L, 1.0)
    column = np.broadcast_to(np.asarray(ratio, dtype=float), (n,))[:, None]  # per run
    a[:, 1, 1] -= e * c_g / ratio**2 / j
    a[:, 1, 2] -= e * k_g / ratio**2 / j
    a[:, 1, 3] = e * c_g / ratio / j
    a[:, 1, 4] = e * k_g / ratio / j
    a[:, 3] = np.where(compliant[:, None],
                       np.stack([np.zeros(n), c_g / ratio / j_load, k_g / ratio / j_load,
                                 -(p.b_L + c_g) / j_load + np.zeros(n),
                                 -(k_g + p.K_h) / j_load + np.zeros(n)], axis=1),
                       a[:, 1] / column)
    b[:, 3] = np.where(compliant[:, None],
                       np.stack([np.zeros(n), np.zeros(n), 1.0 / j_load], axis=1),
                       b[:, 1] / column)
    a[:, 4, 3] = np.where(compliant, 1.0, 0.0)
    a[:, 4, 1] = np.where(compliant, 0.0, 1.0 / ratio)
    return a, b


def current_plant_matrices(p):
    r"""V -> i of one variant without the modes the current does not see: (A, B, C).

    Unloaded or rigid without a hinge stiffness: the states (i, omega) (theta is not seen).
    Compliant without a hinge stiffness: the rigid-body position (theta and N delta moving
    together) is not seen; the states reduce to (i, omega, omega_L, theta/N - delta) with
    :math:`A_r = T A T^+` (A maps that direction to 0). With a hinge stiffness: every state.

    Returns
    -------
    tuple of numpy.ndarray
        A (m, m) [1/s], B (m, 1) [A/(V*s)], C (1, m) [-].
    """
    a, b = plant_matrices(p)
    a, b = a[0], b[0, :, :1]
    k_h = float(np.asarray(p.K_h).reshape(-1)[0])
    if k_h == 0 and a.shape[0] == 3:
        a, b = a[:2, :2], b[:2]
    elif k_h == 0:
        t = np.zeros((4, 5))
        t[0, 0] = t[1, 1] = t[2, 3] = 1.0
        t[3, 2], t[3, 4] = 1.0 / float(np.asarray(p.ratio).reshape(-1)[0]), -1.0
        a, b = t @ a @ np.linalg.pinv(t), t @ b
    c = np.zeros((1, a.shape[0]))
    c[0, 0] = 1.0
    return a, b, c


def fin_output(states, ratio):
    """Output row of N delta (the fin angle on the motor's scale) [rad] for a plant of
    ``states`` (3: theta itself; 5: N times the fin state delta)."""
    row = np.zeros(states)
    if states == 3:
        row[2] = 1.0
    else:
        row[4] = ratio
    return row
