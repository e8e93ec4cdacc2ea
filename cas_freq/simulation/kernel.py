r"""The fixed-step loop compiled with numba: every run of a batch advanced in parallel.

This is the same discrete loop as the reference :class:`~cas_freq.simulation.engine.Engine`
(numpy, vectorised over runs), written per run as plain scalar code so that numba compiles it to
one machine-code loop, ``prange`` over the runs. Per step :math:`t_k \to t_{k+1}` and run
(docs/model.md §2-4 and §9 item 7):

1. **Voltage**: the terminal voltage over the step, read back from the delay line after the
   innermost loop (τc; first-order hold, constant for a sampled controller).
2. **Plant** (§2): :math:`x_{k+1} = \Phi x_k + G_a V_a + G_b V_b`, the exact step of the linear
   motor for a voltage linear over the step (matrices from
   :func:`~cas_freq.simulation.engine.plant_step_matrices`, computed in numpy and passed in).
   A loaded run (:mod:`~cas_freq.simulation.mechanics`) steps its 5 states with the matrices of
   the mode chosen at the step's start and the torques of its nonlinear terms (the table of
   :func:`~cas_freq.simulation.mechanics.table`); an unloaded run (its row of that table
   says so, a batch without a load passes a table of zeros) keeps the 3-state step, a branch
   taken per run (one machine code for both).
3. **Measurements**: each loop's measured signal, quantised to its encoder's count where it
   reads one, through its analog filters, stepped exactly.
4. **The loops**, one row each of the loop table (:func:`tables`, from
   :func:`~cas_freq.simulation.architecture.loop_steps`), outermost first: a loop due at this
   step reads its reference (the command, or the delayed output of the loop outside it), its
   measurement through its digital filters, updates its PI(D) with filtered derivative,
   feed-forward, clamp and anti-windup (:func:`_controller_update`, the scalar form of
   :class:`~cas_freq.simulation.controllers.Controller`) and its path filters; every loop's
   output, held between the updates of a sampled one, enters the delay line after it. Any
   nesting the structure declares, with filters at any point, is stepped by this one loop:
   every argument has the same numba type whatever the architecture, the sampling and the
   load, so each kernel is compiled once for them all.
5. Every ``record_every`` steps the signals of :data:`~cas_freq.simulation.engine.SIGNALS`
   asked for (:func:`record_mask`; theta always).

Each operation is written in the order of the reference, so that a single run gives the same
numbers to the last bit or nearly (the clamp flags where an output rests exactly at its limit
depend on the last bit); in a batch the reference's shortcuts are taken for the whole batch at
once and may round a run differently by an ulp.

The columns of the tables and the blocks the loop inlines (delay lines, controllers, filter
chains) are in :mod:`~cas_freq.simulation.kernel_blocks`.

The state lives in numpy arrays between calls (the engine of :mod:`cas_freq.simulation.compiled`
builds the tables with :func:`tables`), so the simulator can
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
    _FORWARD,
    _G_THETA_CMD,
    _G_V,
    _G_W_BEFORE,
    _GA,
    _GAP,
    _GB,
    _HELD,
    _L_A,
    _L_ANALOG,
    _L_B,
    _L_BACKWARD,
    _L_C,
    _L_DERIVATIVE,
    _L_EVERY,
    _L_F,
    _L_FF_A,
    _L_FF_V,
    _L_GD,
    _L_HAS_D,
    _L_HAS_FF,
    _L_KI,
    _L_KP,
    _L_LIMIT,
    _L_M,
    _L_ON_MEASUREMENT,
    _L_PATH,
    _L_QUANTUM,
    _L_SENSOR,
    _L_SIGNAL,
    _M_A1,
    _M_B1,
    _M_GA,
    _M_GB,
    _M_H,
    _M_PHI,
    _NG,
    _NL,
    _NP,
    _NS,
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
    _S_ANALOG_U,
    _S_DERIVATIVE_U,
    _S_E,
    _S_FILTER,
    _S_INT,
    _S_LIMITED,
    _S_MEASURED,
    _S_OUT,
    _S_OUT_LEFT,
    _S_PATH_U,
    _S_REF,
    _S_REST,
    _S_SENSOR_U,
    _S_Y,
    SIGNAL_CODES,
    _chain,
    _controller_update,
    _from_rest,
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
def start_batch(p, loops, s, g, x, chains, z, ring_right, ring_left, right, left, dt):
    """Controller outputs at t = 0 (plant at rest, nothing before), as Engine.start.

    Parameters
    ----------
    p : numpy.ndarray
        The plant's table (n_runs, _NP).
    loops : numpy.ndarray
        The loop table (n_runs, n_loops, _NL), innermost first (:func:`tables`).
    s, g : numpy.ndarray
        The loops' states (n_runs, n_loops, _NS) and the runs' (n_runs, _NG), updated.
    x : numpy.ndarray
        Plant states (n_runs, 3 or 5) [A, rad/s, rad, ...].
    chains, z : numpy.ndarray
        The filter chains' table and states (n_runs, columns), updated.
    ring_right, ring_left : numpy.ndarray
        The delay lines after each loop, right and left limits (n_runs, n_loops, 2**n slots),
        updated.
    right, left : numpy.ndarray
        Fin command at t = 0, right and left limits (1, 3, 1 or n_runs).
    dt : float
        Step [s].
    """
    n = x.shape[0]
    # nothing is recorded at t = 0 (the engine samples the states), and the plant is at rest
    floats = np.zeros((9, n, 1))
    flags = np.zeros((2, n, 1), dtype=np.bool_)
    q = np.zeros((n, mech.COLUMNS))
    # numpy scalars, not literals: a literal argument would type (and compile) another
    # _advance_run than advance_serial's
    zero, one, first = np.int64(0), np.int64(1), np.bool_(True)
    for r in range(n):
        _advance_run(r, p, loops, s, g, x, chains, z, ring_right, ring_left, right, left, zero,
                     one, zero, floats, flags, dt, q, zero, one, first)
        sampled = loops[r, 0, _L_EVERY] > 0.0
        g[r, _G_V] = _read(ring_right, ring_left, r, 0, int(loops[r, 0, _L_M]),
                           loops[r, 0, _L_F], 0, 0, False, sampled)


@_jit(parallel=True, nogil=True)
def advance_parallel(p, loops, s, g, x, chains, z, ring_right, ring_left, right, left, k0,
                     record_every, record_base, floats, flags, dt, q, record, active, n_steps):
    """:func:`advance_serial` with the runs shared among numba's threads (NUMBA_NUM_THREADS)."""
    for run in prange(x.shape[0]):
        if not active[run]:
            continue
        _advance_run(np.int64(run), p, loops, s, g, x, chains, z, ring_right, ring_left, right,
                     left, k0, record_every, record_base, floats, flags, dt, q, record,
                     n_steps, np.bool_(False))


@_jit(nogil=True)
def advance_serial(p, loops, s, g, x, chains, z, ring_right, ring_left, right, left, k0,
                   record_every, record_base, floats, flags, dt, q, record, active, n_steps):
    """Advance every run from step ``k0`` by ``n_steps`` steps (Engine._step, per run).

    Parameters
    ----------
    p, loops, s, g, x, chains, z, ring_right, ring_left
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
    dt : float
        Step [s].
    q : numpy.ndarray
        The loaded plant's table (n_runs, mechanics.COLUMNS), zeros for a batch without a
        load. Runs with ``q[r, LOADED] == 0`` take the unloaded path (the 3-state plant).
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
        _advance_run(r, p, loops, s, g, x, chains, z, ring_right, ring_left, right, left, k0,
                     record_every, record_base, floats, flags, dt, q, record, n_steps,
                     np.bool_(False))


@_jit()
def _advance_run(r, p, loops, s, g, x, chains, z, ring_right, ring_left, right, left, k0,
                 record_every, record_base, floats, flags, dt, q, record, n_steps, first):
    """Advance run ``r`` (arguments of :func:`advance_serial`); with ``first``, make the
    outputs at t = 0 instead (:func:`start_batch`: no plant step, every loop updated, the
    filters and continuous controllers from rest).

    The plant's states are held in local variables over the steps and written back at the
    end; the loops' in the run's rows of the state. The loop calls no function that takes an
    array: numba counts references to an array passed to a function, inlined or not, with an
    atomic add and subtract per call, which cost more than the arithmetic of a step and, on
    the arrays the threads share, contend between them. So the delay-line reads and pushes and
    the command rows are written out here on the run's rows, with the same operations in the
    same order as the reference (the same numbers to the bit).
    """
    one_row = right.shape[0] == 1  # the command's rows: one for every step
    n_loops = loops.shape[1]
    top = n_loops - 1
    phi0, phi1, phi2 = p[r, _PHI], p[r, _PHI + 1], p[r, _PHI + 2]
    phi3, phi4, phi5 = p[r, _PHI + 3], p[r, _PHI + 4], p[r, _PHI + 5]
    phi6, phi7, phi8 = p[r, _PHI + 6], p[r, _PHI + 7], p[r, _PHI + 8]
    g_a0, g_a1, g_a2 = p[r, _GA], p[r, _GA + 1], p[r, _GA + 2]
    g_b0, g_b1, g_b2 = p[r, _GB], p[r, _GB + 1], p[r, _GB + 2]
    ratio = p[r, _RATIO]
    # the voltage line after loop 0 (the plant's input)
    m_c, f_c = int(loops[r, 0, _L_M]), loops[r, 0, _L_F]
    sampled_c = loops[r, 0, _L_EVERY] > 0.0
    shift_c = 1 if f_c > 0.0 else 0  # v_a and v of a holding line (want_left False)
    sampled_top = loops[r, top, _L_EVERY] > 0.0
    col = r if right.shape[2] > 1 else 0
    mask = ring_right.shape[2] - 1
    lines_right, lines_left = ring_right[r], ring_left[r]  # the run's delay lines
    state, table = s[r], loops[r]
    # the table's whole numbers as integers, converted once: each loop's period, the whole
    # steps of the delay after it, and per filter chain its order, first column and states
    whole = np.empty((n_loops, 14), dtype=np.int64)
    for j in range(n_loops):
        whole[j, 0], whole[j, 1] = int(table[j, _L_EVERY]), int(table[j, _L_M])
        for c in range(9):
            whole[j, 2 + c] = int(table[j, _L_ANALOG + c])
        for c in range(3):
            whole[j, 11 + c] = int(table[j, _L_DERIVATIVE + c])
    i, w, th = x[r, 0], x[r, 1], x[r, 2]
    v, angle = g[r, _G_V], g[r, _G_THETA_CMD]
    # the next step at which to record (a counter, not a division per step)
    next_record = (k0 // record_every + 1) * record_every
    out = next_record // record_every - record_base
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
    loaded_next = np.empty(mech.NX)  # the loaded plant's next states
    if loaded:
        w_l, d_l, w_before = x[r, 3], x[r, 4], g[r, _G_W_BEFORE]
        compliant = q[r, _Q_COMPLIANT] != 0.0
        half, k_g, tau_h = q[r, _Q_HALF], q[r, _Q_K_G], q[r, _Q_TAU_H]
        c_g = q[r, _Q_C_G]
        j_l, b_l, k_h, coulomb = q[r, _Q_J_L], q[r, _Q_B_L], q[r, _Q_K_H], q[r, _Q_F_C]
        e_forward, e_back = q[r, _Q_E_FORWARD], q[r, _Q_E_BACK]
        rec_delta, rec_omega_l = floats[7, r], floats[8, r]
    for row in range(n_steps):
        k = k0 + row
        c_row = 0 if one_row else row
        if not first:
            # 1. voltage at the terminals over [t_k, t_k+1]: loop 0's output delayed by tau_c,
            #    linear over the step (held for a sampled controller)
            if sampled_c:
                j = min(k - m_c - shift_c, k)
                v_a = lines_right[0, j & mask] if j >= 0 else 0.0
                v_b = v_a
                j = min(k + 1 - m_c - shift_c, k)
                v = lines_right[0, j & mask] if j >= 0 else 0.0
            else:
                j = k - m_c
                if j > k:
                    v_a = lines_right[0, k & mask]
                elif f_c == 0.0:
                    v_a = lines_right[0, j & mask] if j >= 0 else 0.0
                else:
                    v_a = ((1.0 - f_c) * (lines_left[0, j & mask] if j >= 0 else 0.0)
                           + f_c * (lines_right[0, (j - 1) & mask] if j >= 1 else 0.0))
                j = k + 1 - m_c
                if j > k:
                    v_b = lines_right[0, k & mask]
                    v = v_b
                elif f_c == 0.0:
                    v_b = lines_left[0, j & mask] if j >= 0 else 0.0
                    v = lines_right[0, j & mask] if j >= 0 else 0.0
                else:
                    before = f_c * (lines_right[0, (j - 1) & mask] if j >= 1 else 0.0)
                    v_b = (1.0 - f_c) * (lines_left[0, j & mask] if j >= 0 else 0.0) + before
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
                for row_x in range(mech.NX):  # each state's sum in the reference's order
                    a_x = at + mech.NX * row_x
                    acc_x = (q[r, a_x] * i + q[r, a_x + 1] * w + q[r, a_x + 2] * th
                             + q[r, a_x + 3] * w_l + q[r, a_x + 4] * d_l)
                    acc_x += q[r, ga + row_x] * v_a
                    acc_x += q[r, gb + row_x] * v_b
                    acc_x += q[r, h + 2 * row_x] * tau_m
                    acc_x += q[r, h + 2 * row_x + 1] * tau_l
                    loaded_next[row_x] = acc_x
                i, w, th = loaded_next[0], loaded_next[1], loaded_next[2]
                w_l, d_l = loaded_next[3], loaded_next[4]
            k += 1
        # 3. the measurements at t_k+1 through the loops' analog filters (Engine._measure)
        output = ratio * d_l if loaded else th  # the output angle on the motor's scale
        for j in range(n_loops):
            order = whole[j, 2]
            if order == 0:
                continue
            code = table[j, _L_SIGNAL]
            u = i if code == 0.0 else (w if code == 1.0 else (th if code == 2.0 else output))
            quantum = table[j, _L_QUANTUM]
            if quantum > 0.0:  # the encoder's count (architecture.quantised)
                u = quantum * np.floor(u / quantum + 0.5)
            y, d = _chain(chains, z, r, whole[j, 3], order, whole[j, 4],
                          state[j, _S_ANALOG_U], u, first)
            state[j, _S_MEASURED] = y + d * u
            state[j, _S_ANALOG_U] = u
        # 4. the command at t_k+1: motor angle, rate and acceleration, right and left limits
        angle = ratio * right[c_row, 0, col]
        rate, acc = ratio * right[c_row, 1, col], ratio * right[c_row, 2, col]
        angle_left, rate_left, acc_left = angle, rate, acc
        if not sampled_top:  # a sampler sees the values from now on
            angle_left = ratio * left[c_row, 0, col]
            rate_left, acc_left = ratio * left[c_row, 1, col], ratio * left[c_row, 2, col]
        # 5. every loop due, outermost first (Engine._loops): its reference (the command, or
        #    the delayed output of the loop outside it), its measurement through its digital
        #    filters, its controller (§3, §4), its path filters; its output into the delay
        #    line after it
        for j in range(top, -1, -1):
            every = whole[j, 0]
            sampled = every > 0
            if first or not sampled or k % every == 0:
                if j == top:
                    reference, reference_left = angle, angle_left
                else:  # the delay line after loop j + 1, read at t_k (its newest sample k)
                    m, f = whole[j + 1, 1], table[j + 1, _L_F]
                    hold = table[j + 1, _L_EVERY] > 0.0
                    at = k - m
                    if hold:
                        at = min(at - (1 if f > 0.0 else 0), k)
                        reference = lines_right[j + 1, at & mask] if at >= 0 else 0.0
                    elif f == 0.0:
                        reference = lines_right[j + 1, at & mask] if at >= 0 else 0.0
                    else:
                        reference = (
                            (1.0 - f) * (lines_left[j + 1, at & mask] if at >= 0 else 0.0)
                            + f * (lines_right[j + 1, (at - 1) & mask] if at >= 1 else 0.0))
                    reference_left = reference
                    if not sampled:  # its left limit
                        if hold:
                            at = min(k - m - 1, k)
                            reference_left = lines_right[j + 1, at & mask] if at >= 0 else 0.0
                        elif f == 0.0:
                            reference_left = lines_left[j + 1, at & mask] if at >= 0 else 0.0
                state[j, _S_REF] = reference
                if whole[j, 2] > 0:
                    measured = state[j, _S_MEASURED]
                else:
                    code = table[j, _L_SIGNAL]
                    measured = (i if code == 0.0 else
                                (w if code == 1.0 else (th if code == 2.0 else output)))
                    quantum = table[j, _L_QUANTUM]
                    if quantum > 0.0:
                        measured = quantum * np.floor(measured / quantum + 0.5)
                order = whole[j, 5]
                if order > 0:
                    y, d = _chain(chains, z, r, whole[j, 6], order, whole[j, 7],
                                  state[j, _S_SENSOR_U], measured, first)
                    state[j, _S_SENSOR_U] = measured
                    measured = y + d * measured
                e_right = reference - measured
                e_left = reference_left - measured
                if table[j, _L_ON_MEASUREMENT] != 0.0:  # the derivative acts on -measured
                    y_left = y_right = -measured
                else:
                    y_left, y_right = e_left, e_right
                order = whole[j, 11]
                if order > 0:  # the derivative's input through its window
                    y, d = _chain(chains, z, r, whole[j, 12], order, whole[j, 13],
                                  state[j, _S_DERIVATIVE_U], y_left, first)
                    state[j, _S_DERIVATIVE_U] = y_right
                    y_left, y_right = y + d * y_left, y + d * y_right
                ff_left = ff_right = 0.0
                if table[j, _L_HAS_FF] != 0.0:
                    ff_v, ff_a = table[j, _L_FF_V], table[j, _L_FF_A]
                    ff_right = ff_v * rate + ff_a * acc
                    ff_left = ff_right if sampled else ff_v * rate_left + ff_a * acc_left
                (state[j, _S_INT], state[j, _S_FILTER], state[j, _S_E], state[j, _S_Y],
                 state[j, _S_REST], u_left, u_right, state[j, _S_LIMITED]) = _controller_update(
                    state[j, _S_INT], state[j, _S_FILTER], state[j, _S_E], state[j, _S_Y],
                    state[j, _S_REST], e_left, e_right, y_left, y_right, ff_left, ff_right,
                    sampled or not first, table[j, _L_KP], table[j, _L_KI], table[j, _L_GD],
                    table[j, _L_A], table[j, _L_B], table[j, _L_C], table[j, _L_HAS_D] != 0.0,
                    table[j, _L_LIMIT], dt * max(every, 1), not sampled,
                    table[j, _L_BACKWARD] != 0.0,
                )
                if sampled:  # held: no jump within an update
                    u_left = u_right
                order = whole[j, 8]
                if order > 0:
                    y, d = _chain(chains, z, r, whole[j, 9], order, whole[j, 10],
                                  state[j, _S_PATH_U], u_left, first)
                    state[j, _S_PATH_U] = u_right
                    u_left, u_right = y + d * u_left, y + d * u_right
                state[j, _S_OUT_LEFT], state[j, _S_OUT] = u_left, u_right
            slot = k & mask
            lines_right[j, slot] = state[j, _S_OUT]
            if not sampled:
                lines_left[j, slot] = state[j, _S_OUT_LEFT]
        # 6. recording (SIGNALS)
        if not first and k == next_record:
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
                rec_i_cmd[out] = state[0, _S_REF]
            if want_integral:
                rec_integral[out] = table[top, _L_KI] * state[top, _S_INT]
            if want_p_limited:
                rec_p_limited[out] = state[1, _S_LIMITED] != 0.0
            if want_c_limited:
                rec_c_limited[out] = state[0, _S_LIMITED] != 0.0
            if loaded:
                rec_delta[out] = d_l
                rec_omega_l[out] = w_l
            next_record += record_every
            out += 1
    x[r, 0], x[r, 1], x[r, 2] = i, w, th
    g[r, _G_V], g[r, _G_THETA_CMD] = v, angle
    if loaded:
        x[r, 3], x[r, 4], g[r, _G_W_BEFORE] = w_l, d_l, w_before


# --- the tables the kernel reads, and the samples it holds (for compiled.py) -----------------

def _chain_columns(chain):
    """Columns of a filter chain in the chain table (Phi row-major, G_a, G_b, C, D)."""
    m = chain.order
    return m * m + 3 * m + 1


def _put_chain(table, start, chain):
    n, m = chain.phi.shape[:2]
    table[:, start:start + m * m] = chain.phi.reshape(n, m * m)
    start += m * m
    for part in (chain.g_a, chain.g_b, chain.c):
        table[:, start:start + m] = part
        start += m
    table[:, start] = chain.d


def tables(params, dt, every=None, method="backward"):
    """The kernel's tables of a batch, from the loops of
    :func:`~cas_freq.simulation.architecture.loop_steps`.

    Parameters
    ----------
    params : LoopParameters
        Batch parameters.
    dt : float
        Step [s].
    every : dict, optional
        Loop name -> update period of its sampled controller in steps (None or absent:
        continuous).
    method : {"backward", "tustin"}
        The sampled controllers' and filters' discretisation
        (:mod:`~cas_freq.simulation.controllers`).

    Returns
    -------
    tuple of numpy.ndarray
        The plant's table ``p`` (n_runs, _NP), the loop table (n_runs, n_loops, _NL), zeroed
        loop and run states, the filter chains' table and (zeroed) states, and the delay
        lines' ring buffers (n_runs, n_loops, 2**k slots: a slot is then a bit mask, not a
        division), right and left limits.
    """
    pr = params
    n = pr.n_runs
    steps = arch.loop_steps(pr, dt, every, method)
    phi, g_a, g_b = plant_step_matrices(pr, dt)
    p = np.zeros((n, _NP))
    p[:, _PHI:_PHI + 9] = phi.reshape(n, 9)
    p[:, _GA:_GA + 3] = g_a
    p[:, _GB:_GB + 3] = g_b
    p[:, _RATIO] = pr.ratio
    loops = np.zeros((n, len(steps), _NL))
    backward = check_method(method) == "backward"
    chain_list = [(j, at, chain) for j, loop in enumerate(steps)
                  for at, chain in ((_L_ANALOG, loop.analog), (_L_SENSOR, loop.sensor),
                                    (_L_PATH, loop.path), (_L_DERIVATIVE, loop.derivative))
                  if chain is not None]
    chains = np.zeros((n, 1 + sum(_chain_columns(chain) for _, _, chain in chain_list)))
    column = state_column = 0
    for j, at, chain in chain_list:
        loops[:, j, at:at + 3] = chain.order, column, state_column
        _put_chain(chains, column, chain)
        column += _chain_columns(chain)
        state_column += 2 * chain.order  # its states, then as many scratch columns
    m_max = 0
    for j, loop in enumerate(steps):
        row = loops[:, j]
        row[:, _L_KP], row[:, _L_KI], row[:, _L_LIMIT] = loop.kp, loop.ki, loop.limit
        # the derivative filter's coefficients (controllers.py), as the reference computes them
        if np.any(loop.kd > 0):
            row[:, _L_HAS_D] = 1.0
            row[:, _L_GD], row[:, _L_A], row[:, _L_B], row[:, _L_C] = derivative_filter(
                loop.kd, loop.tf, dt * (loop.every or 1), sampled=loop.sampled, method=method)
        row[:, _L_FF_V], row[:, _L_FF_A] = loop.ff_v, loop.ff_a
        row[:, _L_HAS_FF] = loop.has_feedforward
        row[:, _L_ON_MEASUREMENT] = loop.on_measurement
        row[:, _L_EVERY] = loop.every or 0
        row[:, _L_BACKWARD] = loop.sampled and backward
        row[:, _L_SIGNAL] = SIGNAL_CODES[loop.signal]
        if loop.quantum is not None:
            row[:, _L_QUANTUM] = loop.quantum
        m, row[:, _L_F] = delay_steps(loop.delay, dt)
        row[:, _L_M] = m
        m_max = max(m_max, ring_size(m))
    slots = 1 << (m_max - 1).bit_length()
    return (p, loops, np.zeros((n, len(steps), _NS)), np.zeros((n, _NG)), chains,
            np.zeros((n, 1 + state_column)),
            np.zeros((n, len(steps), slots)), np.zeros((n, len(steps), slots)))


def sample(loops, s, g, x, loaded):
    """The recorded signals at the present step (SIGNALS, then LOAD_SIGNALS if ``loaded``)."""
    top = loops.shape[1] - 1
    values = (
        x[:, 2], x[:, 1], x[:, 0], g[:, _G_V], g[:, _G_THETA_CMD], s[:, 0, _S_REF],
        loops[:, top, _L_KI] * s[:, top, _S_INT], s[:, 1, _S_LIMITED] != 0,
        s[:, 0, _S_LIMITED] != 0,
    )
    return values + (x[:, 4], x[:, 3]) if loaded else values


def rigid_fin(p, q, floats, columns):
    """Fill the fin rows (delta, omega_L) of a loaded batch's unloaded runs, which the kernel
    skips: their fin follows the motor (theta/N, omega/N)."""
    unloaded = q[:, mech.LOADED] == 0.0
    ratio = p[unloaded, _RATIO][:, None]
    floats[7, unloaded, columns] = floats[0, unloaded, columns] / ratio
    floats[8, unloaded, columns] = floats[1, unloaded, columns] / ratio
