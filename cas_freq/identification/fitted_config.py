"""The config file with a fitted variant added, that ``analyze`` and ``report`` accept at once.

The new variant holds everything that makes the fitted model: the starting variant's own
entries (as written in the file), the ``--set`` overrides of the fit, and the fitted keys, each
with its interval as a comment. It is inserted into the config's text and loaded back
(:func:`cas_freq.drive.variant_text.config_with_variant`, every other line kept), so a text
that would not load, or would load other values than the fitted ones, is never written.
"""

import math
from pathlib import Path

import yaml

from cas_freq.config.loader import _flatten, read_config_file
from cas_freq.drive.variant_text import config_with_variant
from cas_freq.parameters import PARAMETERS


def _scalar(value):
    """A YAML scalar's text that reads back as ``value``."""
    text = yaml.safe_dump(value, default_flow_style=True, width=1000).strip()
    return text.removesuffix("...").strip()


def _si(key, value):
    """``'0.0075 N*m/A'``: a fitted value with its SI unit, 6 significant digits."""
    unit = PARAMETERS[key].unit
    return f"{value:.6g}" if unit == "dimensionless" else f"{value:.6g} {unit}"


def _comment(fit, index, labels):
    """The comment of a fitted entry: its interval and verdict."""
    low, high = fit.interval[index]
    verdict = fit.identifiability["fitted"].keys[index].verdict
    where = fit.at_bound[index]
    if where:
        return f"fitted, at its {where} search bound ({verdict})"
    if not (math.isfinite(low) and math.isfinite(high)):
        determined = [c.text for c in fit.identifiability["fitted"].determined
                      if c.exponents[index]]
        only = f"; the data fix {', '.join(determined)}" if determined else ""
        return f"fitted, {verdict} alone{only}"
    return f"fitted, 95 % [{low:.4g}, {high:.4g}] ({verdict})"


def variant_entries(loaded, fit):
    """(key, value text, comment) lines of the fitted variant."""
    from cas_freq.identification.free_keys import labels

    data = read_config_file(loaded.source)
    entries = {}
    if loaded.variant != "base":
        for key, value in _flatten(data["variants"][loaded.variant] or {}).items():
            entries[key] = (_scalar(value), f"variant {loaded.variant}")
    for key, value in loaded.overrides:
        entries[key] = (_scalar(value), "--set")
    names = labels(fit.free)
    for index, (free, value) in enumerate(zip(fit.free, fit.estimate, strict=True)):
        entries.pop(free.key, None)
        entries[free.key] = (_si(free.key, value), _comment(fit, index, names))
    return [(key, text, note) for key, (text, note) in entries.items()]


def fitted_config_text(loaded, fit, name, sources):
    """The config's text with variant ``name`` of the fit added, loaded back and checked.

    Raises
    ------
    ConfigError
        For a name that exists or is not a plain key, or a result that does not load back with
        the fitted values.
    """
    files = ", ".join(Path(source).name for source in sources)
    comment = (f"cas-freq fit of {', '.join(f.key for f in fit.free)} to {files} "
               f"(model {fit.name!r}, from variant {loaded.variant})")
    expected = {free.key: value for free, value in zip(fit.free, fit.estimate, strict=True)}
    return config_with_variant(loaded.source, name, variant_entries(loaded, fit), comment,
                               expected, "the fitted values", tolerance=1e-5)


__all__ = ["fitted_config_text", "variant_entries"]
