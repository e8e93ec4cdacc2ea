"""Unit spellings on every architecture: pint's reciprocal ``1/s``, the motor constant written
as a torque per current, and logarithmic units (dB) combined or read as something else."""

import math
from pathlib import Path

import pytest
from clirun import run_cli

from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import parse_value
from cas_freq.core.units import to_si

RTOL = 1e-12  # a unit factor applied in floating point: a few ulps
CASCADE = Path(__file__).resolve().parents[1] / "configs" / "cascade_axis.yaml"


@pytest.fixture(autouse=True)
def _no_disk_cache(monkeypatch):
    # a factor cached by another run must not decide what these tests see
    from cas_freq.core import unit_cache

    monkeypatch.setenv(unit_cache.CACHE_ENV, "off")
    unit_cache._table.cache_clear()
    yield
    unit_cache._table.cache_clear()


@pytest.mark.parametrize(("text", "unit", "expected"), [
    ("40 1/s", "1/s", 40.0),  # pint's spelling of s^-1
    ("5 1/s^2", "1/s^2", 5.0),
    ("2000 1/(A*s)*V", "V/(A*s)", 2000.0),
    ("3 1 / min", "1/s", 3 / 60),  # 1/min = 1/60 s^-1
])
def test_a_reciprocal_written_with_1_is_read(text, unit, expected):
    assert to_si(text, unit) == pytest.approx(expected, rel=RTOL)


def test_a_cascade_position_gain_in_1_per_s_loads_as_in_s_minus_1():
    # the cascade's own table gives position_loop.Kp in 1/s: '40 1/s' is the file's '40 s^-1'
    base = load_variant(CASCADE)
    spelled = load_variant(CASCADE, overrides=[("position_loop.Kp", "40 1/s")])
    assert spelled.params.position_loop.Kp == base.params.position_loop.Kp == 40.0


def test_several_numbers_are_still_refused():
    with pytest.raises(ValueError, match="read a number, then '3435 A/rad'"):
        to_si("6 3435 A/rad", "A/rad")
    with pytest.raises(ValueError, match="read a number"):
        to_si("6 1 A/rad", "A/rad")  # a 1 not before '/' is a second number


@pytest.mark.parametrize(("key", "text"), [
    # SI: torque constant [N*m/A] = back-EMF constant [V*s/rad] (power balance), so a
    # datasheet's Km in mN*m/A is Ke in mV*s/rad, and the other way round
    ("motor.Ke", "26.4 mN*m/A"),
    ("motor.Km", "26.4 mV*s/rad"),
    ("motor.Km", "26.4 mN*m/A"),
    ("motor.Ke", "26.4 mV*s/rad"),
])
def test_the_motor_constant_is_read_in_either_unit(key, text):
    assert parse_value(key, text) == pytest.approx(0.0264, rel=RTOL)


def test_ke_equal_to_km_gives_one_constant_in_a_config():
    loaded = load_variant(overrides=[("motor.Km", "26.4 mN*m/A"), ("motor.Ke", "26.4 mN*m/A")])
    assert loaded.params.motor.Ke == pytest.approx(loaded.params.motor.Km, rel=RTOL)
    assert loaded.params.motor.Ke == pytest.approx(0.0264, rel=RTOL)


@pytest.mark.parametrize("key", ["motor.Ke", "motor.Km"])
@pytest.mark.parametrize("text", ["0.0264 V*s", "0.0264 V/Hz", "0.0264 V/min^-1", "0.0264 J/A"])
def test_a_motor_constant_without_its_angle_is_refused(key, text):
    # per revolution or per radian? the two readings are 2π apart
    with pytest.raises(ConfigError, match=rf"^{key}: .*has no angle"):
        parse_value(key, text)


def test_rpm_per_volt_style_ke_keeps_its_factor():
    # 1 V/krpm = 1 V / (1000 * 2π/60 rad/s)
    assert parse_value("motor.Ke", "2.76 V/krpm") == pytest.approx(
        2.76 * 60 / (2000 * math.pi), rel=RTOL)


@pytest.mark.parametrize("text", ["-20 dB/s", "-20 dB*s", "-20 dB/Hz", "-20 dB^2", "-20 s/dB"])
def test_a_logarithmic_unit_combined_is_refused(text):
    with pytest.raises(ConfigError, match=r"^filters\.0\.depth: .*dB is a logarithmic unit: it "
                                          "stands alone"):
        parse_value("filters.0.depth", text)


def test_a_logarithmic_unit_is_not_read_as_another_quantity():
    # pint would read 15 dB as the power ratio 10^1.5 = 3162 %, 1 Np as e^2 and so on
    with pytest.raises(ValueError, match="dB is a logarithmic unit, percent is not"):
        to_si("15 dB", "percent")
    with pytest.raises(ValueError, match="logarithmic unit, dimensionless is not"):
        to_si("3 dB", "dimensionless")
    with pytest.raises(ValueError, match="write it in dB"):
        to_si("3 s", "dB")
    assert to_si("-20 dB", "dB") == -20.0
    # 1 Np = 20/ln(10) dB (field quantities): pint's conversion between logarithmic units
    assert to_si("1 Np", "dB") == pytest.approx(20 / math.log(10), rel=1e-12)


def _config_with(tmp_path, old, new):
    text = CASCADE.read_text(encoding="utf-8")
    assert old in text
    path = tmp_path / "axis.yaml"
    path.write_text(text.replace(old, new), encoding="utf-8")
    return path


@pytest.mark.parametrize(("old", "new", "where"), [
    ("depth: -20 dB}", "depth: -20 dB/s}", "filters.0.depth"),
    ("    min: 20 rad/s\n", "    min: 20 rad/s/dB\n", "requirements.0.min"),
])
def test_a_combined_db_is_a_one_line_input_error(tmp_path, old, new, where):
    code, out, err = run_cli(["analyze", str(_config_with(tmp_path, old, new))])
    assert code == 2, err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert f"{where}: " in err and "logarithmic" in err


def test_a_db_bound_on_a_percentage_is_refused(tmp_path):
    requirement = ("  - id: OS-1\n    metric: step.overshoot_pct\n    max: 15 dB\n"
                   "    step: 10 deg\n")
    path = _config_with(tmp_path, "requirements:\n", "requirements:\n" + requirement)
    with pytest.raises(ConfigError, match=r"requirements\.0\.max: .*15 dB.*logarithmic"):
        load_variant(path)
    fixed = _config_with(tmp_path, "requirements:\n",
                         "requirements:\n" + requirement.replace("15 dB", "15 %"))
    assert load_variant(fixed).params.requirements[0].max == 15.0
