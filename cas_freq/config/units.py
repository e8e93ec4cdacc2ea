"""Unit conversion of config values, re-exported from the bottom module
:mod:`cas_freq.core.units`."""

from cas_freq.core.units import has_unit, registry, to_si

__all__ = ["has_unit", "registry", "to_si"]
