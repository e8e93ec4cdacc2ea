r"""The loops of the declared structure closed in state space, continuous or sampled: one
assembly for the poles of the stability verdicts (:mod:`cas_freq.analysis.stability`,
:mod:`cas_freq.analysis.sampled_stability`), T's matrices and zeros and the python-control
systems (:mod:`cas_freq.analysis.systems`).

:func:`closings` walks the loops of :func:`cas_freq.model.structure.build` from the inside out.
It starts from the plant (input V, outputs the signals of
:data:`cas_freq.model.structure.SIGNALS`) and, loop by loop, puts the loop's forward path in
front of what it has (the controller in its minimal form, the filters on its path, the delay)
and closes it through the loop's sensor on the signal the loop measures. The loop just before
it is closed (:attr:`Closing.opened`) is the loop broken at its error with the loops inside it
closed and those outside open (:meth:`Closing.loop`). The blocks:

- **continuous**: the plant of :func:`cas_freq.model.parts.plant_matrices`; each controller and
  filter in observable companion form; each delay its Padé approximant of order n
  (:func:`cas_freq.model.delay.pade_realization`);
- **sampled** (docs/model.md, "Sampled controllers"): the plant's hold-equivalent at the
  innermost rate with the current loop's delay :math:`\tau_c = mT + \varepsilon` exact
  (:func:`hold_equivalent`), analog filters on a measurement (before its sampler) part of that
  plant (:func:`cas_freq.model.hold.with_analog_filters`: the loop measures the filtered signal);
  each controller and digital filter realised as in continuous time and discretised by the
  generalised bilinear transform (:func:`discretised`); a delay between two controllers a delay
  line of :math:`\lceil \tau/T \rceil` samples of the faster; a slower loop sees the loops
  inside it lifted to its rate (:func:`lifted`). Series and feedback are the same algebra.

The matrices of one run are stacks of one (returned 2-D); those of ``n`` runs are stacks
(n, ., .) of runs that realise alike (:func:`run_groups`). Every product of the continuous
assembly has an inner dimension of 1 (one rounding), so a stack holds, run by run, the same
numbers as each run's own matrices.
"""

import dataclasses

import numpy as np

import cas_freq.model.parts as parts
from cas_freq.core.sampling_config import ALPHA
from cas_freq.core.threads import expm
from cas_freq.model.delay import DEFAULT_PADE_ORDER, pade_realization
from cas_freq.model.hold import measured, with_analog_filters
from cas_freq.model.sampled import groups
from cas_freq.model.structure import (
    SIGNALS,
    analog_sensor,
    build,
    chain_state_space,
    digital_sensor,
    fir_state_space,
)

#: Output row of each measured signal in the assembled systems.
SIGNAL_ROWS = {name: row for row, name in enumerate(SIGNALS)}


@dataclasses.dataclass(frozen=True, eq=False)
class Closing:
    """One loop of :func:`closings`.

    Attributes
    ----------
    opened : tuple
        (A, B, C, D) with the loops inside it closed and it open: inputs its error and its
        command, outputs the plant's signals (then, sampled, each measurement behind analog
        filters).
    row : int
        The output row it measures.
    sensor : tuple or None
        Its sensor filters (sampled: those after its sampler) in state space; None for none.
    closed : tuple
        (A, B, C, D) with it closed: input its command, the same outputs.
    period : float or None
        Its sampling period [s] (None: continuous).
    """

    opened: tuple
    row: int
    sensor: tuple | None
    closed: tuple
    period: float | None

    def loop(self):
        """The loop broken at its error: (A, B, C, D) from the error to the measurement
        through the sensor (for unity feedback the loop broken at the controller's output)."""
        a, b, c, d = self.opened
        row = self.row
        broken = (a, b[..., :1], c[..., row:row + 1, :], d[..., row:row + 1, :1])
        return broken if self.sensor is None else series(broken, self.sensor)


def closings(p, pade_order=DEFAULT_PADE_ORDER, loops=None, n=None, sampled=False, command=True,
             reduced=False):
    """The loops of the runs ``p`` closed one after another from the inside out.

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters
        One run (``n`` None) or ``n`` runs that realise alike (:func:`run_groups`).
    pade_order : int
        Padé order n >= 1 of every delay (continuous).
    loops : int, optional
        Close only this many loops, from the inside (default all).
    n : int, optional
        Number of runs: matrices as stacks (n, ., .); None: one run, 2-D matrices.
    sampled : bool
        The loops sampled at ``p.sample_rates`` by ``p.sampling_method``.
    command : bool
        Realise the outermost loop's command path where it differs from its error's (the
        derivative on the measurement; one run only). False: the command enters as the error.
    reduced : bool
        Continuous, the current loop alone: the plant without the modes the current does not
        see (:func:`cas_freq.model.parts.current_plant_matrices`).

    Returns
    -------
    dict of str to Closing
        Loop name -> its :class:`Closing`, innermost first.
    """
    one = n is None
    n = 1 if one else n
    structure = build(p)
    chosen = structure.loops[:loops]
    form = _Sampling(p, structure) if sampled else _Continuous(pade_order)
    system, row_of = form.plant(p, structure, n, reduced)
    out = {}
    for k, loop in enumerate(chosen):
        system = form.entering(k, structure, system, n)
        discrete = form.discretiser(k)
        own = command and k == len(chosen) - 1 and loop.reference is not None
        path = chain([_block(block, n, discrete) for block in loop.path]
                     + [form.delay(k, loop, n)])
        if loop.derivative:  # realised in z from its gains (no realisation of it in s)
            controller = _windowed_controller(loop, own, n, form.period(k), form.method)
        else:
            controller = _controller(loop, own, n, discrete)
        opened = series(series(controller, path), system)
        row = row_of[form.signal(loop)]
        blocks = form.sensor(loop)
        sensor = chain([_block(block, n, discrete) for block in blocks]) if blocks else None
        system = feedback(opened, row, sensor)
        out[loop.name] = Closing(opened, row, sensor, system, form.period(k))
    return {name: _one(closing) for name, closing in out.items()} if one else out


def command_shaping(p, structure, sampled=False):
    """The shaping of the command before every loop (the blocks of
    :attr:`~cas_freq.model.structure.Structure.command`, ``structure`` the runs' ``build(p)``)
    in state space, one run: continuous, or ``sampled`` discretised at the outermost loop's
    period as its controller is; None for none. In series in front of the outermost loop's
    closing it gives T; the closing's poles stay the loops' own."""
    if not structure.command:
        return None
    form = _Sampling(p, structure) if sampled else _Continuous(DEFAULT_PADE_ORDER)
    discrete = form.discretiser(len(structure.loops) - 1)
    shaping = chain([_block(block, 1, discrete) for block in structure.command])
    return tuple(m[0] if m.ndim == 3 else m for m in shaping)


def run_groups(p, sampled=False):
    """The runs of ``p`` grouped by what sets their state counts (a compliant gear, a hinge
    stiffness, each realised denominator's leading zeros, each delay's samples or being zero):
    a list of index arrays, one per group, each assembled as one stack by :func:`closings`."""
    n = p.n_runs
    structure = build(p)
    columns = [np.broadcast_to(np.asarray(p.K_g) > 0, (n,)),
               np.broadcast_to(np.asarray(p.K_h) != 0, (n,))]
    form = _Sampling(p, structure) if sampled else _Continuous(None)
    for k, loop in enumerate(structure.loops):
        columns += realised_orders(loop, n)
        columns += form.delay_keys(k, np.broadcast_to(np.asarray(loop.delay, dtype=float),
                                                      (n,)).reshape(-1))
    _, group = np.unique(np.column_stack(columns), axis=0, return_inverse=True)
    group = group.reshape(-1)
    return [np.flatnonzero(group == g) for g in range(int(group.max()) + 1 if n else 0)]


def realised_orders(loop, n):
    """Per run, the leading zeros of each denominator a loop's blocks realise (its controller
    in its minimal form, its path and sensor filters): what sets their state counts."""
    controller = loop.controller
    denominators = [controller.minimal()[1] if controller.minimal else
                    parts.stacked(controller.denominator, n)]
    denominators += [parts.stacked(block.denominator, n) for block in (*loop.path, *loop.sensor)]
    return [np.argmax(d != 0, axis=1) for d in denominators]


def z_to_s(z, period):
    """Discrete-time poles or zeros mapped to the s-plane, ln z / T [rad/s]; those at z = 0
    (delay lines: no continuous-time counterpart) left out."""
    z = np.asarray(z, dtype=complex)
    z = z[np.abs(z) > 1e-12]
    return np.log(z) / period


# --- the continuous and the sampled forms ----------------------------------------------------

class _Continuous:
    """Continuous loops: the plant itself, Padé delays, every sensor block in the feedback."""

    def __init__(self, pade_order):
        self.pade_order = pade_order

    def plant(self, p, structure, n, reduced):
        return _reduced_plant(p) if reduced else _plant(p, n)

    def signal(self, loop):
        return loop.feedback

    def sensor(self, loop):
        return loop.sensor

    def entering(self, k, structure, system, n):
        return system

    def discretiser(self, k):
        return _unchanged

    def delay(self, k, loop, n):
        return _pade(loop.delay, self.pade_order, n)

    def delay_keys(self, k, tau):
        """What of loop k's delays (n,) [s] sets its state count: being zero."""
        return [tau == 0]

    def period(self, k):
        return None


class _Sampling:
    """Sampled loops: the held plant with the analog filters, each loop's period and delay
    line, the lifting at a slower loop, the sensor blocks after the samplers."""

    def __init__(self, p, structure):
        self.method = p.sampling_method
        self.plan = groups(structure.names, p.sample_rates)
        self.place = {k: (g, position) for g, group in enumerate(self.plan)
                      for position, k in enumerate(group.loops)}

    def plant(self, p, structure, n, reduced):
        return _held_plant(p, structure, n, self.plan[0].period)

    def signal(self, loop):
        return measured(loop)

    def sensor(self, loop):
        return digital_sensor(loop)

    def period(self, k):
        return self.plan[self.place[k][0]].period

    def _inner_period(self, k):
        """The period of the delay in front of loop k: its own inside its group, that of the
        group inside it where it opens a slower group."""
        g, position = self.place[k]
        return self.plan[g].period if position or not g else self.plan[g - 1].period

    def delay_keys(self, k, tau):
        """What of loop k's delays (n,) [s] sets its state count."""
        if k == 0:  # whole samples and the fractional part: in the hold-equivalent
            return [np.floor(tau / self.period(0) + 1e-9), tau]
        return [np.ceil(tau / self._inner_period(k) - 1e-9)]

    def _samples(self, k, loop):
        tau = float(np.asarray(loop.delay, dtype=float).reshape(-1)[0])
        return int(np.ceil(tau / self._inner_period(k) - 1e-9))

    def entering(self, k, structure, system, n):
        """The loops inside loop k seen at its rate where it opens a slower group: its delay
        as a delay line of the faster rate, then lifted."""
        g, position = self.place[k]
        if not g or position:
            return system
        return lifted(series(delay_line(self._samples(k, structure.loops[k]), (n,)), system),
                      self.plan[g].ratio)

    def discretiser(self, k):
        period = self.period(k)
        return lambda system: discretised(system, period, self.method)

    def delay(self, k, loop, n):
        _, position = self.place[k]
        return delay_line(self._samples(k, loop) if position else 0, (n,))


def _unchanged(system):
    return system


# --- the plants ------------------------------------------------------------------------------

def _plant_rows(p, states, n):
    """The output rows (n, 4, states) of the plant's signals (:data:`SIGNAL_ROWS`)."""
    rows = np.zeros((n, 4, states))
    rows[:, 0, 0] = rows[:, 1, 1] = rows[:, 2, 2] = 1.0
    ratio = np.broadcast_to(np.asarray(p.ratio, dtype=float), (n,))
    values, inverse = np.unique(ratio, return_inverse=True)
    output = np.stack([parts.fin_output(states, float(r)) for r in values])
    rows[:, 3] = output[inverse.reshape(-1)]
    return rows


def _plant(p, n):
    """The continuous plant, input V, outputs the four signals."""
    a, b = parts.plant_matrices(p)
    states = a.shape[-1]
    return (a, b[:, :, :1], _plant_rows(p, states, n), np.zeros((n, 4, 1))), SIGNAL_ROWS


def _reduced_plant(p):
    """The plant of one run seen from the current (:func:`parts.current_plant_matrices`)."""
    a, b, c = parts.current_plant_matrices(p)
    return (a[None], b[None], c[None], np.zeros((1, 1, 1))), {"current": 0}


def _held_plant(p, structure, n, period):
    """The plant with its analog measurement filters, held at the innermost ``period`` and
    delayed by the current loop's delay (the same for every run here); outputs the four
    signals, then each filtered measurement (:func:`cas_freq.model.hold.measured`)."""
    a, b = parts.plant_matrices(p)
    rows = _plant_rows(p, a.shape[-1], n)
    filtered = [loop for loop in structure.loops if analog_sensor(loop)]
    a, b, rows = with_analog_filters(
        a, b[:, :, :1], rows,
        [(SIGNAL_ROWS[loop.feedback], chain_state_space(analog_sensor(loop), n))
         for loop in filtered])
    row_of = {**SIGNAL_ROWS, **{measured(loop): 4 + j for j, loop in enumerate(filtered)}}
    states, outputs = a.shape[-1], rows.shape[1]
    tau = float(np.asarray(structure.loops[0].delay, dtype=float).reshape(-1)[0])
    held = hold_equivalent(a, b, tau, period)
    width = held[0].shape[-1]
    c = np.zeros((n, outputs, width))
    c[:, :, width - states - 1:width - 1] = rows
    return (held[0], held[1], c, np.zeros((n, outputs, 1))), row_of


def hold_equivalent(a, b, tau, period):
    r"""The plant (A, B) (stacks (n, s, s), (n, s, 1)) held at ``period`` [s] and delayed by
    ``tau`` [s] (the same for every run): m whole samples of delay line, then
    :math:`x^+ = \Phi x + \Gamma_1 v + \Gamma_0 v^-` with :math:`\tau = mT + \varepsilon`,
    :math:`\Phi = e^{AT}`, :math:`\Gamma_1 = \int_0^{T-\varepsilon} e^{A\eta} d\eta\, B`,
    :math:`\Gamma_0 = e^{A(T-\varepsilon)} \int_0^{\varepsilon} e^{A\eta} d\eta\, B` (one
    matrix exponential of an augmented matrix each).

    Returns
    -------
    tuple
        (A, B, C, D) with the delay line and one extra state (the previous input), C zero (the
        caller reads the plant's states: the ``s`` before the last).
    """
    n, states = a.shape[0], a.shape[-1]
    whole = int(np.floor(tau / period + 1e-9))
    fraction = tau - whole * period
    fraction = 0.0 if fraction < 1e-9 * period else fraction

    def integral(h):
        m = np.zeros((n, states + 1, states + 1))
        m[:, :states, :states] = a * h
        m[:, :states, states:] = b * h
        e = expm(m)
        return e[:, :states, :states], e[:, :states, states:]

    phi_1, gamma_1 = integral(period - fraction)
    phi_2, psi = integral(fraction)
    big = np.zeros((n, states + 1, states + 1))
    big[:, :states, :states] = phi_1 @ phi_2
    big[:, :states, states:] = phi_1 @ psi
    inputs = np.concatenate([gamma_1, np.ones((n, 1, 1))], axis=1)
    held = (big, inputs, np.zeros((n, 1, states + 1)), np.zeros((n, 1, 1)))
    return series(delay_line(whole, (n,)), held)


# --- the blocks ------------------------------------------------------------------------------

def _controller(loop, own, n, discrete):
    """A loop's controller with two input columns, the error and the command: the same column
    unless ``own`` (its command path, :attr:`cas_freq.model.structure.Loop.reference`,
    realised over the full denominator with its common factors s cancelled; one run)."""
    controller = loop.controller
    if own:
        if n != 1:
            raise ValueError("a command path of its own is realised run by run")
        numerators, denominator = _cancel_zero_roots(
            [parts.stacked(controller.numerator, 1)[0], parts.stacked(loop.reference, 1)[0]],
            parts.stacked(controller.denominator, 1)[0])
        error = realize(numerators[0], denominator)
        command = realize(numerators[1], denominator)
        return discrete((error[0], np.hstack([error[1], command[1]]), error[2],
                         np.hstack([error[3], command[3]])))
    numerator, denominator = (controller.minimal() if controller.minimal else
                              (parts.stacked(controller.numerator, n),
                               parts.stacked(controller.denominator, n)))
    a, b, c, d = discrete(realize(numerator, denominator))
    return a, concatenate([b] * 2, -1), c, concatenate([d] * 2, -1)


def _windowed_controller(loop, own, n, period, method):
    r"""A sampled PID whose derivative reads the mean of its input's last m samples
    (:attr:`~cas_freq.model.structure.Loop.derivative`), in discrete state space with the
    two input columns of :func:`_controller`.

    With :math:`s \to (1 - z^{-1})/(T(\alpha + (1 - \alpha) z^{-1}))`, Q = 1 − z⁻¹,
    :math:`F = (T_f + \alpha T) - (T_f - (1 - \alpha) T) z^{-1}`, the integral's
    :math:`K_i T (\alpha + (1 - \alpha) z^{-1})/Q` and the window A(z):
    :math:`C = K_p + K_i T (\alpha + (1-\alpha) z^{-1})/Q + K_d Q A/F` over Q F (F alone
    where K_i = 0), the command's path without the derivative term. Runs without an
    integrator get poles and zeros at z = 0 to share the state count (deadbeat, unseen).
    """
    alpha = ALPHA[method]
    kp, ki, kd, tf = (np.broadcast_to(np.asarray(g, dtype=float), (n,))
                      for g in loop.controller.gains)
    average = np.asarray(loop.derivative[0].fir, dtype=float)
    width = average.size + 2  # the numerator's terms in z^-1: Q Q A
    ones = np.ones(n)

    def poly(*coefficients):  # per run, ascending powers of z^-1, padded to ``width``
        out = np.zeros((n, width))
        out[:, :len(coefficients)] = np.column_stack(coefficients)
        return out

    def times(a, b):
        return np.stack([np.convolve(x, y)[:width] for x, y in zip(a, b, strict=True)])

    q = poly(ones, -ones)
    f = poly(tf + alpha * period, -(tf - (1.0 - alpha) * period))
    integral = poly(ki * period * alpha, ki * period * (1.0 - alpha))
    derivative = times(poly(*(kd[:, None] * average).T), times(q, q))  # K_d Q Q A
    has_i = (ki > 0)[:, None]
    command = np.where(has_i, times(kp[:, None] * q + integral, f), kp[:, None] * f)
    error = command + np.where(has_i, derivative, times(poly(*(kd[:, None] * average).T), q))
    denominator = np.where(has_i, times(q, f), f)
    a, b, c, d = realize(error, denominator)
    if not own:
        return a, concatenate([b] * 2, -1), c, concatenate([d] * 2, -1)
    reference = realize(command, denominator)
    return a, np.concatenate([b, reference[1]], -1), c, np.concatenate([d, reference[3]], -1)


def _block(block, n, discrete):
    """A block in state space: a digital FIR (:attr:`~cas_freq.model.structure.Block.fir`) as
    it is, any other realised and passed through ``discrete``."""
    if block.fir:
        if discrete is _unchanged:
            raise ValueError(f"{block.name}: a digital block in a continuous loop")
        a, b, c, d = fir_state_space(block, n)
        return a, b[:, :, None], c[:, None, :], d[:, None, None]
    return discrete(realize(parts.stacked(block.numerator, n),
                            parts.stacked(block.denominator, n)))


def _pade(delay, pade_order, n):
    """:func:`~cas_freq.model.delay.pade_realization` of a loop's delay for a stack of ``n``
    runs whose delays are all zero or all positive (2-D where they share it)."""
    taus = np.asarray(delay, dtype=float).reshape(-1)
    values, inverse = np.unique(taus, return_inverse=True)
    if values.size == 1:
        return pade_realization(float(values[0]), pade_order)
    each = [pade_realization(float(tau), pade_order) for tau in values]
    return tuple(np.stack([m[i] for m in each])[np.broadcast_to(inverse.reshape(-1), (n,))]
                 for i in range(4))


def _cancel_zero_roots(numerators, denominator):
    """Divide out every factor s common to all numerators and the denominator."""
    numerators = [np.trim_zeros(np.asarray(n, dtype=float), "f") for n in numerators]
    denominator = np.trim_zeros(np.asarray(denominator, dtype=float), "f")
    while denominator.size > 1 and denominator[-1] == 0 and all(
            n.size > 1 and n[-1] == 0 for n in numerators):
        numerators = [n[:-1] for n in numerators]
        denominator = denominator[:-1]
    return numerators, denominator


def _trim_leading(coefficients):
    """The coefficients (..., width) without the leading columns that are zero in every row."""
    nonzero = np.any(coefficients.reshape(-1, coefficients.shape[-1]) != 0, axis=0)
    return coefficients[..., int(np.argmax(nonzero)) if nonzero.any() else coefficients.shape[-1]:]


def realize(numerator, denominator):
    """(A, B, C, D) of a proper rational function (coefficients, highest power first) in
    observable companion form, normalised by the leading denominator coefficient. Rows of
    stacks (runs, width) give stacks (runs, ., .); their denominators must share a degree."""
    denominator = _trim_leading(np.asarray(denominator, dtype=float))
    numerator = _trim_leading(np.asarray(numerator, dtype=float))
    order = denominator.shape[-1] - 1
    lead = np.broadcast_shapes(numerator.shape[:-1], denominator.shape[:-1])
    if numerator.shape[-1] > order + 1:  # leading zeros of some rows only
        numerator = numerator[..., -(order + 1):]
    numerator = np.concatenate([np.zeros((*numerator.shape[:-1], order + 1 - numerator.shape[-1])),
                                numerator], axis=-1) / denominator[..., :1]
    denominator = denominator / denominator[..., :1]
    d = numerator[..., 0]
    a = np.zeros((*lead, order, order))
    if order:
        a[..., :, 0] = -denominator[..., 1:]
        a[..., :-1, 1:] = np.eye(order - 1)
    b = (numerator[..., 1:] - d[..., None] * denominator[..., 1:])[..., None]
    c = np.zeros((*lead, 1, order))
    if order:
        c[..., 0, 0] = 1.0
    return a, b, c, d[..., None, None]


def discretised(system, period, method):
    """A continuous (A, B, C, D) (or stacks) discretised by the generalised bilinear transform
    (the block's transfer function with s replaced, :func:`cas_freq.model.sampled.equivalent_s`;
    ``period`` [s])."""
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


def lifted(system, ratio):
    """A fast system with its input held for ``ratio`` steps, seen every ``ratio`` steps:
    :math:`A_s = A^M`, :math:`B_s = \\sum_{i<M} A^i B`."""
    a, b, c, d = system
    power = np.broadcast_to(np.eye(a.shape[-1]), a.shape).copy()
    total = np.zeros_like(b)
    for _ in range(ratio):
        total = total + power @ b
        power = power @ a
    return power, total, c, d


# --- interconnection -------------------------------------------------------------------------

def concatenate(arrays, axis):
    """np.concatenate of matrices and stacks of matrices (leading axes broadcast)."""
    lead = np.broadcast_shapes(*(m.shape[:-2] for m in arrays))
    return np.concatenate([np.broadcast_to(m, (*lead, *m.shape[-2:])) for m in arrays],
                          axis=axis)


def series(first, second):
    """``first`` then ``second`` (single input; ``first`` single output); matrices or stacks
    of them (leading axes broadcast)."""
    a1, b1, c1, d1 = first
    a2, b2, c2, d2 = second
    m1, m2 = a1.shape[-1], a2.shape[-1]
    lead = np.broadcast_shapes(*(m.shape[:-2] for m in (*first, *second)))
    a = np.zeros((*lead, m1 + m2, m1 + m2))
    a[..., :m1, :m1] = a1
    a[..., m1:, :m1] = b2 @ c1
    a[..., m1:, m1:] = a2
    return a, concatenate([b1, b2 @ d1], -2), concatenate([d2 @ c1, c2], -1), d2 @ d1


def chain(systems):
    """Single-input single-output systems in series (a unit gain for none)."""
    out = (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1)))
    for system in systems:
        out = series(out, system)
    return out


def feedback(system, row, sensor=None):
    """Negative feedback of output ``row`` (through ``sensor``, if any) to the first input;
    the second input (the command) stays, every output kept. The fed-back output has no
    direct term, as every measured signal here. Matrices or stacks of them."""
    a, b, c, d = system
    b_error, b_command = b[..., :, :1], b[..., :, 1:]
    d_error, d_command = d[..., :, :1], d[..., :, 1:]
    measured_row = c[..., row:row + 1, :]
    if sensor is None:
        return a - b_error @ measured_row, b_command, c - d_error @ measured_row, d_command
    a_s, b_s, c_s, d_s = sensor
    m, q = a.shape[-1], a_s.shape[-1]
    lead = np.broadcast_shapes(*(x.shape[:-2] for x in (*system, *sensor)))
    a_new = np.zeros((*lead, m + q, m + q))
    a_new[..., :m, :m] = a - b_error @ d_s @ measured_row
    a_new[..., :m, m:] = -b_error @ c_s
    a_new[..., m:, :m] = b_s @ measured_row
    a_new[..., m:, m:] = a_s
    c_new = concatenate([c - d_error @ d_s @ measured_row, -d_error @ c_s], -1)
    b_new = concatenate([b_command, np.zeros((q, 1))], -2)
    return a_new, b_new, c_new, d_command


def _one(closing):
    """A :class:`Closing` of a stack of one run as 2-D matrices."""
    def first(system):
        return None if system is None else tuple(m[0] if m.ndim == 3 else m for m in system)

    return Closing(first(closing.opened), closing.row, first(closing.sensor),
                   first(closing.closed), closing.period)
