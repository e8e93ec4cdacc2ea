"""The actuator as python-control systems: Padé delays, composed in state space.

python-control is imported by the functions that build its systems, not with this module:
T's matrices and zeros (:func:`closed_loop_matrices`, :func:`closed_loop_zeros`), which the
report and the design page need, are numpy and scipy only (importing python-control costs
about 1 s: scipy.signal).

Use these where a rational model is needed (poles, state space, linear time responses);
frequency-domain figures come from :mod:`cas_freq.model.loops`, which this module also wraps as
:class:`control.FrequencyResponseData` for exact delays. The plant and the controllers are those
of :mod:`cas_freq.model.parts`.

The systems are those of the declared loop structure (:mod:`cas_freq.model.structure`),
composed in state space by :mod:`cas_freq.model.state_space` (the same matrices whose
eigenvalues are the closed-loop poles). The Padé delays are cascades of low-order sections
(:func:`cas_freq.model.delay.pade_realization`), so orders 8 and 10 of sub-millisecond delays
still give finite, accurate models.
"""

from __future__ import annotations  # the annotations name control's classes

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from cas_freq.model import parts, state_space
from cas_freq.model.delay import DEFAULT_PADE_ORDER
from cas_freq.model.sampled import is_sampled
from cas_freq.model.structure import build

if TYPE_CHECKING:
    import control


def plant_system(params):
    """The plant of :func:`cas_freq.model.parts.plant_matrices` as a python-control system.

    States ``i`` [A], ``omega`` [rad/s], ``theta`` [rad] (motor shaft), and with a compliant
    gear ``omega_L`` [rad/s], ``delta`` [rad] (the output); input ``V`` [V]; outputs the states
    and ``output``, N delta [rad] (the output angle on the motor's scale: theta for a rigid
    gear).
    """
    import control

    p = parts.one_variant(params)
    a, b = parts.plant_matrices(p)
    states = a.shape[1]
    names = ["i", "omega", "theta", "omega_L", "delta"][:states]
    c = np.vstack([np.eye(states), parts.fin_output(states, float(p.ratio[0]))])
    return control.ss(
        a[0], b[0][:, :1], c, np.zeros((states + 1, 1)),
        inputs="V", outputs=[*names, "output"], states=names, name="plant",
    )


#: The system name and (input, output) signal names of each system that is not a loop of the
#: structure, as python-control shows them (the symbols of docs/model.md); each loop's are the
#: structure's (:class:`~cas_freq.model.structure.Loop`: ``symbol`` and ``signals``, from its
#: error to its measurement, :func:`_loop_names`; broken at its error, which for a
#: unity-feedback loop is the same L as broken at the controller output). S runs from the
#: outermost loop's command (``delta_cmd`` on an output encoder).
LOOP_NAMES = {
    "current_closed_loop": ("T_i", "i_cmd", "i"),
    "sensitivity": ("S", "theta_cmd", "e"),
    "closed_loop": ("T", "delta_cmd", "delta"),
}


@dataclasses.dataclass(frozen=True)
class LinearModel:
    """The actuator's loops as python-control state-space systems (Padé delays), named as
    the structure's loops and :data:`LOOP_NAMES` (``model.position_loop.name == "L_p"``).

    Attributes
    ----------
    pade_order : int
        Padé order of every delay.
    plant : control.StateSpace
        V -> (i, omega, theta).
    current_loop, current_closed_loop : control.StateSpace
        L_i (e_i -> i) and T_i (i_cmd -> i).
    position_loop, sensitivity, closed_loop : control.StateSpace
        L_p (e -> theta), S = 1/(1+L_p) (theta_cmd -> e) and T = δ/δ_cmd (delta_cmd -> delta).
    velocity_loop : control.StateSpace or None
        L_v (e_v -> omega) of a drive with a velocity loop, else None.
    """

    pade_order: int
    plant: control.StateSpace
    current_loop: control.StateSpace
    current_closed_loop: control.StateSpace
    position_loop: control.StateSpace
    sensitivity: control.StateSpace
    closed_loop: control.StateSpace
    velocity_loop: control.StateSpace | None = None


def linear_model(params, pade_order=DEFAULT_PADE_ORDER):
    """Build every loop of the declared structure as a python-control system with Padé delays.

    The loops are those of :func:`cas_freq.model.state_space.closings`: each loop k, broken at
    its error, is its forward path in front of the loops inside it closed, read at its
    measurement through its sensor; the current loop of continuous controllers sees the plant
    without the modes the current does not see (the shaft's position, unless a hinge stiffness
    acts on it), which would add spurious poles at 0. T is the whole structure closed, read at
    the output (:func:`closed_loop_matrices`). Sampled loops give discrete-time systems, each
    loop at its own period (the inner loops of a multirate drive at theirs, broken with the
    slower loops open), T and S at the outermost loop's; their delays exact (whole samples and
    the hold-equivalent's fractional part).

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig or cas_freq.core.parameters.LoopParameters
        One variant (SI).
    pade_order : int
        Padé order n >= 1 of every delay (continuous controllers).

    Returns
    -------
    LinearModel
    """
    import control

    p = parts.one_variant(params)
    structure = build(p)
    sampled = is_sampled(p)
    loops = state_space.closings(p, pade_order, sampled=sampled, command=False)
    if not sampled:
        loops[structure.names[0]] = state_space.closings(p, pade_order, loops=1,
                                                         reduced=True)[structure.names[0]]
    systems = {name: control.ss(*closing.loop(), *_timebase(closing.period))
               for name, closing in loops.items()}
    top = structure.names[-1]
    timebase = _timebase(loops[top].period)
    systems["current_closed_loop"] = control.feedback(systems["current_loop"], 1)
    systems["sensitivity"] = control.feedback(control.ss([], [], [], [[1.0]], *timebase),
                                              systems[top])
    closed = closed_loop_matrices(p, pade_order)
    systems["closed_loop"] = control.ss(closed.a, closed.b, closed.c, closed.d, *timebase)
    names = _loop_names(structure)
    named = {key: control.ss(system, name=name, inputs=signal_in, outputs=signal_out)
             for key, system in systems.items()
             for name, signal_in, signal_out in [names[key]]}
    plant = plant_system(p)
    if sampled:
        period = loops[structure.names[0]].period
        held = state_space.hold_equivalent(plant.A[None], plant.B[None], 0.0, period)
        states = plant.A.shape[0]
        plant = control.ss(held[0][0][:states, :states], held[1][0][:states], plant.C, plant.D,
                           period, inputs="V", outputs=plant.output_labels,
                           states=plant.state_labels, name="plant")
    return LinearModel(pade_order, plant, **named)


def _timebase(period):
    """python-control's ``dt`` argument of a system of sampling ``period`` [s] (None:
    continuous, python-control's default)."""
    return () if period is None else (period,)


def _loop_names(structure):
    """:data:`LOOP_NAMES` with each loop's signals as the structure declares them: the
    position loop measures ``delta`` (and S starts at ``delta_cmd``) when it is closed on an
    output encoder."""
    names = {**LOOP_NAMES, **{loop.name: (loop.symbol, *loop.signals)
                              for loop in structure.loops}}
    measured = structure.loops[-1].signals[1]
    names["sensitivity"] = ("S", f"{measured}_cmd", "e")
    return names


#: Largest coefficient [log10] of a loop's characteristic polynomial at which python-control's
#: polynomial ``stability_margins`` stays in floating point: its stability-margin test
#: multiplies two squared polynomials (coefficients to the 4th power, past 1.8e308 from ~1e77).
#: Measured on the shipped variants: 1e75 works, 1e80 raises LinAlgError (infs or NaNs).
POLYNOMIAL_LOG10_LIMIT = 76.0


def polynomial_size(system):
    """log10 of the largest coefficient of a continuous system's characteristic polynomial
    (monic, from its poles): what python-control's polynomial margins raise to the 4th power
    (:data:`POLYNOMIAL_LOG10_LIMIT`). 0 for a static or discrete system (python-control
    evaluates those on the unit circle)."""
    if system.isdtime(strict=True) or system.nstates == 0:
        return 0.0
    coefficients = np.abs(np.poly(np.linalg.eigvals(system.A)))
    return float(np.log10(coefficients[coefficients > 0].max()))


def largest_polynomial(model):
    """(name, log10 size) of the loop of a :class:`LinearModel` with the largest
    characteristic polynomial (:func:`polynomial_size`), over L_i, L_v and L_p."""
    loops = [(name, getattr(model, name)) for name in
             ("current_loop", "velocity_loop", "position_loop")]
    return max(((name, polynomial_size(system)) for name, system in loops
                if system is not None), key=lambda item: item[1])


def margin_safe_model(params, highest):
    """:func:`linear_model` at the highest Padé order <= ``highest`` at which every loop's
    characteristic polynomial stays below :data:`POLYNOMIAL_LOG10_LIMIT` (python-control's
    polynomial ``stability_margins`` then stays finite); order 1 if none does.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig or cas_freq.core.parameters.LoopParameters
        One variant (SI).
    highest : int
        The highest order tried.

    Returns
    -------
    LinearModel
    """
    order = highest
    model = linear_model(params, order)
    while order > 1 and largest_polynomial(model)[1] >= POLYNOMIAL_LOG10_LIMIT:
        order -= 1
        model = linear_model(params, order)
    return model


@dataclasses.dataclass(frozen=True, eq=False)
class ClosedLoopMatrices:
    """T = δ/δ_cmd with Padé delays as state-space matrices (numpy; the matrices of
    :func:`linear_model`'s ``closed_loop``).

    Attributes
    ----------
    a, b, c, d : numpy.ndarray
        State-space matrices of one input (the command) and one output (the output angle).
    period : float or None
        Sampling period [s] of sampled controllers (a discrete-time system), None when the
        controllers are continuous.
    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray
    period: float | None = None


def closed_loop_matrices(params, pade_order=DEFAULT_PADE_ORDER):
    """T's state-space matrices with Padé delays of ``pade_order`` (numpy only).

    The declared structure closed (:func:`cas_freq.model.state_space.closings`), read at the
    output, behind the command's shaping (:func:`~cas_freq.model.state_space.command_shaping`):
    continuous controllers with Padé delays, or sampled ones as the outermost loop's
    closed discrete-time system at its period (delays exact).

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig or cas_freq.core.parameters.LoopParameters
        One variant (SI).
    pade_order : int
        Padé order n >= 1 of every delay (continuous controllers).

    Returns
    -------
    ClosedLoopMatrices
    """
    p = parts.one_variant(params)
    structure = build(p)
    sampled = is_sampled(p)
    top = state_space.closings(p, pade_order, sampled=sampled)[structure.names[-1]]
    a, b, c, d = top.closed
    output = state_space.SIGNAL_ROWS[structure.output]
    system = (a, b, c[output:output + 1], d[output:output + 1])
    shaping = state_space.command_shaping(p, structure, sampled)
    if shaping is not None:
        system = state_space.series(shaping, system)
    return ClosedLoopMatrices(*system, top.period)


def transmission_zeros(a, b, c, d):
    """Finite zeros of a square system (A, B, C, D): the generalised eigenvalues of
    ``[[A, B], [C, D]]`` against ``[[I, 0], [0, 0]]`` (the QZ algorithm), as python-control's
    ``StateSpace.zeros`` computes them without slycot (the same scipy call, so the same numbers).

    Returns
    -------
    numpy.ndarray
        Complex zeros, in the order scipy gives them (infinite ones left out).
    """
    from scipy.linalg import eigvals

    states = a.shape[0]
    if not states:
        return np.array([], dtype=complex)
    pencil = np.block([[a, b], [c, d]]).astype(float)
    identity = np.zeros_like(pencil)
    identity[:states, :states] = np.eye(states)
    zeros = np.asarray(eigvals(pencil, identity, overwrite_a=True), dtype=complex)
    return zeros[~np.isinf(zeros)]


def closed_loop_zeros(params, pade_order, closed=None):
    """Zeros [rad/s] of T = δ/δ_cmd with Padé delays of ``pade_order`` (numpy and scipy).

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order of both delays (that of the engine's poles).
    closed : ClosedLoopMatrices, optional
        :func:`closed_loop_matrices` of ``params`` at ``pade_order``, when already built.

    Returns
    -------
    numpy.ndarray
        Complex zeros [rad/s], sorted by real part then imaginary part (sampled controllers:
        the z-plane zeros mapped by ln z / T, those at z = 0 left out).
    """
    if closed is None:
        closed = closed_loop_matrices(params, pade_order)
    zeros = transmission_zeros(closed.a, closed.b, closed.c, closed.d)
    zeros = zeros[np.isfinite(zeros)]
    if closed.period is not None:  # sampled controllers: z-plane zeros, as the poles
        zeros = state_space.z_to_s(zeros, closed.period)
    return zeros[np.lexsort((zeros.imag, zeros.real))]


def exact_frequency_responses(loops, omega):
    """The loops' exact-delay frequency responses as python-control FRD objects.

    Parameters
    ----------
    loops : cas_freq.model.actuator_loops.ActuatorLoops
        Loops to evaluate (their delay model is used as it is).
    omega : array_like
        Frequencies [rad/s].

    Returns
    -------
    dict of str to control.FrequencyResponseData
        Keys ``current_loop``, ``current_closed_loop``, ``position_loop``, ``sensitivity``,
        ``closed_loop``.
    """
    import control

    omega = np.asarray(omega, dtype=float)
    s = 1j * omega
    names = ("current_loop", "current_closed_loop", "position_loop", "sensitivity", "closed_loop")
    return {name: control.frd(getattr(loops, name)(s), omega, name=name) for name in names}
