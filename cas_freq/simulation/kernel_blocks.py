"""The building blocks of the compiled loop (:mod:`cas_freq.simulation.kernel`): the columns of
its tables, the delay lines, the controllers and the inner blocks, as scalar numba functions.

Each is the scalar form of its numpy reference (:mod:`~cas_freq.simulation.delay_line`,
:mod:`~cas_freq.simulation.controllers`, :mod:`~cas_freq.simulation.architecture`,
:mod:`~cas_freq.simulation.mechanics`), the operations in the same order; most are inlined
into the kernel's loop (``inline="always"``). Split from ``kernel.py``, which keeps the loop
over the steps and the tables.
"""

import cas_freq.simulation.architecture as arch
import cas_freq.simulation.mechanics as mech
from cas_freq.core.jit import cached_jit as _jit

# Columns of the parameter table ``p`` (n_runs, _NP), one row per run.
_PHI = 0  # Phi, row-major, 9 columns
_GA = 9  # G_a, 3 columns
_GB = 12  # G_b, 3 columns
_RATIO = 15  # gear ratio N [-]
_FF_V = 16  # feed-forward of the command rate [A*s/rad]
_FF_A = 17  # feed-forward of the command acceleration [A*s^2/rad]
_CP_KP = 18  # position loop Kp [A/rad]
_CP_KI = 19  # position loop Ki [A/(rad*s)]
_CP_GD = 20  # derivative gain Kd/Tf [A/rad] (0 without derivative)
_CP_A = 21  # derivative filter coefficients a, b, c (controllers.py)
_CP_B = 22
_CP_C = 23
_I_MAX = 24  # current command limit [A]
_CI_KP = 25  # current loop Kp [V/A]
_CI_KI = 26  # current loop Ki [V/(A*s)]
_V_MAX = 27  # voltage limit [V]
_F_C = 28  # fractional part of tau_c / dt
_F_P = 29  # fractional part of tau_p / dt
_ON_MEASUREMENT = 30  # 1.0 where the derivative acts on -theta
_BACKWARD = 31  # 1.0 where sampled controllers integrate by the backward difference
_NP = 32

# Columns of the controller state ``s`` (n_runs, _NS).
_P_INT = 0  # position controller: integral of the error [rad*s]
_P_FILTER = 1  # derivative filter state x_f [rad]
_P_E = 2  # error at the last update (right limit) [rad]
_P_Y = 3  # derivative input at the last update (right limit) [rad]
_P_REST = 4  # output without the integral term at the last update (right limit) [A]
_P_U_LEFT = 5  # output (current command), left and right limits [A]
_P_U = 6
_P_LIMITED = 7  # 1.0 where the right-limit output was clamped
_C_INT = 8  # current controller: integral of the error [A*s]
_C_E = 9  # error at the last update [A]
_C_REST = 10  # output without the integral term at the last update [V]
_C_V_LEFT = 11  # output (voltage command), left and right limits [V]
_C_V = 12
_C_LIMITED = 13  # 1.0 where the right-limit output was clamped
_I_CMD = 14  # current command read at the current controller [A]
_V = 15  # voltage at the motor terminals at the present step (right limit) [V]
_THETA_CMD = 16  # motor-angle command at the present step [rad]
_W_BEFORE = 17  # motor speed one step earlier [rad/s] (loaded runs)
_NS = 18

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

@_jit(inline="always")  # numba-level: array arguments cost a call
def _sample(buffer, r, j):
    """Sample ``j`` of run ``r`` from a ring buffer of 2**n slots (0 before t = 0)."""
    if j < 0:
        return 0.0
    return buffer[r, j & (buffer.shape[1] - 1)]


@_jit(inline="always")  # numba-level: array arguments cost a call
def _read(right, left, r, m, f, q, latest, want_left, hold):
    """Delayed signal at t_q, delay (m + f) dt, newest sample ``latest`` (DelayLine.read).

    Interpolating line: ``(1 - f) u^-[q - m] + f u^+[q - m - 1]`` (for f = 0 the right or left
    limit of sample q - m); a read ahead of the newest sample holds it. Holding line:
    ``u[q - m - 1]`` if f > 0 or for the left limit, else ``u[q - m]``.
    """
    if hold:
        shift = 1 if (want_left or f > 0.0) else 0
        return _sample(right, r, min(q - m - shift, latest))
    j = q - m
    if j > latest:  # ahead of the newest sample (a delay below one step): hold it
        return _sample(right, r, latest)
    if f == 0.0:
        return _sample(left if want_left else right, r, j)
    return (1.0 - f) * _sample(left, r, j) + f * _sample(right, r, j - 1)


@_jit(inline="always")  # numba-level: array arguments cost a call
def _push(right, left, r, k, u_right, u_left, hold):
    """Store sample ``k`` of run ``r``: right and left limits (DelayLine.push)."""
    slot = k & (right.shape[1] - 1)
    right[r, slot] = u_right
    if not hold:
        left[r, slot] = u_left


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


# --- the inner blocks: velocity loop and filters (architecture.py) ----------------------------

@_jit(inline="always")  # numba-level: array arguments cost a call
def _chain(g, gs, r, start, m, z, u_a, u_b):
    """Step the filter chain of order ``m`` whose table starts at column ``start`` of ``g``
    (its states at columns ``z`` .. ``z + m`` of ``gs``, scratch after them) over one step
    for an input linear from ``u_a`` to ``u_b`` (FilterState.step); returns C z_k+1."""
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
    return y


@_jit(inline="always")  # numba-level: array arguments cost a call
def _inner(ext, r, k, ratio, w, u_left, u_right, acc_left, acc_right, p_due, hold_p, dt,
           first):
    """The blocks between the position controller and the current loop at step ``k``
    (Engine._inner_update): the position controller's output limits (``u_left``,
    ``u_right``) through the velocity loop (a cascade: delay line tau_p, PI on the filtered
    motor speed ``w`` with its feed-forward of the command's acceleration ``acc`` [rad/s^2 at
    the output]) and the filters at the current command. ``p_due``: the position controller
    updated at this step; ``hold_p``: it is sampled (the velocity line holds). A sampled
    commander (the velocity controller, or the position controller without one) and the
    filters after it update every ``g[r, COMMANDER_EVERY]`` steps and hold in between.
    ``first``: the outputs at t = 0.

    Returns
    -------
    tuple of float
        The current command's left and right limits [A], and 1.0 where the velocity
        controller's right-limit output was clamped (else the value passed in the state).
    """
    g, gs, m_v, line_right, line_left = ext
    m_path, m_sensor = int(g[r, arch.PATH_ORDER]), int(g[r, arch.SENSOR_ORDER])
    cascade = g[r, arch.CASCADE] != 0.0
    if cascade:
        _push(line_right, line_left, r, k, u_right, u_left, hold_p)
    every = int(g[r, arch.COMMANDER_EVERY])  # the commander's period (0: continuous)
    if cascade:
        due = every == 0 or k % every == 0
    else:
        due = p_due
    if not (first or due):  # a sampled commander's output (and the filters after it) held
        return gs[r, arch.S_CMD_LEFT], gs[r, arch.S_CMD], gs[r, arch.S_LIMITED]
    if cascade:
        f_v = g[r, arch.V_FRACTION]
        sampled_v = every > 0
        w_cmd = _read(line_right, line_left, r, m_v[r], f_v, k, k, False, hold_p)
        w_cmd_left = w_cmd
        if not (hold_p or sampled_v):
            w_cmd_left = _read(line_right, line_left, r, m_v[r], f_v, k, k, True, hold_p)
        measured = w
        if m_sensor > 0:
            start = arch.PATH + m_path * m_path + 3 * m_path + 1  # arch.chain_columns
            d = g[r, start + m_sensor * m_sensor + 3 * m_sensor]
            y = 0.0
            if not first:
                y = _chain(g, gs, r, start, m_sensor, arch.S_PATH + 2 * m_path,
                           gs[r, arch.S_SENSOR_U], w)
            gs[r, arch.S_SENSOR_U] = w
            measured = y + d * w
        ff_a = g[r, arch.V_FF_A]
        if sampled_v:  # a sampler sees the values from now on
            acc_left = acc_right
        (gs[r, arch.S_INT], _, gs[r, arch.S_E], _, gs[r, arch.S_REST], u_left, u_right,
         gs[r, arch.S_LIMITED]) = _controller_update(
            gs[r, arch.S_INT], 0.0, gs[r, arch.S_E], 0.0, gs[r, arch.S_REST],
            w_cmd_left - measured, w_cmd - measured, 0.0, 0.0, ff_a * (ratio * acc_left),
            ff_a * (ratio * acc_right), (not first) or sampled_v, g[r, arch.V_KP],
            g[r, arch.V_KI], 0.0, 0.0, 0.0, 0.0, False, g[r, arch.V_LIMIT],
            dt * max(every, 1), not sampled_v, sampled_v and g[r, arch.V_BACKWARD] != 0.0,
        )
        if sampled_v:  # held: no jump within an update
            u_left = u_right
    if m_path > 0:
        d = g[r, arch.PATH + m_path * m_path + 3 * m_path]
        y = 0.0
        if not first:
            y = _chain(g, gs, r, arch.PATH, m_path, arch.S_PATH, gs[r, arch.S_PATH_U], u_left)
        gs[r, arch.S_PATH_U] = u_right
        u_left, u_right = y + d * u_left, y + d * u_right
    gs[r, arch.S_CMD_LEFT], gs[r, arch.S_CMD] = u_left, u_right
    return u_left, u_right, gs[r, arch.S_LIMITED]



@_jit()  # start_batch only, once per batch: a call (inlining costs compile time)
def _position_update(p, r, theta, angle_left, angle_right, ff_left, ff_right, integral, state,
                     e_before, y_before, rest_before, advance, has_derivative, period, locate,
                     backward):
    """Position controller of run ``r`` on the motor angle ``theta`` (docs/model.md §4).

    Returns the outputs of :func:`_controller_update` (the output is the current command [A]).
    """
    e_right = angle_right - theta
    e_left = angle_left - theta
    if p[r, _ON_MEASUREMENT] != 0.0:  # derivative on the measurement: acts on -theta
        y_left = y_right = -theta
    else:
        y_left, y_right = e_left, e_right
    return _controller_update(
        integral, state, e_before, y_before, rest_before,
        e_left, e_right, y_left, y_right, ff_left, ff_right, advance,
        p[r, _CP_KP], p[r, _CP_KI], p[r, _CP_GD], p[r, _CP_A], p[r, _CP_B], p[r, _CP_C],
        has_derivative, p[r, _I_MAX], period, locate, backward,
    )


@_jit()  # start_batch only, once per batch: a call (inlining costs compile time)
def _current_update(p, r, i, k, current_right, current_left, m_p, hold_p, sampled, integral,
                    e_before, rest_before, advance, period, backward):
    """Current controller of run ``r`` on the command delayed by tau_p (docs/model.md §3).

    Returns
    -------
    tuple of float
        integral, error and rest (for the next update), the output's left and right limits
        [V], 1.0 if clamped, and the current command read [A].
    """
    f_p = p[r, _F_P]
    i_cmd = _read(current_right, current_left, r, m_p, f_p, k, k, False, hold_p)
    e_right = i_cmd - i
    e_left = e_right
    if not sampled:
        e_left = _read(current_right, current_left, r, m_p, f_p, k, k, True, hold_p) - i
    integral, _, e, _, rest, v_left, v_right, limited = _controller_update(
        integral, 0.0, e_before, 0.0, rest_before, e_left, e_right, 0.0, 0.0, 0.0, 0.0,
        advance, p[r, _CI_KP], p[r, _CI_KI], 0.0, 0.0, 0.0, 0.0, False, p[r, _V_MAX], period,
        not sampled, backward,
    )
    if sampled:  # held: no jump within an update
        v_left = v_right
    return integral, e, rest, v_left, v_right, limited, i_cmd


@_jit(inline="always")  # numba-level: array arguments cost a call
def _command(p, commands, r, row):
    """Motor-angle command and feed-forward [rad], [A] of run ``r`` from a row of fin values.

    ``commands[row]`` holds the fin angle, rate and acceleration (one column for every run, or
    one per run) [rad], [rad/s], [rad/s^2]; feed-forward i_ff = FFv d(theta_cmd)/dt +
    FFa d2(theta_cmd)/dt2 (docs/model.md §4).
    """
    col = 0
    if commands.shape[2] > 1:
        col = r
    ratio = p[r, _RATIO]
    angle = ratio * commands[row, 0, col]
    ff = p[r, _FF_V] * (ratio * commands[row, 1, col]) + p[r, _FF_A] * (
        ratio * commands[row, 2, col]
    )
    return angle, ff


# --- the inner blocks as a call, for start_batch -------------------------------------------------
# numba's inline="always" copies a block's IR into every caller, and typing and lowering that
# copy is most of a caller's compile time. In the step loop it saves a call (and the reference
# counts of its array arguments) every step; :func:`cas_freq.simulation.kernel.start_batch` runs
# once per batch, so it calls this twin, compiled once as a function of its own: the same code
# and numbers.
_inner_call = _jit()(_inner.py_func)
