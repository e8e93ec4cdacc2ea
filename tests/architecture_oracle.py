"""An independent reference for the loop figures of every drive architecture (issue 25).

Written from the model definition (docs/model.md §3-§7 and §13, "Drive architectures") and
from Newton's equations, WITHOUT importing cas_freq: only numpy, scipy and python-control.
Tests compare cas_freq against it; tests/test_architecture_oracle.py checks the oracle itself.

Three computations, each a different method:

* ``responses``: the loops and the closed loop at each frequency from ONE complex linear system
  of all signal equations (plant rows from Newton's equations, one row per controller, filter,
  delay and sensor), solved by ``numpy.linalg.solve``. A loop is broken by replacing its
  controller's applied output by an injected unit signal; the returned controller output is
  ``-L``. Loops "open" in a view apply 0 instead of their controller's output.
* ``responses_by_formula``: the general break-point formula (docs/model.md, "Drive
  architectures") composed from python-control transfer functions of the blocks, the plant built
  by impedance algebra (not by the state equations), delays exact by ``exp(-j w tau)``.
* ``pade_closed_loop``: the whole diagram with Padé delays as python-control systems joined by
  ``control.interconnect``: its poles give the stability verdict.

Signals (SI; angles at the MOTOR, the output angle reflected to the motor as y_out = N delta):
r (position command, motor rad), y_p (measured position), u_p (position controller output: a
current command [A] for the PID-on-PI, a velocity command [rad/s] for the cascade), w_cmd
(velocity command), w_meas (measured velocity), u_v (velocity controller output [A]), i_cmd
(current command after delay and filters), u_i (current controller output [V]), V (motor
voltage after the delay), i, theta, y_out; i_meas and y_m: the current and y_p through the
measurement filters (``current_feedback``, ``position_feedback``), what the controllers read.
Loops are numbered from the inside: current, (velocity,) position.
"""

import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import control
import numpy as np
from scipy.optimize import brentq, minimize_scalar

FILTER_POINTS = ("current_command", "velocity_feedback", "current_feedback",
                 "position_feedback")
FILTER_TYPES = ("lowpass1", "lowpass2", "notch")


@dataclass(frozen=True)
class Filter:
    """One filter in series at ``at``: lowpass1 1/(s/w0 + 1); lowpass2 w0^2/(s^2 + 2 z w0 s +
    w0^2); notch (s^2 + 2 d z w0 s + w0^2)/(s^2 + 2 z w0 s + w0^2), z = width/(2 w0),
    d = 10^(depth_db/20) (docs/model.md §13)."""

    at: str
    type: str
    frequency: float            # w0 [rad/s]
    damping: float = 0.7        # z of lowpass2 [-]
    width: float = 0.0          # notch width [rad/s]
    depth_db: float = -20.0     # notch depth at w0 [dB] (< 0)

    def polynomials(self):
        """(num, den) in descending powers of s."""
        w0 = self.frequency
        if self.type == "lowpass1":
            return [1.0], [1.0 / w0, 1.0]
        if self.type == "lowpass2":
            return [w0 * w0], [1.0, 2.0 * self.damping * w0, w0 * w0]
        if self.type == "notch":
            zeta = self.width / (2.0 * w0)
            depth = 10.0 ** (self.depth_db / 20.0)
            return ([1.0, 2.0 * depth * zeta * w0, w0 * w0], [1.0, 2.0 * zeta * w0, w0 * w0])
        raise ValueError(f"filter type: {self.type!r} is not one of {FILTER_TYPES}")


@dataclass(frozen=True)
class Drive:
    """Plain SI parameters of one drive (defaults: no load, rigid gear, no filters).

    ``structure`` is 'pid' (PID position controller -> current command -> current PI, the
    report's EPOS4 structure) or 'cascade' (position P/PI -> velocity command -> velocity PI ->
    current command -> current PI). Gains are per rad of MOTOR angle whatever the sensor.
    """

    R: float                    # [ohm]
    L: float                    # [H]
    Km: float                   # [N m/A]
    Ke: float                   # [V s/rad]
    J: float                    # rotor inertia [kg m^2]
    mu_v: float                 # motor viscous friction [N m s/rad]
    ci_Kp: float                # current PI [V/A]
    ci_Ki: float                # [V/(A s)]
    tau_c: float                # delay current controller -> motor [s]
    cp_Kp: float                # position: PID [A/rad] or cascade P [1/s]
    N: float = 1.0              # gear ratio [-]
    eta: float = 1.0            # forward efficiency [-]
    J_L: float = 0.0            # load inertia at the output [kg m^2]
    b_L: float = 0.0            # load damping at the output [N m s/rad]
    K_h: float = 0.0            # hinge stiffness at the output [N m/rad]
    K_g: float = 0.0            # gear stiffness at the output [N m/rad]; 0 = rigid
    c_g: float = 0.0            # mesh damping in parallel with K_g [N m s/rad]
    structure: str = "pid"
    cp_Ki: float = 0.0          # PID [A/(rad s)] or cascade [1/s^2]
    cp_Kd: float = 0.0          # PID derivative [A s/rad]
    Tf: float | None = None     # PID derivative filter [s]; None: Kd/(10 Kp)
    tau_p: float = 0.0          # delay after the position controller [s]
    derivative_on: str = "error"  # or 'measurement' (PID only; changes T, not the loops)
    cv_Kp: float = 0.0          # velocity PI [A s/rad]
    cv_Ki: float = 0.0          # [A/rad]
    tau_v: float = 0.0          # delay velocity controller -> current loop [s]
    tau_vf: float = 0.0         # velocity feedback first-order low-pass [s]; 0: none
    filters: tuple = field(default=())
    feedback: str = "motor"     # position sensor: 'motor' (theta) or 'output' (N delta)

    def __post_init__(self):
        if self.structure not in ("pid", "cascade"):
            raise ValueError(f"structure: {self.structure!r} is not 'pid' or 'cascade'")
        if self.feedback not in ("motor", "output"):
            raise ValueError(f"feedback: {self.feedback!r} is not 'motor' or 'output'")
        if self.K_g > 0 and self.J_L <= 0:
            raise ValueError("K_g: a compliant gear needs J_L > 0")
        filters = tuple(f if isinstance(f, Filter) else Filter(**f) for f in self.filters)
        for f in filters:
            if f.at not in FILTER_POINTS:
                raise ValueError(f"filter at: {f.at!r} is not one of {FILTER_POINTS}")
            f.polynomials()
            if not f.frequency > 0:
                raise ValueError(f"filter frequency: must be > 0 rad/s, got {f.frequency}")
            if f.type == "notch" and not f.depth_db < 0:
                raise ValueError(f"notch depth_db: must be < 0, got {f.depth_db}")
            if f.type == "notch" and not f.width > 0:
                raise ValueError(f"notch width: must be > 0 rad/s, got {f.width}")
        if self.structure == "pid" and (self.tau_vf or any(
                f.at == "velocity_feedback" for f in filters)):
            raise ValueError("velocity feedback filter without a velocity loop")
        if self.structure == "pid" and (self.cv_Kp or self.cv_Ki or self.tau_v):
            raise ValueError("cv_Kp, cv_Ki, tau_v: velocity-loop values without a velocity loop")
        if self.structure == "cascade" and (self.cp_Kd or self.Tf is not None):
            raise ValueError("cp_Kd, Tf: the cascade's position controller is P or PI")
        object.__setattr__(self, "filters", filters)

    @classmethod
    def from_dict(cls, values):
        """A Drive from a plain dict of the field names above."""
        return cls(**values)

    @property
    def Tf_value(self):
        """The PID's derivative filter time constant [s]."""
        return self.Tf if self.Tf is not None else self.cp_Kd / (10.0 * self.cp_Kp)

    @property
    def loops(self):
        """The loops from the inside out."""
        if self.structure == "cascade":
            return ("current", "velocity", "position")
        return ("current", "position")


# --------------------------------------------------------------------------- blocks (num, den)

def _pi(kp, ki):
    """PI (kp s + ki)/s, or the pure gain kp when ki = 0."""
    return ([kp, ki], [1.0, 0.0]) if ki else ([kp], [1.0])


def _pid(d):
    """C_p = Kp + Ki/s + Kd s/(Tf s + 1) over the common denominator s (Tf s + 1)."""
    kp, ki, kd, tf = d.cp_Kp, d.cp_Ki, d.cp_Kd, d.Tf_value
    num = np.polyadd(np.polymul([kp, ki], [tf, 1.0]), [kd, 0.0, 0.0])
    return list(num), [tf, 1.0, 0.0]


def _pi_part_of_pid(d):
    """Kp + Ki/s over the PID's denominator s (Tf s + 1) (derivative on the measurement)."""
    return list(np.polymul([d.cp_Kp, d.cp_Ki], [d.Tf_value, 1.0])), [d.Tf_value, 1.0, 0.0]


def _position_controller(d):
    return _pid(d) if d.structure == "pid" else _pi(d.cp_Kp, d.cp_Ki)


def _filters_at(d, at):
    return [f.polynomials() for f in d.filters if f.at == at]


def _delay_factor(s, tau, delay):
    """(num, den) values of exp(-s tau): exact, or Padé [n/n] given delay = ('pade', n)."""
    if delay == "exact" or tau == 0.0:
        return np.exp(-s * tau), np.ones_like(s)
    num, den = control.pade(1.0, delay[1])          # in the scaled variable s tau
    return np.polyval(num, s * tau), np.polyval(den, s * tau)


# --------------------------------------------------------------- method 1: one linear system

class _Equations:
    """Linear signal equations sum_j a_j(s) x_j = b(s), one set per frequency point."""

    def __init__(self, s):
        self.s = np.asarray(s, dtype=complex)
        self.index = {}
        self.rows = []

    def add(self, terms, rhs=0.0):
        """One equation: terms is a list of (signal name, coefficient array)."""
        self.rows.append(([(self.index.setdefault(n, len(self.index)), c) for n, c in terms],
                          rhs))

    def equal(self, out, inp, gain=1.0):
        self.add([(out, 1.0), (inp, -gain)])

    def block(self, out, num, den, inp):
        """den(s) out = num(s) inp."""
        self.add([(out, np.polyval(den, self.s)), (inp, -np.polyval(num, self.s))])

    def chain(self, name, blocks, inp):
        """inp through blocks in series; returns the last signal's name."""
        for k, (num, den) in enumerate(blocks):
            out = f"{name}{k}"
            self.block(out, num, den, inp)
            inp = out
        return inp

    def solve(self):
        m, n = len(self.index), self.s.size
        if len(self.rows) != m:
            raise AssertionError(f"{len(self.rows)} equations for {m} signals")
        a = np.zeros((n, m, m), dtype=complex)
        b = np.zeros((n, m), dtype=complex)
        for k, (terms, rhs) in enumerate(self.rows):
            for j, coef in terms:
                a[:, k, j] += coef
            b[:, k] = rhs
        x = np.linalg.solve(a, b[..., None])[..., 0]
        return {name: x[:, j] for name, j in self.index.items()}


def _plant_rows(eq, d):
    """Newton's equations in the Laplace domain (zero initial state).

    Electrical:  L di/dt = V - R i - Ke w      ->  (L s + R) i + Ke s theta = V
    Rigid gear: the output turns with theta/N; on the output shaft J_L delta'' = tau_out -
    b_L delta' - K_h delta, and the gear passes the torque tau_out/(eta N) back to the motor
    (forward efficiency eta), so with delta = theta/N the motor sees
        (J + J_L/(eta N^2)) theta'' + (mu_v + b_L/(eta N^2)) theta' + K_h/(eta N^2) theta = Km i.
    Compliant gear: the gear output angle theta/N drives the output delta through a spring K_g
    and a damper c_g in parallel, torque tau_g = K_g (theta/N - delta) + c_g (w/N - delta');
        output: J_L delta'' = tau_g - b_L delta' - K_h delta
        motor:  J w' = Km i - mu_v w - tau_g/(eta N).
    Written with y_out = N delta (the output angle reflected to the motor).
    """
    s, n, eta = eq.s, d.N, d.eta
    eq.add([("i", d.L * s + d.R), ("theta", d.Ke * s), ("V", -1.0)])
    if d.K_g == 0.0:
        reflect = eta * n * n
        eq.add([("theta", (d.J + d.J_L / reflect) * s * s + (d.mu_v + d.b_L / reflect) * s
                 + d.K_h / reflect), ("i", -d.Km)])
        eq.equal("y_out", "theta")
        return
    spring = d.K_g + d.c_g * s                         # tau_g per rad of (theta/N - delta)
    load = d.J_L * s * s + d.b_L * s + d.K_h           # output shaft's own impedance
    eq.add([("theta", d.J * s * s + d.mu_v * s + spring / (eta * n * n)),
            ("y_out", -spring / (eta * n * n)), ("i", -d.Km)])
    eq.add([("y_out", (load + spring) / n), ("theta", -spring / n)])


def _diagram(eq, d, states, r, delay):
    """Every signal equation of the loops. states[loop] is 'closed', 'open' (its controller's
    output not applied: 0) or 'broken' (a unit signal applied in its place)."""
    s = eq.s
    for loop, state in states.items():          # u_<loop>_applied
        u, applied = f"u_{loop}", f"u_{loop}_applied"
        if state == "closed":
            eq.equal(applied, u)
        else:
            eq.add([(applied, 1.0)], 1.0 if state == "broken" else 0.0)

    def delayed(out, tau, inp):
        num, den = _delay_factor(s, tau, delay)
        eq.add([(out, den), (inp, -num)])

    _plant_rows(eq, d)
    # current loop: u_i = C_i (i_cmd - i_meas), i_meas = filters(i); V = exp(-s tau_c) u_i
    eq.equal("i_meas", eq.chain("fcf", _filters_at(d, "current_feedback"), "i"))
    num, den = _pi(d.ci_Kp, d.ci_Ki)
    eq.add([("u_current", np.polyval(den, s)), ("i_cmd", -np.polyval(num, s)),
            ("i_meas", np.polyval(num, s))])
    delayed("V", d.tau_c, "u_current_applied")
    # what feeds the current command, through its delay and the current_command filters
    inner = "velocity" if d.structure == "cascade" else "position"
    tau_in = d.tau_v if d.structure == "cascade" else d.tau_p
    delayed("i_cmd_delayed", tau_in, f"u_{inner}_applied")
    eq.equal("i_cmd", eq.chain("fcc", _filters_at(d, "current_command"), "i_cmd_delayed"))
    if d.structure == "cascade":
        # velocity loop: w_meas = filters(lowpass(s theta)); u_v = C_v (w_cmd - w_meas)
        eq.add([("w", 1.0), ("theta", -s)])
        blocks = ([([1.0], [d.tau_vf, 1.0])] if d.tau_vf else [])
        blocks += _filters_at(d, "velocity_feedback")
        eq.equal("w_meas", eq.chain("fvf", blocks, "w"))
        num, den = _pi(d.cv_Kp, d.cv_Ki)
        eq.add([("u_velocity", np.polyval(den, s)), ("w_cmd", -np.polyval(num, s)),
                ("w_meas", np.polyval(num, s))])
        delayed("w_cmd", d.tau_p, "u_position_applied")
    # position loop: u_p = C_p (r - y_m), or (Kp + Ki/s)(r - y_m) - D(s) y_m, y_m the
    # position y_p through the position_feedback filters
    eq.equal("y_p", "theta" if d.feedback == "motor" else "y_out")
    eq.equal("y_m", eq.chain("fpf", _filters_at(d, "position_feedback"), "y_p"))
    num, den = _position_controller(d)
    num_r = _pi_part_of_pid(d)[0] if (d.structure == "pid"
                                      and d.derivative_on == "measurement") else num
    eq.add([("u_position", np.polyval(den, s)), ("y_m", np.polyval(num, s))],
           np.polyval(num_r, s) * r)


def _s(omega):
    omega = np.atleast_1d(np.asarray(omega))
    return omega if np.iscomplexobj(omega) else 1j * omega.astype(float)


def loop_response(d, loop, view, omega, delay="exact"):
    """One loop at omega [rad/s] (a complex array is taken as s itself): ``view`` 'L' breaks it
    at its controller's output with the loops inside closed and those outside open, 'L_aat'
    with every other loop closed. The returned controller output per injected unit is -L."""
    k = d.loops.index(loop)
    states = {other: ("closed" if (j < k or view == "L_aat") else "open")
              for j, other in enumerate(d.loops)}
    states[loop] = "broken"
    eq = _Equations(_s(omega))
    _diagram(eq, d, states, 0.0, delay)
    return -eq.solve()[f"u_{loop}"]


def responses(d, omega, delay="exact"):
    """Every loop in both views (``L[loop]``, ``L_aat[loop]``, see ``loop_response``), and the
    closed loop ``T`` = y_out/r = delta/delta_cmd, ``T_measured`` = y_p/r, at omega [rad/s]."""
    out = {view: {loop: loop_response(d, loop, view, omega, delay) for loop in d.loops}
           for view in ("L", "L_aat")}
    out.update(closed_loop(d, omega, delay))
    return out


def loop_function(d, loop, view="L", delay="exact"):
    """omega [rad/s] -> the loop's response (``view`` 'L' or 'L_aat'), vectorised."""
    return lambda omega: loop_response(d, loop, view, omega, delay)


def closed_loop(d, omega, delay="exact"):
    """T = y_out/r = delta/delta_cmd and T_measured = y_p/r at omega [rad/s] (complex: s),
    every loop closed; also at omega = 0 (the controllers' rows are polynomial in s)."""
    eq = _Equations(_s(omega))
    _diagram(eq, d, dict.fromkeys(d.loops, "closed"), 1.0, delay)
    x = eq.solve()
    return {"T": x["y_out"], "T_measured": x["y_p"]}


# ------------------------------------------------ method 2: transfer functions and the formula

def plant_tf(d):
    """i/V, theta/V, y_out/V (y_out = N delta) as python-control transfer functions, by
    impedance algebra: Z_m = torque per motor angle the motor must supply,
    rigid   Z_m = (J + J_L/(eta N^2)) s^2 + (mu_v + b_L/(eta N^2)) s + K_h/(eta N^2);
    compliant: spring Z_g = K_g + c_g s in series with the load Z_L = J_L s^2 + b_L s + K_h, the
    gear passing Z_g Z_L/(Z_g + Z_L)/(eta N^2) to the motor: Z_m = J s^2 + mu_v s + that; and
    theta/i = Km/Z_m, i/V = Z_m/((L s + R) Z_m + Ke Km s), N delta/theta = Z_g/(Z_g + Z_L).
    """
    s = control.tf("s")
    reflect = d.eta * d.N * d.N
    if d.K_g == 0.0:
        z_m = ((d.J + d.J_L / reflect) * s * s + (d.mu_v + d.b_L / reflect) * s
               + d.K_h / reflect)
        out_per_theta = control.tf([1.0], [1.0])
    else:
        z_g = d.K_g + d.c_g * s
        z_l = d.J_L * s * s + d.b_L * s + d.K_h
        z_m = d.J * s * s + d.mu_v * s + z_g * z_l / ((z_g + z_l) * reflect)
        out_per_theta = z_g / (z_g + z_l)
    denominator = (d.L * s + d.R) * z_m + d.Ke * d.Km * s
    theta = d.Km / denominator
    return {"i": z_m / denominator, "theta": theta, "y_out": theta * out_per_theta}


def _tf(num, den):
    return control.tf(num, den)


def _at(system, s):
    return np.asarray(system(s), dtype=complex).reshape(s.shape)


def formula_parts(d, omega):
    """F_k (forward path from loop k's command to the next inner command, exact delays) and
    G_k (the plant signal loop k measures, per volt) at omega [rad/s], loops from the inside."""
    s = 1j * np.asarray(omega, dtype=float)
    plant = {k: _at(g, s) for k, g in plant_tf(d).items()}
    one = np.ones_like(s)

    def series(blocks):
        out = one.copy()
        for num, den in blocks:
            out = out * _at(_tf(num, den), s)
        return out

    cc = series(_filters_at(d, "current_command"))
    forward = [_at(_tf(*_pi(d.ci_Kp, d.ci_Ki)), s) * np.exp(-s * d.tau_c)]
    measured = [plant["i"] * series(_filters_at(d, "current_feedback"))]
    y_p = plant["theta"] if d.feedback == "motor" else plant["y_out"]
    y_p = y_p * series(_filters_at(d, "position_feedback"))
    if d.structure == "cascade":
        vf = series(([([1.0], [d.tau_vf, 1.0])] if d.tau_vf else [])
                    + _filters_at(d, "velocity_feedback"))
        forward.append(cc * _at(_tf(*_pi(d.cv_Kp, d.cv_Ki)), s) * np.exp(-s * d.tau_v))
        measured.append(vf * s * plant["theta"])
        forward.append(_at(_tf(*_pi(d.cp_Kp, d.cp_Ki)), s) * np.exp(-s * d.tau_p))
    else:
        forward.append(cc * _at(_tf(*_pid(d)), s) * np.exp(-s * d.tau_p))
    measured.append(y_p)
    return forward, measured, plant


def responses_by_formula(d, omega):
    """The loops by the general formula, with P_k = F_1 ... F_k and D_k = 1 + sum_{j<=k}
    P_j G_j (D_0 = 1):  L_k = P_k G_k / D_{k-1},  L_k,aat = sum_{j>=k} P_j G_j / D_{k-1};
    and T = (reference path) y_out/V / D_n."""
    forward, measured, plant = formula_parts(d, omega)
    path = np.cumprod(np.array(forward), axis=0)          # P_k
    terms = path * np.array(measured)                     # P_k G_k
    before = 1.0 + np.concatenate([np.zeros_like(terms[:1]), np.cumsum(terms, axis=0)[:-1]])
    tail = np.cumsum(terms[::-1], axis=0)[::-1]           # sum_{j>=k} P_j G_j
    out = {"L": {}, "L_aat": {}}
    for k, loop in enumerate(d.loops):
        out["L"][loop] = terms[k] / before[k]
        out["L_aat"][loop] = tail[k] / before[k]
    reference = path[-1]
    if d.structure == "pid" and d.derivative_on == "measurement":
        s = 1j * np.asarray(omega, dtype=float)
        reference = reference * _at(_tf(*_pi_part_of_pid(d)), s) / _at(_tf(*_pid(d)), s)
    out["T"] = reference * plant["y_out"] / (1.0 + tail[0])
    return out


# ----------------------------------------------------- method 3: Padé state space and poles

def _pade_ss(tau, order, name_in, name_out):
    """exp(-s tau) as Padé [n/n], realised for tau = 1 and time-scaled (A/tau, B/tau), which
    keeps a sub-millisecond delay's model well conditioned (docs/model.md §6)."""
    if tau == 0.0:
        return control.ss([], [], [], [[1.0]], inputs=name_in, outputs=name_out)
    num, den = control.pade(1.0, order)
    unit = control.tf2ss(num, den)
    return control.ss(unit.A / tau, unit.B / tau, unit.C, unit.D, inputs=name_in,
                      outputs=name_out)


def plant_ss(d):
    """The plant's state space from Newton's equations (see ``_plant_rows``), input V, outputs
    i, theta, w, y_out. States: i, theta, w (rigid) plus delta, delta' (compliant)."""
    n, eta = d.N, d.eta
    if d.K_g == 0.0:
        reflect = eta * n * n
        j_eff = d.J + d.J_L / reflect
        a = [[-d.R / d.L, 0.0, -d.Ke / d.L],
             [0.0, 0.0, 1.0],
             [d.Km / j_eff, -d.K_h / reflect / j_eff, -(d.mu_v + d.b_L / reflect) / j_eff]]
        b = [[1.0 / d.L], [0.0], [0.0]]
        c = [[1.0, 0, 0], [0, 1.0, 0], [0, 0, 1.0], [0, 1.0, 0]]
    else:
        kg, cg, jm, jl = d.K_g, d.c_g, d.J, d.J_L
        # tau_g = kg (theta/N - delta) + cg (w/N - delta')
        a = [[-d.R / d.L, 0.0, -d.Ke / d.L, 0.0, 0.0],
             [0.0, 0.0, 1.0, 0.0, 0.0],
             [d.Km / jm, -kg / (eta * n * n * jm), -(d.mu_v + cg / (eta * n * n)) / jm,
              kg / (eta * n * jm), cg / (eta * n * jm)],
             [0.0, 0.0, 0.0, 0.0, 1.0],
             [0.0, kg / (n * jl), cg / (n * jl), -(kg + d.K_h) / jl, -(cg + d.b_L) / jl]]
        b = [[1.0 / d.L], [0.0], [0.0], [0.0], [0.0]]
        c = [[1.0, 0, 0, 0, 0], [0, 1.0, 0, 0, 0], [0, 0, 1.0, 0, 0], [0, 0, 0, n, 0]]
    return control.ss(a, b, c, np.zeros((4, 1)), inputs="V",
                      outputs=["i", "theta", "w", "y_out"], name="plant")


def _tf_block(num, den, name_in, name_out):
    return control.tf2ss(control.tf(num, den), inputs=name_in, outputs=name_out)


def _series_blocks(blocks, name_in, name_out, tag):
    """Blocks in series from name_in to name_out (an identity if there are none)."""
    systems, inp = [], name_in
    for k, (num, den) in enumerate(blocks):
        out = name_out if k == len(blocks) - 1 else f"{tag}{k}"
        systems.append(_tf_block(num, den, inp, out))
        inp = out
    if not systems:
        systems.append(control.ss([], [], [], [[1.0]], inputs=name_in, outputs=name_out))
    return systems


def pade_closed_loop(d, order=6):
    """The closed loop r -> y_out with Padé delays of ``order``, every loop closed, as one
    python-control StateSpace from ``control.interconnect`` of the explicit blocks."""
    sj = control.summing_junction
    parts = [plant_ss(d),
             sj(inputs=["i_cmd", "-i_meas"], output="e_i"),
             _tf_block(*_pi(d.ci_Kp, d.ci_Ki), "e_i", "u_i"),
             _pade_ss(d.tau_c, order, "u_i", "V")]
    parts += _series_blocks(_filters_at(d, "current_feedback"), "i", "i_meas", "fcf")
    parts += _series_blocks(_filters_at(d, "position_feedback"),
                            "theta" if d.feedback == "motor" else "y_out", "y_m", "fpf")
    y_p = "y_m"  # what the position controller reads
    if d.structure == "cascade":
        parts += [_pade_ss(d.tau_v, order, "u_v", "i_pre"),
                  _tf_block(*_pi(d.cv_Kp, d.cv_Ki), "e_v", "u_v"),
                  sj(inputs=["w_cmd", "-w_meas"], output="e_v"),
                  _pade_ss(d.tau_p, order, "u_p", "w_cmd"),
                  _tf_block(*_pi(d.cp_Kp, d.cp_Ki), "e_p", "u_p"),
                  sj(inputs=["r", "-" + y_p], output="e_p")]
        parts += _series_blocks(([([1.0], [d.tau_vf, 1.0])] if d.tau_vf else [])
                                + _filters_at(d, "velocity_feedback"), "w", "w_meas", "fvf")
    else:
        parts += [_pade_ss(d.tau_p, order, "u_p", "i_pre")]
        if d.derivative_on == "measurement":
            tf_ = d.Tf_value
            parts += [_tf_block(*_pi(d.cp_Kp, d.cp_Ki), "e_p", "u_pi"),
                      _tf_block([d.cp_Kd, 0.0], [tf_, 1.0], y_p, "u_d"),
                      sj(inputs=["u_pi", "-u_d"], output="u_p")]
        else:
            parts += [_tf_block(*_pid(d), "e_p", "u_p")]
        parts += [sj(inputs=["r", "-" + y_p], output="e_p")]
    parts += _series_blocks(_filters_at(d, "current_command"), "i_pre", "i_cmd", "fcc")
    return control.interconnect(parts, inplist=["r"], outlist=["y_out"], check_unused=False)


def closed_loop_poles(d, order=6):
    """Eigenvalues of the Padé closed loop's state matrix [rad/s]."""
    return np.linalg.eigvals(np.asarray(pade_closed_loop(d, order).A))


def is_stable(d, order=6):
    """Every Padé closed-loop pole strictly in the left half-plane."""
    return bool(np.all(closed_loop_poles(d, order).real < 0.0))


# ------------------------------------------------------------------------------ the figures

def _wrap_pm(phase_deg):
    """PM = 180 deg + phase, taken modulo 360 into (-180, 180]."""
    pm = 180.0 - np.mod(-np.asarray(phase_deg, float), 360.0)
    return np.where(pm <= -180.0, pm + 360.0, pm)


def _feature_points(d):
    """Extra grid points around the lightly damped plant modes (poles of the plant with the
    voltage and with the current as input, roots of the output shaft held by the spring) and
    the filters' w0, so that narrow resonances and
    notches cannot hide between grid points."""
    a = np.asarray(plant_ss(d).A)
    roots = list(np.linalg.eigvals(a))                 # driven by the voltage
    roots += list(np.linalg.eigvals(a[1:, 1:]))        # driven by the current: zeros of i/V
    if d.K_g:
        roots += list(np.roots([d.J_L, d.b_L + d.c_g, d.K_h + d.K_g]))
    centres = [(abs(p), -p.real / abs(p)) for p in roots if abs(p) > 0 and p.imag > 0]
    for f in d.filters:
        num, den = f.polynomials()
        centres.append((f.frequency, (den[1] / (2 * f.frequency)) if len(den) == 3 else 1.0))
    points = [wn * (1.0 + max(z, 1e-7) * np.linspace(-40.0, 40.0, 801)) for wn, z in centres]
    return np.concatenate(points) if points else np.zeros(0)


def grid(d, w_min=1e-2, w_max=1e6, per_decade=2000):
    """Log grid [rad/s] plus the feature points inside the range."""
    base = np.geomspace(w_min, w_max, int(round(per_decade * math.log10(w_max / w_min))) + 1)
    extra = _feature_points(d)
    extra = extra[(extra > w_min) & (extra < w_max)]
    return np.unique(np.concatenate([base, extra]))


@dataclass(frozen=True)
class LoopFigures:
    """Margins of one loop: every crossover and the headlines (docs/model.md §7)."""

    gain_crossovers_rad_s: tuple
    phase_margins_deg: tuple
    delay_margins_s: tuple
    phase_crossovers_rad_s: tuple
    gain_margins_db: tuple
    crossover_rad_s: float | None       # headline: the smallest |PM|
    phase_margin_deg: float | None
    gain_margin_db: float | None        # smallest upper (> 0 dB) margin
    phase_crossover_rad_s: float | None
    gain_margin_low_db: float | None    # lower margin closest to 0 dB
    phase_crossover_low_rad_s: float | None
    delay_margin_s: float | None        # the smallest over the gain crossovers


def _refine(fun, w, values):
    """Roots of fun between grid points where values changes sign, by brentq on the exact
    response (log frequency as the variable)."""
    roots = []
    sign = np.sign(values)
    for k in np.flatnonzero(sign[:-1] * sign[1:] < 0):
        x = brentq(lambda u: float(fun(math.exp(u))), math.log(w[k]), math.log(w[k + 1]),
                   xtol=1e-15, rtol=8.9e-16, maxiter=200)
        roots.append(math.exp(x))
    roots += list(w[values == 0.0])
    return sorted(roots)


def loop_figures(fun, w):
    """Figures of the loop response ``fun`` (omega [rad/s] -> complex) found on grid w."""
    lw = fun(w)
    scalar = lambda g: (lambda x: g(fun(np.array([x]))[0]))  # noqa: E731
    gains = _refine(scalar(lambda v: math.log(abs(v))), w, np.log(np.abs(lw)))
    phases = np.angle(fun(np.array(gains)), deg=True) if gains else np.zeros(0)
    pms = _wrap_pm(phases)
    delays = np.where(pms >= 0, np.radians(pms), np.radians(pms) + 2 * math.pi) / np.array(
        gains if gains else np.zeros(0))
    candidates = _refine(scalar(lambda v: v.imag), w, lw.imag)
    values = fun(np.array(candidates)) if candidates else np.zeros(0, complex)
    # L real and negative; Im L also changes sign where L passes through 0 (an undamped zero on
    # the j w axis), which is no phase crossover: the angle there is not 180 deg
    keep = (values.real < 0) & (np.abs(values.imag) <= 1e-6 * np.abs(values))
    crossings = np.array(candidates)[keep] if candidates else np.zeros(0)
    gms = -20.0 * np.log10(np.abs(values[keep]))
    best = int(np.argmin(np.abs(pms))) if gains else None
    upper = np.flatnonzero(gms > 0)
    lower = np.flatnonzero(gms < 0)
    up = upper[np.argmin(gms[upper])] if upper.size else None
    low = lower[np.argmax(gms[lower])] if lower.size else None
    return LoopFigures(
        tuple(gains), tuple(pms), tuple(delays), tuple(crossings), tuple(gms),
        gains[best] if best is not None else None,
        float(pms[best]) if best is not None else None,
        float(gms[up]) if up is not None else None,
        float(crossings[up]) if up is not None else None,
        float(gms[low]) if low is not None else None,
        float(crossings[low]) if low is not None else None,
        float(np.min(delays)) if gains else None)


@dataclass(frozen=True)
class ClosedLoopFigures:
    """Bandwidth and resonance peak of T (docs/model.md §7)."""

    dc_gain: float
    bandwidth_rad_s: float | None
    peak_db: float | None               # max |T|/|T(0)| at an interior maximum (None: none)
    peak_rad_s: float | None            # None: the largest value is at the range's edge
    phase_90_rad_s: float | None        # lowest w where the phase of T reaches -90 deg


def closed_loop_figures(d, w, delay="exact"):
    """T(0) from the signal equations at s = 0, the first -3.0103 dB point and the peak."""
    t0 = abs(closed_loop(d, np.array([0j]), delay)["T"][0])
    at = lambda x: closed_loop(d, np.array([x]), delay)["T"][0]  # noqa: E731
    mag = lambda x: abs(at(x)) / t0  # noqa: E731
    tw = closed_loop(d, w, delay)["T"]
    rel = np.abs(tw) / t0
    # -90 deg: the phase unwrapped along the grid from DC, refined inside its grid interval
    phase = np.degrees(np.unwrap(np.angle(tw)))
    after = np.flatnonzero(phase <= -90.0)
    phase_90 = None
    if after.size and after[0] > 0:
        k = after[0]
        local = lambda x: phase[k - 1] + np.degrees(np.angle(at(x) / tw[k - 1])) + 90.0  # noqa
        phase_90 = math.exp(brentq(lambda u: local(math.exp(u)), math.log(w[k - 1]),
                                   math.log(w[k]), xtol=1e-15, rtol=8.9e-16))
    below = np.flatnonzero(rel < 1.0 / math.sqrt(2.0))
    bandwidth = None
    if below.size and below[0] > 0:
        k = below[0]
        bandwidth = math.exp(brentq(lambda u: mag(math.exp(u)) - 1.0 / math.sqrt(2.0),
                                    math.log(w[k - 1]), math.log(w[k]), xtol=1e-15,
                                    rtol=8.9e-16))
    k = int(np.argmax(rel))
    if 0 < k < w.size - 1:
        best = minimize_scalar(lambda u: -mag(math.exp(u)), bounds=(math.log(w[k - 1]),
                               math.log(w[k + 1])), method="bounded",
                               options={"xatol": 1e-12})
        peak_w, peak = math.exp(best.x), -best.fun
    else:  # largest at the range's edge: no peak (the edge value is a bound)
        peak_w, peak = None, None
    return ClosedLoopFigures(t0, bandwidth, None if peak is None else 20.0 * math.log10(peak),
                             peak_w, phase_90)


def figures(d, w_min=1e-2, w_max=1e6, per_decade=2000, delay="exact", views=("L", "L_aat")):
    """Every loop's figures in ``views`` ('L' cascade, 'L_aat' loop at a time) on the range
    [w_min, w_max] [rad/s], the closed loop's figures, and the Padé-6 verdict."""
    w = grid(d, w_min, w_max, per_decade)
    out = {"loops": {}, "stable": is_stable(d)}
    for loop in d.loops:
        out["loops"][loop] = {}
        for view in views:
            fun = loop_function(d, loop, view, delay)
            out["loops"][loop][view] = loop_figures(_cached(fun, w, fun(w)), w)
    out["closed_loop"] = closed_loop_figures(d, w, delay)
    return out


def as_analyze_keys(result):
    """The figures of ``figures(...)`` under the JSON keys of ``cas-freq analyze``:
    ``<loop>_loop.<key>`` for the cascade view, ``<loop>_loop.loop_at_a_time.<key>`` for the
    loop-at-a-time view (docs/model.md §13), ``closed_loop.<key>``. A flat dict."""
    keys = ("crossover_rad_s", "phase_margin_deg", "delay_margin_s", "gain_margin_db",
            "phase_crossover_rad_s", "gain_margin_low_db", "phase_crossover_low_rad_s")
    out = {}
    for loop, views in result["loops"].items():
        for view, figs in views.items():
            prefix = f"{loop}_loop." + ("loop_at_a_time." if view == "L_aat" else "")
            out.update({prefix + key: getattr(figs, key) for key in keys})
    cl = result["closed_loop"]
    out.update({"closed_loop.dc_gain_db": 20.0 * math.log10(cl.dc_gain),
                "closed_loop.bandwidth_rad_s": cl.bandwidth_rad_s,
                "closed_loop.peak_db": cl.peak_db, "closed_loop.peak_rad_s": cl.peak_rad_s,
                "closed_loop.phase_90_rad_s": cl.phase_90_rad_s})
    return out


def _cached(fun, w, values):
    """fun, answering the whole grid from values already computed."""
    def call(x):
        x = np.asarray(x)
        if x.shape == w.shape and np.array_equal(x, w):
            return values
        return fun(x)
    return call


# ------------------------------------------------------------------- the shipped QT-CAS config

_UNITS = {"": 1.0, "ohm": 1.0, "mH": 1e-3, "N*m/A": 1.0, "V*s/rad": 1.0, "kg*m^2": 1.0,
          "rpm": 2.0 * math.pi / 60.0, "A": 1.0, "V/A": 1.0, "V/(A*s)": 1.0, "V": 1.0,
          "ms": 1e-3, "A/rad": 1.0, "A/(rad*s)": 1.0, "A*s/rad": 1.0, "A*s^2/rad": 1.0,
          "N*m*s/rad": 1.0, "mN*m": 1e-3, "N*m/rad": 1.0, "N*m": 1.0}


def _si(value):
    """A YAML value with an optional unit string -> SI float (only the units the shipped
    configs/qt_cas.yaml uses; anything else is refused, not guessed)."""
    if isinstance(value, (int, float)):
        return float(value)
    match = re.fullmatch(r"\s*([-+0-9.eE]+)\s*(.*?)\s*", str(value))
    if not match or match.group(2) not in _UNITS:
        raise ValueError(f"unit of {value!r} not known to the oracle")
    return float(match.group(1)) * _UNITS[match.group(2)]


def qt_cas_drive(variant="base", path=None):
    """The QT-CAS drive of configs/qt_cas.yaml (a variant's dotted keys applied over the base
    values), read with yaml.safe_load and converted by ``_si``."""
    import yaml
    path = Path(path) if path else Path(__file__).resolve().parents[1] / "configs/qt_cas.yaml"
    raw = yaml.safe_load(path.read_text(encoding="utf-8"))
    flat = {}
    for section in ("motor", "gear", "load", "current_loop", "position_loop"):
        for key, value in (raw.get(section) or {}).items():
            flat[f"{section}.{key}"] = value
    flat.update((raw.get("variants") or {}).get(variant, {}) if variant != "base" else {})
    get = lambda key, default=0.0: _si(flat[key]) if key in flat else default  # noqa: E731
    km = get("motor.Km")
    if "motor.mu_v" in flat:
        mu_v = get("motor.mu_v")
    else:               # mu_v = Km I0 / n0 (docs/model.md §1: n0 in rpm)
        no_load = raw["motor"]["no_load"]
        mu_v = km * _si(no_load["current"]) / _si(no_load["speed"])
    return Drive(
        R=get("motor.R"), L=get("motor.L"), Km=km, Ke=get("motor.Ke"), J=get("motor.J"),
        mu_v=mu_v, N=get("gear.ratio", 1.0), eta=get("gear.efficiency", 1.0),
        J_L=get("load.inertia"), b_L=get("load.damping"), K_h=get("load.hinge_stiffness"),
        K_g=get("gear.stiffness"), c_g=get("gear.damping"),
        ci_Kp=get("current_loop.Kp"), ci_Ki=get("current_loop.Ki"),
        tau_c=get("current_loop.delay"), cp_Kp=get("position_loop.Kp"),
        cp_Ki=get("position_loop.Ki"), cp_Kd=get("position_loop.Kd"),
        Tf=get("position_loop.Tf", None), tau_p=get("position_loop.delay"),
        derivative_on=flat.get("position_loop.derivative_on", "error"))


def example_cascade(**changes):
    """A made-up industrial axis for the tests (not a shipped config): cascade P -> PI -> PI,
    compliant gear (two-mass mode near 800 rad/s), velocity feedback low-pass, a notch at the
    current command and a low-pass on the velocity feedback; ``changes`` replace fields."""
    values = dict(
        R=1.0, L=2e-3, Km=0.1, Ke=0.1, J=1e-4, mu_v=1e-5, N=10.0, eta=0.9, J_L=5e-3, b_L=0.01,
        K_h=20.0, K_g=2000.0, c_g=0.05, ci_Kp=4.0, ci_Ki=2000.0, tau_c=5e-5,
        structure="cascade", cp_Kp=40.0, cp_Ki=100.0, cv_Kp=0.3, cv_Ki=15.0, tau_v=1e-4,
        tau_vf=2e-4, tau_p=2e-4,
        filters=(Filter("current_command", "notch", 800.0, width=400.0, depth_db=-20.0),
                 Filter("velocity_feedback", "lowpass2", 3000.0, damping=0.7)))
    values.update(changes)
    return Drive(**values)


def loaded_qt_cas_loop_at_a_time():
    """The issue's claim on QT-CAS ``loaded``: the current loop's headline (crossover, PM) with
    the position loop open and with it closed (loop at a time)."""
    d = qt_cas_drive("loaded")
    w = grid(d)
    out = {}
    for view in ("L", "L_aat"):
        figs = loop_figures(loop_function(d, "current", view), w)
        out[view] = (figs.crossover_rad_s, figs.phase_margin_deg)
    return out


__all__ = ["Drive", "Filter", "loop_response", "loop_function", "closed_loop", "responses",
           "responses_by_formula", "formula_parts", "plant_tf",
           "plant_ss", "pade_closed_loop", "closed_loop_poles", "is_stable", "grid",
           "loop_figures", "closed_loop_figures", "figures", "qt_cas_drive",
           "loaded_qt_cas_loop_at_a_time", "example_cascade", "as_analyze_keys", "replace"]
