"""Angles in units (issue 24): pint takes radians as dimensionless, so without a rule of its own
``16300 min^-1`` would be read as 16300 rad/min (2π off from rpm), ``Hz`` as ``rad/s`` and
``25000 rad/s`` as 25000 Hz. The rule: the power of an angle must match (cas_freq.core.units)."""

import json
import math

import pytest

from cas_freq.config import load_variant
from cas_freq.core import unit_cache
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import parse_value
from cas_freq.core.units import to_si

RTOL = 1e-12  # a unit factor applied in floating point: a few ulps


@pytest.mark.parametrize(("text", "unit", "expected"), [
    # 1 rpm = 2π rad / 60 s; 1 rev/s = 2π rad/s; 1 deg/s = π/180 rad/s (definitions)
    ("16300 rpm", "rad/s", 16300 * 2 * math.pi / 60),
    ("10 rev/s", "rad/s", 10 * 2 * math.pi),
    ("600 rev/min", "rad/s", 600 * 2 * math.pi / 60),
    ("90 deg/s", "rad/s", math.pi / 2),
    ("300 rad/s", "rad/s", 300.0),
    # Ke per angular rate: 1 mV/rpm = 1e-3 V / (2π/60 rad/s)
    ("1 mV/rpm", "V*s/rad", 1e-3 * 60 / (2 * math.pi)),
    ("0.0105 V/(rad/s)", "V*s/rad", 0.0105),
    # a frequency in frequency units
    ("25 kHz", "Hz", 25e3),
    ("2500 s^-1", "Hz", 2500.0),
])
def test_units_with_the_same_angle_convert(text, unit, expected):
    assert to_si(text, unit) == pytest.approx(expected, rel=RTOL)


@pytest.mark.parametrize(("text", "unit", "hint"), [
    # a bare 1/time on an angular rate: the unit meant, with the number
    ("16300 min^-1", "rad/s", r"min\^-1: rpm\? \('16300 rpm'\)"),
    ("10 Hz", "rad/s", r"Hz: rev/s\? \('10 rev/s'\)"),
    ("10 s^-1", "rad/s", r"s\^-1: rev/s\?"),
    ("2 h^-1", "rad/s", "write rpm, rev/s, deg/s or rad/s"),
    # Ke without its angle
    ("0.0105 V/Hz", "V*s/rad", "V/Hz has no angle where V\\*s/rad has one"),
    ("0.0105 V*s", "V*s/rad", "V\\*s has no angle"),
    # a rate with an angle on a frequency key
    ("25000 rad/s", "Hz", "rad/s is an angular rate, not a frequency"),
    ("1500 rpm", "Hz", "rpm is an angular rate, not a frequency"),
    # other powers of an angle
    ("6.3 A", "A/rad", "A has no angle where A/rad has one"),
    ("10 deg", "dimensionless", "has an angle to the power 1 where dimensionless has it "
                                "to the power 0"),
])
def test_units_with_another_angle_are_refused(text, unit, hint):
    with pytest.raises(ValueError, match=hint):
        to_si(text, unit)


def test_the_rule_is_the_parameter_tables_for_every_key(shipped_raw):
    # One rule, read from each key's declared unit: the speed, Ke and a sample rate alike,
    # named by their dotted key.
    with pytest.raises(ConfigError, match=r"^motor\.no_load\.speed: .*min\^-1: rpm\?"):
        parse_value("motor.no_load.speed", "16300 min^-1")
    with pytest.raises(ConfigError, match=r"^motor\.Ke: .*V/Hz has no angle"):
        parse_value("motor.Ke", "0.066 V/Hz")
    with pytest.raises(ConfigError, match=r"^simulation\.current_loop_rate: .*not a frequency"):
        parse_value("simulation.current_loop_rate", "25000 rad/s")
    with pytest.raises(ConfigError, match=r"motor\.no_load\.speed: .*rpm\?"):
        load_variant(overrides=[("motor.no_load.speed", "16300 min^-1")])


def test_a_factor_stored_under_the_old_rules_is_never_read(tmp_path, monkeypatch):
    # The disk cache of factors bypasses pint: an old cache file holding min^-1 -> rad/s
    # (stored when that conversion was accepted) must not let it through.
    import importlib.metadata

    monkeypatch.setenv(unit_cache.CACHE_ENV, str(tmp_path))
    unit_cache._table.cache_clear()
    try:
        version = importlib.metadata.version("pint")
        (tmp_path / f"unit-factors-pint-{version}.json").write_text(
            json.dumps([["min^-1", "rad/s", 1 / 60]]), encoding="utf-8")
        with pytest.raises(ValueError, match="rpm"):
            to_si("16300 min^-1", "rad/s")
        assert unit_cache.cached_factor("min^-1", "rad/s") is None
    finally:
        unit_cache._table.cache_clear()
