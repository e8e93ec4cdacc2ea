"""The loop of docs/model.md written again as a python-control ``nlsys``: the independent second
implementation that tests/test_simulation_nlsys.py checks the simulator against, and that
benchmarks/run.py times python-control with. Kept apart from the tests so the benchmark can
import it without pytest (it puts this folder on sys.path).

States: the motor's i, omega, theta; the current PI's integral of e_i; the position PID's
integral of e; the derivative filter state x_f (T_f x_f' = e - x_f, so the derivative term
K_d (e - x_f) / T_f is K_d s / (T_f s + 1) e); then the states of Padé models of the position
and current delays. Both outputs are clamped (±i_max, ±v_max), and each integrator holds while
its output is clamped and its error would push it further out (docs/model.md).
"""

import control
import numpy as np


def _pade_state_space(tau, order):
    """(A, B, C, D) of the Padé approximant of exp(-s tau), realised for tau = 1 and rescaled.

    Realising the unit delay and scaling time (A/tau, B/tau) avoids the ill-conditioned
    coefficients of a sub-millisecond delay's transfer function (docs/model.md, Delays).
    """
    num, den = control.pade(1.0, order)
    unit = control.tf2ss(num, den)
    return (
        np.asarray(unit.A) / tau, np.asarray(unit.B).ravel() / tau,
        np.asarray(unit.C).ravel(), float(np.asarray(unit.D).item()),
    )


def actuator_nlsys(config, pade_order=None):
    """The loop of docs/model.md as a ``control.nlsys``; input theta_cmd [rad], output every state.

    Parameters are read from the validated config (SI). Delays of 0 are left out; others need
    ``pade_order``.
    """
    motor, cur, pos = config.motor, config.current_loop, config.position_loop
    assert pos.derivative_on == "error" and pos.Kd > 0
    R, L, Km, Ke, J, mu_v = motor.R, motor.L, motor.Km, motor.Ke, motor.J, motor.viscous_friction
    tf = pos.Tf if pos.Tf is not None else pos.Kd / (10.0 * pos.Kp)  # docs/model.md default
    delays = []
    for tau in (pos.delay, cur.delay):  # position -> current, current -> motor terminals
        if tau == 0:
            delays.append(None)
        else:
            assert pade_order, "a nonzero delay needs a Padé order"
            delays.append(_pade_state_space(tau, pade_order))
    sizes = [0 if d is None else d[0].shape[0] for d in delays]
    split = 6 + sizes[0]

    def through(delay, z, u):
        if delay is None:
            return u, np.zeros(0)
        a, b, c, d = delay
        return c @ z + d * u, a @ z + b * u

    def update(t, x, u, params):
        i, omega, theta, int_i, int_p, x_f = x[:6]
        # Position PID on e = theta_cmd - theta, derivative on the error, clamp, anti-windup.
        e = u[0] - theta
        u_p = pos.Kp * e + pos.Ki * int_p + pos.Kd * (e - x_f) / tf
        d_int_p = 0.0 if (abs(u_p) > pos.i_max and e * u_p > 0) else e
        i_cmd, dz_p = through(delays[0], x[6:split], np.clip(u_p, -pos.i_max, pos.i_max))
        # Current PI, clamp, anti-windup.
        e_i = i_cmd - i
        u_c = cur.Kp * e_i + cur.Ki * int_i
        d_int_i = 0.0 if (abs(u_c) > cur.v_max and e_i * u_c > 0) else e_i
        volts, dz_c = through(delays[1], x[split:], np.clip(u_c, -cur.v_max, cur.v_max))
        # Plant (report Fig. 5).
        di = (volts - R * i - Ke * omega) / L
        domega = (Km * i - mu_v * omega) / J
        return np.concatenate(
            [[di, domega, omega, d_int_i, d_int_p, (e - x_f) / tf], dz_p, dz_c]
        )

    n = 6 + sum(sizes)
    return control.nlsys(update, None, inputs=1, outputs=n, states=n, name="actuator")


