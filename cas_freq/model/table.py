r"""The loop structure compiled into a table, and the one walk that evaluates it.

:func:`table` multiplies out each loop of a :class:`~cas_freq.model.structure.Structure` once
(a :class:`Row`, innermost first: loop k's path commands loop k − 1). :func:`walk` then runs
the recurrence of :mod:`cas_freq.model.structure`

.. math::
    E_{-1} = \Delta, \qquad A_k = A_{k-1}\, a_k\, d_k, \qquad
    c_k = A_k\, g_k\, \tilde F_{k-1}, \qquad E_k = \beta_k E_{k-1} + c_k, \qquad
    \beta_k = b_k \bar d_k f_k

(:math:`d_k/\bar d_k` the delay: :math:`e^{-s\tau_k}/1` exact, :math:`D(-s\tau)/D(s\tau)` Padé)
over the rows, in an *algebra*: the only thing that differs between the frequency responses
on a grid (:class:`Values`), the Padé characteristic polynomials (:class:`Polynomials`), the
sampled loops' hold-equivalent (:class:`cas_freq.model.sampled.SampledValues`) and the
compiled kernel (:mod:`cas_freq.analysis.response_kernel`, which reads the same rows as
coefficient stacks). The figures are ratios of the walk's terms (:func:`cascade`,
:func:`at_a_time`, :func:`command`, :func:`entering`): the cascade view
:math:`L_k = c_k/(\beta_k E_{k-1})`, the loop-at-a-time view, the closed loop's numerator and
the load and noise inputs.
"""

import dataclasses

import numpy as np

import cas_freq.model.parts as parts
from cas_freq.model.delay import pade_denominator
from cas_freq.model.parts import polyadd, polymul, product
from cas_freq.model.structure import digital_sensor, measured


@dataclasses.dataclass(frozen=True)
class Row:
    r"""One loop multiplied out: polynomials (tuples of coefficients, highest power first) and
    its delay.

    Attributes
    ----------
    name, symbol, breaks_at : str
        The loop's figure prefix, its loop transfer function's symbol and where it is broken
        (:class:`~cas_freq.model.structure.Loop`).
    a, b : tuple
        The controller's and the path filters' numerators, and their denominators.
    g : tuple
        The measured plant signal's numerator per volt through the sensor's numerators.
    f : tuple
        The sensor's denominators.
    tau : float or numpy.ndarray
        The delay after the path [s].
    reference : tuple or None
        The command's numerator at this controller's output over ``b``, before the delay
        (None: no command enters here).
    sensor : tuple
        The sensor's numerators alone (where a noise enters before them).
    feedback, measured : str
        The plant signal measured, and the name its sampler reads
        (:func:`cas_freq.model.structure.measured`: behind analog filters, their output).
    digital_numerator, digital_denominator : tuple
        Those of the sensor blocks after the sampler.
    feedforward : tuple or None
        :math:`\Phi(s)` of the command added to this controller's output.
    controller_denominator, path_numerator : tuple
        Where the feed-forward enters (:math:`\Phi\, b^c_k\, a^{path}_k`).
    """

    name: str
    symbol: str
    breaks_at: str
    a: tuple
    b: tuple
    g: tuple
    f: tuple
    tau: object
    reference: tuple | None
    sensor: tuple
    feedback: str
    measured: str
    digital_numerator: tuple
    digital_denominator: tuple
    feedforward: tuple | None
    controller_denominator: tuple
    path_numerator: tuple


@dataclasses.dataclass(frozen=True)
class Table:
    """The loops of a batch of runs, innermost first, over the plant's denominator
    :math:`\\Delta`, with the numerator per volt (``seen``) of the plant signal T reads
    (``output``) and the shaping of the command before every loop, (numerator, denominator)
    polynomials of :attr:`~cas_freq.model.structure.Structure.command` (None: no shaping)."""

    rows: tuple
    denominator: tuple
    seen: tuple
    output: str
    shaping: tuple | None = None

    @property
    def names(self):
        """The loops' figure prefixes, innermost first."""
        return tuple(row.name for row in self.rows)

    def arrays(self):
        """The same table with every coefficient an array (n,) where it varies between runs,
        else a float (the same number), ready for :meth:`pick`."""
        return _mapped(self, _arrays, lambda polynomial: polynomial is not None)

    def pick(self, runs, count=None):
        """The table (of :meth:`arrays`) of the runs ``runs`` (indices), of its first
        ``count`` loops (all by default)."""
        def picked(polynomial):
            return tuple(c[runs] if isinstance(c, np.ndarray) else c for c in polynomial)

        return _mapped(self, picked, _varies, count)


_POLYNOMIALS = ("a", "b", "g", "f", "reference", "sensor", "digital_numerator",
                "digital_denominator", "feedforward", "controller_denominator",
                "path_numerator")


def _varies(polynomial):
    return polynomial is not None and any(isinstance(c, np.ndarray) for c in polynomial)


def _mapped(table, function, where, count=None):
    """The table's first ``count`` rows with ``function`` applied to each polynomial
    ``where`` says (the delay as a polynomial of one coefficient)."""
    rows = []
    for row in table.rows[:count]:
        changes = {name: function(getattr(row, name)) for name in _POLYNOMIALS
                   if where(getattr(row, name))}
        if where((row.tau,)):
            changes["tau"] = function((row.tau,))[0]
        rows.append(dataclasses.replace(row, **changes) if changes else row)
    shaping = table.shaping
    if shaping is not None:
        shaping = tuple(function(polynomial) if where(polynomial) else polynomial
                        for polynomial in shaping)
    return Table(tuple(rows), function(table.denominator), function(table.seen), table.output,
                 shaping)


def _arrays(polynomial):
    return tuple(float(c) if np.ndim(c) == 0 else np.asarray(c) for c in polynomial)


def table(structure, feedforward=False, minimal=False, output=None):
    """The loops of ``structure`` multiplied out, innermost first (see the module docstring).

    Parameters
    ----------
    structure : cas_freq.model.structure.Structure
    feedforward : bool
        Let the feed-forward act (the command enters every controller with one).
    minimal : bool
        Use the blocks' minimal forms (coefficient stacks; for characteristic polynomials:
        no command enters, ``reference`` is None).
    output : str, optional
        The plant signal T reads (default the structure's: the output angle).

    Returns
    -------
    Table
    """
    rows = []
    top = len(structure.loops) - 1
    for k, loop in enumerate(structure.loops):
        controller = loop.controller
        if minimal and controller.minimal is not None:
            c_num, c_den = (tuple(stack.T) for stack in controller.minimal())
        else:
            c_num, c_den = controller.numerator, controller.denominator
        path_num = product(block.numerator for block in loop.path)
        path_den = product(block.denominator for block in loop.path)
        reference = None
        if k == top and not minimal:
            reference = loop.reference if loop.reference is not None else c_num
        if feedforward and loop.feedforward is not None and not minimal:
            injected = polymul(loop.feedforward, c_den)
            reference = injected if reference is None else polyadd(reference, injected)
        sensor = product(block.numerator for block in loop.sensor)
        digital = digital_sensor(loop)
        rows.append(Row(
            name=loop.name, symbol=loop.symbol, breaks_at=loop.breaks_at,
            a=polymul(c_num, path_num), b=polymul(c_den, path_den),
            g=polymul(structure.plant.signals[loop.feedback], sensor),
            f=product(block.denominator for block in loop.sensor), tau=loop.delay,
            reference=None if reference is None else polymul(reference, path_num),
            sensor=sensor, feedback=loop.feedback, measured=measured(loop),
            digital_numerator=product(block.numerator for block in digital),
            digital_denominator=product(block.denominator for block in digital),
            feedforward=loop.feedforward, controller_denominator=controller.denominator,
            path_numerator=path_num,
        ))
    output = output or structure.output
    shaping = None
    if structure.command:
        shaping = (product(block.numerator for block in structure.command),
                   product(block.denominator for block in structure.command))
    return Table(tuple(rows), structure.plant.denominator, structure.plant.signals[output],
                 output, shaping)


def shaped(t, table, algebra):
    """T times the command's shaping :math:`W = a^{cmd}/b^{cmd}` (``table.shaping``) in the
    algebra's values (T itself where there is none)."""
    if table.shaping is None:
        return t
    numerator, denominator = table.shaping
    return t * algebra.poly(numerator) / algebra.poly(denominator)


# --- the algebras ----------------------------------------------------------------------------

class Values:
    """Complex values at the frequencies ``s`` [rad/s] (any shape broadcasting against the
    runs' coefficients), with the delays of ``delay``
    (:class:`~cas_freq.model.delay.DelayModel`: exact or Padé)."""

    one = 1.0
    zero = 0.0

    def __init__(self, s, delay=None):
        self.s = s
        self.model = delay

    @staticmethod
    def mul(x, y):
        """x y."""
        return x * y

    @staticmethod
    def add(x, y):
        """x + y."""
        return x + y

    def poly(self, polynomial):
        """The polynomial's value (a constant as it is)."""
        return parts.polyval(polynomial, self.s) if len(polynomial) > 1 else polynomial[0]

    def plant(self, table):
        """:math:`E_{-1} = \\Delta`."""
        return self.poly(table.denominator)

    def delay(self, row):
        """(numerator, denominator) of the row's delay; None: 1."""
        return self.model.response(self.s, row.tau), None

    def measured(self, row):
        """:math:`g_k`."""
        return self.poly(row.g)

    def sensor(self, row):
        """:math:`f_k`."""
        return self.poly(row.f)


class Polynomials(Values):
    """Polynomials in s of ``n`` runs: tuples of coefficient columns (n,), highest power
    first, each delay its Padé approximant of order ``order``
    (:func:`pade_polynomials`); ``transform`` is applied to every coefficient that enters
    (``numpy.abs``: the walk in the coefficients' magnitudes, a bound on the terms summed)."""

    one = (1.0,)
    zero = (0.0,)
    mul = staticmethod(polymul)
    add = staticmethod(polyadd)

    def __init__(self, n, order, transform=None):
        super().__init__(None)
        self.n = n
        self.order = order
        self.transform = transform

    def poly(self, polynomial):
        """The polynomial as columns (n,) of floats."""
        columns = tuple(np.broadcast_to(np.asarray(c, dtype=float), (self.n,))
                        for c in polynomial)
        if self.transform is None:
            return columns
        return tuple(self.transform(c) for c in columns)

    def delay(self, row):
        """(D(-s tau), D(s tau))."""
        tau = np.broadcast_to(np.asarray(row.tau, dtype=float), (self.n,))
        denominator, numerator = pade_polynomials(tau, self.order)
        return self.poly(tuple(numerator.T)), self.poly(tuple(denominator.T))


def pade_polynomials(tau, order):
    """(D(s tau), D(-s tau)) as stacks of polynomials in s, for delays ``tau`` [s] (n,)."""
    d = pade_denominator(order)
    powers = np.arange(order, -1, -1)
    scale = tau[:, None] ** powers
    return d * scale, d * scale * (-1.0) ** powers


# --- the walk --------------------------------------------------------------------------------

@dataclasses.dataclass(frozen=True)
class Step:
    """One loop's terms in the walk's algebra.

    ``inner``: :math:`E_{k-1}`; ``gain_in``, ``gain``: :math:`A_{k-1}`, :math:`A_k`;
    ``sensed_in``: :math:`\\tilde F_{k-1}`; ``delay``: :math:`d_k`; ``b``: :math:`b_k \\bar d_k`;
    ``f``: :math:`f_k`; ``beta``: :math:`\\beta_k`; ``c``: :math:`c_k`.
    """

    name: str
    inner: object
    gain_in: object
    gain: object
    sensed_in: object
    delay: object
    b: object
    f: object
    beta: object
    c: object


@dataclasses.dataclass(frozen=True)
class Walk:
    """The walk's steps (innermost first) and its totals after the last: :math:`E_{top}`
    (``e``), :math:`A_{top}` (``gain``) and :math:`\\tilde F_{top}` (``sensed``)."""

    steps: tuple
    e: object
    gain: object
    sensed: object

    @property
    def characteristic(self):
        """:math:`E_k` of loops 0..k closed, for every k (loop name -> term)."""
        terms = [step.inner for step in self.steps[1:]] + [self.e]
        return {step.name: term for step, term in zip(self.steps, terms, strict=True)}


def walk(table, algebra, count=None, e=None):
    """The recurrence over the first ``count`` rows of ``table`` (all by default), starting
    from ``e`` (default :math:`\\Delta`, ``algebra.plant``).

    Parameters
    ----------
    table : Table
    algebra : Values or Polynomials or cas_freq.model.sampled.SampledValues
        The arithmetic: ``mul``, ``add``, ``one``, and each row's values (``poly``,
        ``delay``, ``measured``, ``sensor``).
    count : int, optional
        How many loops, from the inside.
    e : optional
        :math:`E_{-1}` in the algebra.

    Returns
    -------
    Walk
    """
    mul, add = algebra.mul, algebra.add
    e = algebra.plant(table) if e is None else e
    gain = sensed = algebra.one
    steps = []
    for row in table.rows[:count]:
        delay, lag = algebra.delay(row)
        b = algebra.poly(row.b)
        if lag is not None:
            b = mul(b, lag)
        f = algebra.sensor(row)
        beta = mul(b, f)
        gain_in = gain
        gain = mul(mul(gain, algebra.poly(row.a)), delay)
        c = mul(mul(gain, algebra.measured(row)), sensed)
        steps.append(Step(row.name, e, gain_in, gain, sensed, delay, b, f, beta, c))
        e = add(mul(beta, e), c)
        sensed = mul(sensed, f)
    return Walk(tuple(steps), e, gain, sensed)


# --- the figures: ratios of the walk's terms -------------------------------------------------

def cascade(steps):
    """Each loop broken at its controller's output, the loops inside closed and those outside
    open: :math:`L_k = c_k/(\\beta_k E_{k-1})` (loop name -> value)."""
    return {step.name: step.c / (step.beta * step.inner) for step in steps}


def at_a_time(steps):
    """Each loop broken with every other loop closed: :math:`L_k^{aat} = U_k / (E_{k-1}
    \\prod_{m \\ge k} \\beta_m)`, :math:`U_k = \\sum_{j \\ge k} c_j \\prod_{j < m} \\beta_m`
    (loop name -> value, innermost first)."""
    out = {}
    upper, above = 0.0, 1.0
    for step in reversed(steps):
        upper = upper + step.c * above
        above = above * step.beta
        out[step.name] = upper / (above * step.inner)
    return dict(reversed(out.items()))


def command(steps, entering, algebra):
    """The closed loop's numerator before the sensed output: :math:`\\sum_k A_{k-1}
    \\varphi_k d_k \\prod_{m > k} b_m` with ``entering[k]`` the terms :math:`\\varphi_k` of loop
    k (a sequence, empty where none enters)."""
    mul, add = algebra.mul, algebra.add
    total = algebra.zero
    for step, terms in zip(steps, entering, strict=True):
        total = mul(total, step.b)
        for value in terms:
            total = add(total, mul(mul(step.gain_in, value), step.delay))
    return total


def references(table, algebra):
    """Each row's command term (:func:`command`'s ``entering``): its ``reference``."""
    return [() if row.reference is None else (algebra.poly(row.reference),)
            for row in table.rows]


def entering(steps, table, weights, algebra):
    r""":math:`\sum_k A_k h_k \sigma_k \tilde F_{k-1} \prod_{m > k} \beta_m` for inputs
    :math:`h_k` entering loop k's measurement before its sensor numerators :math:`\sigma_k`
    (``weights[k]``, a polynomial or None: nothing enters there), with
    :math:`\prod_m \beta_m` (the load and noise inputs, :mod:`cas_freq.model.disturbance`)."""
    mul, add = algebra.mul, algebra.add
    total = algebra.zero
    betas = algebra.one
    for step, row, h in zip(steps, table.rows, weights, strict=True):
        total = mul(total, step.beta)
        if h is not None:
            total = add(total, mul(mul(mul(step.gain, algebra.poly(h)),
                                       algebra.poly(row.sensor)), step.sensed_in))
        betas = mul(betas, step.beta)
    return total, betas
