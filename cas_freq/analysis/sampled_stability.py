r"""Stability of sampled loops from their discrete-time poles (docs/model.md, "Sampled
controllers").

The loops of the declared structure are assembled in discrete-time state space, inside out,
with the same interconnections as the continuous closed loop
(:func:`cas_freq.analysis.stability.loop_system`; series and feedback are the same algebra in
discrete time):

- the plant's hold-equivalent at the innermost rate with the current loop's delay
  :math:`\tau_c = mT + \varepsilon` exact: m samples of delay line, then
  :math:`x^+ = \Phi x + \Gamma_1 v + \Gamma_0 v^-`, :math:`\Phi = e^{AT}`,
  :math:`\Gamma_1 = \int_0^{T-\varepsilon} e^{A\eta} d\eta\, B`,
  :math:`\Gamma_0 = e^{A(T-\varepsilon)} \int_0^{\varepsilon} e^{A\eta} d\eta\, B`
  (one matrix exponential of an augmented matrix each); analog filters on a measurement
  (before its sampler) are part of this plant (:func:`cas_freq.model.hold.with_analog_filters`),
  a loop then measures the filtered signal;
- each controller and filter realised as in continuous time and discretised by the
  generalised bilinear transform (:math:`\alpha = 1` backward, :math:`1/2` Tustin), which has
  exactly the transfer function of the block with s replaced (:mod:`cas_freq.model.sampled`);
- a delay between two controllers as a delay line of :math:`\lceil \tau/T \rceil` samples;
- a slower loop sees the loops inside it lifted to its rate: their command held for M fast
  steps, :math:`A_s = A^M`, :math:`B_s = \sum_{i<M} A^i B`.

A loop is stable when every pole of its closed loop (with the loops inside it) lies inside the
unit circle, marginal within :data:`cas_freq.analysis.stability.MARGINAL_TOLERANCE` of it.
"""

import dataclasses

import numpy as np
from scipy.linalg import expm

from cas_freq.analysis.stability import (
    MARGINAL_TOLERANCE,
    SIGNAL_ROWS,
    _concatenate,
    _feedback,
    _realize,
    realised_orders,
    series,
)
from cas_freq.model import parts
from cas_freq.model.hold import measured, with_analog_filters
from cas_freq.model.sampled import groups
from cas_freq.model.structure import analog_sensor, build, chain_state_space, digital_sensor
from cas_freq.threads import one_blas_thread

#: The generalised bilinear transform's alpha of each method.
ALPHA = {"backward": 1.0, "tustin": 0.5}


def discretised(system, period, method):
    """A continuous (A, B, C, D) (or stacks) discretised by the generalised bilinear transform
    (the block's transfer function with s replaced, :func:`cas_freq.model.sampled.equivalent_s`).
    """
    a, b, c, d = system
    alpha = ALPHA[method]
    states = a.shape[-1]
    if states == 0:
        return system
    eye = np.eye(states)
    inverse = np.linalg.inv(eye - alpha * period * a)
    return (inverse @ (eye + (1.0 - alpha) * period * a), inverse @ b * period,
            c @ inverse, d + alpha * period * (c @ inverse @ b))


def delay_line(samples, lead=()):
    """z^-d in state space (d >= 0 samples)."""
    d = int(samples)
    if d == 0:
        return (np.zeros((*lead, 0, 0)), np.zeros((*lead, 0, 1)), np.zeros((*lead, 1, 0)),
                np.ones((*lead, 1, 1)))
    a = np.zeros((*lead, d, d))
    a[..., 1:, :-1] = np.eye(d - 1)
    b = np.zeros((*lead, d, 1))
    b[..., 0, 0] = 1.0
    c = np.zeros((*lead, 1, d))
    c[..., 0, -1] = 1.0
    return a, b, c, np.zeros((*lead, 1, 1))


def hold_equivalent(a, b, tau, period):
    """The plant (A, B) (stacks (n, s, s), (n, s, 1)) held at ``period`` and delayed by ``tau``
    (the same for every run here): (A, B, C, D) with the delay line and one extra state for
    the fractional part; outputs the four measured signals (rows of ``C`` set by the caller:
    here the states themselves)."""
    n, states = a.shape[0], a.shape[-1]
    whole = int(np.floor(tau / period + 1e-9))
    fraction = tau - whole * period
    fraction = 0.0 if fraction < 1e-9 * period else fraction

    def integral(h):
        m = np.zeros((n, states + 1, states + 1))
        m[:, :states, :states] = a * h
        m[:, :states, states:] = b * h
        with one_blas_thread():
            e = expm(m)
        return e[:, :states, :states], e[:, :states, states:]

    phi_1, gamma_1 = integral(period - fraction)
    phi_2, psi = integral(fraction)
    phi = phi_1 @ phi_2
    gamma_0 = phi_1 @ psi
    big = np.zeros((n, states + 1, states + 1))
    big[:, :states, :states] = phi
    big[:, :states, states:] = gamma_0
    inputs = np.concatenate([gamma_1, np.ones((n, 1, 1))], axis=1)
    held = (big, inputs, np.zeros((n, 1, states + 1)), np.zeros((n, 1, 1)))
    return series(delay_line(whole, (n,)), held), states


def loop_poles(p):
    """The discrete-time poles of every loop closed with the loops inside it, per run.

    Parameters
    ----------
    p : cas_freq.parameters.LoopParameters
        The runs, with ``sample_rates``.

    Returns
    -------
    dict of str to list of numpy.ndarray
        Loop name (innermost first) -> each run's poles (complex, in the z-plane of the loop's
        own rate); an inner loop's without those at z = 1 (:func:`_unseen`).
    """
    out = {name: [None] * p.n_runs for name in build(p).names}
    for name, rows, poles, inner in _poles_by_group(p):
        for r, value in zip(rows, poles, strict=True):
            out[name][r] = value[~_unseen(value)] if inner else value
    return out


def loop_verdicts(p):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` of every loop (closed with the loops
    inside it) of every run, as :func:`cas_freq.analysis.stability.loop_verdicts`."""
    out = {name: np.empty(p.n_runs, dtype=object) for name in build(p).names}
    for name, rows, poles, inner in _poles_by_group(p):
        radius = np.abs(poles)
        if inner:
            radius = np.where(_unseen(poles), 0.0, radius)
        out[name][rows] = np.where(
            np.any(radius > 1.0 + MARGINAL_TOLERANCE, axis=-1), "unstable",
            np.where(np.any(radius >= 1.0 - MARGINAL_TOLERANCE, axis=-1), "marginal", "stable"))
    return out


def _poles_by_group(p):
    """(loop name, runs, their poles (runs, states), whether an inner loop) for each group of
    runs that realise alike (one eigenvalue call per group and loop)."""
    n = p.n_runs
    top = build(p).names[-1]
    _, group = np.unique(_shapes(p), axis=0, return_inverse=True)
    for g in range(int(group.max()) + 1 if n else 0):
        rows = np.flatnonzero(group.reshape(-1) == g)
        for name, matrices in _assembled(p.take(rows), rows.size).items():
            with one_blas_thread():
                yield name, rows, np.linalg.eigvals(matrices), name != top


def _unseen(poles):
    """An inner loop's poles at z = 1: modes its loops do not see (the shaft's position) or
    exact cancellations, as the continuous inner loops' factors s
    (:func:`cas_freq.analysis.stability.loop_polynomials`); not counted in its verdict."""
    return np.abs(poles - 1.0) <= MARGINAL_TOLERANCE


def _shapes(p):
    """Per run, what sets its state count (runs alike are assembled as one stack)."""
    n = p.n_runs
    structure = build(p)
    plan = groups(structure.names, p.sample_rates)
    columns = [np.broadcast_to(np.asarray(p.K_g) > 0, (n,)),
               np.broadcast_to(np.asarray(p.K_h) != 0, (n,))]
    period = {k: group.period for group in plan for k in group.loops}
    inner_period = {}
    for g, group in enumerate(plan):
        for position, k in enumerate(group.loops):
            inner_period[k] = group.period if position or not g else plan[g - 1].period
    for k, loop in enumerate(structure.loops):
        columns += realised_orders(loop, n)
        tau = np.broadcast_to(np.asarray(loop.delay, dtype=float), (n,))
        samples = (np.floor(tau / period[k] + 1e-9) if k == 0
                   else np.ceil(tau / inner_period[k] - 1e-9))
        columns.append(samples)
        if k == 0:
            columns.append(tau)  # the fractional part sets the hold-equivalent
    return np.column_stack(columns)


def _assembled(p, n):
    """The closed-loop state matrices (n, s, s) of each loop of runs that realise alike."""
    return {name: closing.closed[0] for name, closing in _closed(p, n, build(p)).items()}


def loop_systems(p):
    """Each loop of one run as discrete-time state spaces, innermost first.

    Returns
    -------
    dict of str to Closing
        Loop name -> its loop broken at its controller's output (inputs error and command;
        outputs the four plant signals, then each measurement behind analog filters), the row
        it measures, its digital sensor, the system with it closed (input the command) and its
        period [s].
    """
    return _closed(p, 1, build(p))


def _closed(p, n, structure):
    """:func:`_assembled` of the structure ``structure`` of the runs ``p``."""
    plan = groups(structure.names, p.sample_rates)
    method = p.sampling_method
    a, b = parts.plant_matrices(p)
    states = a.shape[-1]
    rows = np.zeros((n, 4, states))
    rows[:, 0, 0] = rows[:, 1, 1] = rows[:, 2, 2] = 1.0
    ratio = np.broadcast_to(np.asarray(p.ratio, dtype=float), (n,))
    rows[:, 3] = np.stack([parts.fin_output(states, float(r)) for r in ratio])
    b = b[:, :, :1]
    # analog measurement filters: continuous, before the sampler, so in the held plant
    filtered = [loop for loop in structure.loops if analog_sensor(loop)]
    a, b, rows = with_analog_filters(
        a, b, rows, [(SIGNAL_ROWS[loop.feedback], chain_state_space(analog_sensor(loop), n))
                     for loop in filtered])
    row_of = {**SIGNAL_ROWS, **{measured(loop): 4 + j for j, loop in enumerate(filtered)}}
    states, outputs = a.shape[-1], rows.shape[1]
    tau = float(np.asarray(structure.loops[0].delay, dtype=float).reshape(-1)[0])
    system, _ = hold_equivalent(a, b, tau, plan[0].period)
    width = system[0].shape[-1]
    c = np.zeros((n, outputs, width))
    c[:, :, width - states - 1:width - 1] = rows
    system = (system[0], system[1], c, np.zeros((n, outputs, 1)))
    out = {}
    for g, group in enumerate(plan):
        if g:
            tau = np.asarray(structure.loops[group.loops[0]].delay, dtype=float)
            samples = int(np.ceil(float(tau.reshape(-1)[0]) / plan[g - 1].period - 1e-9))
            system = _lifted(series(delay_line(samples, (n,)), system), group.ratio)
        for position, k in enumerate(group.loops):
            loop = structure.loops[k]
            samples = 0
            if position:
                tau = np.asarray(loop.delay, dtype=float).reshape(-1)[0]
                samples = int(np.ceil(float(tau) / group.period - 1e-9))
            forward = _forward(loop, group.period, method, samples, n)
            sensor = _sensor(loop, group.period, method, n)
            opened = series(forward, system)
            row = row_of[measured(loop)]
            system = _feedback(opened, row, sensor)
            out[structure.names[k]] = Closing(opened, row, sensor, system, group.period)
    return out


@dataclasses.dataclass(frozen=True, eq=False)
class Closing:
    """One loop of :func:`loop_systems`: ``opened`` (A, B, C, D) with the loops inside it
    closed and it open, ``row`` the measured signal, ``sensor`` its filters (or None),
    ``closed`` the same with it closed, ``period`` its sampling period [s]."""

    opened: tuple
    row: int
    sensor: tuple | None
    closed: tuple
    period: float


def _forward(loop, period, method, samples, n):
    """A loop's controller (minimal form) and path filters, discretised, then its delay line;
    two input columns (error, command) as :func:`cas_freq.analysis.stability.loop_forward`."""
    controller = loop.controller
    numerator, denominator = (controller.minimal() if controller.minimal else
                              (parts.stacked(controller.numerator, n),
                               parts.stacked(controller.denominator, n)))
    first = discretised(_realize(numerator, denominator), period, method)
    for block in loop.path:
        first = series(first, discretised(_realize(parts.stacked(block.numerator, n),
                                                   parts.stacked(block.denominator, n)),
                                          period, method))
    first = series(first, delay_line(samples, (n,)))
    a, b, c, d = first
    return a, _concatenate([b] * 2, -1), c, _concatenate([d] * 2, -1)


def _sensor(loop, period, method, n):
    """A loop's digital sensor blocks (after its sampler), discretised; None for none."""
    sensor = None
    for block in digital_sensor(loop):
        part = discretised(_realize(parts.stacked(block.numerator, n),
                                    parts.stacked(block.denominator, n)), period, method)
        sensor = part if sensor is None else series(sensor, part)
    return sensor


def _lifted(system, ratio):
    """A fast system with its input held for ``ratio`` steps, seen every ``ratio`` steps."""
    a, b, c, d = system
    power = np.broadcast_to(np.eye(a.shape[-1]), a.shape).copy()
    total = np.zeros_like(b)
    for _ in range(ratio):
        total = total + power @ b
        power = power @ a
    return power, total, c, d


def closed_loop_poles(p):
    """The whole loop's discrete-time poles of one run mapped to the s-plane,
    :math:`s = \\ln z / T` [rad/s] (T the outermost loop's period; those at z = 0 left out),
    sorted by real part, largest first: the continuous-time poles whose sampled motion they
    are."""
    poles = loop_poles(p)[build(p).names[-1]][0]
    s = z_to_s(poles, periods_of(p)[-1])
    return s[np.argsort(-s.real, kind="stable")]


def z_to_s(z, period):
    """Discrete-time poles or zeros mapped to the s-plane, ln z / T [rad/s]; those at z = 0
    (delay lines: no continuous-time counterpart) left out."""
    z = np.asarray(z, dtype=complex)
    z = z[np.abs(z) > 1e-12]
    return np.log(z) / period


def periods_of(p):
    """Each loop's period [s], innermost first."""
    structure = build(p)
    return [group.period for group in groups(structure.names, p.sample_rates)
            for _ in group.loops]
