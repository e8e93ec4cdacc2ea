"""The config file with a fitted variant added, that ``analyze`` and ``report`` accept at once.

The new variant holds everything that makes the fitted model: the starting variant's own
entries (as written in the file), the ``--set`` overrides of the fit, and the fitted keys, each
with its interval as a comment. It is inserted into the config's text and loaded back
(:func:`cas_freq.drive.variant_text.config_with_variant`, every other line kept), so a text
that would not load, or would load other values than the fitted ones, is never written.
"""

import math
from pathlib import Path

from cas_freq.drive.variant_text import config_with_variant, si_text
from cas_freq.drive.variant_text import variant_entries as entries_with
from cas_freq.identification.free_keys import labels


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
    names = labels(fit.free)
    changed = {free.key: (si_text(free.key, value, loaded.params), _comment(fit, index, names))
               for index, (free, value) in enumerate(zip(fit.free, fit.estimate, strict=True))}
    return entries_with(loaded, changed)


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
    text, _ = config_with_variant(loaded.source, name, variant_entries(loaded, fit), comment,
                                  expected, "the fitted values", tolerance=1e-5)
    return text


__all__ = ["fitted_config_text", "variant_entries"]
