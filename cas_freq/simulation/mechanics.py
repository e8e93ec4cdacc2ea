r"""The loaded drivetrain in the simulator: exact steps per mode and the nonlinear terms.

The linear plant with a load, a compliant gear, backdrive and backlash is
:func:`cas_freq.model.parts.plant_matrices` (docs/model.md §5, "Load and drivetrain"); this
module discretises it per mode and decides, per run at the start of every
step, which mode applies and which constant torques act over the step. Within a step the
dynamics are the exact linear ones; the switching is explicit (decided from the state at
:math:`t_k`), so its error is first order in dt at each switch. Runs without any load term
never come here: the engines keep their unloaded 3-state path for them (the same numbers to
the bit as without this module).

States (five for every loaded run): :math:`x = (i, \omega, \theta, \omega_L, \delta)`; a rigid
gear's fin states follow the motor (:math:`\delta = \theta/N`). Inputs: the voltage V, linear
over the step (first-order hold, as the unloaded plant), and two torques held over the step
(zero-order hold): :math:`\tau_m` on the motor shaft and :math:`\tau_L` on the fin.

.. math::
    x_{k+1} = \Phi_m x_k + G_{a,m} V_a + G_{b,m} V_b + H_m (\tau_m, \tau_L)^T

for the mode m, from the exponential of the augmented matrix
:math:`[[A, B_V, 0, B_\tau], [0, 0, 1/dt, 0], [0, 0, 0, 0], [0, 0, 0, 0]]\,dt` (Franklin, Powell
& Workman, *Digital Control of Dynamic Systems*, 3rd ed., §6.3.2), one exponential per distinct
plant and mode.

Modes (:data:`FORWARD`, :data:`BACKDRIVE`, :data:`GAP`, :data:`HELD`):

- **Forward / backdrive.** The gear's reaction on the motor is scaled by
  :math:`e = 1/\eta` while the motor drives the fin and by :math:`e = \eta_b` while the fin
  drives the motor (``plant_matrices(backdrive=True)``; :math:`\eta_b = 0` is a self-locking
  worm: the fin cannot drive the motor). Backdrive when the power the gear delivers to the fin
  is negative, :math:`P < 0`:

  - rigid gear: :math:`P = (J_L \ddot\delta + b_L \dot\delta + K_h \delta - \tau_h)\,\dot\delta`
    with :math:`\delta = \theta_k/N`, :math:`\dot\delta = \omega_k/N` and
    :math:`\ddot\delta = (\omega_k - \omega_{k-1})/(N\,dt)` (the previous step's change;
    :math:`\omega_{-1} = 0`);
  - compliant gear: :math:`P = (K_g\, dz(\theta_k/N - \delta_k) + c_g (\omega_k/N -
    \omega_{L,k}))\, \omega_k/N` (the gear's spring and mesh damping).

  :math:`P = 0` (inside the play) is forward.
- **Held** (the gear's friction holding the shaft at rest). A shaft at rest, within one step's
  change of the forward mode's speed of it (:math:`|\omega_k| \le |\dot\omega_F|\,dt`, the
  motor's acceleration of the forward mode at :math:`t_k`), takes the mode of a step from rest:
  forward if the forward mode's step (fin rate :math:`\dot\omega_F\,dt/N`, the acceleration
  term :math:`J_L \dot\omega_F/N` in P for a rigid gear) has :math:`P \ge 0` (the motor drives
  the fin); else backdrive if the backdrive mode's step has :math:`P < 0` (the load drives the
  motor); else neither can move it and the gear holds it: the motor's speed (and a rigid
  gear's fin speed) is set to 0 and stays 0 over the step (the forward plant with those rows
  of A and B zero), and no Coulomb friction acts. A self-locking worm (:math:`\eta_b = 0`)
  under a hinge bias and no motor torque is held for good (before this mode, the first step
  from rest was taken as motor-driven and the bias moved the shaft by a step's worth each time
  it stopped: ~0.012 deg/s of creep); a gear with :math:`\eta < 1` is held while the motor's
  torque lies between the backdrive and the forward value of the load's.
- **Backlash** (compliant gear only), total play b at the fin:
  :math:`dz(x) = x - b/2` for :math:`x > b/2`, :math:`x + b/2` for :math:`x < -b/2`, else 0,
  with :math:`x = \theta/N - \delta`. Inside the play (:data:`GAP`) the spring carries no torque
  (``plant_matrices(engaged=False)``). In contact the spring torque is
  :math:`K_g (x \mp b/2)`: the engaged matrices carry :math:`K_g x`, and the constant
  :math:`c = \mp K_g b/2` enters as :math:`\tau_L \mathrel{+}= c` on the fin and
  :math:`\tau_m \mathrel{+}= -e\,c/N` on the motor.
- **Hinge bias** :math:`\tau_h`: :math:`\tau_L \mathrel{+}= \tau_h` (a rigid gear's B reflects
  it to the motor with e/N).
- **Coulomb friction** :math:`F_c` on the motor shaft, with a stiction band. With
  :math:`J_m` the mode's motor-side inertia (:math:`J + e J_L/N^2` rigid, J compliant; 1 over
  the mode's :math:`B_{\omega,\tau_m}`) and :math:`\tau_{net}` the net motor-side torque of the
  linear terms at :math:`t_k` (:math:`J_m` times the mode's :math:`\dot\omega` from
  :math:`A x_k + B_\tau (\tau_m, \tau_L)`: :math:`K_m i - \mu \omega` minus the reflected load
  or spring, plus the other torques):

  - sliding, :math:`|\omega_k| > F_c\,dt/J_m`: :math:`\tau_m \mathrel{-}= F_c\,
    \mathrm{sign}(\omega_k)`;
  - otherwise stuck or breaking away: the friction is the torque that would stop the shaft
    within the step, clamped to :math:`\pm F_c`:
    :math:`\tau_f = \mathrm{clip}(\tau_{net} + J_m \omega_k/dt, -F_c, F_c)`,
    :math:`\tau_m \mathrel{-}= \tau_f`.

  A shaft at rest under a torque below :math:`F_c` therefore stays at rest (to the change of
  the torque within one step), and a sliding shaft feels the full :math:`F_c` against its
  motion.

Where Coulomb friction should stop the motion, the explicit rule may alternate from step to
step (omega changes sign every step or two): the discrete form of the sticking motion, whose
speed is O(dt) while the position, current and torques converge to those of the stuck shaft.

A contact change inside a step is seen at the next step: the spring then starts from a
penetration of about the impact speed times dt, an energy error of order
:math:`(\omega_g\,dt)^2` of the impact's kinetic energy with :math:`\omega_g = \sqrt{K_g/J_L}`
(1e-3 for K_g = 1e3 N*m/rad, J_L = 2e-5 kg*m^2 at dt = 5 us); a gear whose contact frequency
approaches 1/dt needs a smaller step.

The order per step: contact and spring offset; power and mode; the mode from rest (held);
torques; friction; the exact step. Both engines (:class:`Drivetrain` vectorised for the numpy
reference, the kernel's scalar code) perform these operations in this order.
"""


import numpy as np

from cas_freq.core.threads import expm
from cas_freq.model.parts import plant_matrices

#: Mode indices: engaged with the motor driving, engaged with the fin driving, inside the play,
#: the motor's shaft held at rest by the gear.
FORWARD, BACKDRIVE, GAP, HELD = 0, 1, 2, 3
MODES = 4
#: States of a loaded run: i, omega, theta, omega_L, delta.
NX = 5

# Columns of the kernel's table of a loaded run (:func:`table`): per mode _PER_MODE values from
# mode * _PER_MODE: Phi (row-major), G_a, G_b, H (row-major, 5 x 2), A's omega row, B's omega
# row for (tau_m, tau_L); then the run's constants.
PHI, GA, GB, H, A1, B1 = 0, 25, 30, 35, 45, 50
_PER_MODE = 52
COMPLIANT = MODES * _PER_MODE  # 1.0 for a compliant gear
K_G = COMPLIANT + 1  # gear stiffness [N*m/rad]
HALF_PLAY = COMPLIANT + 2  # b/2 [rad]
TAU_H = COMPLIANT + 3  # hinge bias [N*m]
J_LOAD = COMPLIANT + 4  # load inertia [kg*m^2]
B_LOAD = COMPLIANT + 5  # load damping [N*m*s/rad]
K_HINGE = COMPLIANT + 6  # hinge stiffness [N*m/rad]
F_COULOMB = COMPLIANT + 7  # Coulomb friction [N*m]
E_FORWARD = COMPLIANT + 8  # 1/eta
E_BACK = COMPLIANT + 9  # eta_b
RATIO = COMPLIANT + 10  # N
LOADED = COMPLIANT + 11  # 1.0 where the run has any load term
C_G = COMPLIANT + 12  # gear mesh damping [N*m*s/rad]
COLUMNS = COMPLIANT + 13


def distinct_exponentials(matrices):
    """expm of each matrix of a stack (..., m, m), computed once per distinct matrix.

    A sine-dwell batch repeats one plant over hundreds of runs; scipy's expm works matrix by
    matrix, so the result is the same to the bit, and each exponential costs several BLAS
    calls, slow when BLAS threads are contended: they run on one BLAS thread
    (:func:`cas_freq.core.threads.one_blas_thread`).
    """
    shape = matrices.shape
    size = shape[-1]
    flat = matrices.reshape(-1, size * size)
    if flat.shape[0] == 1:  # one matrix (a single run): nothing to share
        unique, inverse = flat, np.zeros(1, dtype=int)
    else:
        unique, inverse = np.unique(flat, axis=0, return_inverse=True)
    exponentials = expm(unique.reshape(-1, size, size))
    return exponentials[inverse.reshape(-1)].reshape(shape)


def step_matrices(params, dt):
    """Exact one-step matrices of every run's 5-state plant in each mode.

    Parameters
    ----------
    params : LoopParameters
        Batch parameters.
    dt : float
        Step [s].

    Returns
    -------
    tuple of numpy.ndarray
        :math:`\\Phi` (n, 4, 5, 5), :math:`G_a`, :math:`G_b` (n, 4, 5), H (n, 4, 5, 2) for
        (tau_m, tau_L) [per N*m], and the continuous omega rows A[1] (n, 4, 5) and
        B[1, 1:] (n, 4, 2), modes in the order FORWARD, BACKDRIVE, GAP, HELD.
    """
    n = params.n_runs
    a, b = _plants(params)
    size = NX + 4
    m = np.zeros((n, MODES, size, size))
    m[..., :NX, :NX] = a
    m[..., :NX, NX] = b[..., 0]
    m[..., NX, NX + 1] = 1.0 / dt
    m[..., :NX, NX + 2:] = b[..., 1:]
    e = distinct_exponentials(m * dt)
    phi = e[..., :NX, :NX].copy()
    g_a = e[..., :NX, NX] - e[..., :NX, NX + 1]
    g_b = e[..., :NX, NX + 1].copy()
    h = e[..., :NX, NX + 2:].copy()
    return phi, g_a, g_b, h, a[..., 1, :].copy(), b[..., 1, 1:].copy()


_MODE_OPTIONS = ({}, {"backdrive": True}, {"engaged": False})


def _plants(params):
    """A (n, 4, 5, 5) and B (n, 4, 5, 3) of every run in the modes FORWARD, BACKDRIVE, GAP,
    HELD (the forward plant with the motor's speed, and a rigid gear's fin speed, constant:
    started at 0 they stay 0)."""
    modes = [plant_matrices(params, states=NX, **options) for options in _MODE_OPTIONS]
    a, b = (m.copy() for m in modes[FORWARD])
    a[:, 1] = b[:, 1] = 0.0  # the motor's speed
    rigid = np.broadcast_to(np.asarray(params.K_g) <= 0, (a.shape[0],))
    a[rigid, 3] = b[rigid, 3] = 0.0  # a rigid gear's fin speed, which follows it
    modes.append((a, b))
    return (np.stack([m[0] for m in modes], axis=1), np.stack([m[1] for m in modes], axis=1))


def table(params, dt):
    """The kernel's per-run table (n, :data:`COLUMNS`) of a batch with some loaded run."""
    p = params
    n = p.n_runs
    phi, g_a, g_b, h, a1, b1 = step_matrices(p, dt)
    q = np.zeros((n, COLUMNS))
    for mode in range(MODES):
        base = mode * _PER_MODE
        q[:, base + PHI:base + GA] = phi[:, mode].reshape(n, 25)
        q[:, base + GA:base + GB] = g_a[:, mode]
        q[:, base + GB:base + H] = g_b[:, mode]
        q[:, base + H:base + A1] = h[:, mode].reshape(n, 10)
        q[:, base + A1:base + B1] = a1[:, mode]
        q[:, base + B1:base + _PER_MODE] = b1[:, mode]
    q[:, COMPLIANT] = p.compliant
    q[:, K_G], q[:, HALF_PLAY], q[:, TAU_H] = p.K_g, 0.5 * p.backlash, p.tau_h
    q[:, J_LOAD], q[:, B_LOAD], q[:, K_HINGE], q[:, F_COULOMB] = p.J_L, p.b_L, p.K_h, p.F_c
    q[:, E_FORWARD], q[:, E_BACK], q[:, RATIO] = 1.0 / p.eta, p.eta_b, p.ratio
    q[:, LOADED] = p.loaded
    q[:, C_G] = p.c_g
    return q


class Drivetrain:
    """The loaded plant of a batch, stepped with numpy (the reference engine's plant).

    Parameters
    ----------
    params : LoopParameters
        Batch parameters.
    dt : float
        Step [s].
    """

    def __init__(self, params, dt):
        p = params
        self.dt = dt
        self.phi, self.g_a, self.g_b, self.h, self.a1, self.b1 = step_matrices(p, dt)
        self.compliant = np.asarray(p.compliant, dtype=bool)
        self.any_compliant = bool(self.compliant.any())
        self.half = 0.5 * p.backlash
        self.k_g, self.c_g, self.tau_h, self.ratio = p.K_g, p.c_g, p.tau_h, p.ratio
        self.j_l, self.b_l, self.k_h, self.f_c = p.J_L, p.b_L, p.K_h, p.F_c
        self.e = np.stack([1.0 / p.eta, p.eta_b, 1.0 / p.eta, 1.0 / p.eta], axis=1)  # per mode
        self.friction = bool(np.any(p.F_c > 0))
        self.rows = np.arange(p.n_runs)

    def inputs(self, x, omega_before):
        """Mode (n,) and torques (tau_m, tau_L) (n,) [N*m] for the step from state ``x``.

        ``omega_before`` is the motor speed one step earlier [rad/s] (rigid gear's fin
        acceleration). The rules of the module docstring, in their order.
        """
        dt, ratio = self.dt, self.ratio
        w, th = x[:, 1], x[:, 2]
        # contact and spring offset (compliant gear)
        gear = th / ratio - x[:, 4]
        half = self.half
        above, below = gear > half, gear < -half
        dz = np.where(above, gear - half, np.where(below, gear + half, 0.0))
        offset = np.where(above, -self.k_g * half, np.where(below, self.k_g * half, 0.0))
        gap = self.compliant & (half > 0) & ~above & ~below
        # power the gear delivers to the fin
        rate = w / ratio
        accel = (w - omega_before) / (ratio * dt)
        delta = th / ratio
        power_rigid = (self.j_l * accel + self.b_l * rate + self.k_h * delta - self.tau_h) * rate
        power_compliant = (self.k_g * dz + self.c_g * (rate - x[:, 3])) * rate
        power = np.where(self.compliant, power_compliant, power_rigid)
        mode = np.where(gap, GAP, np.where(power < 0.0, BACKDRIVE, FORWARD))
        c = np.where(self.compliant, offset, 0.0)
        tau_l = self.tau_h + c
        mode = self._from_rest(x, dz, delta, c, tau_l, mode)
        held = mode == HELD
        e = self.e[self.rows, mode]
        tau_m = -(e * c) / ratio
        if self.friction:
            a1, b1 = self.a1[self.rows, mode], self.b1[self.rows, mode]
            b_m = np.where(held, 1.0, b1[:, 0])  # a held shaft: no friction acts
            acc = (a1[:, 0] * x[:, 0] + a1[:, 1] * w + a1[:, 2] * th + a1[:, 3] * x[:, 3]
                   + a1[:, 4] * x[:, 4] + b_m * tau_m + b1[:, 1] * tau_l)
            f_c = self.f_c
            stop = (acc + w / dt) / b_m  # tau_net + J_m omega / dt
            sliding = np.abs(w) > f_c * dt * b_m
            tau_f = np.where(sliding, f_c * np.sign(w), np.minimum(np.maximum(stop, -f_c), f_c))
            tau_m = tau_m - np.where(held, 0.0, tau_f)
        return mode, tau_m, tau_l

    def _from_rest(self, x, dz, delta, c, tau_l, mode):
        """The mode of a shaft at rest (the module docstring's rule; ``mode`` elsewhere), (n,).

        At rest: within one step's change of the forward mode's speed of it. There the mode is
        that of a step from rest: forward where the forward mode's step has the gear deliver
        power to the fin (>= 0), else backdrive where the backdrive mode's step has the fin
        deliver it (< 0: the load back-drives the shaft), else held.
        """
        dt, ratio, w = self.dt, self.ratio, x[:, 1]
        power = []
        for m in (FORWARD, BACKDRIVE):
            acc = self._acceleration(m, x, -(self.e[:, m] * c) / ratio, tau_l)
            if m == FORWARD:
                at_rest = np.abs(w) <= np.abs(acc) * dt
            rate = acc * dt / ratio  # the fin's rate after a step from rest [rad/s]
            power.append(np.where(
                self.compliant, (self.k_g * dz + self.c_g * (rate - x[:, 3])) * rate,
                (self.j_l * acc / ratio + self.b_l * rate + self.k_h * delta - self.tau_h) * rate))
        rest = np.where(power[0] >= 0.0, FORWARD, np.where(power[1] < 0.0, BACKDRIVE, HELD))
        return np.where(at_rest & (mode != GAP), rest, mode)

    def _acceleration(self, mode, x, tau_m, tau_l):
        """The motor's acceleration [rad/s^2] at state ``x`` in ``mode`` under the torques
        (tau_m, tau_L) [N*m], from the mode's continuous omega row (A x + B_tau tau)."""
        a1, b1 = self.a1[:, mode], self.b1[:, mode]
        return (a1[:, 0] * x[:, 0] + a1[:, 1] * x[:, 1] + a1[:, 2] * x[:, 2] + a1[:, 3] * x[:, 3]
                + a1[:, 4] * x[:, 4] + b1[:, 0] * tau_m + b1[:, 1] * tau_l)

    def step(self, x, omega_before, v_a, v_b):
        """The state after one step from ``x`` (n, 5) with the voltage from v_a to v_b [V]."""
        mode, tau_m, tau_l = self.inputs(x, omega_before)
        rows = self.rows
        held = mode == HELD
        if held.any():  # the gear stops the shaft (and a rigid gear's fin) at once
            x = x.copy()
            x[held, 1] = 0.0
            x[held & ~self.compliant, 3] = 0.0
        phi, g_a, g_b, h = (m[rows, mode] for m in (self.phi, self.g_a, self.g_b, self.h))
        out = np.einsum("rij,rj->ri", phi, x)
        out += g_a * v_a[:, None]
        out += g_b * v_b[:, None]
        out += h[:, :, 0] * tau_m[:, None]
        out += h[:, :, 1] * tau_l[:, None]
        return out
