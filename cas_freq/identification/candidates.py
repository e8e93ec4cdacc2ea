"""Candidate model structures, each fitted to the same recordings and ranked (``cas-freq fit
--candidates FILE``; docs/identification.md, "Candidates side by side").

A candidates file is YAML (read safely, as a config is)::

    candidates:
      - name: sampled_encoder              # a letter or _, then letters, digits, _ or -
        source: report §3 (EPOS4, ENX 16 EASY encoder)  # what justifies the structure
        set:                               # --set overrides that make the structure
          sampling.current_loop: 25 kHz
          sensors.counts_per_rev: 2048
        free:                              # the keys fitted, each with its start
          position_loop.Kd:
            start: 0.0381 A*s/rad
            bounds: [0.005 A*s/rad, 0.1 A*s/rad]   # the search (optional)
            plausible: [0.0381 A*s/rad, 0.0381 A*s/rad]  # what a datasheet or the report
            evidence: report Table 2                # allows, and where it says so (optional)
        assumed: [sensors.counts_per_rev]  # keys of set: that no document gives (optional)

A candidate is **plausible** when every free key has a ``plausible`` range (what a datasheet,
the report or a measurement allows) and its fitted 95 % interval reaches into it, and no key of
its ``set:`` is ``assumed``; a key without a range, or an assumed one, needs a value no
datasheet or report gives. A candidate with a key that the data cannot
determine is **flagged** (its information criterion already charges the extra parameter).
"""

import dataclasses
import math
import re

from cas_freq.config.loader import read_config_file
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import check_key, parse_value
from cas_freq.identification.free_keys import ModelSpec

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]{0,63}")
_FREE_FIELDS = {"start", "bounds", "plausible", "evidence"}
_FIELDS = {"name", "source", "set", "free", "assumed"}


@dataclasses.dataclass(frozen=True)
class Candidate:
    """One candidate structure.

    Attributes
    ----------
    name : str
        Its name.
    source : str
        What justifies it (a report section, a datasheet).
    overrides : tuple of str
        ``KEY=VALUE`` texts, applied as ``--set`` to the variant before the fit.
    spec : ModelSpec
        Its free keys, starts and search bounds [SI].
    plausible : dict
        Free key -> (lower, upper) [SI] that a datasheet or the report allows.
    evidence : dict
        Free key -> where that range comes from.
    assumed : tuple of str
        ``KEY=VALUE`` texts of the overrides that no datasheet or report gives.
    """

    name: str
    source: str
    overrides: tuple
    spec: ModelSpec
    plausible: dict
    evidence: dict
    assumed: tuple = ()


def _pair(value, key, field, where, config):
    if not (isinstance(value, list) and len(value) == 2):
        raise ConfigError(f"{where}: free.{key}.{field}: expected [LOWER, UPPER], got "
                          f"{value!r}")
    try:
        return tuple(float(parse_value(key, item, config)) for item in value)
    except ConfigError as exc:
        raise ConfigError(f"{where}: free.{key}.{field}: {exc}") from None


def _free(free, where, config):
    if not isinstance(free, dict) or not free:
        raise ConfigError(f"{where}: free: expected a mapping of at least one key to fit "
                          f"(KEY: {{start: VALUE, ...}}), got {free!r}")
    keys, starts, bounds, plausible, evidence = [], {}, {}, {}, {}
    for key, entry in free.items():
        try:
            check_key(key, config)
        except ConfigError as exc:
            raise ConfigError(f"{where}: free: {exc}") from None
        entry = {} if entry is None else entry
        if not isinstance(entry, dict) or set(entry) - _FREE_FIELDS:
            raise ConfigError(f"{where}: free.{key}: expected a mapping with "
                              f"{', '.join(sorted(_FREE_FIELDS))}, got {entry!r}")
        keys.append(key)
        if "start" in entry:
            try:
                starts[key] = float(parse_value(key, entry["start"], config))
            except ConfigError as exc:
                raise ConfigError(f"{where}: free.{key}.start: {exc}") from None
        if "bounds" in entry:
            bounds[key] = _pair(entry["bounds"], key, "bounds", where, config)
        if "plausible" in entry:
            low, high = _pair(entry["plausible"], key, "plausible", where, config)
            if low > high:
                raise ConfigError(f"{where}: free.{key}.plausible: the lower end {low:g} is "
                                  f"above the upper {high:g}")
            plausible[key] = (low, high)
            evidence[key] = str(entry.get("evidence", "")).strip()
    return ModelSpec(name="", keys=tuple(keys), starts=starts, bounds=bounds), plausible, evidence


def read_candidates(path, config=None):
    """The candidates of the YAML file ``path`` (module docstring), checked against the
    validated ``config`` (its architecture's keys).

    Raises
    ------
    ConfigError
        Naming the file, the candidate and the field for a missing or malformed entry, a
        repeated name, an unknown key or a value that does not read as the key's.
    """
    data = read_config_file(path)
    items = data.get("candidates")
    if set(data) != {"candidates"} or not isinstance(items, list) or not items:
        raise ConfigError(f"{path}: expected one top-level key 'candidates:' with a list of "
                          f"candidates (name, source, set, free), got keys {sorted(data)}")
    candidates = []
    for number, item in enumerate(items, 1):
        where = f"{path}: candidate {number}"
        if not isinstance(item, dict):
            raise ConfigError(f"{where}: expected a mapping (name, source, set, free), got "
                              f"{item!r}")
        unknown = set(item) - _FIELDS
        if unknown:
            raise ConfigError(f"{where}: unknown field(s) {sorted(unknown)}; accepted: "
                              f"{', '.join(sorted(_FIELDS))}")
        name = item.get("name")
        if not (isinstance(name, str) and _NAME.fullmatch(name)):
            raise ConfigError(f"{where}: name: must be a letter or _ followed by letters, "
                              f"digits, _ or -, got {name!r}")
        where = f"{path}: candidate {name!r}"
        if name in (c.name for c in candidates):
            raise ConfigError(f"{where}: two candidates are named {name!r}")
        source = item.get("source")
        if not (isinstance(source, str) and source.strip()):
            raise ConfigError(f"{where}: source: say what justifies the structure (a report "
                              f"section, a datasheet), got {source!r}")
        overrides = item.get("set") or {}
        if not isinstance(overrides, dict):
            raise ConfigError(f"{where}: set: expected a mapping KEY: VALUE, got "
                              f"{overrides!r}")
        spec, plausible, evidence = _free(item.get("free"), where, config)
        assumed = item.get("assumed") or []
        if not (isinstance(assumed, list) and set(assumed) <= set(overrides)):
            raise ConfigError(f"{where}: assumed: expected a list of keys of its set: "
                              f"({', '.join(overrides) or 'none'}), got {assumed!r}")
        candidates.append(Candidate(
            name=name, source=source.strip(),
            overrides=tuple(f"{key}={value}" for key, value in overrides.items()),
            spec=dataclasses.replace(spec, name=name), plausible=plausible,
            evidence=evidence,
            assumed=tuple(f"{key}={overrides[key]}" for key in assumed)))
    return candidates


def plausibility(candidate, fit):
    """(verdict, reasons) of a fitted candidate: ``"plausible"`` when every free key's 95 %
    interval reaches into its plausible range, else ``"needs values no datasheet gives"``
    with the keys that do not (and the assumed ones of its ``set:``)."""
    reasons = [f"{text}: set, no datasheet or report gives it" for text in candidate.assumed]
    for index, free in enumerate(fit.free):
        low, high = fit.interval[index]
        estimate = fit.estimate[index]
        allowed = candidate.plausible.get(free.key)
        if allowed is None:
            reasons.append(f"{free.key}: no datasheet or report range given")
            continue
        # an interval the data do not give (None or not finite): the estimate alone
        low = estimate if low is None or not math.isfinite(low) else low
        high = estimate if high is None or not math.isfinite(high) else high
        if high < allowed[0] or low > allowed[1]:
            reasons.append(f"{free.key} = {estimate:.4g} {free.unit}, outside "
                           f"[{allowed[0]:.4g}, {allowed[1]:.4g}] "
                           f"({candidate.evidence.get(free.key) or 'the plausible range'})")
    return ("plausible" if not reasons else "needs values no datasheet gives"), reasons


__all__ = ["Candidate", "plausibility", "read_candidates"]
