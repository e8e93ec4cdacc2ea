"""The actuator as python-control systems: Padé delays, composed in state space.

Use these where a rational model is needed (poles, state space, linear time responses);
frequency-domain figures come from :mod:`cas_freq.model.loops`, which this module also wraps as
:class:`control.FrequencyResponseData` for exact delays. The plant and the controllers are those
of :mod:`cas_freq.model.parts`.

The Padé delays are cascades of low-order sections (:func:`cas_freq.model.delay.pade_system`)
and every composition is done on state-space objects, so orders 8 and 10 of sub-millisecond
delays still give finite, accurate models.
"""

import dataclasses

import control
import numpy as np

from cas_freq.model import parts
from cas_freq.model.delay import DEFAULT_PADE_ORDER, pade_system


def plant_system(params):
    """The plant of :func:`cas_freq.model.parts.plant_matrices` as a python-control system.

    States ``i`` [A], ``omega`` [rad/s], ``theta`` [rad] (motor shaft), and with a compliant
    gear ``omega_L`` [rad/s], ``delta`` [rad] (the output); input ``V`` [V]; outputs the states
    and ``output``, N delta [rad] (the output angle on the motor's scale: theta for a rigid
    gear).
    """
    p = parts.one_variant(params)
    a, b = parts.plant_matrices(p)
    states = a.shape[1]
    names = ["i", "omega", "theta", "omega_L", "delta"][:states]
    c = np.vstack([np.eye(states), parts.fin_output(states, float(p.ratio[0]))])
    return control.ss(
        a[0], b[0][:, :1], c, np.zeros((states + 1, 1)),
        inputs="V", outputs=[*names, "output"], states=names, name="plant",
    )


def _ss(numerator, denominator):
    num = np.trim_zeros(np.asarray([float(np.squeeze(c)) for c in numerator]), "f")
    den = np.trim_zeros(np.asarray([float(np.squeeze(c)) for c in denominator]), "f")
    return control.ss(control.tf(num if num.size else [0.0], den))


#: Each loop's system name and (input, output) signal names, as python-control shows them:
#: the symbols of docs/model.md. L_i runs from the current error to the measured current and
#: L_p from the position error to the measured angle (each loop broken at its error, which for
#: a unity-feedback loop is the same L as broken at the controller output).
LOOP_NAMES = {
    "current_loop": ("L_i", "e_i", "i"),
    "current_closed_loop": ("T_i", "i_cmd", "i"),
    "position_loop": ("L_p", "e", "theta"),
    "sensitivity": ("S", "theta_cmd", "e"),
    "closed_loop": ("T", "delta_cmd", "delta"),
}


@dataclasses.dataclass(frozen=True)
class LinearModel:
    """The actuator's loops as python-control state-space systems (Padé delays), named as
    :data:`LOOP_NAMES` (``model.position_loop.name == "L_p"``).

    Attributes
    ----------
    pade_order : int
        Padé order of both delays.
    plant : control.StateSpace
        V -> (i, omega, theta).
    current_loop, current_closed_loop : control.StateSpace
        L_i (e_i -> i) and T_i (i_cmd -> i).
    position_loop, sensitivity, closed_loop : control.StateSpace
        L_p (e -> theta), S = 1/(1+L_p) (theta_cmd -> e) and T = δ/δ_cmd (delta_cmd -> delta).
    """

    pade_order: int
    plant: control.StateSpace
    current_loop: control.StateSpace
    current_closed_loop: control.StateSpace
    position_loop: control.StateSpace
    sensitivity: control.StateSpace
    closed_loop: control.StateSpace


def linear_model(params, pade_order=DEFAULT_PADE_ORDER):
    """Build every loop of docs/model.md as a python-control system with Padé delays.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig or cas_freq.parameters.LoopParameters
        One variant (SI).
    pade_order : int
        Padé order n >= 1 of both delays.

    Returns
    -------
    LinearModel
    """
    p = parts.one_variant(params)
    plant = plant_system(p)
    delay_c = pade_system(float(p.tau_c[0]), pade_order)
    delay_p = pade_system(float(p.tau_p[0]), pade_order)
    c_i = _ss(parts.current_controller(p), (1.0, 0.0))
    filter_ = parts.position_filter(p)
    c_p = _ss(parts.position_controller(p),
              (float(np.squeeze(filter_[0])), float(filter_[1]), 0.0))

    # Current loop, broken at the voltage: without the modes i does not see (the shaft's
    # position, unless a hinge stiffness acts on it), which would add spurious poles at 0.
    y = control.ss(*parts.current_plant_matrices(p), [[0.0]])
    l_i = control.series(c_i, delay_c, y)
    t_i = control.feedback(l_i, 1)

    # Current loop closed around the full plant: i_cmd -> theta.
    current_pi = control.ss(c_i, inputs="e_i", outputs="v_c", name="current_pi")
    delay = control.ss(delay_c, inputs="v_c", outputs="V", name="current_delay")
    error = control.summing_junction(inputs=["i_cmd", "-i"], output="e_i", name="current_error")
    to_theta = control.interconnect(
        [current_pi, delay, plant, error], inputs="i_cmd", outputs=["theta", "output"],
        check_unused=False,
    )
    # (theta, fin) per controller output, then the three position-loop systems.
    seen_both = control.series(
        delay_p, control.ss(to_theta.A, to_theta.B, to_theta.C, to_theta.D)
    )
    seen = control.ss(seen_both.A, seen_both.B, seen_both.C[:1], seen_both.D[:1])
    l_p = control.series(c_p, seen)
    sensitivity = control.feedback(control.ss([], [], [], [[1.0]]), l_p)
    # T: the loop closed on theta, read at the fin (N delta) where the gear is compliant
    closed = _position_closed_loop(p, c_p, seen if plant.nstates == 3 else seen_both, l_p)
    loops = {"current_loop": l_i, "current_closed_loop": t_i, "position_loop": l_p,
             "sensitivity": sensitivity, "closed_loop": closed}
    named = {key: control.ss(system, name=name, inputs=signal_in, outputs=signal_out)
             for key, system in loops.items()
             for name, signal_in, signal_out in [LOOP_NAMES[key]]}
    return LinearModel(pade_order, plant, **named)


def _position_closed_loop(p, c_p, seen, l_p):
    """T = N delta/theta_cmd (theta/theta_cmd for a rigid gear), a minimal realisation for
    either derivative placement; ``seen`` gives (theta, N delta) per controller output."""
    if seen.noutputs == 1 and not p.derivative_on_measurement[0]:
        return control.feedback(l_p, 1)  # the fin follows theta: T = L_p/(1 + L_p)
    plant = control.ss(seen, inputs="u", outputs=["theta", "output"][:seen.noutputs],
                       name="seen")
    if not p.derivative_on_measurement[0]:
        blocks = [control.ss(c_p, inputs="e", outputs="u", name="c_p"), plant]
    else:
        # u = (Kp + Ki/s)(r - theta) - Kd s/(Tf s + 1) theta: one PI state, one filter state.
        pi = control.ss(_ss(parts.reference_path(p), (1.0, 0.0)), inputs="e", outputs="u_pi",
                        name="pi")
        tf, kd = float(p.Tf[0]), float(p.cp_Kd[0])
        derivative = control.ss(
            control.tf([kd, 0.0], [tf, 1.0]) if kd > 0 else control.tf([0.0], [1.0]),
            inputs="theta", outputs="u_d", name="derivative",
        )
        blocks = [pi, derivative, plant,
                  control.summing_junction(inputs=["u_pi", "-u_d"], output="u", name="u_sum")]
    error = control.summing_junction(inputs=["r", "-theta"], output="e", name="e_sum")
    return control.interconnect([*blocks, error], inputs="r",
                                outputs="output" if seen.noutputs == 2 else "theta")


def closed_loop_zeros(params, pade_order):
    """Zeros [rad/s] of python-control's T = δ/δ_cmd with Padé delays of ``pade_order``.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order of both delays (that of the engine's poles).

    Returns
    -------
    numpy.ndarray
        Complex zeros [rad/s], sorted by real part then imaginary part.
    """
    zeros = np.asarray(control.zeros(linear_model(params, pade_order).closed_loop), complex)
    zeros = zeros[np.isfinite(zeros)]
    return zeros[np.lexsort((zeros.imag, zeros.real))]


def exact_frequency_responses(loops, omega):
    """The loops' exact-delay frequency responses as python-control FRD objects.

    Parameters
    ----------
    loops : cas_freq.model.loops.ActuatorLoops
        Loops to evaluate (their delay model is used as it is).
    omega : array_like
        Frequencies [rad/s].

    Returns
    -------
    dict of str to control.FrequencyResponseData
        Keys ``current_loop``, ``current_closed_loop``, ``position_loop``, ``sensitivity``,
        ``closed_loop``.
    """
    omega = np.asarray(omega, dtype=float)
    s = 1j * omega
    names = ("current_loop", "current_closed_loop", "position_loop", "sensitivity", "closed_loop")
    return {name: control.frd(getattr(loops, name)(s), omega, name=name) for name in names}
