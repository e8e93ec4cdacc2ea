r"""Frequency responses of sampled (digital) loops, exact at the sampling instants.

A drive runs its controllers at fixed rates (the EPOS4: the current loop at 25 kHz, the
position loop at 2.5 kHz). ``sampling:`` (docs/config.md) declares them; the loops of the
declared structure (:mod:`cas_freq.model.structure`) are then evaluated as the drive runs them
(docs/model.md, "Sampled controllers"):

- every controller, path filter, digital feedback filter and command path, and the command's
  shaping (``position_command``, at the outermost loop's period), is the continuous block
  with :math:`s` replaced by :math:`(1 - z^{-1})/T` (``backward``) or
  :math:`\frac{2}{T}\frac{z - 1}{z + 1}` (``tustin``), :math:`z = e^{j\omega T}`, T the
  period of the loop it belongs to;
- the current controller's output is held (zero-order hold) and reaches the motor after the
  current loop's delay :math:`\tau_c = mT + \varepsilon` (:math:`0 \le \varepsilon < T`): the
  plant's hold-equivalent (modified z-transform, :mod:`cas_freq.model.hold`) is exact, from
  the plant's modes :math:`p_i` (eigenvalues of the state matrix of
  :func:`cas_freq.model.parts.plant_matrices`), with :math:`\lambda_i = e^{p_i T}`:

  .. math::
      P_y(z) = z^{-m} \sum_i \frac{w_{y,i}\,(g_{1,i} + g_{0,i} z^{-1})}{z - \lambda_i},
      \quad g_{1,i} = \int_0^{T-\varepsilon} e^{p_i \eta}\, d\eta, \quad
      g_{0,i} = e^{p_i (T - \varepsilon)} \int_0^{\varepsilon} e^{p_i \eta}\, d\eta

  (:math:`w_{y,i}` the mode's residue in the measured signal y per volt);
- an analog filter on a measurement (before its sampler: ``current_feedback``,
  ``position_feedback``) is part of that hold-equivalent, not discretised: the plant's modes
  with residues :math:`w_{y,i} F(p_i)` and the filter's own modes held exactly
  (:class:`AnalogPart`);
- a delay between two controllers (the held output of one, sampled by the next) is
  :math:`\lceil \tau / T_{inner} \rceil` samples of the inner (faster) controller;
- where an outer loop runs M times slower than the loops inside it (multirate), the inner
  loops are closed at their rate and the outer loop sees their response through its hold and
  its sampler, the decimation sum

  .. math::
      P(e^{j\omega T_s}) = \frac{1}{M} \sum_{k=0}^{M-1} H_M(z_k)\, z_k^{-d}\, G(z_k),
      \qquad z_k = e^{j(\omega + 2\pi k/T_s) T_f}, \qquad H_M(z) = \sum_{i<M} z^{-i}.

The loops are then composed by the same walk over the loop table as the continuous ones
(:func:`cas_freq.model.table.walk`), a group of loops of one rate at a time, in the algebra of
:class:`SampledValues`. Each loop's response
is a function of its own :math:`e^{j\omega T}`: meaningful up to its Nyquist frequency
:math:`\pi/T` (the figures stop there). The closed loop T is the output's samples per
command sample at the outermost loop's rate. Loop-at-a-time views of loops inside a slower
loop are not defined (with the slower loop closed they are periodically time-varying): NaN.
"""

import dataclasses
import math

import numpy as np

import cas_freq.model.parts as parts
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import Filter
from cas_freq.model.hold import WHOLE, PlantModes, hold_equivalent, plant_modes
from cas_freq.model.loops import LoopResponses
from cas_freq.model.loops import responses as continuous
from cas_freq.model.structure import build
from cas_freq.model.table import Values, command, shaped, table, walk
from cas_freq.model.table import at_a_time as table_at_a_time
from cas_freq.model.table import cascade as table_cascade

#: The discretisations of a sampled controller (docs/model.md).
METHODS = ("backward", "tustin")


@dataclasses.dataclass(frozen=True)
class Group:
    """Loops running at one rate (innermost first).

    Attributes
    ----------
    period : float
        Sampling period T [s].
    loops : tuple of int
        Indices of its loops in the structure.
    ratio : int
        Its period over the period of the group inside it (1 for the innermost).
    """

    period: float
    loops: tuple
    ratio: int


def is_sampled(p):
    """True where the parameters declare sampled loops (``sample_rates``)."""
    return bool(getattr(p, "sample_rates", ()))


#: Why a loop inside a slower sampled loop has no loop-at-a-time figures (not defined: ...).
TIME_VARYING = "a slower sampled loop around it makes it periodically time-varying"


def time_varying_views(sample_rates):
    """The loops whose loop-at-a-time view has no figures (:data:`TIME_VARYING`): those
    inside a slower sampled loop, every loop faster than the slowest (none when continuous).

    Parameters
    ----------
    sample_rates : tuple of (str, float) or dict of str to float
        The sampled loops and their rates [Hz] (``LoopParameters.sample_rates``, or analyze's
        ``sampling["rates_hz"]``).
    """
    rates = dict(sample_rates)
    slowest = min(rates.values(), default=None)
    return tuple(loop for loop, rate in rates.items()
                 if not math.isclose(rate, slowest, rel_tol=WHOLE))


def groups(names, sample_rates):
    """The loops grouped by rate, innermost first.

    Parameters
    ----------
    names : tuple of str
        The structure's loops, innermost first.
    sample_rates : tuple of (str, float)
        Sampled loops and their rates [Hz].

    Returns
    -------
    list of Group
    """
    rates = dict(sample_rates)
    unknown = sorted(set(rates) - set(names))
    if unknown:
        raise ConfigError(f"sampling.{unknown[0]}: the drive has no such loop "
                          f"(its loops: {', '.join(names)})")
    missing = [name for name in names if name not in rates]
    if missing:
        raise ConfigError(
            f"sampling.{missing[0]}: missing; with any loop sampled, every loop is (an inner "
            "loop is never slower than the loop around it, and a continuous loop inside a "
            "sampled one is not modelled)")
    out = []
    for k, name in enumerate(names):
        period = 1.0 / float(rates[name])
        if out and math.isclose(period, out[-1].period, rel_tol=WHOLE):
            out[-1] = dataclasses.replace(out[-1], loops=(*out[-1].loops, k))
            continue
        ratio = 1
        if out:
            exact = period / out[-1].period
            ratio = round(exact)
            if ratio < 1 or not math.isclose(exact, ratio, rel_tol=1e-9):
                raise ConfigError(
                    f"sampling.{name}: {rates[name]:g} Hz; accepted: the rate of the loop inside "
                    f"it ({rates[names[k - 1]]:g} Hz) divided by a whole number")
        out.append(Group(period, (k,), ratio))
    return out


def equivalent_s(omega, period, method):
    r"""The value of s that a discretised block sees at :math:`z = e^{j\omega T}`.

    Backward: :math:`(1 - z^{-1})/T`; Tustin: :math:`\frac{2}{T}\frac{z - 1}{z + 1} =
    \frac{2j}{T}\tan(\omega T/2)` (both computed without cancellation near z = 1).

    Parameters
    ----------
    omega : numpy.ndarray
        Frequencies [rad/s].
    period : float
        T [s].
    method : str
        ``"backward"`` or ``"tustin"``.
    """
    if method == "backward":
        return -np.expm1(-1j * omega * period) / period
    if method == "tustin":
        return 2j * np.tan(0.5 * omega * period) / period
    raise ConfigError(f"sampling.method: {method!r}; accepted: {', '.join(METHODS)}")


@dataclasses.dataclass(frozen=True, eq=False)
class SampledResponses(LoopResponses):
    """:class:`cas_freq.model.loops.LoopResponses` of sampled loops (each loop's response at
    its own z = e^(j omega T)), with each loop's sampling period [s]."""

    periods: dict = dataclasses.field(default_factory=dict)


def periods(p):
    """Each loop's sampling period [s], innermost first (name -> T)."""
    structure = build(p)
    return {structure.names[k]: group.period
            for group in groups(structure.names, p.sample_rates) for k in group.loops}


def nyquist_frequencies(p):
    """Each loop's Nyquist frequency pi/T [rad/s] (name -> value)."""
    return {name: math.pi / period for name, period in periods(p).items()}


def responses(p, s, closed=True, loop_at_a_time=False, output=None, modes=None,
              feedforward=False, through=None):
    r"""Every loop's response and (optionally) T of sampled loops at ``s = j omega``.

    Parameters
    ----------
    p : types.SimpleNamespace or LoopParameters
        Parameters broadcastable against ``s``, with ``sample_rates`` and ``sampling_method``.
    s : numpy.ndarray
        Points on the imaginary axis, ``1j * omega`` [rad/s].
    closed : bool
        Also compute T (the output's samples per command sample).
    loop_at_a_time : bool
        Also every loop broken with all the others closed (NaN for a loop inside a slower one).
    output : str, optional
        The plant signal T reads (default the structure's output).
    modes : PlantModes, optional
        The runs' plant modes, if already decomposed (:func:`plant_modes`).
    feedforward : bool
        Let the feed-forward act on the command in T: the command's rate and acceleration as
        the drive's trajectory generator knows them (the polynomial at s = j omega, sampled),
        added to the controller's output of its loop (loops of the outermost rate only).
    through : str, optional
        Only the loops of the groups up to the one holding this loop (at omega itself; the
        loops outside it do not change them); not with ``closed``.

    Returns
    -------
    SampledResponses
    """
    return _evaluate(Prepared.of(p, modes), s, closed, loop_at_a_time, output, feedforward,
                     through)


@dataclasses.dataclass(frozen=True, eq=False)
class Prepared:
    """The runs' loops multiplied out once (structure, rate groups, the loop table, plant
    modes; the analog sensors are in the plant's modes), for :func:`responses` of all of them
    or of a few at a time (:meth:`pick`: the margin searches' refinements)."""

    structure: object
    plan: list
    method: str
    table: object
    modes: PlantModes
    shape: tuple

    @classmethod
    def of(cls, p, modes=None):
        """The loops of the runs ``p``."""
        structure = build(p)
        return cls(structure, groups(structure.names, p.sample_rates),
                   getattr(p, "sampling_method", "backward"), table(structure).arrays(),
                   plant_modes(p) if modes is None else modes, _runs(p))

    def pick(self, runs):
        """The same of the runs ``runs`` (indices into the runs of 1-D parameters)."""
        return dataclasses.replace(self, table=self.table.pick(runs),
                                   modes=self.modes.pick(runs), shape=np.shape(runs))


class SampledValues(Values):
    """The walk's algebra (:func:`cas_freq.model.table.walk`) of one group of loops at one
    rate: complex values at :math:`z = e^{j\\nu T}`, each block at the equivalent ``x`` of s
    (:func:`equivalent_s`), the measured signals those of the plant's hold-equivalent (or of
    the faster group inside, ``signals``), a delay between two controllers whole samples of
    this rate (none on the group's ``first`` loop: the hold-equivalent holds it)."""

    def __init__(self, x, z_inverse, period, signals, first):
        super().__init__(x)
        self.z_inverse = z_inverse
        self.period = period
        self.signals = signals
        self.first = first

    def delay(self, row):
        """(z^-samples, None)."""
        if row.name == self.first:
            return 1.0, None
        return self.z_inverse ** _samples(row.tau, self.period), None

    def measured(self, row):
        """The sampled signal through the digital sensor's numerators."""
        return self.signals[row.measured] * self.poly(row.digital_numerator)

    def sensor(self, row):
        """The digital sensor's denominators."""
        return self.poly(row.digital_denominator)


def _evaluate(prepared, s, closed, loop_at_a_time, output, feedforward, through):
    """:func:`responses` of prepared loops."""
    structure, plan, method = prepared.structure, prepared.plan, prepared.method
    rows, modes = prepared.table, prepared.modes
    if through is not None:
        k = structure.names.index(through)
        plan = [group for group in plan if min(group.loops) <= k]
        closed = False
    if feedforward and any(structure.loops[k].feedforward is not None
                           for group in plan[:-1] for k in group.loops):
        raise ConfigError("sampling: the feed-forward into a loop faster than the outermost is "
                          "not modelled in the frequency domain (sample those loops alike)")
    omega = np.asarray(s).imag
    rank = len(np.broadcast_shapes(omega.shape, prepared.shape))
    omega = omega.reshape((1,) * (rank - omega.ndim) + omega.shape)  # aliases go before
    seen = output or structure.output
    top = len(plan) - 1

    # the frequencies each group is evaluated at: omega and its aliases at the slower rates
    frequencies = [None] * len(plan)
    nu = omega
    for g in range(top, -1, -1):
        frequencies[g] = nu
        if g:
            k = np.arange(plan[g].ratio).reshape((-1,) + (1,) * nu.ndim)
            nu = nu[None] + 2.0 * np.pi * k / plan[g].period

    signals = hold_equivalent(modes, rows.rows[0].tau, plan[0].period, frequencies[0])
    cascade, views = {}, {}
    t = None
    for g, group in enumerate(plan):
        nu = frequencies[g]
        group_rows = dataclasses.replace(rows, rows=tuple(rows.rows[k] for k in group.loops))
        values = SampledValues(equivalent_s(nu, group.period, method),
                               np.exp(-1j * nu * group.period), group.period, signals,
                               group_rows.rows[0].name)
        found = walk(group_rows, values, e=1.0)
        aliases = nu.ndim - omega.ndim
        cascade.update({name: _own(value, aliases)
                        for name, value in table_cascade(found.steps).items()})
        if loop_at_a_time:
            for name, value in table_at_a_time(found.steps).items():
                value = _own(value, aliases)
                views[name] = value if g == top else np.full_like(value, np.nan)
        if g == top:
            if closed:
                entering = [_entering(row, values, nu, feedforward) for row in group_rows.rows]
                t = (command(found.steps, entering, values) * found.sensed * signals[seen]
                     / found.e)
                t = shaped(t, rows, values)  # the command's shaping at the outermost rate
            break
        # what the next (slower) group's loops see: held, delayed, sampled
        outer = plan[g + 1]
        fast = group.period
        held = (values.z_inverse ** _samples(rows.rows[outer.loops[0]].tau, fast)
                * _hold_sum(nu, fast, outer.ratio))
        signals = {name: np.mean(held * found.gain * value * found.sensed / found.e, axis=0)
                   for name, value in signals.items()}
    period_of = {structure.names[k]: group.period for group in plan for k in group.loops}
    ndim = np.ndim(s)
    return SampledResponses({name: _trim(v, ndim) for name, v in cascade.items()},
                            None if t is None else _trim(t, ndim),
                            {name: _trim(v, ndim) for name, v in views.items()}
                            if loop_at_a_time else None, period_of)


def _entering(row, values, nu, feedforward):
    """What the command adds at this row's controller output
    (:func:`cas_freq.model.table.command`): its reference and, with the feed-forward, the
    command's rate and acceleration as the trajectory generator knows them (the polynomial at
    s = j nu) over the controller's denominator."""
    out = () if row.reference is None else (values.poly(row.reference),)
    if feedforward and row.feedforward is not None:
        out += (parts.polyval(row.feedforward, 1j * nu) * values.poly(row.controller_denominator)
                * values.poly(row.path_numerator),)
    return out


def _runs(p):
    """The shape the runs' parameters broadcast to (() where every one is a scalar)."""
    shapes = [np.shape(value) for value in vars(p).values() if isinstance(value, np.ndarray)]
    shapes += [np.shape(getattr(item, name)) for item in getattr(p, "filters", ())
               for name in Filter.NUMBERS
               if isinstance(getattr(item, name, None), np.ndarray)]
    return np.broadcast_shapes(*shapes)


def _trim(values, ndim):
    """Without the leading axes of length 1 that the runs' rank added to ``s``'s."""
    values = np.asarray(values)
    while values.ndim > ndim and values.shape[0] == 1:
        values = values[0]
    return values


def _samples(tau, period):
    """Whole samples of a delay between two controllers: ceil(tau/T) (per run)."""
    return np.ceil(np.asarray(tau, dtype=float) / period - WHOLE)


def _hold_sum(nu, period, count):
    """H_M(z) = sum_(i<M) z^-i at z = e^(j nu T) (M at z = 1)."""
    low = -np.expm1(-1j * nu * period)
    high = -np.expm1(-1j * nu * period * count)
    near = np.abs(low) < 1e-300
    return np.where(near, float(count), high / np.where(near, 1.0, low))


def _own(values, aliases):
    """A group's response at omega itself (the first of its aliases)."""
    return values[(0,) * aliases] if aliases else values


class PreparedSampled:
    """:class:`cas_freq.model.loops.PreparedResponses` for sampled loops: the responses of a
    few runs of a batch at a time (the margin searches' refinements).

    Parameters
    ----------
    selector : cas_freq.model.loops.Selector
        The batch's parameters.
    """

    def __init__(self, selector):
        self.prepared = Prepared.of(selector())

    def responses(self, runs, s, closed=True, delay=None, loop_at_a_time=False, through=None):
        """:func:`responses` of the runs ``runs`` (indices, one per value of ``s``); ``delay``
        is accepted for the continuous evaluator's signature (a sampled loop's delays are
        exact)."""
        if closed or loop_at_a_time:
            through = None
        return _evaluate(self.prepared.pick(runs), s, closed, loop_at_a_time, None, False,
                         through)

    def current_loop(self, runs, s, delay=None):
        """The innermost loop's response of the runs ``runs``."""
        return self.responses(runs, s, closed=False).loops["current_loop"]


def grid_responses(p, omega, closed=True, loop_at_a_time=False):
    """:func:`responses` on a sorted grid of frequencies, each loop only below its Nyquist
    frequency (NaN from it up), T and the outermost loop's below the outermost's: each group
    of loops is evaluated up to its own Nyquist frequency and no further.

    Parameters
    ----------
    p : types.SimpleNamespace or LoopParameters
        Parameters broadcastable against ``omega``'s points.
    omega : numpy.ndarray
        Increasing frequencies [rad/s], shape (m,).
    closed, loop_at_a_time : bool
        As :func:`responses`.

    Returns
    -------
    SampledResponses
    """
    omega = np.asarray(omega, dtype=float)
    structure = build(p)
    plan = groups(structure.names, p.sample_rates)
    edges = [int(np.searchsorted(omega, np.pi / group.period)) for group in plan]
    out = responses(p, 1j * omega[:edges[-1]], closed=closed, loop_at_a_time=loop_at_a_time)
    pieces = {name: [v] for name, v in out.loops.items()}
    views = {name: [v] for name, v in (out.loop_at_a_time or {}).items()}
    start = edges[-1]
    for g in range(len(plan) - 2, -1, -1):  # the faster groups, on up to their Nyquist
        inner = structure.names[plan[g].loops[-1]]
        part = responses(p, 1j * omega[start:edges[g]], closed=False,
                         loop_at_a_time=loop_at_a_time, through=inner)
        for name in pieces:
            pieces[name].append(part.loops.get(name, _nan_like(pieces[name][0],
                                                               edges[g] - start)))
        for name in views:
            views[name].append(_nan_like(views[name][0], edges[g] - start))
        start = edges[g]

    def joined(chunks):
        value = np.concatenate([np.broadcast_to(c, (*np.shape(chunks[0])[:-1], c.shape[-1]))
                                if np.ndim(c) else c for c in chunks], axis=-1)
        return np.concatenate([value, _nan_like(value, omega.size - value.shape[-1])], axis=-1)

    t = None
    if out.closed_loop is not None:
        t = joined([out.closed_loop])
    return SampledResponses({name: joined(c) for name, c in pieces.items()}, t,
                            {name: joined(c) for name, c in views.items()}
                            if loop_at_a_time else None, out.periods)


def _nan_like(values, count):
    """NaN of ``values``' leading shape and ``count`` points."""
    return np.full((*np.shape(values)[:-1], count), np.nan, dtype=complex)


def drive_responses(p, s, closed=True, loop_at_a_time=False):
    """The loops' responses as the drive runs them: sampled where ``p`` declares sampling
    (NaN at and above each loop's Nyquist frequency, T and the loops' views above the
    outermost's, so that curves stop there), else continuous with exact delays
    (:func:`cas_freq.model.loops.responses`).

    Parameters
    ----------
    p : types.SimpleNamespace or LoopParameters
        Parameters broadcastable against ``s``.
    s : numpy.ndarray
        ``1j * omega`` [rad/s].
    closed, loop_at_a_time : bool
        As :func:`responses`.
    """
    if not is_sampled(p):
        return continuous(p, s, closed=closed, loop_at_a_time=loop_at_a_time)
    omega = np.asarray(s).imag
    if omega.ndim == 1 and np.all(np.diff(omega) > 0):
        return grid_responses(p, omega, closed=closed, loop_at_a_time=loop_at_a_time)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # (cut off below)
        found = responses(p, s, closed=closed, loop_at_a_time=loop_at_a_time)
    limits = nyquist_frequencies(p)
    top = limits[list(limits)[-1]]

    def cut(values, limit):
        return np.where(omega < limit, values, np.nan)

    return SampledResponses(
        {name: cut(v, limits[name]) for name, v in found.loops.items()},
        None if found.closed_loop is None else cut(found.closed_loop, top),
        None if found.loop_at_a_time is None else
        {name: cut(v, limits[name]) for name, v in found.loop_at_a_time.items()},
        found.periods)
