"""Conversion of config values with units to SI floats, with pint.

This module sits at the bottom of the package (it imports nothing from cas_freq), so the
parameter table (:mod:`cas_freq.parameters`), the config schema and the CLI share one
conversion.

A config value is either a plain number, taken as already in SI, or a string such as
``"0.071 mH"``, ``"16300 rpm"``, ``"5.54 g*cm^2"`` or ``"0.4 ms"``, parsed by pint and
converted to the SI unit the field expects. Radians are dimensionless in pint, so ``A/rad``
and ``A`` are the same dimension, as they are physically.
"""

import functools
import math
import numbers

import pint


@functools.cache
def registry():
    """The shared pint unit registry (built once, on first use: ~0.1 s)."""
    return pint.UnitRegistry()


def to_si(value, unit):
    """Convert a config value to a float in ``unit``.

    Parameters
    ----------
    value : float or int or str
        A number (already in ``unit``) or a quantity string like ``"0.4 ms"``.
    unit : str
        The SI unit the value is wanted in, as pint spells it (``"s"``, ``"A/rad"``).

    Returns
    -------
    float
        The magnitude in ``unit``.

    Raises
    ------
    TypeError
        If ``value`` is neither a number nor a string.
    ValueError
        If the string does not parse, or its unit has another dimension than ``unit``.
    """
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, str)):
        raise TypeError(
            f"expected a number in {unit} or a string with a unit, got {type(value).__name__}"
        )
    if isinstance(value, numbers.Real):
        return float(value)
    ureg = registry()
    try:
        quantity = ureg.Quantity(value.strip())
    except Exception as exc:  # noqa: BLE001 - pint's parser raises many kinds (TokenError, ...)
        raise ValueError(f"cannot read {value!r} as a quantity ({exc})") from None
    if not isinstance(quantity, ureg.Quantity) or quantity.unitless:
        # a bare number inside a string ("0.4", or YAML's "1e-6"): already SI
        return float(getattr(quantity, "magnitude", quantity))
    target = ureg.Unit(unit)
    if quantity.dimensionality != target.dimensionality:
        raise ValueError(
            f"{value!r} has dimension {quantity.dimensionality}, expected that of {unit} "
            f"({target.dimensionality})"
        )
    magnitude = float(quantity.to(target).magnitude)
    if not math.isfinite(magnitude):
        raise ValueError(f"{value!r} is not finite")
    return magnitude
