"""An independent reference for the sampled loops of issue 26 (tests only).

Written from the model definition (docs/model.md §2-§4, /work/shared/MODEL.md "Sampled
controllers" and the issue's shared design), WITHOUT cas_freq's frequency-domain code: cas_freq
is used only to load a config and read its SI parameter values (:func:`drive_of`). Everything
else is numpy, scipy and python-control. Tests compare cas_freq.model.sampled against it;
tests/test_sampled_oracle.py checks the oracle itself.

The drive is the report's PID-on-PI with a rigid gear (the configs qt_cas base/fitted and
dc_servo), written from the physical equations (docs/model.md §2)::

    L di/dt = V - R i - Ke w,    J dw/dt = Km i - mu_v w,    dtheta/dt = w

states (i, w, theta), input the motor voltage V, outputs i and theta. The current controller's
output is held (zero-order hold) and reaches the terminals tau_c later; the current and the
angle are sampled at the current controller's instants. The position controller's output
(a current command) reaches the current controller after ceil(tau_p / T_inner) inner samples.

Four computations, each a different method:

* :func:`single_rate` (item 1): every loop at one period T with tau_c = d_c T (an integer
  number of samples): the plant's hold-equivalent by ``control.sample_system(..., 'zoh')``,
  the delays as z^-d, the controllers as discrete transfer functions, composed with
  ``control.series`` / ``control.feedback``. Exact (to rounding).
* :func:`hold_equivalent` : the exact hold-equivalent of a continuous state space with a
  FRACTIONAL delay tau = D T + e (0 <= e < T), the modified z-transform as a state space: the
  held input u_{k-D-1} acts for the first e of each period, u_{k-D} for the rest, so
  x_{k+1} = Phi(T) x_k + Phi(T - e) Gamma(e) u_{k-D-1} + Gamma(T - e) u_{k-D}
  (Phi(h) = e^{A h}, Gamma(h) = int_0^h e^{A s} ds B), with a shift register of the held
  inputs. Exact (to rounding).
* :func:`hold_equivalent_by_aliasing` (item 2): the sum
  P_h(e^{jwT}) = (1/T) sum_k H0(j w_k) e^{-j w_k tau} G(j w_k), w_k = w + 2 pi k/T,
  H0(s) = (1 - e^{-sT})/s, truncated at |k| <= K, for ANY G evaluable on the jw axis (e.g. a
  continuous current loop with its exact delay). Its accuracy: see that function.
* :func:`lifted` (item 3): the multirate loop (current loop at T_f, position loop at
  T_s = M T_f) as a slow-rate state space x[n+1] = A_f^M x[n] + (sum_{i<M} A_f^i B_f) u[n]
  of the fast closed current loop, the fast delay register of the position command and the
  M-step hold; the measurement is the fast state's angle every M-th fast step.

Every response is evaluated at z = e^{j w T} from a state space by a linear solve (never from
multiplied-out polynomials, whose coefficients lose all precision when the poles crowd z = 1 at
a fast rate), and the margins are found by root finding on those exact responses
(:func:`margins`).
"""

import math
from dataclasses import dataclass, replace

import control
import numpy as np
from scipy.linalg import expm
from scipy.optimize import brentq

METHODS = ("backward", "tustin")


# ---------------------------------------------------------------------------------- the drive

@dataclass(frozen=True)
class Drive:
    """Plain SI parameters of a PID-on-PI drive with a rigid, unloaded gear.

    Gains per rad of MOTOR angle; ``derivative_on_measurement``: the derivative acts on -theta
    (docs/model.md §4), which changes T only.
    """

    R: float                    # [ohm]
    L: float                    # [H]
    Km: float                   # [N m/A]
    Ke: float                   # [V s/rad]
    J: float                    # [kg m^2]
    mu_v: float                 # [N m s/rad]
    ci_Kp: float                # current PI [V/A]
    ci_Ki: float                # [V/(A s)]
    tau_c: float                # current controller -> terminals [s]
    cp_Kp: float                # position PID [A/rad]
    cp_Ki: float                # [A/(rad s)]
    cp_Kd: float                # [A s/rad]
    Tf: float                   # derivative filter [s]
    tau_p: float                # position controller -> current controller [s]
    derivative_on_measurement: bool = False
    # analog filters on the measured current and angle, before the samplers: (num, den) in s,
    # highest power first (the anti-aliasing filters of issue 26); (1,)/(1,): none
    current_filter: tuple = ((1.0,), (1.0,))
    angle_filter: tuple = ((1.0,), (1.0,))


def drive_of(path, variant="base"):
    """The Drive of a config variant. cas_freq only loads the config and resolves the derived
    values (mu_v from the no-load point, Tf = Kd/(10 Kp)); the oracle refuses anything it does
    not model (a load, a compliant gear, filters, a velocity loop, output feedback)."""
    from cas_freq.config import load_variant
    from cas_freq.core.parameters import LoopParameters

    p = LoopParameters.from_config(load_variant(path, variant).params)
    if p.cascade or p.feedback_output or p.filters or np.any(p.loaded):
        raise ValueError(f"{path} {variant}: the sampled oracle models the rigid, unloaded "
                         "PID-on-PI drive only")
    value = lambda name: float(getattr(p, name)[0])  # noqa: E731
    return Drive(R=value("R"), L=value("L"), Km=value("Km"), Ke=value("Ke"), J=value("J"),
                 mu_v=value("mu_v"), ci_Kp=value("ci_Kp"), ci_Ki=value("ci_Ki"),
                 tau_c=value("tau_c"), cp_Kp=value("cp_Kp"), cp_Ki=value("cp_Ki"),
                 cp_Kd=value("cp_Kd"), Tf=value("Tf"), tau_p=value("tau_p"),
                 derivative_on_measurement=bool(p.derivative_on_measurement[0]))


def plant_matrices(d, output=False):
    """(A, B, C) of the plant: states (i, w, theta), input V, outputs (i, theta); with analog
    measurement filters (``current_filter``, ``angle_filter``) the outputs are the filtered
    current and angle: the plant in series with the diagonal bank of the filters, composed by
    python-control (``control.series`` of the plant and ``control.append`` of the filters'
    own realisations). ``output``: a third output, the angle unfiltered (what T reads)."""
    a = np.array([[-d.R / d.L, -d.Ke / d.L, 0.0],
                  [d.Km / d.J, -d.mu_v / d.J, 0.0],
                  [0.0, 1.0, 0.0]])
    b = np.array([[1.0 / d.L], [0.0], [0.0]])
    c = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]] + ([[0.0, 0.0, 1.0]] if output else []))
    none = ((1.0,), (1.0,))
    if d.current_filter == none and d.angle_filter == none:
        return a, b, c
    bank = control.append(control.ss(control.tf(*d.current_filter)),
                          control.ss(control.tf(*d.angle_filter)),
                          *([control.ss([], [], [], [[1.0]])] if output else []))
    filtered = control.series(control.ss(a, b, c, np.zeros((c.shape[0], 1))), bank)
    if np.any(np.asarray(filtered.D) != 0):
        raise ValueError("the filtered plant has a direct term")  # a strictly proper plant
    return np.asarray(filtered.A), np.asarray(filtered.B), np.asarray(filtered.C)


def plant_ss(d):
    """The plant as a continuous python-control state space (outputs i, theta)."""
    return control.ss(*plant_matrices(d), np.zeros((2, 1)))


def samples(tau, period):
    """ceil(tau/period) as an integer, a ratio within 1e-9 of an integer taken as that integer
    (0.4 ms / 40 us is 10.000000000000002 in floating point: 10 samples, not 11)."""
    ratio = tau / period
    nearest = round(ratio)
    return int(nearest) if abs(ratio - nearest) <= 1e-9 * max(1.0, ratio) else math.ceil(ratio)


def integer_samples(tau, period):
    """tau/period, which must be an integer (to 1e-9)."""
    ratio = tau / period
    if abs(ratio - round(ratio)) > 1e-9 * max(1.0, ratio):
        raise ValueError(f"tau = {tau} s is not a multiple of T = {period} s")
    return int(round(ratio))


# ------------------------------------------------------------------------ digital controllers

def _z(period):
    return control.tf([1.0, 0.0], [1.0], period)


def pi_controller(kp, ki, period, method="backward"):
    """Discrete PI: backward Kp + Ki T z/(z - 1); tustin Kp + Ki (T/2)(z + 1)/(z - 1)."""
    z = _z(period)
    if method == "backward":
        return kp + ki * period * z / (z - 1)
    if method == "tustin":
        return kp + ki * period / 2 * (z + 1) / (z - 1)
    raise ValueError(f"method: {method!r} is not one of {METHODS}")


def derivative(kd, tf, period, method="backward"):
    """Discrete filtered derivative Kd s/(Tf s + 1): backward (s -> (z - 1)/(T z))
    Kd (z - 1)/((Tf + T) z - Tf); tustin (s -> (2/T)(z - 1)/(z + 1))
    2 Kd (z - 1)/((2 Tf + T) z + (T - 2 Tf))."""
    z = _z(period)
    if method == "backward":
        return kd * (z - 1) / ((tf + period) * z - tf)
    if method == "tustin":
        return 2 * kd * (z - 1) / ((2 * tf + period) * z + (period - 2 * tf))
    raise ValueError(f"method: {method!r} is not one of {METHODS}")


def controllers(d, period_i, period_p, method="backward"):
    """(C_i, C_p, C_r) as discrete transfer functions: the current PI at ``period_i``, the
    position PID and its reference path (C_p with the derivative on the error, Kp + Ki/s part
    only with the derivative on the measurement) at ``period_p``."""
    c_i = pi_controller(d.ci_Kp, d.ci_Ki, period_i, method)
    pi_p = pi_controller(d.cp_Kp, d.cp_Ki, period_p, method)
    c_p = pi_p + derivative(d.cp_Kd, d.Tf, period_p, method) if d.cp_Kd else pi_p
    return c_i, c_p, (pi_p if d.derivative_on_measurement else c_p)


def delay_tf(n, period):
    """z^-n."""
    return control.tf([1.0], [1.0] + [0.0] * n, period)


# --------------------------------------------------------------------------- evaluation

def evaluate(system, omega):
    """A SISO python-control system at z = e^{j omega dt} (discrete) or s = j omega, from its
    state space by one linear solve per frequency."""
    ss = control.ss(system) if not isinstance(system, control.StateSpace) else system
    z = np.exp(1j * np.asarray(omega, float) * ss.dt) if ss.isdtime() else 1j * np.asarray(
        omega, float)
    return evaluate_ss(ss.A, ss.B, ss.C, ss.D, z)


def evaluate_ss(a, b, c, dd, z):
    """C (z I - A)^-1 B + D of a SISO (A, B, C, D) at the points ``z`` (any shape)."""
    z = np.asarray(z, complex)
    n = a.shape[0]
    if n == 0:
        return np.full(z.shape, complex(np.asarray(dd).item()))
    flat = z.reshape(-1)
    m = flat[:, None, None] * np.eye(n) - a
    x = np.linalg.solve(m, np.broadcast_to(b[:, :1], (flat.size, n, 1)))
    return ((c[:1] @ x)[:, 0, 0] + np.asarray(dd).reshape(-1)[0]).reshape(z.shape)


# ----------------------------------------------------------------- item 1: single rate

@dataclass(frozen=True)
class SampledLoops:
    """Discrete python-control state spaces of one sampled drive.

    ``current``: L_i broken at the current controller's output (at its period);
    ``plant_p``: what the position controller drives (its output -> theta samples, the current
    loop closed, at the position loop's period); ``c_p``, ``c_r``: the position controller and
    its reference path; ``position`` = series(c_p, plant_p): L_p broken at the position
    controller's output; ``closed`` = series(c_r, feedback(plant_p, c_p)): T = theta samples /
    command samples; ``loop`` = feedback(plant_p, c_p), whose states are every state of the
    closed loop once (its eigenvalues are the closed-loop poles).
    """

    current: control.StateSpace
    plant_p: control.StateSpace
    c_p: control.StateSpace
    c_r: control.StateSpace
    plant_out: control.StateSpace | None = None  # to the unfiltered angle (None: plant_p)

    @property
    def position(self):
        return control.series(self.c_p, self.plant_p)

    @property
    def loop(self):
        return control.feedback(self.plant_p, self.c_p)

    @property
    def closed(self):
        return control.series(self.c_r, self.loop)

    def responses(self, omega):
        """{'current_loop', 'position_loop', 'closed_loop'} at the real frequencies omega
        [rad/s]: each block evaluated from its state space, then T = C_r G/(1 + C_p G)
        point by point (no cancelling poles and zeros near z = 1 in one realisation)."""
        g = evaluate(self.plant_p, omega)
        l_p = evaluate(self.c_p, omega) * g
        out = g if self.plant_out is None else evaluate(self.plant_out, omega)
        return {"current_loop": evaluate(self.current, omega), "position_loop": l_p,
                "closed_loop": evaluate(self.c_r, omega) * out / (1 + l_p)}

    def poles(self):
        """The closed-loop poles (z) at the position loop's rate."""
        return np.linalg.eigvals(self.loop.A)

    def stable(self):
        """All closed-loop poles strictly inside the unit circle."""
        return bool(np.all(np.abs(self.poles()) < 1.0))


def single_rate(d, period, method="backward"):
    """Item 1: every loop at one period T [s]; tau_c must be a multiple of T; tau_p is
    ceil(tau_p/T) samples (the position controller's output reaches the current controller
    at its first sampling instant at or after tau_p).

    The plant's hold-equivalent is ``control.sample_system(plant, T, 'zoh')`` (V -> i, theta,
    one state space so that the closed loop has each state once); the delay tau_c = d_c T is
    z^-d_c on the voltage. Composed with control.series/feedback: L_i = C_i z^-dc P_i (broken
    at the current controller's output); the current loop closed,
    i_cmd -> (i, theta) = feedback(P z^-dc C_i, [1, 0]); what the position controller drives,
    G = (i_cmd -> theta) z^-dp; L_p = C_p G, T = C_r G/(1 + C_p G).
    """
    plant = control.sample_system(plant_ss(d), period, "zoh")
    c_i, c_p, c_r = controllers(d, period, period, method)
    delay_c = control.ss(delay_tf(integer_samples(d.tau_c, period), period))
    delay_p = control.ss(delay_tf(samples(d.tau_p, period), period))
    forward = control.series(control.ss(c_i), delay_c)
    current = control.series(forward, plant[0, 0])
    closed_current = control.feedback(control.series(forward, plant), np.array([[1.0, 0.0]]))
    plant_p = control.series(delay_p, closed_current[1, 0])
    return SampledLoops(current, plant_p, control.ss(c_p), control.ss(c_r))


# ------------------------------------------- the exact hold-equivalent with a fractional delay

def _phi_gamma(a, b, h):
    """(e^{A h}, int_0^h e^{A s} ds B) from one matrix exponential of [[A, B], [0, 0]] h."""
    n, m = b.shape
    big = np.zeros((n + m, n + m))
    big[:n, :n], big[:n, n:] = a, b
    e = expm(big * h)
    return e[:n, :n], e[:n, n:]


def hold_equivalent(a, b, c, period, tau):
    """The exact zero-order-hold equivalent (modified z-transform) of dx/dt = A x + B u(t - tau),
    y = C x, for any delay tau >= 0, as discrete matrices (Ad, Bd, Cd) at ``period``.

    Write tau = D T + e, 0 <= e < T. Over [kT, kT + e) the plant sees u_{k-D-1}, over
    [kT + e, (k+1)T) it sees u_{k-D}, so
    x_{k+1} = Phi(T) x_k + Phi(T - e) Gamma(e) u_{k-D-1} + Gamma(T - e) u_{k-D}.
    The held inputs u_{k-1} .. u_{k-D-1} are a shift register (its last cell only when e > 0);
    the state is (x, u_{k-1}, u_{k-2}, ...). Single input; y_k = C x_k (no feedthrough).
    """
    n = a.shape[0]
    dd = int(math.floor(tau / period + 1e-9))
    e = tau - dd * period
    if e < 1e-9 * period:
        e = 0.0
    phi, _ = _phi_gamma(a, b, period)
    phi_rest, gamma_rest = _phi_gamma(a, b, period - e)
    b_late = gamma_rest                                # multiplies u_{k-D}
    b_early = phi_rest @ _phi_gamma(a, b, e)[1] if e else None   # multiplies u_{k-D-1}
    cells = dd + (1 if e else 0)
    size = n + cells
    ad = np.zeros((size, size))
    bd = np.zeros((size, 1))
    ad[:n, :n] = phi
    if cells:
        bd[n, 0] = 1.0                                 # u_{k-1} <- u_k
        for j in range(1, cells):
            ad[n + j, n + j - 1] = 1.0                 # u_{k-1-j} <- u_{k-j}
    if dd == 0:
        bd[:n] += b_late
    else:
        ad[:n, n + dd - 1:n + dd] += b_late
    if e:
        ad[:n, n + dd:n + dd + 1] += b_early
    cd = np.hstack([c, np.zeros((c.shape[0], cells))])
    return ad, bd, cd


def first_order_modified_z(a, period, tau, z):
    """The hold-equivalent of G(s) = e^{-s tau}/(s + a) worked out by hand (test reference).

    x' = -a x + u(t - tau), tau = D T + e, 0 <= e < T. Over one period the plant sees u_{k-D-1}
    for e seconds, then u_{k-D} for T - e:
        x(kT + e)   = e^{-a e} x_k + (1 - e^{-a e})/a u_{k-D-1}
        x_{k+1}     = e^{-a (T-e)} x(kT + e) + (1 - e^{-a (T-e)})/a u_{k-D}
                    = e^{-aT} x_k + (e^{-a(T-e)} - e^{-aT})/a u_{k-D-1}
                      + (1 - e^{-a(T-e)})/a u_{k-D}
    so, with b0 = (1 - e^{-a(T-e)})/a and b1 = (e^{-a(T-e)} - e^{-aT})/a,
        P_h(z) = z^-D (b0 z + b1) / (z (z - e^{-aT})),
    Jury's modified z-transform with m = 1 - e/T (e = 0: the ordinary ZOH equivalent
    z^-D (1 - e^{-aT})/(a (z - e^{-aT}))).
    """
    dd = math.floor(tau / period + 1e-9)
    e = max(tau - dd * period, 0.0)
    b0 = (1 - math.exp(-a * (period - e))) / a
    b1 = (math.exp(-a * (period - e)) - math.exp(-a * period)) / a
    z = np.asarray(z, complex)
    return z ** (-dd) * (b0 * z + b1) / (z * (z - math.exp(-a * period)))


# ---------------------------------------------------------- item 2: the aliasing sum

def hold_equivalent_by_aliasing(g, period, tau, omega, k_max=20000, relative_degree=1,
                                chunk=4001):
    r"""The hold-equivalent of e^{-s tau} G(s) at z = e^{j omega T} by the aliasing sum

    .. math:: P_h = \frac{1}{T}\sum_{|k| \le K} H_0(j\omega_k) e^{-j\omega_k\tau} G(j\omega_k),
              \quad \omega_k = \omega + 2\pi k/T, \quad H_0(s) = (1 - e^{-sT})/s

    (Poisson's sum of the sampled pulse response; valid because the response of the held
    input is continuous at the sampling instants, G strictly proper). ``g`` is any callable
    s -> G(s) (vectorised), tau >= 0 any delay, fractional or not.

    Accuracy: with G(s) ~ c/s^r (r = ``relative_degree`` >= 1) the terms fall off as
    |k|^-(r+1), and the dropped tail is at most about a_K K/r, a_K the size of the terms at
    k = +-K; the function returns ``tail = 2 a_K (K/r + 1)`` (twice that: a safe bound), with
    a_K = |1 - e^{-j w T}|/T |G(j w_K)|/|w_K| summed over k = +-K. The error of ``value`` is
    below ``tail`` plus rounding (~1e-11 relative: e^{-j w_k tau} at arguments up to
    2 pi K tau/T). With tau/T an integer every term adds and the error is about half the
    bound; with a fractional tau/T the phases e^{-j 2 pi k tau/T} rotate and cancel and the
    error is far smaller: for the QT-CAS voltage -> current (r = 1) at 25 kHz with
    tau_c = 1.5 T and K = 20000 the bound is < 5e-4 of |P_h| up to 0.999 of the Nyquist
    frequency (< 1e-6 below a tenth of it), the actual error < 1e-8 (tests).

    Returns
    -------
    value, tail : numpy.ndarray (complex, float), shape of omega
    """
    omega = np.asarray(omega, float)
    flat = omega.reshape(-1)
    total = np.zeros(flat.size, complex)
    ks = np.arange(-k_max, k_max + 1, dtype=float)
    hold = (1 - np.exp(-1j * flat * period)) / period          # the same for every k
    for start in range(0, ks.size, chunk):
        w_k = flat[:, None] + 2 * np.pi * ks[None, start:start + chunk] / period
        s_k = 1j * w_k
        total += np.sum(np.exp(-s_k * tau) * g(s_k) / s_k, axis=1)
    ends = flat[:, None] + 2 * np.pi * np.array([-k_max, k_max])[None, :] / period
    tail = (2.0 * np.abs(hold) * np.sum(np.abs(g(1j * ends)) / np.abs(ends), axis=1)
            * (k_max / relative_degree + 1))
    return (hold * total).reshape(omega.shape), tail.reshape(omega.shape)


# ------------------------------------------------------------------ continuous pieces

def _poly(num, s):
    return np.polyval(num, s)


def current_voltage_to_current(d):
    """Y(s) = i/V = (J s + mu_v)/((L s + R)(J s + mu_v) + Ke Km) (docs/model.md §2)."""
    num = [d.J, d.mu_v]
    den = np.polyadd(np.polymul([d.L, d.R], [d.J, d.mu_v]), [d.Ke * d.Km])
    return lambda s: _poly(num, s) / _poly(den, s)


def voltage_to_angle(d):
    """theta/V = Km/(s ((L s + R)(J s + mu_v) + Ke Km)) (docs/model.md §2: Y M)."""
    den = np.polymul(np.polyadd(np.polymul([d.L, d.R], [d.J, d.mu_v]), [d.Ke * d.Km]),
                     [1.0, 0.0])
    return lambda s: d.Km / _poly(den, s)


def continuous_current_to_angle(d):
    """The continuous current loop closed, times M: theta/i_cmd = T_i(s) M(s) with
    L_i = C_i e^{-s tau_c} Y, T_i = L_i/(1 + L_i), M = Km/(s (J s + mu_v)) (docs/model.md)."""
    y = current_voltage_to_current(d)

    def g(s):
        l_i = (d.ci_Kp + d.ci_Ki / s) * np.exp(-s * d.tau_c) * y(s)
        return l_i / (1 + l_i) * d.Km / (s * (d.J * s + d.mu_v))
    return g


def continuous_position_controller(d):
    """C_p(s) = Kp + Ki/s + Kd s/(Tf s + 1)."""
    return lambda s: d.cp_Kp + d.cp_Ki / s + d.cp_Kd * s / (d.Tf * s + 1)


def issue_position_loop(d, period, method="backward", k_max=2000):
    """The issue's own computation: the position loop sampled at ``period`` (its PID
    discretised, its output held), the current loop CONTINUOUS with its exact delay, tau_p a
    transport delay: L_p(e^{jwT}) = C_p(e^{jwT}) P_h(e^{jwT}), P_h the hold-equivalent of
    e^{-s tau_p} T_i(s) M(s) by the aliasing sum (T_i M ~ 1/s^3: terms ~ k^-4).
    Returns L_p as a function of omega (and its tail bound as an attribute)."""
    _, c_p, _ = controllers(d, period, period, method)
    g = continuous_current_to_angle(d)

    def loop(omega):
        value, _ = hold_equivalent_by_aliasing(g, period, d.tau_p, omega, k_max,
                                               relative_degree=3)
        return evaluate(c_p, omega) * value
    return loop


# ---------------------------------------------------------------- item 3: multirate, lifted

def _closed_current_loop(d, fast, method):
    """The fast closed current loop as matrices (A, B, C_theta, C_i, A-part for L_i):
    plant hold-equivalent with the exact (fractional) tau_c, PI at ``fast``. Input: the current
    command the current controller reads; outputs theta as measured (through an angle
    filter) and unfiltered, two rows of C_theta (no feedthrough).
    Also returns the open current loop L_i (broken at the controller's output) as a system."""
    a, b, c = plant_matrices(d, output=True)
    ap, bp, cp = hold_equivalent(a, b, c, fast, d.tau_c)
    pi = control.ss(pi_controller(d.ci_Kp, d.ci_Ki, fast, method))
    ac, bc, cc, dc = pi.A, pi.B, pi.C, pi.D
    ci, ct = cp[:1], cp[1:]  # the (filtered) current; the angle measured, then unfiltered
    # u = Cc xc + Dc (r - i);  xp+ = Ap xp + Bp u;  xc+ = Ac xc + Bc (r - i)
    top = np.hstack([ap - bp @ dc @ ci, bp @ cc])
    bottom = np.hstack([-bc @ ci, ac])
    a_cl = np.vstack([top, bottom])
    b_cl = np.vstack([bp @ dc, bc])
    c_theta = np.hstack([ct, np.zeros((2, ac.shape[0]))])
    current = control.series(pi, control.ss(ap, bp, ci, 0, fast))
    return a_cl, b_cl, c_theta, current


def fast_position_plant(d, fast, method="backward"):
    """The position controller's output -> theta at the FAST rate, as a python-control state
    space: a shift register of d_p = ceil(tau_p/T_f) fast samples (the current controller
    reads the command d_p fast samples late) into the fast closed current loop (exact
    hold-equivalent with tau_c, PI); outputs the angle measured, then unfiltered. Also returns
    L_i (broken at the current controller's output)."""
    a_cl, b_cl, c_theta, current = _closed_current_loop(d, fast, method)
    n = a_cl.shape[0]
    dp = samples(d.tau_p, fast)
    size = n + dp
    a = np.zeros((size, size))
    b = np.zeros((size, 1))
    a[:n, :n] = a_cl
    if dp:
        a[:n, n + dp - 1:n + dp] = b_cl                # the current loop reads u delayed dp
        b[n, 0] = 1.0
        for j in range(1, dp):
            a[n + j, n + j - 1] = 1.0
    else:
        b[:n] = b_cl
    c = np.hstack([c_theta, np.zeros((2, dp))])
    return control.ss(a, b, c, np.zeros((2, 1)), fast), current


def lifted(d, fast, ratio, method="backward"):
    """Item 3: the current loop at period ``fast`` [s], the position loop at ratio*fast.

    The fast system (:func:`fast_position_plant`: x = fast closed current loop and the delay
    register, input the slow controller's output, output theta) sees the slow controller's
    output u_s[n] from fast step nM on, constant for M = ``ratio`` fast steps; the slow
    controller reads theta at fast step nM (the command the current controller reads at fast
    step k is u_s[floor((k - d_p)/M)]). Over one slow period:
        x[(n+1)M] = A^M x[nM] + (sum_{i<M} A^i B) u_s[n],   theta_s[n] = C x[nM]
    which is the slow system that L_p and T are composed from (at period M T_f).
    """
    fast_plant, current = fast_position_plant(d, fast, method)
    a, b = fast_plant.A, fast_plant.B
    a_s = np.eye(a.shape[0])
    b_s = np.zeros_like(b)
    for _ in range(ratio):                             # b_s = sum_{i<M} A^i B, a_s = A^M
        b_s = a @ b_s + b
        a_s = a @ a_s
    slow = ratio * fast
    plant_p = control.ss(a_s, b_s, fast_plant.C[:1], 0, slow)
    plant_out = control.ss(a_s, b_s, fast_plant.C[1:], 0, slow)
    _, c_p, c_r = controllers(d, fast, slow, method)
    return SampledLoops(current, plant_p, control.ss(c_p), control.ss(c_r), plant_out)


# ----------------------------------------------------------------------------- margins

@dataclass(frozen=True)
class Margins:
    """Headline margins of a loop: PM [deg] at the crossover nearest -1 (wc [rad/s]); the
    smallest upper GM [dB] (w180 [rad/s]); None where absent in the range."""

    phase_margin_deg: float | None
    crossover_rad_s: float | None
    gain_margin_db: float | None
    phase_crossover_rad_s: float | None


def margins(loop, w_min, w_max, points=4000):
    """Margins of ``loop`` (a callable omega -> L) on [w_min, w_max] (for a discrete loop
    w_max just below the Nyquist frequency pi/T): every |L| = 1 and every real negative L
    bracketed on a log grid and refined by brentq (to 1e-12 relative in omega)."""
    w = np.geomspace(w_min, w_max, points)
    val = loop(w)
    scalar = lambda x: complex(loop(np.array([x]))[0])  # noqa: E731
    pm, wc = None, None
    mag = np.abs(val) - 1.0
    for k in np.nonzero(np.sign(mag[:-1]) != np.sign(mag[1:]))[0]:
        x = brentq(lambda x: abs(scalar(x)) - 1.0, w[k], w[k + 1], xtol=1e-12 * w[k])
        m = (math.degrees(np.angle(scalar(x))) + 360.0) % 360.0 - 180.0
        if pm is None or abs(m) < abs(pm):
            pm, wc = m, x
    gm, w180 = None, None
    im = val.imag
    for k in np.nonzero((np.sign(im[:-1]) != np.sign(im[1:])) & (val.real[:-1] < 0))[0]:
        x = brentq(lambda x: scalar(x).imag, w[k], w[k + 1], xtol=1e-12 * w[k])
        v = scalar(x)
        if v.real < 0:
            g = -20 * math.log10(abs(v))
            if g > 0 and (gm is None or g < gm):
                gm, w180 = g, x
    return Margins(pm, wc, gm, w180)


def sampled_margins(system, w_min=1.0, points=4000):
    """:func:`margins` of a discrete SISO system up to (1 - 1e-9) of its Nyquist frequency."""
    return margins(lambda w: evaluate(system, w), w_min, (1 - 1e-9) * math.pi / system.dt,
                   points)


def continuous_margins(d, w_min=1.0, w_max=1e6, points=4000):
    """Margins of the continuous L_i and L_p with exact delays (docs/model.md §3-§4)."""
    y = current_voltage_to_current(d)
    g = continuous_current_to_angle(d)
    c_p = continuous_position_controller(d)
    l_i = lambda w: (d.ci_Kp + d.ci_Ki / (1j * w)) * np.exp(-1j * w * d.tau_c) * y(1j * w)  # noqa: E731,E501
    l_p = lambda w: c_p(1j * w) * np.exp(-1j * w * d.tau_p) * g(1j * w)  # noqa: E731
    return {"current_loop": margins(l_i, w_min, w_max, points),
            "position_loop": margins(l_p, w_min, w_max, points)}


__all__ = ["Drive", "Margins", "SampledLoops", "continuous_current_to_angle",
           "continuous_margins", "continuous_position_controller", "controllers",
           "current_voltage_to_current", "delay_tf", "derivative", "drive_of", "evaluate",
           "evaluate_ss", "fast_position_plant", "first_order_modified_z", "hold_equivalent",
           "hold_equivalent_by_aliasing", "integer_samples", "issue_position_loop", "lifted",
           "margins", "pi_controller", "plant_matrices", "plant_ss", "replace",
           "sampled_margins", "samples", "single_rate", "voltage_to_angle"]
