"""The building blocks of the compiled loop (:mod:`cas_freq.simulation.kernel`): the columns of
its tables, the delay lines, the controllers and the filter chains, as scalar numba functions.

Each is the scalar form of its numpy reference (:mod:`~cas_freq.simulation.delay_line`,
:mod:`~cas_freq.simulation.controllers`, :mod:`~cas_freq.simulation.architecture`,
:mod:`~cas_freq.simulation.mechanics`), the operations in the same order; most are inlined
into the kernel's loop (``inline="always"``). Split from ``kernel.py``, which keeps the loop
over the steps and the tables.
"""

import cas_freq.simulation.mechanics as mech
from cas_freq.core.jit import cached_jit as _jit

# Columns of the parameter table ``p`` (n_runs, _NP), one row per run: the plant.
_PHI = 0  # Phi, row-major, 9 columns
_GA = 9  # G_a, 3 columns
_GB = 12  # G_b, 3 columns
_RATIO = 15  # gear ratio N [-]
_NP = 16

# Columns of the loop table (n_runs, n_loops, _NL), one row per loop, innermost first
# (architecture.loop_steps): its controller (gains, derivative filter coefficients of
# controllers.derivative_filter, clamp), feed-forward of the motor-angle command's rate and
# acceleration, derivative on the measurement, update period in steps (0: continuous), the
# backward difference of a sampled loop, the signal it measures (:data:`SIGNAL_CODES`), the delay
# after it (whole steps and fraction), whether some run of the batch has a derivative term or a
# feed-forward, and per filter chain (analog measurement, digital measurement, path, the
# derivative's input) its order (0: none), its first column in the chain table and its states'
# first column in the chain state, and one count of the encoder it reads (0: not quantised).
(_L_KP, _L_KI, _L_GD, _L_A, _L_B, _L_C, _L_LIMIT, _L_FF_V, _L_FF_A, _L_ON_MEASUREMENT,
 _L_EVERY, _L_BACKWARD, _L_SIGNAL, _L_M, _L_F, _L_HAS_D, _L_HAS_FF) = range(17)
_L_ANALOG, _L_SENSOR, _L_PATH = 17, 20, 23  # each: order, first column, first state column
_L_QUANTUM = 26
_L_DERIVATIVE = 27  # order, first column, first state column
_NL = 30

#: The code of each measured signal in the loop table (structure.SIGNALS).
SIGNAL_CODES = {"current": 0, "motor_velocity": 1, "motor_angle": 2, "output_angle": 3}

# Columns of the loop state (n_runs, n_loops, _NS): the controller (integral, derivative filter
# state, error, derivative input and output without the integral at the last update, right
# limits), its output's left and right limits (after the path filters), 1.0 where its right one
# was clamped, the reference read at its last update, its measurement through the analog filters
# at this step, and the last input of each filter chain.
(_S_INT, _S_FILTER, _S_E, _S_Y, _S_REST, _S_OUT_LEFT, _S_OUT, _S_LIMITED, _S_REF, _S_MEASURED,
 _S_ANALOG_U, _S_SENSOR_U, _S_PATH_U, _S_DERIVATIVE_U) = range(14)
_NS = 14

# Columns of the run state (n_runs, _NG).
_G_V = 0  # voltage at the motor terminals at the present step (right limit) [V]
_G_THETA_CMD = 1  # motor-angle command at the present step [rad]
_G_W_BEFORE = 2  # motor speed one step earlier [rad/s] (loaded runs)
_NG = 3

# The loaded plant's table (mechanics.table): per mode, the matrices; then the run's constants.
_PER_MODE = mech._PER_MODE
_M_PHI, _M_GA, _M_GB, _M_H, _M_A1, _M_B1 = mech.PHI, mech.GA, mech.GB, mech.H, mech.A1, mech.B1
_Q_COMPLIANT, _Q_K_G, _Q_HALF, _Q_TAU_H = (mech.COMPLIANT, mech.K_G, mech.HALF_PLAY,
                                           mech.TAU_H)
_Q_J_L, _Q_B_L, _Q_K_H, _Q_F_C = mech.J_LOAD, mech.B_LOAD, mech.K_HINGE, mech.F_COULOMB
_Q_E_FORWARD, _Q_E_BACK, _Q_LOADED = mech.E_FORWARD, mech.E_BACK, mech.LOADED
_Q_C_G, _Q_RATIO = mech.C_G, mech.RATIO
_FORWARD, _BACKDRIVE, _GAP, _HELD = mech.FORWARD, mech.BACKDRIVE, mech.GAP, mech.HELD

# --- delay lines (delay_line.py) --------------------------------------------------------------

@_jit()  # start_batch only
def _read(right, left, r, line, m, f, q, latest, want_left, hold):
    """Delayed signal at t_q of delay line ``line``, delay (m + f) dt, newest sample ``latest``
    (DelayLine.read), from ring buffers (n_runs, n_lines, 2**n slots), 0 before t = 0.

    Interpolating line: ``(1 - f) u^-[q - m] + f u^+[q - m - 1]`` (for f = 0 the right or left
    limit of sample q - m). Holding line: ``u[q - m - 1]`` if f > 0 or for the left limit,
    else ``u[q - m]``.
    """
    mask = right.shape[2] - 1
    if hold:
        j = min(q - m - (1 if (want_left or f > 0.0) else 0), latest)
        return right[r, line, j & mask] if j >= 0 else 0.0
    j = q - m
    if f == 0.0:
        if j < 0:
            return 0.0
        return left[r, line, j & mask] if want_left else right[r, line, j & mask]
    return ((1.0 - f) * (left[r, line, j & mask] if j >= 0 else 0.0)
            + f * (right[r, line, (j - 1) & mask] if j >= 1 else 0.0))


# --- controllers (controllers.py) -------------------------------------------------------------

@_jit()
def _clip_unit(x):
    """``x`` clipped to [0, 1]; NaN stays NaN (as np.minimum(np.maximum(x, 0), 1))."""
    if x < 0.0:
        return 0.0
    if x > 1.0:
        return 1.0
    return x


@_jit()
def _sign(x):
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return x  # 0 (or NaN)


@_jit()
def _clamp(u, limit):
    return min(max(u, -limit), limit)


@_jit(inline="always")
def _acceleration(q, r, mode, i, w, th, w_l, d_l, tau_m, tau_l):
    """The motor's acceleration [rad/s^2] in ``mode`` (mechanics.Drivetrain._acceleration)."""
    a1, b1 = mode * _PER_MODE + _M_A1, mode * _PER_MODE + _M_B1
    return (q[r, a1] * i + q[r, a1 + 1] * w + q[r, a1 + 2] * th + q[r, a1 + 3] * w_l
            + q[r, a1 + 4] * d_l + q[r, b1] * tau_m + q[r, b1 + 1] * tau_l)


@_jit(inline="always")
def _from_rest(q, r, mode, i, w, th, w_l, d_l, dz, c, tau_l, dt):
    """The mode of a shaft at rest, ``mode`` elsewhere (mechanics.Drivetrain._from_rest)."""
    ratio = q[r, _Q_RATIO]
    compliant = q[r, _Q_COMPLIANT] != 0.0
    k_g, c_g = q[r, _Q_K_G], q[r, _Q_C_G]
    j_l, b_l, k_h, tau_h = q[r, _Q_J_L], q[r, _Q_B_L], q[r, _Q_K_H], q[r, _Q_TAU_H]
    delta = th / ratio
    acc = _acceleration(q, r, _FORWARD, i, w, th, w_l, d_l, -(q[r, _Q_E_FORWARD] * c) / ratio,
                        tau_l)
    if not abs(w) <= abs(acc) * dt:
        return mode
    rate = acc * dt / ratio
    if compliant:
        power = (k_g * dz + c_g * (rate - w_l)) * rate
    else:
        power = (j_l * acc / ratio + b_l * rate + k_h * delta - tau_h) * rate
    if power >= 0.0:
        return _FORWARD
    acc = _acceleration(q, r, _BACKDRIVE, i, w, th, w_l, d_l, -(q[r, _Q_E_BACK] * c) / ratio,
                        tau_l)
    rate = acc * dt / ratio
    if compliant:
        power = (k_g * dz + c_g * (rate - w_l)) * rate
    else:
        power = (j_l * acc / ratio + b_l * rate + k_h * delta - tau_h) * rate
    return _BACKDRIVE if power < 0.0 else _HELD


@_jit(inline="always")
def _anti_windup(integral, e_start, e_end, rest_start, rest_end, ki, limit, period, locate,
                 backward):
    """New integral, conditional integration (controllers.integrate_with_anti_windup).

    With ``locate`` (continuous controllers) the instants where the clamp starts or ends inside
    the update are located on the output held at the old integral, and only the unclamped part
    is integrated; then an increment that would carry the output beyond the limit integrates
    only up to it (docs/model.md §3, anti-windup). ``backward``: a sampled controller's
    increment ``period * e_end`` instead of the trapezoidal rule.
    """
    if backward:
        increment = period * e_end
    else:
        increment = 0.5 * period * (e_start + e_end)
    trial = integral + increment
    u_trial = rest_end + ki * trial
    if locate:
        held = ki * integral
        held_start = rest_start + held
        held_end = rest_end + held
        if abs(u_trial) > limit or abs(held_start) > limit or abs(held_end) > limit:
            side = _sign(e_start + e_end)  # the direction the integral moves the output
            u_start, u_end = side * held_start, side * held_end
            over_start, over_end = u_start > limit, u_end > limit
            cross = _clip_unit((limit - u_start) / (u_end - u_start))
            steady = e_start * e_end >= 0  # else: the error changes sign; decide at the end
            s0 = cross if (steady and over_start and not over_end) else 0.0
            s1 = 1.0
            if steady and over_end:
                s1 = 0.0 if over_start else cross
            s0 = min(s0, s1)
            slope = e_end - e_start
            increment = 0.5 * period * (s1 - s0) * (2 * e_start + slope * (s0 + s1))
            trial = integral + increment
            u_trial = rest_end + ki * trial
    if abs(u_trial) > limit and increment * u_trial > 0:
        # only the fraction of the increment that brings the output to the limit
        step = ki * increment
        if step == 0.0:
            return integral
        edge = _sign(u_trial) * limit
        fraction = _clip_unit((edge - rest_end - ki * integral) / step)
        return integral + fraction * increment
    return trial


@_jit(inline="always")
def _controller_update(
    integral, state, e_before, y_before, rest_before, e_left, e_right, y_left, y_right,
    ff_left, ff_right, advance, kp, ki, gain_d, a, b, c, has_derivative, limit, period, locate,
    backward,
):
    r"""One update of a PI(D) controller with clamp and anti-windup (Controller.update).

    :math:`u = K_p e + K_i \int e + (K_d/T_f)(y - x_f) + u_{ff}`, the filter state advanced by
    :math:`x_f^+ = a x_f + b y^- + c (y^+ - y^-)`, the integral by the trapezoidal rule with
    anti-windup (``backward``: a sampled controller's backward difference, ``T e_n``); from the
    inputs' left limits (end of the interval) and right limits (from now on). ``advance``
    False: the first outputs of a continuous controller (states stay).

    Returns
    -------
    tuple of float
        integral, filter state, error, derivative input, rest (right limits, for the next
        update), clamped output's left and right limits, and 1.0 if the right one was clamped.
    """
    rest_left = kp * e_left
    rest_right = kp * e_right
    if has_derivative:
        if advance:
            state = a * state + b * y_before + c * (y_left - y_before)
        rest_left = rest_left + gain_d * (y_left - state)
        rest_right = rest_right + gain_d * (y_right - state)
        y_before = y_right
    rest_left = rest_left + ff_left
    rest_right = rest_right + ff_right
    if advance:
        integral = _anti_windup(
            integral, e_before, e_left, rest_before, rest_left, ki, limit, period, locate,
            backward,
        )
    ki_integral = ki * integral
    u_left = _clamp(rest_left + ki_integral, limit)
    u_right = rest_right + ki_integral
    limited = 0.0
    if abs(u_right) > limit:
        limited = 1.0
        u_right = _clamp(u_right, limit)
    return integral, state, e_right, y_before, rest_right, u_left, u_right, limited


# --- filters (architecture.py) ---------------------------------------------------------------

@_jit(inline="always")  # numba-level: array arguments cost a call
def _chain(g, gs, r, start, m, z, u_a, u_b, first):
    """Step the filter chain of order ``m`` whose table starts at column ``start`` of ``g``
    (its states at columns ``z`` .. ``z + m`` of ``gs``, scratch after them) over one step
    for an input linear from ``u_a`` to ``u_b`` (FilterState.step); returns C z_k+1 and the
    direct term D (the output is ``C z + D u``). ``first``: the outputs at t = 0 from rest
    (C z = 0, no step)."""
    d = g[r, start + m * m + 3 * m]
    if first:
        return 0.0, d
    g_a, g_b, c = start + m * m, start + m * m + m, start + m * m + 2 * m
    for i in range(m):
        acc = 0.0
        for j in range(m):
            acc += g[r, start + i * m + j] * gs[r, z + j]
        acc += g[r, g_a + i] * u_a
        acc += g[r, g_b + i] * u_b
        gs[r, z + m + i] = acc
    y = 0.0
    for i in range(m):
        gs[r, z + i] = gs[r, z + m + i]
        y += g[r, c + i] * gs[r, z + i]
    return y, d
