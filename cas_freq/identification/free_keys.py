"""Which config keys a physical fit frees, from where it starts, and in which coordinate.

A model to fit is written ``[NAME:] KEY[=START],KEY[=START],...`` (the ``--params`` option):
the dotted keys that are free (any numeric key the simulation reads, as a sweep varies it:
:data:`cas_freq.core.parameters.VARIABLE_KEYS`, load and drivetrain keys, the filters' numbers
``filters.<i>.<name>`` and the no-load point included), each starting from the variant's value
or from ``START`` (a number in the key's SI unit or a string with a unit, as ``--set`` takes
it). A key the variant leaves at 0 or absent (``motor.coulomb_friction``, ``gear.stiffness``)
needs a START.

A positive key (every key whose range is >= 0, started above 0) is fitted as its logarithm: a
step of the optimiser is a relative change, the intervals are ratios (they stay positive), and
the identifiability of products and ratios (Km/J) is a linear question. A key that may take
either sign (``load.hinge_stiffness``, ``load.hinge_bias``) is fitted as value / scale, the
scale being the start's magnitude (or 1 in SI for a start of 0).
"""

import dataclasses
import math
import re

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import (
    CASCADE_PARAMETERS,
    LINEAR_PARAMETERS,
    base_values,
    check_key,
    loop_values,
    parameter,
    parse_value,
)

#: How far a fit may move a key from its start: a factor (log keys) or scales (others).
SEARCH_FACTOR = 1e3

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]{0,63}")


@dataclasses.dataclass(frozen=True)
class ModelSpec:
    """One model to fit: a name and its free keys with optional starts.

    Attributes
    ----------
    name : str
        The model's name (``"model 1"`` when the option gives none).
    keys : tuple of str
        Free dotted keys, in the option's order.
    starts : dict
        Key -> start value [SI] where the option gives one; for a key whose unit depends on
        the architecture (a cascade's position gains, a linear output's loads) the text as
        given, read in the config's unit by :func:`free_keys`.
    bounds : dict
        Key -> (lower, upper) of its search [SI] where one is given (a candidates file,
        :mod:`~cas_freq.identification.candidates`); else the key's accepted range within
        :data:`SEARCH_FACTOR` of the start.
    """

    name: str
    keys: tuple
    starts: dict
    bounds: dict = dataclasses.field(default_factory=dict)


def parse_model_spec(text, number=1):
    """Read one ``--params`` option: ``[NAME:] KEY[=START],...``.

    Raises
    ------
    ConfigError
        For an empty list, a repeated or unknown key (listing the accepted ones), a start that
        does not read as a value of the key, or a malformed name.
    """
    option = f"--params {text!r}"
    name, colon, rest = str(text).partition(":")
    if colon and "=" not in name and "." not in name:
        name = name.strip()
        if not _NAME.fullmatch(name):
            raise ConfigError(f"{option}: the model name {name!r} must be a letter or _ followed "
                              "by letters, digits, _ or -")
    else:
        name, rest = f"model {number}", str(text)
    keys, starts = [], {}
    for part in rest.split(","):
        key, equals, value = part.partition("=")
        key = key.strip()
        if not key:
            raise ConfigError(f"{option}: expected KEY[=START],KEY[=START],... e.g. "
                              "motor.Km,motor.J,motor.mu_v")
        try:
            check_key(key)
        except ConfigError as exc:
            raise ConfigError(f"{option}: {exc}") from None
        if key in keys:
            raise ConfigError(f"{option}: {key} is given twice")
        keys.append(key)
        if equals and (key in CASCADE_PARAMETERS or key in LINEAR_PARAMETERS):
            starts[key] = value.strip()  # read in the config's architecture (free_keys)
        elif equals:
            starts[key] = parse_value(key, value.strip())
    return ModelSpec(name=name, keys=tuple(keys), starts=starts)


@dataclasses.dataclass(frozen=True)
class FreeKey:
    """One free key: its start and the coordinate it is fitted in.

    Attributes
    ----------
    key : str
        Dotted config key.
    start : float
        Start value [SI].
    log : bool
        Fitted as ln(value) (else as value / scale).
    scale : float
        Value per unit of the coordinate for a linear key [SI] (1 for a log key).
    lower, upper : float
        Bounds of the coordinate (the key's accepted range within :data:`SEARCH_FACTOR` of
        the start).
    unit : str
        The key's SI unit in the config's architecture (default that of :data:`PARAMETERS`).
    """

    key: str
    start: float
    log: bool
    scale: float
    lower: float
    upper: float
    unit: str = ""

    def __post_init__(self):
        if not self.unit:
            object.__setattr__(self, "unit", parameter(self.key).unit)

    @property
    def short(self):
        """The key's last part (``Km`` of ``motor.Km``)."""
        return self.key.rsplit(".", 1)[-1]

    def coordinate(self, value):
        """The fit coordinate of a value [SI]."""
        return math.log(value) if self.log else value / self.scale

    def value(self, coordinate):
        """The value [SI] of a fit coordinate."""
        return math.exp(coordinate) if self.log else coordinate * self.scale


def _bounds(parameter, start, log, scale):
    """(lower, upper) of the coordinate: the key's range within SEARCH_FACTOR of the start."""
    if log:
        low = math.log(start / SEARCH_FACTOR)
        high = math.log(start * SEARCH_FACTOR)
        floor = max(parameter.lower or 0.0, parameter.smallest or 0.0)
        if floor > 0:
            low = max(low, math.log(floor))
        if parameter.upper is not None:
            high = min(high, math.log(parameter.upper))
        return low, high
    low, high = start - SEARCH_FACTOR * scale, start + SEARCH_FACTOR * scale
    if parameter.lower is not None:
        low = max(low, parameter.lower)
    if parameter.upper is not None:
        high = min(high, parameter.upper)
    return low / scale, high / scale


def _start(key, loop, config):
    """The value [SI] ``key`` has in the run ``loop`` (built from ``config``): the loop's field
    or filter number where one carries it (derived values resolved), else the config's own value
    (the no-load point, a screw's lead); 0 where neither has one."""
    values = loop_values(loop, key, config)
    if values is not None:
        return float(np.asarray(values).ravel()[0])
    if config is None:
        raise ConfigError(f"--params: {key} is carried by no loop field; its start needs the "
                          "config")
    if key.startswith("motor.no_load.") and config.motor.mu_v is not None:
        raise ConfigError(f"--params: {key}: the config gives motor.mu_v directly, so the "
                          "no-load point is not read; free motor.mu_v instead")
    value = base_values(config).get(key)
    return 0.0 if value is None else float(value)


def free_keys(spec, loop, variant="base", config=None):
    """The :class:`FreeKey` of each key of ``spec``, started from ``loop`` (one run's
    :class:`~cas_freq.core.parameters.LoopParameters`, derived values resolved) or the spec's start;
    ``config`` (the validated config of ``loop``), when given, refuses a key its architecture
    does not have.

    Raises
    ------
    ConfigError
        For a key the config's architecture does not have (or the no-load point of a config that
        gives mu_v), or a key that starts at 0 (or absent) where a fit in ratios needs a start
        above 0.
    """
    free = []
    for key in spec.keys:
        if config is not None:  # a key of the config's architecture (no Kd with a velocity loop)
            try:
                check_key(key, config)
            except ConfigError as exc:
                raise ConfigError(f"--params: {exc}") from None
        record = parameter(key, config)
        if key in spec.starts:
            start = spec.starts[key]
            if isinstance(start, str):  # a key whose unit is the architecture's
                try:
                    start = parse_value(key, start, config)
                except ConfigError as exc:
                    raise ConfigError(f"--params: {exc}") from None
            start = float(start)
        else:
            start = _start(key, loop, config)
        nonnegative = record.lower is not None and record.lower >= 0
        if nonnegative and not start > 0:
            where = ("given as the start" if key in spec.starts
                     else f"in variant {variant!r}")
            raise ConfigError(
                f"--params: {key} is {start:g} {record.unit} ({where}); a fit of a key "
                f"that cannot be negative needs a start above 0: give one, e.g. --params "
                f"...,{key}=VALUE (in {record.unit} or with a unit)")
        scale = 1.0 if nonnegative else (abs(start) or 1.0)
        low, high = _bounds(record, start, nonnegative, scale)
        if key in spec.bounds:
            low, high = _given_bounds(key, spec.bounds[key], start, nonnegative, scale,
                                      (low, high))
        free.append(FreeKey(key=key, start=start, log=nonnegative, scale=scale,
                            lower=low, upper=high, unit=record.unit))
    return free


def _given_bounds(key, bounds, start, log, scale, accepted):
    """The coordinate bounds of a search range ``bounds`` [SI] given for ``key``, within the
    ``accepted`` coordinates of the key's range; the start must lie inside."""
    lower, upper = (float(value) for value in bounds)
    if not lower < upper:
        raise ConfigError(f"{key}: bounds: the lower bound {lower:g} must be below the upper "
                          f"{upper:g}")
    if not lower <= start <= upper:
        raise ConfigError(f"{key}: bounds [{lower:g}, {upper:g}]: the start {start:g} lies "
                          "outside them")
    if log and not lower > 0:
        raise ConfigError(f"{key}: bounds [{lower:g}, {upper:g}]: a key that cannot be "
                          "negative is searched in ratios: its lower bound must be above 0")
    low, high = (math.log(lower), math.log(upper)) if log else (lower / scale, upper / scale)
    return max(low, accepted[0]), min(high, accepted[1])


def labels(free):
    """A short label per free key: its last part, or the whole key where two share one."""
    shorts = [item.short for item in free]
    return [item.short if shorts.count(item.short) == 1 else item.key for item in free]


__all__ = ["FreeKey", "ModelSpec", "SEARCH_FACTOR", "free_keys", "labels", "parse_model_spec"]
