"""The keys a tune frees, their bounds, and the unit box the search works in.

``--free KEY,KEY`` names the keys (default: the position loop's Kp, Ki and Kd); ``--bounds
KEY=LO:HI`` sets a key's range (numbers in SI or strings with units, as ``--set`` takes them).
Without bounds a key ranges over a factor :data:`DEFAULT_FACTOR` either side of the variant's
value. A key whose bounds are both above 0 is searched in its logarithm (gains span decades;
a step is a ratio); one whose range includes 0 or negative values, linearly. Every candidate
is a point of the unit box [0, 1]^k mapped to the keys' values.
"""

import dataclasses
import math

import numpy as np

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import (
    check_key,
    is_cascade,
    loop_values,
    parameter,
    parse_value,
    unit_of,
    variant_parameters,
)
from cas_freq.tuning.options import CASCADE_DEFAULT_FREE, DEFAULT_FACTOR, DEFAULT_FREE


@dataclasses.dataclass(frozen=True)
class TuneKey:
    """One free key and its range.

    Attributes
    ----------
    key : str
    start : float
        The variant's value [SI].
    lower, upper : float
        The range [SI].
    log : bool
        Searched in ln(value) (both bounds > 0), else linearly.
    unit : str
        The key's SI unit in the config's architecture (default that of
        :data:`~cas_freq.core.parameters.PARAMETERS`).
    """

    key: str
    start: float
    lower: float
    upper: float
    log: bool
    unit: str = ""

    def __post_init__(self):
        if not self.unit:
            object.__setattr__(self, "unit", unit_of(self.key))

    def value(self, unit):
        """Values [SI] of unit-box coordinates ``unit`` (array in [0, 1])."""
        unit = np.asarray(unit, dtype=float)
        if self.log:
            low, high = math.log(self.lower), math.log(self.upper)
            return np.exp(low + unit * (high - low))
        return self.lower + unit * (self.upper - self.lower)

    def unit_of(self, value):
        """The unit-box coordinate of a value [SI]."""
        if self.log:
            low, high = math.log(self.lower), math.log(self.upper)
            return (math.log(value) - low) / (high - low)
        return (value - self.lower) / (self.upper - self.lower)


def default_free(config):
    """The keys freed without ``--free``: the PID gains, or with a velocity loop the position
    P gain and the velocity PI gains."""
    return CASCADE_DEFAULT_FREE if is_cascade(config) else DEFAULT_FREE


def parse_free(text, config=None):
    """``KEY,KEY`` -> tuple of keys (checked, no repeats; in ``config``'s architecture when
    given)."""
    keys = [part.strip() for part in str(text).split(",")]
    if not text or any(not key for key in keys):
        raise ConfigError(f"--free {text!r}: expected KEY,KEY,... e.g. "
                          f"{','.join(DEFAULT_FREE)}")
    for key in keys:
        check_key(key, config)
        if parameter(key, config).field is None and not key.startswith("filters."):
            raise ConfigError(f"--free {key}: not a parameter of the loops (it only derives "
                              "another); free the key it derives")
    if len(set(keys)) != len(keys):
        raise ConfigError(f"--free {text!r}: a key is given twice")
    return tuple(keys)


def parse_bounds(texts, free, config=None):
    """``KEY=LO:HI`` options -> {key: (lo, hi)} [SI], every key one of ``free`` (its unit that
    of ``config``'s architecture)."""
    bounds = {}
    for text in texts:
        key, sep, rest = str(text).partition("=")
        key = key.strip()
        low, colon, high = rest.partition(":")
        if not sep or not colon:
            raise ConfigError(f"--bounds {text!r}: expected KEY=LO:HI, e.g. "
                              "position_loop.Kp=1:20")
        if key not in free:
            raise ConfigError(f"--bounds {key}: not a free key (free: {', '.join(free)})")
        lo, hi = parse_value(key, low.strip(), config), parse_value(key, high.strip(), config)
        if not lo < hi:
            raise ConfigError(f"--bounds {text!r}: LO must be below HI")
        bounds[key] = (lo, hi)
    return bounds


def tune_keys(params, free, bounds):
    """The :class:`TuneKey` of each free key, started at ``params``' value."""
    loop = variant_parameters(params, {})
    keys = []
    for key in free:
        start = float(loop_values(loop, key, params)[0])
        if key in bounds:
            lower, upper = bounds[key]
        elif start > 0:
            lower, upper = start / DEFAULT_FACTOR, start * DEFAULT_FACTOR
        else:
            raise ConfigError(f"--free {key}: the variant's value is {start:g} "
                              f"{unit_of(key, params)}, so no default range is a factor of it; "
                              f"give --bounds {key}=LO:HI")
        keys.append(TuneKey(key, start, lower, upper, log=lower > 0,
                            unit=unit_of(key, params)))
    return keys


def sobol(count, dimensions, seed):
    """``count`` scrambled Sobol points of [0, 1]^dimensions (reproducible for ``seed``)."""
    from scipy.stats import qmc

    sampler = qmc.Sobol(dimensions, scramble=True, seed=np.random.default_rng(seed))
    power = max(0, math.ceil(math.log2(max(count, 1))))
    return sampler.random_base2(power)[:count]


__all__ = ["DEFAULT_FACTOR", "DEFAULT_FREE", "TuneKey", "default_free", "parse_bounds",
           "parse_free", "sobol", "tune_keys"]
