"""The loop filters of a config (``filters:``, docs/config.md).

Each filter sits in series at one point of the loop, ``at``:

- ``position_command``: on the command, before every loop (it shapes the reference: it
  multiplies T and changes no loop's margins);
- ``current_command``: after the velocity or position controller, before the current loop;
- ``velocity_command``: after the position controller, before the velocity loop's error (needs
  a velocity loop);
- ``velocity_feedback``: on the measured velocity (needs a velocity loop);
- ``current_feedback``: on the measured current (the current loop's sensor);
- ``position_feedback``: on the measured angle of the position loop (the motor's or, with
  ``position_loop.feedback: output``, the output's).

The first four act on the controllers' signals: they are digital where the drive is sampled
(discretised with their loop's controller; the position command's with the outermost loop's).
The measurement filters (:data:`ANALOG_POINTS`) act on the continuous measurement before the
sampler (anti-aliasing): analog whatever the drive.

Each filter is of one kind, ``type``, declared once in :data:`FILTERS` (a
:class:`FilterType`: its numbers and its transfer function, read by the config schema, the
parameter keys and the loop structure's :func:`cas_freq.model.structure.filter_block`; the
formulas: docs/model.md, "Filters").

:data:`FILTER_PARAMETERS` holds the records of a filter's numbers (unit, bounds, meaning), as
:data:`cas_freq.core.parameters.PARAMETERS` does for the other keys. A new kind of filter is a
:class:`FilterType` in :data:`FILTERS` with the records of any new numbers (each record is a
per-run field of :class:`Filter`, and a field of the config schema's filter item).
:class:`Filter` carries one filter of a batch of runs: its point and kind are the same for the
whole batch (they shape the loop), its numbers are per run.
This module imports only :mod:`cas_freq.core.exceptions` and
:mod:`cas_freq.core.parameter_record`.
"""

import dataclasses

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameter_record import Parameter

__all__ = ["ANALOG_POINTS", "COMMAND_POINT", "DEFAULT_DAMPING", "FILTERS", "FILTER_NUMBERS",
           "FILTER_PARAMETERS", "FILTER_POINTS", "FILTER_TYPES", "VELOCITY_POINTS", "Filter",
           "FilterType", "depth_problem", "number_field", "point_problem", "type_problem"]

#: The point on the command before every loop (the shaping of the reference).
COMMAND_POINT = "position_command"
#: Where a filter may sit.
FILTER_POINTS = ("current_command", "velocity_command", "velocity_feedback",
                 "current_feedback", "position_feedback", COMMAND_POINT)
#: The points of a velocity loop (a drive without one refuses them).
VELOCITY_POINTS = ("velocity_command", "velocity_feedback")
#: The points on a measurement before it is sampled (analog filters, continuous even where the
#: controllers are sampled): point -> the loop whose measurement it filters.
ANALOG_POINTS = {"current_feedback": "current_loop", "position_feedback": "position_loop"}
#: Damping of a ``lowpass2`` without ``damping`` (1/√2: Butterworth) [-].
DEFAULT_DAMPING = 0.7071


@dataclasses.dataclass(frozen=True)
class FilterType:
    """One kind of filter (a config's ``type:``).

    Attributes
    ----------
    name : str
        Its ``type:`` in a config.
    label : str
        Its block's name in the loop structure.
    numbers : tuple of str
        The config names of the numbers it takes (their records, unit and bounds, in
        :data:`FILTER_PARAMETERS`; their per-run fields :func:`number_field`).
    transfer : callable
        ``transfer(item) -> (numerator, denominator)``: its transfer function, 1 at s = 0, as
        polynomials in s (tuples, highest power first) of the item's per-run numbers
        (:class:`Filter`'s fields, arrays or scalars broadcasting over runs).
    """

    name: str
    label: str
    numbers: tuple
    transfer: object


def _lowpass1(item):
    """1/(s/w0 + 1)."""
    return (1.0,), (1.0 / item.frequency, 1.0)


def _lowpass2(item):
    """1/(s^2/w0^2 + 2 z s/w0 + 1)."""
    w0 = item.frequency
    return (1.0,), (1.0 / (w0 * w0), 2.0 * item.damping / w0, 1.0)


def _notch(item):
    """(s^2/w0^2 + 2 d z s/w0 + 1)/(s^2/w0^2 + 2 z s/w0 + 1), z = width/(2 w0),
    d = 10^(depth/20)."""
    w0 = item.frequency
    zeta = item.width / (2.0 * w0)
    depth = 10.0 ** (item.depth_db / 20.0)
    return ((1.0 / (w0 * w0), 2.0 * depth * zeta / w0, 1.0),
            (1.0 / (w0 * w0), 2.0 * zeta / w0, 1.0))


def _leadlag(item):
    """(1 + s/w_z)/(1 + s/w_p): a lead where the zero is below the pole, a lag above."""
    return (1.0 / item.zero, 1.0), (1.0 / item.pole, 1.0)


#: The kinds of filter, by ``type:``.
FILTERS = {kind.name: kind for kind in (
    FilterType("lowpass1", "low-pass", ("frequency",), _lowpass1),
    FilterType("lowpass2", "low-pass", ("frequency", "damping"), _lowpass2),
    FilterType("notch", "notch", ("frequency", "width", "depth"), _notch),
    FilterType("leadlag", "lead-lag", ("zero", "pole"), _leadlag),
)}
#: The kinds of filter, each with the numbers it takes (config names; ``frequency`` first).
FILTER_NUMBERS = {name: kind.numbers for name, kind in FILTERS.items()}
FILTER_TYPES = tuple(FILTERS)
#: A number's per-run field of :class:`Filter` where it differs from its config name.
_FIELDS = {"depth": "depth_db"}


def number_field(name):
    """The :class:`Filter` field of a filter's number ``name`` (its config name)."""
    return _FIELDS.get(name, name)

#: The numbers of a filter of ``filters:`` (:mod:`cas_freq.core.filters_config`), by item key;
#: the dotted key of filter i's number is ``filters.<i>.<name>``.
FILTER_PARAMETERS = {
    p.key.rpartition(".")[2]: p for p in (
        Parameter("filters.N.frequency", None, "rad/s", 0.0, True, 1e9,
                  "filter frequency w0, > 0..1e9 [rad/s]"),
        Parameter("filters.N.damping", None, "dimensionless", 0.0, True, 100.0,
                  f"damping of a lowpass2 filter, default {DEFAULT_DAMPING:g}, > 0..100 "
                  "[dimensionless]"),
        Parameter("filters.N.width", None, "rad/s", 0.0, True, 1e9,
                  "width of a notch filter, > 0..1e9 [rad/s]"),
        Parameter("filters.N.depth", None, "dB", -300.0, False, None,
                  "depth of a notch filter at its frequency, below 0 dB, >= -300 [dB]"),
        Parameter("filters.N.zero", None, "rad/s", 0.0, True, 1e9,
                  "zero frequency w_z of a leadlag filter, > 0..1e9 [rad/s]"),
        Parameter("filters.N.pole", None, "rad/s", 0.0, True, 1e9,
                  "pole frequency w_p of a leadlag filter, > 0..1e9 [rad/s]"),
    )
}


def _positive(record):
    """True for a number that must be > 0 (its record's bound is > 0)."""
    return record.lower == 0.0 and record.strict


def point_problem(at):
    """What is wrong with a filter point ``at``, or None."""
    if at in FILTER_POINTS:
        return None
    return f"{at!r} is not a filter point; use {_alternatives(FILTER_POINTS)}"


def type_problem(kind):
    """What is wrong with a filter type ``kind``, or None."""
    if kind in FILTER_TYPES:
        return None
    return f"{kind!r} is not a filter type; use {_alternatives(FILTER_TYPES)}"


def _alternatives(names):
    return f"{', '.join(names[:-1])} or {names[-1]}"


def depth_problem(values):
    """What is wrong with notch depths [dB] (array), or None: a notch's depth is below 0 dB."""
    values = np.atleast_1d(np.asarray(values, dtype=float))
    bad = ~(values < 0)
    if not bad.any():
        return None
    return f"a notch's depth is below 0 dB, got {float(values[bad][0]):g} dB"


class Filter:
    """One filter of a batch of runs: its point and kind (the same for every run) and its
    numbers per run.

    Parameters
    ----------
    at : str
        Its point, one of :data:`FILTER_POINTS`.
    kind : str
        Its type, one of :data:`FILTER_TYPES`.
    frequency : array_like, optional
        ω0 per run [rad/s], for the kinds that take one.
    **numbers : array_like
        Its other numbers per run, by field (:func:`number_field` of their config names:
        ``damping`` [-], ``width`` [rad/s], ``depth_db`` [dB], ...; the records of
        :data:`FILTER_PARAMETERS` give their units and bounds).

    Every field of :data:`NUMBERS` is an attribute: a read-only 1-D array, all of one length
    (scalars broadcast); the numbers the kind does not take are NaN whatever is given.
    """

    #: The per-run fields, in order: one per record of :data:`FILTER_PARAMETERS`.
    NUMBERS = tuple(number_field(name) for name in FILTER_PARAMETERS)

    def __init__(self, at, kind, frequency=np.nan, **numbers):
        for problem in (point_problem(at), type_problem(kind)):
            if problem:
                raise ConfigError(f"simulation parameters: filter: {problem}")
        unknown = sorted(set(numbers) - set(self.NUMBERS))
        if unknown:
            raise ConfigError(f"simulation parameters: filter: no number {unknown[0]!r}; "
                              f"the numbers are {', '.join(self.NUMBERS)}")
        self.at, self.kind = at, kind
        numbers = {"frequency": frequency, **numbers}
        try:
            arrays = np.broadcast_arrays(*(np.atleast_1d(np.asarray(numbers.get(name, np.nan),
                                                                    dtype=float))
                                           for name in self.NUMBERS))
        except ValueError:
            raise ConfigError("simulation parameters: filter: its numbers' shapes do not "
                              "broadcast") from None
        used = {number_field(name): name for name in FILTER_NUMBERS[kind]}
        for field, array in zip(self.NUMBERS, arrays, strict=True):
            if array.ndim != 1:
                raise ConfigError(f"simulation parameters: filter {field}: must be 1-D, got "
                                  f"{array.shape}")
            array = np.array(array) if field in used else np.full(array.shape, np.nan)
            if field in used:
                positive = _positive(FILTER_PARAMETERS[used[field]])
                if not (np.isfinite(array).all() and (not positive or (array > 0).all())):
                    raise ConfigError(f"simulation parameters: a {kind} filter's {field} must "
                                      f"be finite{' and > 0' if positive else ''}")
            array.setflags(write=False)
            setattr(self, field, array)
        if kind == "notch":
            problem = depth_problem(self.depth_db)
            if problem:
                raise ConfigError(f"simulation parameters: filter depth_db: {problem}")

    def __repr__(self):
        numbers = ", ".join(f"{number_field(name)}={getattr(self, number_field(name))!r}"
                            for name in FILTER_NUMBERS[self.kind])
        return f"Filter({self.at!r}, {self.kind!r}, {numbers})"

    def replace(self, **numbers):
        """This filter with the numbers ``numbers`` (by field) replaced."""
        return Filter(self.at, self.kind, **{
            **{name: getattr(self, name) for name in self.NUMBERS}, **numbers})

    @property
    def n_runs(self):
        """Number of runs."""
        return getattr(self, self.NUMBERS[0]).shape[0]

    @property
    def notch_damping(self):
        """ζ = Δω/(2ω0) of a notch [-] (NaN for the other kinds)."""
        return self.width / (2.0 * self.frequency)

    def broadcast(self, n):
        """This filter with every array of length ``n``."""
        return self.replace(**{name: np.broadcast_to(getattr(self, name), (n,))
                               for name in self.NUMBERS})

    def take(self, rows):
        """The runs ``rows`` (a slice, or an array of run indices)."""
        return self.replace(**{name: getattr(self, name)[rows] for name in self.NUMBERS})

    @classmethod
    def stacked(cls, filters):
        """One filter of several runs from filters of the same point and kind (one per run
        group, in order)."""
        first = filters[0]
        return cls(first.at, first.kind, **{
            name: np.concatenate([getattr(f, name) for f in filters]) for name in cls.NUMBERS})
