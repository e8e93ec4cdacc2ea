"""Tolerances of config keys: a relative (``10%``) or absolute (``0.02 ms``, ``±0.036 ohm``)
half-width around the key's nominal value. The box p_i in [p_i0 - Δ_i, p_i0 + Δ_i] is what the
Monte Carlo draws from and the worst case searches (docs/model.md, "Tolerances and the worst
case"); the ``--tolerance KEY=TOL`` option and the config's ``tolerances:`` read them alike.
"""

import dataclasses
import math
import re

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import check_key, parameter, unit_of
from cas_freq.core.units import to_si

#: A leading "±" or "+/-" of a half-width (the width is symmetric either way).
_PLUS_MINUS = re.compile(r"^\s*(±|\+/-|\+-)\s*")


@dataclasses.dataclass(frozen=True)
class Tolerance:
    """One toleranced key: ``relative`` (fraction) or ``absolute`` [SI]."""

    key: str
    relative: float | None
    absolute: float | None

    def half_width(self, base):
        """Half-width of the band around ``base`` [SI]."""
        return abs(base) * self.relative if self.relative is not None else self.absolute


def parse_tolerance(text, config=None):
    """``KEY=10%`` or ``KEY=0.02 ms`` (or a plain number in SI) → :class:`Tolerance`; an
    absolute width in the key's unit in ``config``'s architecture (a velocity loop changes the
    position gains' units)."""
    key, sep, value = str(text).partition("=")
    key, value = key.strip(), value.strip()
    accepted = (f"--tolerance {text!r}: expected KEY=PERCENT% or KEY=ABSOLUTE (a number in the "
                f"key's SI unit or with a unit), e.g. motor.Km=10% or current_loop.delay=0.02ms")
    if not sep or not key or not value:
        raise ConfigError(accepted)
    check_key(key, config)
    value = _PLUS_MINUS.sub("", value)
    match = re.fullmatch(r"([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*%", value)
    if match:
        relative = float(match.group(1)) / 100.0
        if not (math.isfinite(relative) and relative >= 0):
            raise ConfigError(accepted)
        return Tolerance(key, relative, None)
    # a width, not a value of the key: in the key's unit, but its bound is >= 0, not the key's
    unit = unit_of(key, config)
    try:
        parameter(key, config).check_has_unit(value)
        absolute = to_si(value, unit)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ConfigError(f"--tolerance {key}: cannot read {value!r} as a width in {unit} "
                          f"({exc})") from None
    if not (math.isfinite(absolute) and absolute >= 0):
        raise ConfigError(f"--tolerance {key}: must be >= 0 {unit}, got {value!r}")
    return Tolerance(key, None, absolute)



__all__ = ["Tolerance", "parse_tolerance"]
