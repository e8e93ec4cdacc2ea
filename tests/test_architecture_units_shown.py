"""Every unit compare shows or converts is the architecture's own (a cascade's position gain is
in 1/s, not the PID-on-PI's A/rad), and tune's Pareto columns name each key's loop."""

from pathlib import Path

import pytest

from cas_freq.config import load_variant
from cas_freq.core.figures import FIGURES
from cas_freq.report.compare import in_unit, parameter_differences
from cas_freq.tuning.summary import column_label, tune_text

ROOT = Path(__file__).resolve().parents[1]
CASCADE = ROOT / "configs" / "cascade_axis.yaml"


def _row(rows, key):
    return next(row for row in rows if row[0] == key)


@pytest.mark.parametrize("fast", ["80 s^-1", "80 1/s", 80])
def test_compare_shows_a_cascade_position_gain_in_1_per_s(fast):
    # the file writes Kp: 40 s^-1; a variant at 80 (with or without a unit) is 80 of the same
    # unit, never A/rad (base code: DimensionalityError ampere/radian -> 1/second with a
    # unit, "40 A/rad | 80 A/rad" without)
    variants = [load_variant(CASCADE), load_variant(CASCADE,
                                                     overrides=[("position_loop.Kp", fast)])]
    rows, _ = parameter_differences(variants)
    key, meaning, *cells = _row(rows, "position_loop.Kp")
    assert cells == ["40 s^-1", "80 s^-1"]  # the baseline's unit, the first written
    assert "cascade" in meaning
    assert not any("A/rad" in cell for row in rows for cell in row[2:])


def test_compare_across_architectures_shows_each_in_its_own_unit():
    # the QT-CAS's PID-on-PI and the cascade: one row, each cell in its own table's unit
    rows, _ = parameter_differences([load_variant(None), load_variant(CASCADE)])
    cells = _row(rows, "position_loop.Kp")[2:]
    assert cells[0].endswith(" A/rad") and cells[1] == "40 s^-1"
    assert _row(rows, "position_loop.Ki")[3] == "100 s^-2"


def test_equal_numbers_of_different_units_are_a_difference(tmp_path):
    # Kp = 40 A/rad (PID-on-PI) and Kp = 40 1/s (cascade) are not "equal"
    qt = load_variant(None, overrides=[("position_loop.Kp", 40)])
    rows, _ = parameter_differences([qt, load_variant(CASCADE)])
    assert _row(rows, "position_loop.Kp")[2:] == ("40 A/rad", "40 s^-1")


def test_in_unit_converts_with_the_architectures_unit():
    cascade = load_variant(CASCADE).params
    # 40 1/s in 1/min: 40 * 60 (definition of the minute)
    assert in_unit(40.0, "position_loop.Kp", "1/min", cascade) == pytest.approx(2400.0,
                                                                                rel=1e-12)


def _tune_data(keys):
    """The smallest tune_dict-shaped data tune_text reads, one Pareto point."""
    values = {key: float(i + 1) for i, key in enumerate(keys)}
    point = {**values, "closed_loop.bandwidth_rad_s": 100.0,
             "position_loop.phase_margin_deg": 50.0, "step.overshoot_pct": 5.0}
    return {
        "config": "axis", "variant": "base", "candidates": 1, "feasible_candidates": 1,
        "seconds": 1.0, "seed": 0, "held": [], "not_held": [], "feasible": True,
        "objective": {"name": "max-bandwidth", "sense": "max",
                      "figure": "closed_loop.bandwidth_rad_s"},
        "scenarios": {"label": "nominal", "count": 1},
        "before": {"values": values, "requirements": []},
        "tuned": {"values": values, "requirements": [], "stable": True},
        "free": [{"key": key, "lower": 0.5, "upper": 2.0, "unit": "1/s", "scale": "log"}
                 for key in keys],
        "at_bound": dict.fromkeys(keys), "pareto": [point], "best_reachable": {},
    }


def test_tune_pareto_columns_name_each_keys_loop():
    keys = ["position_loop.Kp", "velocity_loop.Kp", "velocity_loop.Ki"]
    text = tune_text(_tune_data(keys))
    heading = FIGURES["closed_loop.bandwidth_rad_s"].heading  # the table's label and unit
    header = next(line for line in text.splitlines() if heading in line)
    assert header.split()[:3] == ["position.Kp", "velocity.Kp", "velocity.Ki"]
    row = text.splitlines()[-1].split()
    assert row[:3] == ["1", "2", "3"]  # each value under its own column
    assert column_label("filters.0.frequency") == "filters.0.frequency"


def test_fit_params_start_and_unit_are_the_cascades():
    # a cascade's Kp in 1/s: the start '80 1/s' is read in it (base code: refused as not
    # A/rad), and the free key says 1/s (base code: A/rad, the PID-on-PI's)
    from cas_freq.core.parameters import variant_parameters
    from cas_freq.identification.free_keys import free_keys, parse_model_spec

    config = load_variant(CASCADE).params
    spec = parse_model_spec("position_loop.Kp=80 1/s,velocity_loop.Kp", 1)
    kp, kv = free_keys(spec, variant_parameters(config, {}), "base", config)
    assert (kp.start, kp.unit) == (80.0, "1/s")
    assert (kv.start, kv.unit) == (1.3, "A*s/rad")  # the file's value, in the file's SI unit


def test_the_profile_feedforward_is_shown_in_the_architectures_units():
    # a cascade's ff_v feeds the velocity command: dimensionless, not A*s/rad
    from types import SimpleNamespace

    from cas_freq.core.parameters import unit_of
    from cas_freq.report.profile import _feedforward_text

    cascade = load_variant(CASCADE).params
    units = (unit_of("position_loop.ff_v", cascade), unit_of("position_loop.ff_a", cascade))
    text = _feedforward_text(SimpleNamespace(ff_v=1.0, ff_a=2e-4, ff_units=units))
    assert "ff_v = 1," in text and "ff_a = 0.0002 A*s^2/rad" in text
    assert "A*s/rad" not in text.replace("A*s^2/rad", "")
