r"""The fixed-step core: every run of a batch advanced at once with numpy.

Plant (docs/model.md, report Fig. 5), states :math:`x = (i, \omega, \theta)`:

.. math::
    L \dot i = V - R i - K_e \omega, \qquad J \dot\omega = K_m i - \mu_v \omega, \qquad
    \dot\theta = \omega

It is linear, so each step of length dt is integrated exactly (:func:`plant_step_matrices`) for a
terminal voltage that is linear over the step (first-order hold; constant for a sampled current
controller). That voltage is the innermost (current) controller's output delayed by
:math:`\tau_c`, so it is known before the step: the delays make the scheme explicit. After each
plant step the loops of :func:`~cas_freq.simulation.architecture.loop_steps` are updated from
the outermost in (the position controller on the measured angle, then any velocity controller,
then the current controller, each on the delayed output of the one outside it;
:mod:`~cas_freq.simulation.controllers`) and their outputs pushed into the delay lines after
them (:mod:`~cas_freq.simulation.delay_line`).

Where some run of the batch has a load or drivetrain term, every run of the batch steps the
5-state loaded plant of :mod:`~cas_freq.simulation.mechanics` instead (mode and torques decided
per run at the start of each step), and the fin's angle and rate are recorded as well
(:data:`LOAD_SIGNALS`). A batch without any keeps the 3-state step below, to the bit.

Continuous controllers are updated every step and read back with linear interpolation, so the
whole loop is integrated to second order in dt. Sampled controllers are updated every
``n`` steps and held (zero-order hold), each loop at its own period (``every``, a dict of
loop name to steps, :data:`~cas_freq.simulation.architecture.LOOPS`), discretised by the
sampling method (:mod:`~cas_freq.simulation.controllers`); the filters after a sampled
controller at its rate (:mod:`~cas_freq.simulation.architecture`).
"""

import math

import numpy as np

import cas_freq.simulation.architecture as architecture
from cas_freq.simulation.commands import Step, fin_limits
from cas_freq.simulation.controllers import Controller
from cas_freq.simulation.delay_line import DelayLine
from cas_freq.simulation.mechanics import NX, Drivetrain, distinct_exponentials

#: Names of the signals recorded per sample, in the order of :meth:`Engine.sample`.
SIGNALS = (
    "theta", "omega", "i", "V", "theta_cmd", "current_command", "position_integral",
    "current_limited", "voltage_limited",
)
#: Signals recorded after :data:`SIGNALS` when some run of the batch is loaded
#: (:mod:`~cas_freq.simulation.mechanics`): the fin's angle [rad] and rate [rad/s], states of a
#: compliant gear (a rigid gear's follow the motor, theta/N and omega/N).
LOAD_SIGNALS = ("delta", "omega_L")

#: The recorded signals held as booleans (the others are floats).
FLAG_SIGNALS = ("current_limited", "voltage_limited")

_CHUNK = 2048


def recorded_rows(first, n_steps, record_every):
    """Samples recorded over steps ``first`` .. ``first + n_steps - 1`` (every
    ``record_every``-th step)."""
    return (first + n_steps - 1) // record_every - (-(-first // record_every)) + 1


def plant_step_matrices(params, dt):
    r"""Exact one-step matrices of the plant for an input linear over the step.

    With :math:`V(t_k + s) = V_a + (V_b - V_a) s/dt`,
    :math:`x_{k+1} = \Phi x_k + G_a V_a + G_b V_b`, from the exponential of the augmented
    matrix :math:`[[A, B, 0], [0, 0, 1/dt], [0, 0, 0]] \, dt` (Franklin, Powell & Workman,
    *Digital Control of Dynamic Systems*, 3rd ed., §6.3.2, first-order hold).

    Parameters
    ----------
    params : LoopParameters
        Batch parameters.
    dt : float
        Step [s].

    Returns
    -------
    tuple of numpy.ndarray
        :math:`\Phi` (n_runs, 3, 3), :math:`G_a` and :math:`G_b` (n_runs, 3).
    """
    p = params
    m = np.zeros((p.n_runs, 5, 5))
    m[:, 0, 0] = -p.R / p.L
    m[:, 0, 1] = -p.Ke / p.L
    m[:, 1, 0] = p.Km / p.J
    m[:, 1, 1] = -p.mu_v / p.J
    m[:, 2, 1] = 1.0
    m[:, 0, 3] = 1.0 / p.L
    m[:, 3, 4] = 1.0 / dt
    e = distinct_exponentials(m * dt)
    return e[:, :3, :3], e[:, :3, 3] - e[:, :3, 4], e[:, :3, 4].copy()


def _merged_steps(commands):
    """One step per run (a batch of step sizes) as one Step of per-run amplitudes and starts.

    The same values at every time, computed at once instead of one command at a time; other
    commands are returned as given.
    """
    if not (isinstance(commands, (list, tuple)) and commands
            and all(type(c) is Step for c in commands)):
        return commands
    amplitudes = [np.asarray(c.amplitude_rad, dtype=float) for c in commands]
    starts = [np.asarray(c.start_s, dtype=float) for c in commands]
    if any(a.ndim or s.ndim for a, s in zip(amplitudes, starts, strict=True)):
        return commands
    return Step(np.array(amplitudes), np.array(starts))


class CommandSet:
    """Motor-angle commands of every run, evaluated for many times at once.

    Parameters
    ----------
    commands : command or sequence of commands
        One command (whose parameters broadcast to (n_runs,)) or one per run.
    ratio : numpy.ndarray
        Gear ratio per run [-].
    """

    def __init__(self, commands, ratio):
        self.commands = _merged_steps(commands)
        self.ratio = ratio

    @property
    def columns(self):
        """Columns of :meth:`fin`: n_runs for one command per run, else at most that."""
        return self.fin(np.zeros(1))[0].shape[1]

    def fin(self, t, left=False):
        """(angle [rad], rate [rad/s], acceleration [rad/s^2]) at the fin at times ``t`` [s].

        Each of shape (len(t), 1) where every run has the same command, else (len(t), n_runs).
        """
        if isinstance(self.commands, (list, tuple)):
            parts = [c.fin(t, left=left) for c in self.commands]
            return tuple(np.stack([np.broadcast_to(p[j], t.shape) for p in parts], axis=1)
                         for j in range(3))
        return self._shaped(self.commands.fin(t[:, None], left), t)

    def held_from(self):
        """The time [s] after which every command holds its value (both limits; a step after
        its start), inf where it is not known to."""
        if isinstance(self.commands, (list, tuple)):
            return math.inf
        held = getattr(self.commands, "held_from", None)
        return math.inf if held is None else held()

    def fin_limits(self, t):
        """``(fin(t), fin(t, left=True))``, from one evaluation of the command where it can."""
        if isinstance(self.commands, (list, tuple)):
            return self.fin(t), self.fin(t, left=True)
        return tuple(self._shaped(limit, t) for limit in fin_limits(self.commands, t[:, None]))

    @staticmethod
    def _shaped(out, t):
        """The (angle, rate, acceleration) of one command broadcast to (len(t), columns)."""
        shape = np.broadcast(*out).shape
        if len(shape) < 2:
            shape = (t.shape[0], 1)
        return tuple(a if np.shape(a) == shape else np.broadcast_to(a, shape) for a in out)

    def motor_limits(self, t):
        """Right and left limits of (angle [rad], rate [rad/s], acceleration [rad/s^2]) at
        the motor, each (len(t), n), from :meth:`fin_limits`."""
        n = self.ratio.shape[0]
        return tuple(tuple(self.ratio * np.broadcast_to(part, (t.shape[0], n)) for part in limit)
                     for limit in self.fin_limits(t))


class Engine:
    """State of a batch of runs, advanced step by step.

    The loops are the rows of :func:`~cas_freq.simulation.architecture.loop_steps`, innermost
    first; each step, after the plant, every loop due is updated from the outermost in, each
    reading the delayed output of the loop outside it (the outermost the command), and each
    loop's output is pushed into the delay line after it (the innermost's drives the plant).

    Per step the work is a few numpy operations on arrays of shape (n_runs,), so for small
    batches their fixed cost dominates: the engine takes the commands' rows a chunk of steps at
    a time, computes the feed-forward for the chunk at once, and tells the controllers where the
    command does not jump (they then compute each output once, see
    :class:`~cas_freq.simulation.controllers.Controller`).

    Parameters
    ----------
    params : LoopParameters
        Batch parameters.
    commands : CommandSet
        Commands of every run.
    dt : float
        Step [s].
    every : dict, optional
        Loop name (:data:`~cas_freq.simulation.architecture.LOOPS`) -> update period of its
        sampled controller in steps; None or absent for a continuous one.
    method : {"backward", "tustin"}
        The sampled controllers' and filters' discretisation.
    """

    def __init__(self, params, commands, dt, every=None, method="backward"):
        p = params
        n = p.n_runs
        self.dt = dt
        self.commands = commands
        # a batch with some loaded run: the 5-state plant of mechanics.py for every run
        self.drivetrain = Drivetrain(p, dt) if np.any(p.loaded) else None
        #: Names of the signals of :meth:`sample` and :meth:`advance`.
        self.signals = SIGNALS if self.drivetrain is None else SIGNALS + LOAD_SIGNALS
        if self.drivetrain is None:
            self.phi, self.g_a, self.g_b = plant_step_matrices(p, dt)
        self.x = np.zeros((n, 3 if self.drivetrain is None else NX))  # (i, omega, theta, ...)
        self.omega_before = np.zeros(n)  # omega one step earlier (loaded plant)
        self._next = np.empty((n, 3))
        self._inputs = np.empty((n, 3))
        self._volts = np.empty((n, 3))
        self.ratio, self.loaded = p.ratio, p.loaded
        #: The loops, innermost first (architecture.loop_steps), and per loop its controller,
        #: the delay line after it and the states of its filters (None: none).
        self.loops = loops = architecture.loop_steps(p, dt, every, method)
        self.controllers = [
            Controller(loop.kp, loop.ki, loop.kd, loop.tf, loop.limit,
                       dt * (loop.every or 1), sampled=loop.sampled, method=method)
            for loop in loops]
        self.lines = [DelayLine(loop.delay, dt, hold=loop.sampled) for loop in loops]
        self.analog, self.sensor, self.path, self.derivative = (
            [None if chain is None else architecture.FilterState(chain) for chain in chains]
            for chains in zip(*((loop.analog, loop.sensor, loop.path, loop.derivative)
                                for loop in loops), strict=True))
        top = loops[-1]
        on = top.on_measurement
        # Derivative input: the error everywhere (None), -theta everywhere (True), or mixed.
        self._derivative_on = None if not on.any() else (True if on.all() else on)
        #: Per loop: its outputs' left and right limits, where its right one was clamped, the
        #: reference it read at its last update and its measurement at this step.
        self.out_left, self.out = [None] * len(loops), [None] * len(loops)
        self.limited = [None] * len(loops)
        self.reference, self.measured = [None] * len(loops), [None] * len(loops)
        #: The controller whose output is the current command (its clamp is current_limited).
        self.commander = self.controllers[1]
        self.k = 0

    def _signal(self, name):
        """The plant signal a loop measures (structure.SIGNALS); the output angle on the
        motor's scale N*delta (a rigid, unloaded run's is theta)."""
        if name == "current":
            return self.x[:, 0]
        if name == "motor_velocity":
            return self.x[:, 1]
        theta = self.x[:, 2]
        if name == "motor_angle" or self.drivetrain is None:
            return theta
        return np.where(self.loaded, self.ratio * self.x[:, 4], theta)

    def _measure(self, start=False):
        """Each loop's measurement at this step: its signal, quantised to its encoder's count
        where it reads one, through its analog filters (if any), stepped exactly for a
        measurement linear over the step."""
        for j, loop in enumerate(self.loops):
            measured = self._signal(loop.signal)
            if loop.quantum is not None:  # the encoder's count
                measured = architecture.quantised(measured, loop.quantum)
            chain = self.analog[j]
            if chain is not None:
                measured = (chain.start if start else chain.step)(measured, measured)[1]
            self.measured[j] = measured

    def _due(self, j, k):
        every = self.loops[j].every
        return every is None or k % every == 0

    def _update(self, j, k, left, right, start=False):
        """Loop ``j``'s controller at step ``k``: its reference (the command, or the delayed
        output of loop j + 1), its measurement through its digital filters, its output
        through the filters in its path."""
        loop, controller = self.loops[j], self.controllers[j]
        top = j == len(self.loops) - 1
        if top:
            reference, reference_left = right[0], left[0]
        elif loop.sampled:  # a sampler sees the reference from now on
            reference = reference_left = self.lines[j + 1].read(k)
        else:
            reference, reference_left = self.lines[j + 1].read_limits(k)
        self.reference[j] = reference
        measured = self.measured[j]
        if self.sensor[j] is not None:
            chain = self.sensor[j]
            measured = (chain.start if start else chain.step)(measured, measured)[1]
        e_r = reference - measured
        e_l = e_r if reference_left is reference else reference_left - measured
        y_r = y_l = None  # the derivative's input: the error, or -measured where it says so
        if top and self._derivative_on is not None:
            y_r = self._derivative_input(e_r, measured)
            y_l = y_r if e_l is e_r else self._derivative_input(e_l, measured)
        if self.derivative[j] is not None:  # through its window
            chain = self.derivative[j]
            y_l, y_r = (e_l, e_r) if y_r is None else (y_l, y_r)
            same = y_l is y_r
            y_l, y_r = (chain.start if start else chain.step)(y_l, y_r)
            y_l = y_r if same else y_l
        ff_r, ff_l = right[1][j], left[1][j]
        if loop.sampled:  # a sampler sees the values from now on
            ff_l = ff_r
        step = controller.start if start else controller.update
        u_left, u_right, self.limited[j] = step(e_l, e_r, y_l, y_r, ff_l, ff_r)
        if loop.sampled:  # held: no jump within an update
            u_left = u_right
        if self.path[j] is not None:
            chain = self.path[j]
            u_left, u_right = (chain.start if start else chain.step)(u_left, u_right)
        self.out_left[j], self.out[j] = u_left, u_right

    def _derivative_input(self, e, measured):
        """-``measured`` where the derivative acts on the measurement, else the error ``e``."""
        on = self._derivative_on
        return -measured if on is True else np.where(on, -measured, e)

    def _loops(self, k, left, right, start=False):
        """Every loop due at step ``k``, outermost first, each output into its delay line."""
        for j in range(len(self.loops) - 1, -1, -1):
            if start or self._due(j, k):
                self._update(j, k, left, right, start)
            self.lines[j].push(k, self.out[j], self.out_left[j])

    def _command_rows(self, times):
        """The commands at ``times``: right and left limits, and where they differ.

        Returns
        -------
        tuple
            Per limit (right, left): the motor angle [rad] (len(times), n_runs) and per loop
            its feed-forward (same shape, or None where it is 0 throughout); and per time,
            whether the limits differ (a list of bool).
        """
        (angle, rate, accel), (angle_left, rate_left, accel_left) = (
            self.commands.motor_limits(times))
        if self.loops[-1].sampled:  # a sampler sees the values from now on
            angle_left, rate_left, accel_left = angle, rate, accel
        jumps = np.any(angle != angle_left, axis=1)
        ffs, ffs_left = [], []
        for loop in self.loops:
            ff = ff_left = None
            if loop.has_feedforward:
                ff = loop.ff_v * rate + loop.ff_a * accel
                ff_left = loop.ff_v * rate_left + loop.ff_a * accel_left
                if not (np.count_nonzero(ff) or np.count_nonzero(ff_left)):
                    ff = ff_left = None
                else:
                    jumps |= np.any(ff != ff_left, axis=1)
            ffs.append(ff)
            ffs_left.append(ff_left)
        return (angle, ffs), (angle_left, ffs_left), jumps.tolist()

    @staticmethod
    def _row(rows, j):
        """Row ``j`` of a limit of :meth:`_command_rows`: (angle, per loop feed-forward or
        None)."""
        angle, ffs = rows
        return angle[j], tuple(None if ff is None else ff[j] for ff in ffs)

    def start(self):
        """Controller outputs at t = 0 (plant at rest, nothing before), then the sample at 0."""
        rows, rows_left, _ = self._command_rows(np.zeros(1))
        right, left = self._row(rows, 0), self._row(rows_left, 0)
        self.theta_cmd = right[0]
        self._measure(start=True)
        self._loops(0, left, right, start=True)
        self.v = self.lines[0].read(0)
        return tuple(np.array(value) for value in self.sample())

    def sample(self):
        """The recorded signals at the present step, in the order of :attr:`signals`.

        Some are views of the engine's state, valid until the next step.
        """
        top = self.controllers[-1]
        values = (
            self.x[:, 2], self.x[:, 1], self.x[:, 0], self.v, self.theta_cmd,
            self.reference[0], top.ki * top.integral, self.limited[1], self.limited[0],
        )
        if self.drivetrain is None:
            return values
        return values + (self.x[:, 4], self.x[:, 3])

    def recorded_rows(self, n_steps, record_every=1):
        """How many samples the next ``n_steps`` steps record."""
        return recorded_rows(self.k + 1, n_steps, record_every)

    def record_only(self, names):
        """The compiled engine's choice of recorded signals; this engine computes and records
        every signal anyway (the simulator keeps only ``names``)."""

    def stop(self, runs):
        """The compiled engine stops advancing the runs where ``runs`` is True; this engine
        advances every run anyway (the simulator blanks the stopped runs' samples)."""

    def advance_into(self, n_steps, record_every, floats, flags, offset):
        """:meth:`advance`, its samples copied into ``floats`` (the float signals of
        :attr:`signals` in order, n_runs, capacity) and ``flags`` (current_limited,
        voltage_limited) from column ``offset`` on (the compiled engine writes them there
        itself); returns their times [s]."""
        t, signals = self.advance(n_steps, record_every)
        columns = slice(offset, offset + len(t))
        names = [name for name in self.signals if name not in FLAG_SIGNALS]
        for row, name in enumerate(names):
            floats[row, :, columns] = signals[name]
        for row, name in enumerate(FLAG_SIGNALS):
            flags[row, :, columns] = signals[name]
        return t

    def advance(self, n_steps, record_every=1):
        """Advance ``n_steps`` steps; record every ``record_every``-th sample.

        Returns
        -------
        tuple of (numpy.ndarray, dict of str to numpy.ndarray)
            Times of the recorded samples [s] and each signal of :attr:`signals`, shape
            (n_runs, n_samples).
        """
        first = self.k + 1
        steps = np.arange(first, first + n_steps)
        kept = steps[steps % record_every == 0]
        n, nx = self.x.shape
        states = np.empty((kept.size, n, nx))
        volts, theta_cmd, i_cmd, integral = (np.empty((kept.size, n)) for _ in range(4))
        limited = np.zeros((2, kept.size, n), dtype=bool)
        top, current, commander = self.controllers[-1], self.controllers[0], self.commander
        row = 0
        for chunk in range(first, first + n_steps, _CHUNK):
            stop = min(chunk + _CHUNK, first + n_steps)
            rows, rows_left, jumps = self._command_rows(np.arange(chunk, stop) * self.dt)
            recorded = np.arange(chunk, stop) % record_every == 0
            theta_cmd[row : row + np.count_nonzero(recorded)] = rows[0][recorded]
            for j, (jump, record) in enumerate(zip(jumps, recorded.tolist(), strict=True)):
                right = self._row(rows, j)
                left = self._row(rows_left, j) if jump else right
                self._step(left, right)
                if record:
                    states[row] = self.x
                    volts[row] = self.v
                    i_cmd[row] = self.reference[0]
                    integral[row] = top.integral
                    if commander.clamped:  # else current_limited is False throughout
                        limited[0, row] = self.limited[1]
                    if current.clamped:
                        limited[1, row] = self.limited[0]
                    row += 1
        out = dict(
            theta=states[:, :, 2], omega=states[:, :, 1], i=states[:, :, 0], V=volts,
            theta_cmd=theta_cmd, current_command=i_cmd, position_integral=top.ki * integral,
            current_limited=limited[0], voltage_limited=limited[1],
        )
        if self.drivetrain is not None:
            out.update(delta=states[:, :, 4], omega_L=states[:, :, 3])
        return kept * self.dt, {name: out[name].T for name in self.signals}

    def _step(self, left, right):
        """One step: the plant over [t_k, t_k+1], then the controllers at t_k+1.

        ``left`` and ``right`` are the command's rows (:meth:`_row`) at t_k+1; the same
        tuple where it does not jump there.
        """
        k = self.k
        line = self.lines[0]
        v_a = self.v if line.reads_past else line.read(k)  # self.v: line.read(k) at step k-1
        if line.hold:
            v_next, v_b = line.read(k + 1), v_a
        else:
            v_next, v_b = line.read_limits(k + 1)
        if self.drivetrain is not None:  # the loaded plant, its mode and torques per run
            x = self.drivetrain.step(self.x, self.omega_before, v_a, v_b)
            self.omega_before = self.x[:, 1]
            self.x = x
        else:
            # x <- Phi x + G_a V_a + G_b V_b, in place and in this order (the rounding of
            # the clamp flags where an output rests exactly at its limit depends on it). Each
            # voltage is first copied into every column: a product without broadcasting is
            # cheaper.
            x, inputs, volts = self._next, self._inputs, self._volts
            np.einsum("rij,rj->ri", self.phi, self.x, out=x)
            volts[...] = v_a[:, None]
            x += np.multiply(self.g_a, volts, out=inputs)
            if v_b is not v_a:
                volts[...] = v_b[:, None]
            x += np.multiply(self.g_b, volts, out=inputs)
            self._next, self.x = self.x, x
        self.k = k = k + 1
        self.v = v_next
        self.theta_cmd = right[0]
        self._measure()
        self._loops(k, left, right)
