"""The ``requirements:`` list of a config: units of bounds, conditions, clear errors.

Reference values are unit conversions worked out by hand in each test.
"""

import math

import pytest

from cas_freq.config import load_variant
from cas_freq.config.requirement import METRICS, Requirement, metric_unit, parse_frequency_spec
from cas_freq.core.exceptions import ConfigError


def _config(shipped_raw, write_config, requirements):
    shipped_raw["requirements"] = requirements
    return write_config(shipped_raw)


def _load(shipped_raw, write_config, requirements):
    return load_variant(_config(shipped_raw, write_config, requirements), "base").params


def test_shipped_requirements(shipped_config_path):
    params = load_variant(shipped_config_path, "base").params
    by_id = {r.id: r for r in params.requirements}
    assert by_id["BW-1"].metric == "closed_loop.bandwidth_rad_s"
    assert by_id["BW-1"].min == 300.0 and by_id["BW-1"].severity == "required"
    assert by_id["OS-1"].max == 15.0 and by_id["OS-1"].step == pytest.approx(math.radians(10))
    assert by_id["GM-P"].severity == "advisory" and by_id["PM-P"].min == 45.0


@pytest.mark.parametrize(
    ("metric", "bound", "expected"),
    [
        ("closed_loop.bandwidth_rad_s", "300 rad/s", 300.0),
        ("closed_loop.bandwidth_rad_s", 300, 300.0),  # a bare number is in the figure's unit
        ("closed_loop.bandwidth_rad_s", "2864.79 rpm", 300.0),  # 2864.79 * 2 pi / 60
        ("position_loop.phase_margin_deg", "0.785398 rad", 45.0),  # pi/4 rad
        ("position_loop.gain_margin_db", "6 dB", 6.0),
        ("position_loop.gain_margin_db", "-6dB", -6.0),
        ("step.overshoot_pct", "15 %", 15.0),
        ("step.overshoot_pct", "0.15", 0.15),  # bare: already percent
        ("step.settling_time_s", "30 ms", 0.03),
        ("step.max_current_a", "20000 mA", 20.0),
        ("fit.zeta", 0.6, 0.6),
    ],
)
def test_bounds_in_the_figures_unit(metric, bound, expected):
    conditions = {"step": "10 deg"} if metric.split(".")[0] in ("step", "fit") else {}
    requirement = Requirement(id="R", metric=metric, min=bound, **conditions)
    assert requirement.min == pytest.approx(expected, rel=1e-5)


def test_every_metric_has_a_unit():
    for metric in METRICS:
        metric_unit(metric)  # raises for a key without a known unit


@pytest.mark.parametrize(
    ("requirement", "expect"),
    [
        ({"id": "X", "metric": "closed_loop.bandwith_rad_s", "min": 1},
         "requirements.0.metric: unknown figure 'closed_loop.bandwith_rad_s'"),
        ({"id": "X", "metric": "closed_loop.bandwidth_rad_s", "min": "300 V"},
         "requirements.0.min: '300 V' has dimension"),
        ({"id": "X", "metric": "closed_loop.bandwidth_rad_s", "min": "48 Hz"},
         "Hz is a rate per time, not an angular rate"),
        ({"id": "X", "metric": "closed_loop.bandwidth_rad_s"}, "X: give min, max or both"),
        ({"id": "X", "metric": "step.overshoot_pct", "max": 15}, "needs the test condition 'step'"),
        ({"id": "X", "metric": "closed_loop.bandwidth_rad_s", "min": 1, "step": "10 deg"},
         "'step' does not apply"),
        ({"id": "X", "metric": "step.overshoot_pct", "max": 15, "step": 10},
         "give an output angle with a unit"),
        ({"id": "X", "metric": "sinedwell.bandwidth_rad_s", "min": 1, "amplitude": "10 deg",
          "frequencies": "1:2"}, "MIN:MAX:N"),
        ({"id": "X", "metric": "closed_loop.peak_db", "min": 5, "max": 1}, "min 5 is above max 1"),
        ({"id": "X", "metric": "closed_loop.peak_db", "max": 1, "severity": "must"},
         "requirements.0.severity: must be one of"),
        ({"id": "X", "metric": "closed_loop.peak_db", "max": 1, "limit": 3},
         "requirements.0.limit: unknown key"),
    ],
)
def test_bad_requirements_name_the_key(shipped_raw, write_config, requirement, expect):
    with pytest.raises(ConfigError) as error:
        _load(shipped_raw, write_config, [requirement])
    assert expect in str(error.value)


def test_duplicate_ids(shipped_raw, write_config):
    same = {"id": "A", "metric": "closed_loop.peak_db", "max": 6}
    with pytest.raises(ConfigError, match="ids must be unique, repeated: A"):
        _load(shipped_raw, write_config, [same, same])


def test_passes_and_margin():
    r = Requirement(id="R", metric="closed_loop.bandwidth_rad_s", min=300, max=2000)
    assert r.passes(300.0) and r.passes(2000.0) and not r.passes(299.9)
    assert not r.passes(None) and not r.passes(float("nan"))
    assert r.margin(400.0) == 100.0  # nearer bound: 400 - 300
    assert r.margin(1950.0) == 50.0  # 2000 - 1950
    assert r.margin(250.0) == -50.0 and r.margin(None) is None


def test_frequency_spec():
    assert parse_frequency_spec("10:1000:3") == pytest.approx((10.0, 100.0, 1000.0))
    assert parse_frequency_spec([300, 100]) == (100.0, 300.0)
    for bad in ("0:1:3", "1:2", "a,b", [], [True], "5,-1"):
        with pytest.raises(ValueError, match="MIN:MAX:N"):
            parse_frequency_spec(bad)
