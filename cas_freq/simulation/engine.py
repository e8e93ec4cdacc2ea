r"""The fixed-step core: every run of a batch advanced at once with numpy.

Plant (MODEL.md, report Fig. 5), states :math:`x = (i, \omega, \theta)`:

.. math::
    L \dot i = V - R i - K_e \omega, \qquad J \dot\omega = K_m i - \mu_v \omega, \qquad
    \dot\theta = \omega

It is linear, so each step of length dt is integrated exactly (:func:`plant_step_matrices`) for a
terminal voltage that is linear over the step (first-order hold; constant for a sampled current
controller). That voltage is the current controller's output delayed by :math:`\tau_c`, so it
is known before the step: both delays make the scheme explicit. After each plant step the
position controller (on :math:`\theta`), then the current controller (on :math:`i` and the
current command delayed by :math:`\tau_p`) are updated (:mod:`~cas_freq.simulation.controllers`)
and their outputs pushed into the delay lines (:mod:`~cas_freq.simulation.delay_line`).

Continuous controllers are updated every step and read back with linear interpolation, so the
whole loop is integrated to second order in dt. Sampled controllers are updated every
``n`` steps and held (zero-order hold).
"""

import numpy as np
from scipy.linalg import expm

from cas_freq.simulation.controllers import Controller
from cas_freq.simulation.delay_line import DelayLine

#: Names of the signals recorded per sample, in the order of :meth:`Engine.sample`.
SIGNALS = (
    "theta", "omega", "i", "V", "theta_cmd", "current_command", "position_integral",
    "current_limited", "voltage_limited",
)

_CHUNK = 2048


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
    e = expm(m * dt)
    return e[:, :3, :3], e[:, :3, 3] - e[:, :3, 4], e[:, :3, 4].copy()


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
        self.commands = commands
        self.ratio = ratio

    def motor(self, t, left=False):
        """(angle [rad], rate [rad/s], acceleration [rad/s^2]) at the motor, each (len(t), n)."""
        n = self.ratio.shape[0]
        if isinstance(self.commands, (list, tuple)):
            parts = [c.fin(t, left=left) for c in self.commands]
            out = [np.stack([np.broadcast_to(p[j], t.shape) for p in parts], axis=1)
                   for j in range(3)]
        else:
            out = [np.broadcast_to(a, (t.shape[0], n)) for a in self.commands.fin(t[:, None], left)]
        return tuple(self.ratio * part for part in out)


class Engine:
    """State of a batch of runs, advanced step by step.

    Parameters
    ----------
    params : LoopParameters
        Batch parameters.
    commands : CommandSet
        Commands of every run.
    dt : float
        Step [s].
    current_every, position_every : int or None
        Update period of a sampled controller in steps; None for a continuous one.
    """

    def __init__(self, params, commands, dt, current_every=None, position_every=None):
        p = params
        self.dt = dt
        self.commands = commands
        self.phi, self.g_a, self.g_b = plant_step_matrices(p, dt)
        self.current_every, self.position_every = current_every, position_every
        self.current = Controller(
            p.ci_Kp, p.ci_Ki, np.zeros_like(p.ci_Kp), p.Tf, p.v_max, dt * (current_every or 1),
            sampled=current_every is not None,
        )
        self.position = Controller(
            p.cp_Kp, p.cp_Ki, p.cp_Kd, p.Tf, p.i_max, dt * (position_every or 1),
            sampled=position_every is not None,
        )
        self.cp_Ki, self.ff_v, self.ff_a = p.cp_Ki, p.ff_v, p.ff_a
        self.on_measurement = p.derivative_on_measurement
        self.voltage_line = DelayLine(p.tau_c, dt, hold=current_every is not None)
        self.current_line = DelayLine(p.tau_p, dt, hold=position_every is not None)
        self.x = np.zeros((p.n_runs, 3))
        self.k = 0

    def _errors(self, cmd):
        theta_cmd, rate, accel = cmd
        theta = self.x[:, 2]
        e = theta_cmd - theta
        y = np.where(self.on_measurement, -theta, e) if self.on_measurement.any() else e
        return e, y, self.ff_v * rate + self.ff_a * accel

    def _position_update(self, left, right, start=False):
        step = self.position.start if start else self.position.update
        if self.position_every is not None:  # a sampler sees the values from now on
            left = right
        (e_l, y_l, ff_l), (e_r, y_r, ff_r) = self._errors(left), self._errors(right)
        self.u_left, self.u_p, self.current_limited = step(e_l, e_r, y_l, y_r, ff_l, ff_r)
        if self.position_every is not None:
            self.u_left = self.u_p

    def _current_update(self, start=False):
        step = self.current.start if start else self.current.update
        self.i_cmd = self.current_line.read(self.k)
        i = self.x[:, 0]
        if self.current_every is None:
            i_left = self.current_line.read(self.k, left=True)
            self.v_left, self.v_c, self.voltage_limited = step(i_left - i, self.i_cmd - i)
        else:
            _, self.v_c, self.voltage_limited = step(self.i_cmd - i, self.i_cmd - i)
            self.v_left = self.v_c

    def start(self):
        """Controller outputs at t = 0 (plant at rest, nothing before), then the sample at 0."""
        t0 = np.zeros(1)
        right = [part[0] for part in self.commands.motor(t0)]
        left = [part[0] for part in self.commands.motor(t0, left=True)]
        self.theta_cmd = right[0]
        self._position_update(left, right, start=True)
        self.current_line.push(0, self.u_p, self.u_left)
        self._current_update(start=True)
        self.voltage_line.push(0, self.v_c, self.v_left)
        self.v = self.voltage_line.read(0)
        return self.sample()

    def sample(self):
        """The recorded signals at the present step, in the order of :data:`SIGNALS`."""
        return (
            self.x[:, 2], self.x[:, 1], self.x[:, 0], self.v, self.theta_cmd, self.i_cmd,
            self.cp_Ki * self.position.integral, self.current_limited, self.voltage_limited,
        )

    def advance(self, n_steps, record_every=1):
        """Advance ``n_steps`` steps; record every ``record_every``-th sample.

        Returns
        -------
        tuple of (numpy.ndarray, dict of str to numpy.ndarray)
            Times of the recorded samples [s] and each signal of :data:`SIGNALS`, shape
            (n_samples, n_runs).
        """
        first = self.k + 1
        steps = np.arange(first, first + n_steps)
        kept = steps[steps % record_every == 0]
        n = self.x.shape[0]
        out = {name: np.empty((kept.size, n), dtype=bool if "limited" in name else float)
               for name in SIGNALS}
        row = 0
        for chunk in range(first, first + n_steps, _CHUNK):
            times = np.arange(chunk, min(chunk + _CHUNK, first + n_steps)) * self.dt
            right = self.commands.motor(times)
            left = self.commands.motor(times, left=True)
            for j in range(times.size):
                self._step([part[j] for part in left], [part[j] for part in right])
                if self.k % record_every == 0:
                    for name, value in zip(SIGNALS, self.sample(), strict=True):
                        out[name][row] = value
                    row += 1
        return kept * self.dt, out

    def _step(self, left, right):
        k = self.k
        line = self.voltage_line
        v_a = line.read(k)
        v_b = v_a if line.hold else line.read(k + 1, left=True)
        self.x = (
            np.einsum("rij,rj->ri", self.phi, self.x)
            + self.g_a * v_a[:, None] + self.g_b * v_b[:, None]
        )
        self.k = k = k + 1
        self.v = line.read(k)
        self.theta_cmd = right[0]
        if self.position_every is None or k % self.position_every == 0:
            self._position_update(left, right)
        self.current_line.push(k, self.u_p, self.u_left)
        if self.current_every is None or k % self.current_every == 0:
            self._current_update()
        line.push(k, self.v_c, self.v_left)
