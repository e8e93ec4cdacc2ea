"""Exceptions raised by cas_freq.

Each is a subclass of the matching built-in, as python-control's are, so callers can catch
``ValueError`` or ``TypeError`` as usual: every error cas_freq raises on purpose is bad input
(a value, a file, an option), so the base :class:`CasFreqError` is a ``ValueError`` and
:class:`ConfigTypeError` is a ``TypeError`` as well. The CLI maps exactly these to exit 2;
anything else is a bug (a traceback, exit 1). Messages name the dotted config key, the value
and what is accepted, e.g. ``position_loop.Kd: must be >= 0, got -0.1 A*s/rad``.
"""


class CasFreqError(ValueError):
    """Base class of every error cas_freq raises on purpose: bad input, a ``ValueError``."""


class ConfigError(CasFreqError, ValueError):
    """A configuration value, key or file is not acceptable."""


class ConfigTypeError(CasFreqError, TypeError):
    """A configuration value has the wrong type (e.g. a list where a number is expected)."""


class ModelError(CasFreqError, ValueError):
    """A model cannot be built from otherwise valid parameters (e.g. an improper controller)."""


#: Most items an error message lists before it says how many more there are.
MAX_LISTED = 10


def listed(items, separator="; ", most=MAX_LISTED):
    """``items`` (strings) joined for an error message, cut after ``most`` with a count:
    ``"a; b; ... and 9,990 more"``, so a file with 10,000 problems gives one short line."""
    items = list(items)
    shown = separator.join(items[:most])
    rest = len(items) - most
    return shown if rest <= 0 else f"{shown}{separator}... and {rest:,} more"
