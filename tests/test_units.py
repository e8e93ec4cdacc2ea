"""Unit strings of the config files -> SI floats (cas_freq.core.units.to_si)."""

import math

import pytest

from cas_freq.core.units import to_si

# Tolerance of the unit conversions below: pint multiplies by conversion factors in floating
# point (0.071 mH comes back as 7.099999999999999e-05), so exact equality is not expected, but
# anything beyond a few ulps would be a wrong factor. rel 1e-12 separates the two.
CONVERSION_RTOL = 1e-12


@pytest.mark.parametrize(
    ("value", "unit"),
    [(0.361, "ohm"), (20, "dimensionless"), (7.19e-7, "kg*m^2"), (0, "s"), (-3.5, "A*s/rad")],
)
def test_numbers_pass_through_as_si(value, unit):
    # A plain number is already in the field's SI unit (module docstring): returned unchanged.
    result = to_si(value, unit)
    assert type(result) is float
    assert result == value


@pytest.mark.parametrize(
    ("text", "unit", "expected"),
    [
        # Report Table 3: L = 7.1e-5 H, written as 0.071 mH in configs/qt_cas.yaml.
        ("0.071 mH", "H", 7.1e-5),
        # Report Table 3 n0 = 16,300 read as rpm (docs/model.md erratum): 1 rpm = 2*pi/60 rad/s.
        ("16300 rpm", "rad/s", 16300 * 2 * math.pi / 60),
        # Catalog inertia 5.54 g*cm^2 = 5.54 * 1e-3 kg * 1e-4 m^2 = 5.54e-7 kg*m^2 (Table 3).
        ("5.54 g*cm^2", "kg*m^2", 5.54e-7),
        # Position-loop delay of report §4: 0.4 ms.
        ("0.4 ms", "s", 4e-4),
        # Current-loop delay of report §4: 0.06 ms.
        ("0.06 ms", "s", 6e-5),
        # Degrees to radians: 10 deg = 10*pi/180 rad (the report's 10 deg step).
        ("10 deg", "rad", math.radians(10)),
        # An angle in other units than rad: the same power of an angle (module docstring).
        ("2 N*m/deg", "N*m/rad", 2 * 180 / math.pi),
        ("1 mV/rpm", "V*s/rad", 1e-3 * 60 / (2 * math.pi)),
        # Surrounding blanks are ignored.
        ("  0.4 ms ", "s", 4e-4),
    ],
)
def test_unit_strings_convert_to_si(text, unit, expected):
    assert to_si(text, unit) == pytest.approx(expected, rel=CONVERSION_RTOL)


def test_wrong_dimension_names_both_dimensions():
    with pytest.raises(ValueError) as info:
        to_si("0.4 m", "s")
    message = str(info.value)
    assert "'0.4 m'" in message
    assert "[length]" in message  # what was given
    assert "[time]" in message  # what the field needs


def test_wrong_power_of_a_unit_is_a_wrong_dimension():
    with pytest.raises(ValueError, match=r"\[time\] \*\* 2"):
        to_si("0.4 ms ms", "s")


@pytest.mark.parametrize("text", ["3 foo", "", "abc ohm"])
def test_unparsable_string_raises_value_error(text):
    with pytest.raises(ValueError, match="cannot read"):
        to_si(text, "s")


@pytest.mark.parametrize("text", ["(", "0.4 ms)", "1/0 s"])
def test_malformed_expression_raises_value_error(text):
    with pytest.raises(ValueError, match="cannot read"):
        to_si(text, "s")


@pytest.mark.parametrize("text", ["nan s", "inf s", "1e400 s"])
def test_non_finite_quantity_string_raises_value_error(text):
    with pytest.raises(ValueError, match="not finite|must be finite|does not start with a number"):
        to_si(text, "s")


@pytest.mark.parametrize(("text", "expected"), [("0.4e-3", 4e-4), ("6e-4", 6e-4)])
def test_bare_number_in_a_string_is_si(text, expected):
    # The code's own comment: a bare number inside a string is taken as SI, like a number.
    assert to_si(text, "s") == pytest.approx(expected, rel=CONVERSION_RTOL)


def test_bare_number_string_for_dimensionless_field():
    # The same string is fine where the field itself is dimensionless (gear ratio).
    assert to_si("20", "dimensionless") == 20.0


@pytest.mark.parametrize(
    ("value", "type_name"),
    [([1.0], "list"), (True, "bool"), (False, "bool"), (None, "NoneType"), ({"a": 1}, "dict")],
)
def test_non_number_non_string_raises_type_error(value, type_name):
    # bool is an int subclass in Python, but True is never a physical quantity.
    with pytest.raises(TypeError) as info:
        to_si(value, "ohm")
    assert type_name in str(info.value)
    assert "ohm" in str(info.value)


def test_config_layer_reexports_the_one_conversion():
    # cas_freq.config.units is kept for the config layer's callers; it is the same function.
    from cas_freq.config import units as config_units

    assert config_units.to_si is to_si
