"""Unit conversion of config values, re-exported from the bottom module :mod:`cas_freq.units`."""

from cas_freq.units import has_unit, registry, to_si

__all__ = ["has_unit", "registry", "to_si"]
