"""Unit conversion of config values, re-exported from the bottom module :mod:`cas_freq.units`."""

from cas_freq.units import registry, to_si

__all__ = ["registry", "to_si"]
