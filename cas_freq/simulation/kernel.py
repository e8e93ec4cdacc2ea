r"""The fixed-step loop compiled with numba: every run of a batch advanced in parallel.

This is the same discrete loop as the reference :class:`~cas_freq.simulation.engine.Engine`
(numpy, vectorised over runs), written per run as plain scalar code so that numba compiles it to
one machine-code loop, ``prange`` over the runs. Per step :math:`t_k \to t_{k+1}` and run
(docs/model.md §2-4 and §9 item 7):

1. **Delay line τc** (:func:`_read`): the terminal voltage over the step, read back from the
   current controller's past outputs (first-order hold; constant for a sampled controller).
2. **Plant** (§2): :math:`x_{k+1} = \Phi x_k + G_a V_a + G_b V_b`, the exact step of the linear
   motor for a voltage linear over the step (matrices from
   :func:`~cas_freq.simulation.engine.plant_step_matrices`, computed in numpy and passed in).
   A loaded run (:mod:`~cas_freq.simulation.mechanics`) steps its 5 states with the matrices of
   the mode chosen at the step's start and the torques of its nonlinear terms (the table of
   :func:`~cas_freq.simulation.mechanics.table`); an unloaded run (its row of that table
   says so, a batch without a load passes a table of zeros) keeps the 3-state step, a branch
   taken per run (one machine code for both, not one specialisation each: with the
   architecture as data, that cut the kernels' first compilation from 132 to 55 s of CPU,
   for 11 to 14 % more CPU per step).
3. **Position controller** (§4): PID with filtered derivative, feed-forward, clamp to ±i_max,
   anti-windup (:func:`_controller_update`, the scalar form of
   :class:`~cas_freq.simulation.controllers.Controller`); its output enters the delay line τp.
   The architecture is data (the inner blocks' table ``ext``,
   :mod:`~cas_freq.simulation.architecture`): the position loop measures N*delta with output
   feedback; its output goes through the velocity loop of a cascade (delay line tau_p, PI on
   the filtered speed, clamp ±i_max) and the filters at the current command (:func:`_inner`)
   before the delay line read in step 4; a PID-on-PI has neither (orders 0, no cascade).
   Every argument has the same numba type whatever the architecture, the sampling and the
   load, so each kernel is compiled once for them all.
4. **Current controller** (§3): PI on the delayed current command, clamp to ±v_max,
   anti-windup; its output enters the delay line τc.
5. Every ``record_every`` steps the signals of :data:`~cas_freq.simulation.engine.SIGNALS`
   asked for (:func:`record_mask`; theta always).

Sampled controllers (§9 item 8) update every ``n`` steps and are held in between, each loop at
its own period (the velocity controller's and the filters after a sampled controller in the
inner blocks' table, :mod:`~cas_freq.simulation.architecture`). Each
operation is written in the order of the reference, so that a single run gives the same
numbers to the last bit or nearly (the clamp flags where an output rests exactly at its limit
depend on the last bit); in a batch the reference's shortcuts are taken for the whole batch at
once and may round a run differently by an ulp.

The columns of the tables and the blocks the loop inlines (delay lines, controllers, inner
blocks) are in :mod:`~cas_freq.simulation.kernel_blocks`.

The state lives in numpy arrays between calls (the engine of :mod:`cas_freq.simulation.compiled`
builds the tables with :func:`parameter_table`), so the simulator can
advance a batch by any number of steps, check settling, extend the horizon and report progress
as with the reference engine. Functions are compiled with ``cache=True``: the first call in a
fresh environment compiles them (10 to 30 s on a 2-core machine); later processes load the
machine code from numba's cache (about 0.2 s, plus 0.2 s to import numba). The cache sits next
to this file, or in ``NUMBA_CACHE_DIR``, or, if this directory is not writable, in a per-user
folder (:func:`cas_freq.core.jit.configure_cache`); where no place is writable, the functions are
compiled in each process. The
functions that advance a batch release the GIL (``nogil``): another thread of the process (the
second-order fits of :func:`~cas_freq.studies.steps.batch_steps`) runs while they do.
"""

import os

import numba
import numpy as np
from numba import prange

import cas_freq.simulation.architecture as arch
import cas_freq.simulation.mechanics as mech
from cas_freq.core.jit import cached_jit as _jit
from cas_freq.simulation.controllers import check_method, derivative_filter
from cas_freq.simulation.delay_line import delay_steps, ring_size
from cas_freq.simulation.engine import (
    SIGNALS,
    plant_step_matrices,
)
from cas_freq.simulation.kernel_blocks import (
    _BACKDRIVE,
    _BACKWARD,
    _C_E,
    _C_INT,
    _C_LIMITED,
    _C_REST,
    _C_V,
    _C_V_LEFT,
    _CI_KI,
    _CI_KP,
    _CP_A,
    _CP_B,
    _CP_C,
    _CP_GD,
    _CP_KI,
    _CP_KP,
    _F_C,
    _F_P,
    _FF_A,
    _FF_V,
    _FORWARD,
    _GA,
    _GAP,
    _GB,
    _HELD,
    _I_CMD,
    _I_MAX,
    _M_A1,
    _M_B1,
    _M_GA,
    _M_GB,
    _M_H,
    _M_PHI,
    _NP,
    _NS,
    _ON_MEASUREMENT,
    _P_E,
    _P_FILTER,
    _P_INT,
    _P_LIMITED,
    _P_REST,
    _P_U,
    _P_U_LEFT,
    _P_Y,
    _PER_MODE,
    _PHI,
    _Q_B_L,
    _Q_C_G,
    _Q_COMPLIANT,
    _Q_E_BACK,
    _Q_E_FORWARD,
    _Q_F_C,
    _Q_HALF,
    _Q_J_L,
    _Q_K_G,
    _Q_K_H,
    _Q_LOADED,
    _Q_TAU_H,
    _RATIO,
    _THETA_CMD,
    _V,
    _V_MAX,
    _W_BEFORE,
    _chain,
    _command,
    _controller_update,
    _current_update,
    _from_rest,
    _inner,
    _inner_call,
    _position_update,
    _push,
    _read,
    _sign,
)

# numba's threading layer: workqueue unless NUMBA_THREADING_LAYER chooses. The default order
# picks GNU OpenMP where present, and a process forked after a parallel kernel ran (a
# multiprocessing pool) is then terminated when it launches one; workqueue is fork-safe, and
# the lock of cas_freq.simulation.compiled keeps two threads from launching at once, which
# workqueue does not allow.
if "NUMBA_THREADING_LAYER" not in os.environ:
    numba.config.THREADING_LAYER = "workqueue"


# Rows of the float recordings (the bool ones are current_limited, voltage_limited).
FLOAT_SIGNALS = SIGNALS[:7]
#: The signals of the kernel's record mask, bit j for RECORDED[j] (:func:`record_mask`).
RECORDED = SIGNALS


def record_mask(names, loaded=False):
    """The kernel's bit mask of the recorded signals ``names`` (None: every one).

    theta is always recorded (the output angle, the settling check's); a loaded batch also
    records omega (:func:`rigid_fin` derives the unloaded runs' fin rate from it).
    """
    names = set(RECORDED if names is None else names) | {"theta"}
    if loaded:
        names.add("omega")
    return sum(1 << j for j, name in enumerate(RECORDED) if name in names)


# --- one run: start and steps -----------------------------------------------------------------

@_jit()
def start_batch(p, m, x, s, voltage_right, voltage_left, current_right, current_left,
                right, left, every_c, every_p, has_derivative, dt, ext):
    """Controller outputs at t = 0 (plant at rest, nothing before), as Engine.start.

    Parameters
    ----------
    p : numpy.ndarray
        Parameter table (n_runs, _NP).
    m : numpy.ndarray
        Whole steps of the delays (n_runs, 2): tau_c, tau_p.
    x, s : numpy.ndarray
        Plant states (n_runs, 3) [A, rad/s, rad] and controller states (n_runs, _NS), updated.
    voltage_right, voltage_left, current_right, current_left : numpy.ndarray
        Ring buffers of the delay lines (n_runs, slots) [V], [A], updated.
    right, left : numpy.ndarray
        Fin command at t = 0, right and left limits (1, 3, 1 or n_runs).
    every_c, every_p : int
        Update period of a sampled controller in steps, 0 for a continuous one.
    has_derivative : bool
        Some run has a derivative term (Kd > 0).
    dt : float
        Step [s].
    ext : tuple
        The inner blocks (velocity loop, filters, output feedback; none for a PID-on-PI
        without filters): the table, state and velocity-line steps of
        :func:`~cas_freq.simulation.architecture.kernel_tables` and the velocity line's ring
        buffers.
    """
    for r in range(x.shape[0]):
        sampled_p, sampled_c = every_p > 0, every_c > 0
        backward = p[r, _BACKWARD] != 0.0
        # the current command is held where its commander is sampled
        hold_i = ext[0][r, arch.COMMANDER_EVERY] > 0.0
        angle, ff = _command(p, right, r, 0)
        angle_left, ff_left = angle, ff
        if not sampled_p:  # a sampler sees the values from now on
            angle_left, ff_left = _command(p, left, r, 0)
        s[r, _THETA_CMD] = angle
        # the measurements from rest through their analog filters (Engine._measure): d u
        i_meas, th_meas = x[r, 0], x[r, 2]
        g, gs = ext[0], ext[1]
        m_i, m_a = int(g[r, arch.I_ORDER]), int(g[r, arch.A_ORDER])
        if m_i > 0:
            gs[r, arch.S_I_U] = i_meas
            i_meas = g[r, int(g[r, arch.I_AT]) + m_i * m_i + 3 * m_i] * i_meas
        if m_a > 0:
            gs[r, arch.S_A_U] = th_meas
            th_meas = g[r, int(g[r, arch.A_AT]) + m_a * m_a + 3 * m_a] * th_meas
        # a sampled controller makes its first update from zero samples before t = 0
        (s[r, _P_INT], s[r, _P_FILTER], s[r, _P_E], s[r, _P_Y], s[r, _P_REST],
         s[r, _P_U_LEFT], s[r, _P_U], s[r, _P_LIMITED]) = _position_update(
            p, r, th_meas, angle_left, angle, ff_left, ff, 0.0, 0.0, 0.0, 0.0, 0.0, sampled_p,
            has_derivative, dt * max(every_p, 1), not sampled_p, sampled_p and backward,
        )
        # the position loop measures the same at rest (theta = N delta)
        col = r if right.shape[2] > 1 else 0
        u_left, u_right, _ = _inner_call(
            ext, r, 0, p[r, _RATIO], x[r, 1], s[r, _P_U_LEFT], s[r, _P_U],
            right[0, 2, col] if sampled_p else left[0, 2, col], right[0, 2, col],
            True, sampled_p, dt, True)
        _push(current_right, current_left, r, 0, u_right, u_left, hold_i)
        (s[r, _C_INT], s[r, _C_E], s[r, _C_REST], s[r, _C_V_LEFT], s[r, _C_V],
         s[r, _C_LIMITED], s[r, _I_CMD]) = _current_update(
            p, r, i_meas, 0, current_right, current_left, m[r, 1], hold_i, sampled_c,
            0.0, 0.0, 0.0, sampled_c, dt * max(every_c, 1), sampled_c and backward,
        )
        _push(voltage_right, voltage_left, r, 0, s[r, _C_V], s[r, _C_V_LEFT], sampled_c)
        s[r, _V] = _read(voltage_right, voltage_left, r, m[r, 0], p[r, _F_C], 0, 0, False,
                         sampled_c)


@_jit(parallel=True, nogil=True)
def advance_parallel(p, m, x, s, voltage_right, voltage_left, current_right, current_left,
                     right, left, k0, record_every, record_base, floats, flags,
                     every_c, every_p, has_derivative, dt, q, ext, record, active, n_steps):
    """:func:`advance_serial` with the runs shared among numba's threads (NUMBA_NUM_THREADS)."""
    for run in prange(x.shape[0]):
        if not active[run]:
            continue
        _advance_run(np.int64(run), p, m, x, s, voltage_right, voltage_left, current_right,
                     current_left, right, left, k0, record_every, record_base, floats,
                     flags, every_c, every_p, has_derivative, dt, q, ext, record, n_steps)


@_jit(nogil=True)
def advance_serial(p, m, x, s, voltage_right, voltage_left, current_right, current_left,
                   right, left, k0, record_every, record_base, floats, flags,
                   every_c, every_p, has_derivative, dt, q, ext, record, active, n_steps):
    """Advance every run from step ``k0`` by ``n_steps`` steps (Engine._step, per run).

    Parameters
    ----------
    p, m, x, s, voltage_right, voltage_left, current_right, current_left
        As for :func:`start_batch`; the states are updated in place.
    right, left : numpy.ndarray
        Fin command (angle [rad], rate [rad/s], acceleration [rad/s^2]) at steps k0 + 1, ...,
        right and left limits, shape (n_steps, 3, 1 or n_runs), or (1, 3, 1 or n_runs) for a
        command that holds its value over these steps (a step after its start).
    k0 : int
        Step index at the start.
    record_every, record_base : int
        Step k is recorded if ``k % record_every == 0``, in row
        ``k // record_every - record_base``.
    floats, flags : numpy.ndarray
        Recordings (7, n_runs, rows), or (9, ...) with the fin's angle and rate where ``q`` is
        given (written for the loaded runs only), and (2, n_runs, rows) of bool, written.
    every_c, every_p, has_derivative, dt
        As for :func:`start_batch`.
    q : numpy.ndarray
        The loaded plant's table (n_runs, mechanics.COLUMNS), zeros for a batch without a
        load. Runs with ``q[r, LOADED] == 0`` take the unloaded path (the 3-state plant).
    ext : tuple
        The inner blocks, as for :func:`start_batch`.
    record : int
        Bit mask of the signals written (bit j: :data:`RECORDED` [j], :func:`record_mask`);
        the rows of the others are left as they were (recording every signal is about 40 %
        of a step's time).
    active : numpy.ndarray
        Bool (n_runs,): the runs advanced; the others keep their states and recordings as
        they were (a run that has stopped, :meth:`CompiledEngine.stop`).
    n_steps : int
        Steps to advance.
    """
    for r in range(x.shape[0]):
        if not active[r]:
            continue
        _advance_run(r, p, m, x, s, voltage_right, voltage_left, current_right,
                     current_left, right, left, k0, record_every, record_base, floats,
                     flags, every_c, every_p, has_derivative, dt, q, ext, record, n_steps)


@_jit()
def _advance_run(r, p, m, x, s, voltage_right, voltage_left, current_right, current_left,
                 right, left, k0, record_every, record_base, floats, flags,
                 every_c, every_p, has_derivative, dt, q, ext, record, n_steps):
    """Advance run ``r`` (arguments of :func:`advance_serial`).

    The run's states are held in local variables over the steps and written back at the end.
    The loop calls no function that takes an array: numba counts references to an array
    passed to a function, inlined or not, with an atomic add and subtract per call, which cost
    more than the arithmetic of a step and, on the arrays the threads share, contend between
    them. So the delay-line reads (:func:`_read`), pushes (:func:`_push`), command rows
    (:func:`_command`) and the controllers' inputs (:func:`_position_update`,
    :func:`_current_update`) are written out here on scalars and on the run's rows, with the
    same operations in the same order (the same numbers to the bit).
    """
    one_row = right.shape[0] == 1  # the command's rows: one for every step
    sampled_p, sampled_c = every_p > 0, every_c > 0
    period_p, period_c = dt * max(every_p, 1), dt * max(every_c, 1)
    m_c, m_p, f_c, f_p = m[r, 0], m[r, 1], p[r, _F_C], p[r, _F_P]
    phi0, phi1, phi2 = p[r, _PHI], p[r, _PHI + 1], p[r, _PHI + 2]
    phi3, phi4, phi5 = p[r, _PHI + 3], p[r, _PHI + 4], p[r, _PHI + 5]
    phi6, phi7, phi8 = p[r, _PHI + 6], p[r, _PHI + 7], p[r, _PHI + 8]
    g_a0, g_a1, g_a2 = p[r, _GA], p[r, _GA + 1], p[r, _GA + 2]
    g_b0, g_b1, g_b2 = p[r, _GB], p[r, _GB + 1], p[r, _GB + 2]
    ratio, ff_v, ff_a = p[r, _RATIO], p[r, _FF_V], p[r, _FF_A]
    cp_kp, cp_ki, cp_gd = p[r, _CP_KP], p[r, _CP_KI], p[r, _CP_GD]
    cp_a, cp_b, cp_c, i_max = p[r, _CP_A], p[r, _CP_B], p[r, _CP_C], p[r, _I_MAX]
    ci_kp, ci_ki, v_max = p[r, _CI_KP], p[r, _CI_KI], p[r, _V_MAX]
    on_measurement = p[r, _ON_MEASUREMENT] != 0.0
    backward = p[r, _BACKWARD] != 0.0
    backward_p, backward_c = sampled_p and backward, sampled_c and backward
    # the current command is held where its commander is sampled (the velocity controller in
    # a cascade, else the position controller)
    hold_i = ext[0][r, arch.COMMANDER_EVERY] > 0.0
    col = r if right.shape[2] > 1 else 0
    mask_c, mask_p = voltage_right.shape[1] - 1, current_right.shape[1] - 1
    # the delay lines' reads at step k (_read): the sample index, for a holding line
    shift_c = 1 if f_c > 0.0 else 0  # v_a and v of a holding line (want_left False)
    shift_p = 1 if f_p > 0.0 else 0
    i, w, th = x[r, 0], x[r, 1], x[r, 2]
    p_int, p_filter, p_e, p_y, p_rest = (s[r, _P_INT], s[r, _P_FILTER], s[r, _P_E], s[r, _P_Y],
                                         s[r, _P_REST])
    u_left, u_p, p_limited = s[r, _P_U_LEFT], s[r, _P_U], s[r, _P_LIMITED]
    c_int, c_e, c_rest = s[r, _C_INT], s[r, _C_E], s[r, _C_REST]
    v_left, v_c, c_limited = s[r, _C_V_LEFT], s[r, _C_V], s[r, _C_LIMITED]
    i_cmd, v, angle = s[r, _I_CMD], s[r, _V], s[r, _THETA_CMD]
    # the next steps at which to record and to update a sampled controller (counters, not
    # a division per step)
    next_record = (k0 // record_every + 1) * record_every
    out = next_record // record_every - record_base
    next_p = (k0 // every_p + 1) * every_p if sampled_p else 0
    next_c = (k0 // every_c + 1) * every_c if sampled_c else 0
    # the run's rows of the recordings, each contiguous (views made once, outside the loop)
    rec_theta, rec_omega, rec_i, rec_v = floats[0, r], floats[1, r], floats[2, r], floats[3, r]
    rec_angle, rec_i_cmd, rec_integral = floats[4, r], floats[5, r], floats[6, r]
    rec_p_limited, rec_c_limited = flags[0, r], flags[1, r]
    # the signals asked for (record_mask; theta always, and theta, omega, delta and omega_L in
    # a loaded batch)
    want_omega, want_i, want_v = (record & 2) != 0, (record & 4) != 0, (record & 8) != 0
    want_angle, want_i_cmd = (record & 16) != 0, (record & 32) != 0
    want_integral, want_p_limited = (record & 64) != 0, (record & 128) != 0
    want_c_limited = (record & 256) != 0
    # a loaded run (its row of q says so): fin states, constants and recordings (mechanics.py)
    w_l = d_l = w_before = 0.0
    compliant = False
    half = k_g = c_g = tau_h = j_l = b_l = k_h = coulomb = e_forward = e_back = 0.0
    rec_delta, rec_omega_l = rec_theta, rec_omega
    loaded = q[r, _Q_LOADED] != 0.0
    if loaded:
        w_l, d_l, w_before = x[r, 3], x[r, 4], s[r, _W_BEFORE]
        compliant = q[r, _Q_COMPLIANT] != 0.0
        half, k_g, tau_h = q[r, _Q_HALF], q[r, _Q_K_G], q[r, _Q_TAU_H]
        c_g = q[r, _Q_C_G]
        j_l, b_l, k_h, coulomb = q[r, _Q_J_L], q[r, _Q_B_L], q[r, _Q_K_H], q[r, _Q_F_C]
        e_forward, e_back = q[r, _Q_E_FORWARD], q[r, _Q_E_BACK]
        rec_delta, rec_omega_l = floats[7, r], floats[8, r]
    # the inner blocks (ext, architecture.py): output feedback, and the current command's
    # clamp flag (the velocity controller's in a cascade)
    i_limited = p_limited
    output_feedback = ext[0][r, arch.OUTPUT] != 0.0
    if ext[0][r, arch.CASCADE] != 0.0:
        i_limited = ext[1][r, arch.S_LIMITED]
    # the analog filters on the measured current and angle (orders 0: none)
    m_i, m_a = int(ext[0][r, arch.I_ORDER]), int(ext[0][r, arch.A_ORDER])
    # no block between the position controller and the current loop (no velocity loop, no
    # filter at the current command): the position controller's output is the current
    # command, pushed as it is (what _inner returns then, without its table reads)
    direct = ext[0][r, arch.CASCADE] == 0.0 and ext[0][r, arch.PATH_ORDER] == 0.0
    for row in range(n_steps):
        k = k0 + row
        c_row = 0 if one_row else row
        # 1. voltage at the terminals over [t_k, t_k+1]: the current controller's output
        #    delayed by tau_c, linear over the step (held for a sampled controller)
        if sampled_c:
            j = min(k - m_c - shift_c, k)
            v_a = voltage_right[r, j & mask_c] if j >= 0 else 0.0
            v_b = v_a
            j = min(k + 1 - m_c - shift_c, k)
            v = voltage_right[r, j & mask_c] if j >= 0 else 0.0
        else:
            j = k - m_c
            if j > k:
                v_a = voltage_right[r, k & mask_c]
            elif f_c == 0.0:
                v_a = voltage_right[r, j & mask_c] if j >= 0 else 0.0
            else:
                v_a = ((1.0 - f_c) * (voltage_left[r, j & mask_c] if j >= 0 else 0.0)
                       + f_c * (voltage_right[r, (j - 1) & mask_c] if j >= 1 else 0.0))
            j = k + 1 - m_c
            if j > k:
                v_b = voltage_right[r, k & mask_c]
                v = v_b
            elif f_c == 0.0:
                v_b = voltage_left[r, j & mask_c] if j >= 0 else 0.0
                v = voltage_right[r, j & mask_c] if j >= 0 else 0.0
            else:
                before = f_c * (voltage_right[r, (j - 1) & mask_c] if j >= 1 else 0.0)
                v_b = (1.0 - f_c) * (voltage_left[r, j & mask_c] if j >= 0 else 0.0) + before
                v = v_b
        # 2. plant (§2): x <- Phi x + G_a V_a + G_b V_b
        if not loaded:
            x0 = phi0 * i + phi1 * w + phi2 * th
            x1 = phi3 * i + phi4 * w + phi5 * th
            x2 = phi6 * i + phi7 * w + phi8 * th
            x0 += g_a0 * v_a
            x1 += g_a1 * v_a
            x2 += g_a2 * v_a
            x0 += g_b0 * v_b
            x1 += g_b1 * v_b
            x2 += g_b2 * v_b
            i, w, th = x0, x1, x2
        else:
            # the loaded plant (mechanics.py, Drivetrain.inputs and step, in their order):
            # contact and spring offset, power and mode, torques, friction, exact step
            gear = th / ratio - d_l
            above, below = gear > half, gear < -half
            dz = offset = 0.0
            if above:
                dz, offset = gear - half, -k_g * half
            elif below:
                dz, offset = gear + half, k_g * half
            rate = w / ratio
            if compliant:
                power = (k_g * dz + c_g * (rate - w_l)) * rate
            else:
                accel = (w - w_before) / (ratio * dt)
                power = (j_l * accel + b_l * rate + k_h * (th / ratio) - tau_h) * rate
            if compliant and half > 0.0 and not above and not below:
                mode = _GAP
            elif power < 0.0:
                mode = _BACKDRIVE
            else:
                mode = _FORWARD
            c = offset if compliant else 0.0
            tau_l = tau_h + c
            if mode != _GAP:
                mode = _from_rest(q, r, mode, i, w, th, w_l, d_l, dz, c, tau_l, dt)
            held = mode == _HELD
            e = e_back if mode == _BACKDRIVE else e_forward
            tau_m = -(e * c) / ratio
            base = mode * _PER_MODE
            if coulomb > 0.0 and not held:
                b_m = q[r, base + _M_B1]
                a1 = base + _M_A1
                acc = (q[r, a1] * i + q[r, a1 + 1] * w + q[r, a1 + 2] * th + q[r, a1 + 3] * w_l
                       + q[r, a1 + 4] * d_l + b_m * tau_m + q[r, base + _M_B1 + 1] * tau_l)
                stop = (acc + w / dt) / b_m
                if abs(w) > coulomb * dt * b_m:
                    tau_f = coulomb * _sign(w)
                else:
                    tau_f = min(max(stop, -coulomb), coulomb)
                tau_m = tau_m - tau_f
            w_before = w
            if held:  # the gear stops the shaft (and a rigid gear's fin) at once
                w = 0.0
                if not compliant:
                    w_l = 0.0
            # x <- Phi x + G_a V_a + G_b V_b + H (tau_m, tau_L), as the reference's sums
            at, ga, gb, h = base + _M_PHI, base + _M_GA, base + _M_GB, base + _M_H
            x0 = (q[r, at] * i + q[r, at + 1] * w + q[r, at + 2] * th
                  + q[r, at + 3] * w_l + q[r, at + 4] * d_l)
            x0 += q[r, ga] * v_a
            x0 += q[r, gb] * v_b
            x0 += q[r, h] * tau_m
            x0 += q[r, h + 1] * tau_l
            x1 = (q[r, at + 5] * i + q[r, at + 6] * w + q[r, at + 7] * th
                  + q[r, at + 8] * w_l + q[r, at + 9] * d_l)
            x1 += q[r, ga + 1] * v_a
            x1 += q[r, gb + 1] * v_b
            x1 += q[r, h + 2] * tau_m
            x1 += q[r, h + 3] * tau_l
            x2 = (q[r, at + 10] * i + q[r, at + 11] * w + q[r, at + 12] * th
                  + q[r, at + 13] * w_l + q[r, at + 14] * d_l)
            x2 += q[r, ga + 2] * v_a
            x2 += q[r, gb + 2] * v_b
            x2 += q[r, h + 4] * tau_m
            x2 += q[r, h + 5] * tau_l
            x3 = (q[r, at + 15] * i + q[r, at + 16] * w + q[r, at + 17] * th
                  + q[r, at + 18] * w_l + q[r, at + 19] * d_l)
            x3 += q[r, ga + 3] * v_a
            x3 += q[r, gb + 3] * v_b
            x3 += q[r, h + 6] * tau_m
            x3 += q[r, h + 7] * tau_l
            x4 = (q[r, at + 20] * i + q[r, at + 21] * w + q[r, at + 22] * th
                  + q[r, at + 23] * w_l + q[r, at + 24] * d_l)
            x4 += q[r, ga + 4] * v_a
            x4 += q[r, gb + 4] * v_b
            x4 += q[r, h + 8] * tau_m
            x4 += q[r, h + 9] * tau_l
            i, w, th, w_l, d_l = x0, x1, x2, x3, x4
        k += 1
        # 3. the measurements at t_k+1 through their analog filters (Engine._measure)
        i_meas = i
        measured = th
        if loaded and output_feedback:
            measured = ratio * d_l  # the output angle on the motor's scale
        if m_i > 0:
            g, gs = ext[0], ext[1]
            at = int(g[r, arch.I_AT])
            y = _chain(g, gs, r, at, m_i, int(g[r, arch.I_Z]), gs[r, arch.S_I_U], i)
            gs[r, arch.S_I_U] = i
            i_meas = y + g[r, at + m_i * m_i + 3 * m_i] * i
        if m_a > 0:
            g, gs = ext[0], ext[1]
            at = int(g[r, arch.A_AT])
            y = _chain(g, gs, r, at, m_a, int(g[r, arch.A_Z]), gs[r, arch.S_A_U], measured)
            gs[r, arch.S_A_U] = measured
            measured = y + g[r, at + m_a * m_a + 3 * m_a] * measured
        # 4. position controller at t_k+1 (§4), its output into the delay line tau_p
        angle = ratio * right[c_row, 0, col]
        ff = ff_v * (ratio * right[c_row, 1, col]) + ff_a * (ratio * right[c_row, 2, col])
        p_due = not sampled_p or k == next_p
        if p_due:
            angle_left, ff_left = angle, ff
            if sampled_p:
                next_p += every_p
            else:
                angle_left = ratio * left[c_row, 0, col]
                ff_left = (ff_v * (ratio * left[c_row, 1, col])
                           + ff_a * (ratio * left[c_row, 2, col]))
            e_right = angle - measured
            e_left = angle_left - measured
            if on_measurement:  # derivative on the measurement: acts on -theta
                y_left = y_right = -measured
            else:
                y_left, y_right = e_left, e_right
            p_int, p_filter, p_e, p_y, p_rest, u_left, u_p, p_limited = _controller_update(
                p_int, p_filter, p_e, p_y, p_rest, e_left, e_right, y_left, y_right,
                ff_left, ff, True, cp_kp, cp_ki, cp_gd, cp_a, cp_b, cp_c, has_derivative,
                i_max, period_p, not sampled_p, backward_p,
            )
            i_limited = p_limited
        slot = k & mask_p
        if direct:
            current_right[r, slot] = u_p
            if not hold_i:
                current_left[r, slot] = u_left
        else:  # the velocity loop and the filters at the current command
            acc_right = right[c_row, 2, col]
            acc_left = acc_right if sampled_p else left[c_row, 2, col]
            cmd_left, cmd_right, limited = _inner(ext, r, k, ratio, w, u_left, u_p, acc_left,
                                                  acc_right, p_due, sampled_p, dt, False)
            if ext[0][r, arch.CASCADE] != 0.0:
                i_limited = limited
            current_right[r, slot] = cmd_right
            if not hold_i:
                current_left[r, slot] = cmd_left
        # 5. current controller at t_k+1 (§3) on the measured current, its output into the
        #    delay line tau_c
        if not sampled_c or k == next_c:
            if sampled_c:
                next_c += every_c
            # the current command delayed by tau_p (_read at k, newest sample k)
            if hold_i:
                j = min(k - m_p - shift_p, k)
                i_cmd = current_right[r, j & mask_p] if j >= 0 else 0.0
            else:
                j = k - m_p
                if j > k:
                    i_cmd = current_right[r, k & mask_p]
                elif f_p == 0.0:
                    i_cmd = current_right[r, j & mask_p] if j >= 0 else 0.0
                else:
                    i_cmd = ((1.0 - f_p) * (current_left[r, j & mask_p] if j >= 0 else 0.0)
                             + f_p * (current_right[r, (j - 1) & mask_p] if j >= 1 else 0.0))
            e_right = i_cmd - i_meas
            e_left = e_right
            if not sampled_c:
                if hold_i:
                    j = min(k - m_p - 1, k)
                    i_left = current_right[r, j & mask_p] if j >= 0 else 0.0
                else:
                    j = k - m_p
                    if j > k:
                        i_left = current_right[r, k & mask_p]
                    elif f_p == 0.0:
                        i_left = current_left[r, j & mask_p] if j >= 0 else 0.0
                    else:
                        i_left = ((1.0 - f_p) * (current_left[r, j & mask_p] if j >= 0 else 0.0)
                                  + f_p * (current_right[r, (j - 1) & mask_p] if j >= 1
                                           else 0.0))
                e_left = i_left - i_meas
            c_int, _, c_e, _, c_rest, v_left, v_c, c_limited = _controller_update(
                c_int, 0.0, c_e, 0.0, c_rest, e_left, e_right, 0.0, 0.0, 0.0, 0.0,
                True, ci_kp, ci_ki, 0.0, 0.0, 0.0, 0.0, False, v_max, period_c, not sampled_c,
                backward_c,
            )
            if sampled_c:  # held: no jump within an update
                v_left = v_c
        slot = k & mask_c
        voltage_right[r, slot] = v_c
        if not sampled_c:
            voltage_left[r, slot] = v_left
        # 6. recording (SIGNALS)
        if k == next_record:
            rec_theta[out] = th  # always: the output angle
            if want_omega:
                rec_omega[out] = w
            if want_i:
                rec_i[out] = i
            if want_v:
                rec_v[out] = v
            if want_angle:
                rec_angle[out] = angle
            if want_i_cmd:
                rec_i_cmd[out] = i_cmd
            if want_integral:
                rec_integral[out] = cp_ki * p_int
            if want_p_limited:
                rec_p_limited[out] = i_limited != 0.0
            if want_c_limited:
                rec_c_limited[out] = c_limited != 0.0
            if loaded:
                rec_delta[out] = d_l
                rec_omega_l[out] = w_l
            next_record += record_every
            out += 1
    x[r, 0], x[r, 1], x[r, 2] = i, w, th
    s[r, _P_INT], s[r, _P_FILTER], s[r, _P_E], s[r, _P_Y], s[r, _P_REST] = (p_int, p_filter, p_e,
                                                                           p_y, p_rest)
    s[r, _P_U_LEFT], s[r, _P_U], s[r, _P_LIMITED] = u_left, u_p, p_limited
    s[r, _C_INT], s[r, _C_E], s[r, _C_REST] = c_int, c_e, c_rest
    s[r, _C_V_LEFT], s[r, _C_V], s[r, _C_LIMITED] = v_left, v_c, c_limited
    s[r, _I_CMD], s[r, _V], s[r, _THETA_CMD] = i_cmd, v, angle
    if loaded:
        x[r, 3], x[r, 4], s[r, _W_BEFORE] = w_l, d_l, w_before


# --- the tables the kernel reads, and the samples it holds (for compiled.py) -----------------

def parameter_table(params, dt, position_every, inner, method="backward"):
    """The kernel's per-run parameter table and delay steps of a batch.

    Parameters
    ----------
    params : LoopParameters
        Batch parameters.
    dt : float
        Step [s].
    position_every : int or None
        Update period of a sampled position controller in steps; None for a continuous one.
    inner : cas_freq.simulation.architecture.Inner
        The runs' inner blocks (:func:`~cas_freq.simulation.architecture.inner_blocks`): in a
        cascade the delay line read by the current controller is the velocity loop's (tau_v).
        The position controller's numbers come from the structure
        (:func:`~cas_freq.simulation.architecture.position`).
    method : {"backward", "tustin"}
        The sampled controllers' discretisation (:mod:`~cas_freq.simulation.controllers`).

    Returns
    -------
    tuple
        The table ``p`` (n_runs, _NP), the whole delay steps ``m`` (n_runs, 2) of tau_c and
        tau_p, whether any run has a derivative term, and the ring sizes (2**k slots, a slot is
        then a bit mask, not a division) of the voltage and current delay lines.
    """
    pr = params
    n = pr.n_runs
    phi, g_a, g_b = plant_step_matrices(pr, dt)
    p = np.zeros((n, _NP))
    p[:, _PHI:_PHI + 9] = phi.reshape(n, 9)
    p[:, _GA:_GA + 3] = g_a
    p[:, _GB:_GB + 3] = g_b
    position = arch.position(pr)
    p[:, _RATIO], p[:, _FF_V], p[:, _FF_A] = pr.ratio, position.ff_v, position.ff_a
    p[:, _CP_KP], p[:, _CP_KI], p[:, _I_MAX] = position.kp, position.ki, position.limit
    ci_kp, ci_ki, _, _, v_max = arch.current(pr)
    p[:, _CI_KP], p[:, _CI_KI], p[:, _V_MAX] = ci_kp, ci_ki, v_max
    p[:, _ON_MEASUREMENT] = pr.derivative_on_measurement
    p[:, _BACKWARD] = check_method(method) == "backward"
    # the derivative filter's coefficients (controllers.py), as the reference computes them
    has_derivative = bool(np.any(position.kd > 0))
    if has_derivative:
        filter_ = derivative_filter(position.kd, position.tf, dt * (position_every or 1),
                                    sampled=position_every is not None, method=method)
        p[:, _CP_GD], p[:, _CP_A], p[:, _CP_B], p[:, _CP_C] = filter_
    # the line the current controller reads: after the position controller (tau_p), or in a
    # cascade after the velocity controller (tau_v)
    current_delay = np.broadcast_to(inner.velocity_delay, (n,)) if inner.cascade else pr.tau_p
    (m_c, f_c), (m_p, f_p) = delay_steps(pr.tau_c, dt), delay_steps(current_delay, dt)
    p[:, _F_C], p[:, _F_P] = f_c, f_p
    slots = tuple(1 << (ring_size(m) - 1).bit_length() for m in (m_c, m_p))
    return p, np.stack([m_c, m_p], axis=1), has_derivative, slots


def controller_state(n_runs):
    """A zeroed controller state table (n_runs, _NS)."""
    return np.zeros((n_runs, _NS))


def sample(p, x, s, loaded):
    """The recorded signals at the present step (SIGNALS, then LOAD_SIGNALS if ``loaded``)."""
    values = (
        x[:, 2], x[:, 1], x[:, 0], s[:, _V], s[:, _THETA_CMD], s[:, _I_CMD],
        p[:, _CP_KI] * s[:, _P_INT], s[:, _P_LIMITED] != 0, s[:, _C_LIMITED] != 0,
    )
    return values + (x[:, 4], x[:, 3]) if loaded else values


def rigid_fin(p, q, floats, columns):
    """Fill the fin rows (delta, omega_L) of a loaded batch's unloaded runs, which the kernel
    skips: their fin follows the motor (theta/N, omega/N)."""
    unloaded = q[:, mech.LOADED] == 0.0
    ratio = p[unloaded, _RATIO][:, None]
    floats[7, unloaded, columns] = floats[0, unloaded, columns] / ratio
    floats[8, unloaded, columns] = floats[1, unloaded, columns] / ratio
