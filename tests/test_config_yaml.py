"""Config values a user hits by accident (issue 24): YAML 1.1's sexagesimal and octal numbers,
and a bare number where datasheets give another unit than SI."""

import math

import pytest
import yaml

from cas_freq.config import load_variant, parse_set_option, read_config_file
from cas_freq.config.loader import default_config_path
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.tolerances import parse_tolerance


def _shipped_with(old, new):
    """The shipped config's text with the line part ``old`` replaced by ``new`` (once)."""
    text = default_config_path().read_text(encoding="utf-8")
    assert text.count(old) == 1, old
    return text.replace(old, new)


# --- YAML 1.2 scalars: no base-60, no octal ------------------------------------------------------


@pytest.mark.parametrize(("written", "hint"), [("20:1", "write 20"), ("50:1", "write 50"),
                                               ("3:2", "write 1.5")])
def test_a_ratio_a_colon_b_is_refused_with_the_number_to_write(write_config, written, hint):
    # YAML 1.1 (PyYAML's default) reads 20:1 as the base-60 integer 20*60 + 1 = 1201 and 50:1
    # as 3001, silently; a YAML 1.2 reader keeps the string, which no numeric key accepts.
    path = write_config(_shipped_with("ratio: 20 ", f"ratio: {written} "))
    with pytest.raises(ConfigError, match=rf"gear\.ratio: cannot read '{written}': a ratio "
                                          rf"a:b is not a number; {hint}\b"):
        load_variant(path)


def test_a_yaml_1_2_directive_changes_nothing(write_config):
    # "%YAML 1.2" did not help PyYAML: the file is read as YAML 1.2 with or without it.
    path = write_config("%YAML 1.2\n---\n" + _shipped_with("ratio: 20 ", "ratio: 20:1 "))
    with pytest.raises(ConfigError, match=r"gear\.ratio: .*write 20"):
        load_variant(path)


def test_a_leading_zero_is_decimal_never_octal(write_config):
    # YAML 1.1 reads 020 as octal 16 and 010 as 8; YAML 1.2's core schema reads them as the
    # decimal 20 and 10, which is what a user who types a leading zero means.
    text = _shipped_with("ratio: 20 ", "ratio: 020 ")
    text = text.replace("  Kp: 6.3435 A/rad", "  Kp: 010")
    params = load_variant(write_config(text)).params
    assert params.gear.ratio == 20.0
    assert params.position_loop.Kp == 10.0


def test_other_scalars_follow_the_yaml_1_2_core_schema(write_config):
    path = write_config("a: 1e-6\nb: yes\nc: on\nd: 0x1F\ne: 0o17\nf: 2024-01-02\ng: -20:20:5\n"
                        "h: .inf\ni: ~\nj: True\n")
    data = read_config_file(path)
    # 1e-6 is a float in YAML 1.2 (a string in 1.1); yes/on and a date are strings; a grid
    # MIN:MAX:N stays the string the grid parser reads (1.1: the integer -73205)
    assert data == {"a": 1e-6, "b": "yes", "c": "on", "d": 31, "e": 15, "f": "2024-01-02",
                    "g": "-20:20:5", "h": math.inf, "i": None, "j": True}


@pytest.mark.parametrize("tagged", ["!!int 1:30", "!!float 1:30", "!!bool yes"])
def test_an_explicit_tag_needs_the_yaml_1_2_form(write_config, tagged):
    with pytest.raises(ConfigError, match="a tagged value does not convert"):
        read_config_file(write_config(f"a: {tagged}\n"))


def test_set_values_are_read_as_yaml_1_2():
    assert parse_set_option("gear.ratio=20:1") == ("gear.ratio", "20:1")
    assert parse_set_option("position_loop.Kp=010") == ("position_loop.Kp", 10)
    with pytest.raises(ConfigError, match=r"gear\.ratio: cannot read '50:1'.*write 50"):
        load_variant(overrides=[parse_set_option("gear.ratio=50:1")])


# --- a key whose datasheets give another unit than SI needs a unit --------------------------------


@pytest.mark.parametrize("written", ["8520", "'8520'", "8520.0"])
def test_a_bare_no_load_speed_is_refused_with_the_rpm_hint(write_config, written):
    # A bare number would be read as 8520 rad/s, where the datasheet means 8520 rpm (892 rad/s).
    path = write_config(_shipped_with("speed: 16300 rpm", f"speed: {written}"))
    with pytest.raises(ConfigError, match=r"motor\.no_load\.speed: needs a unit, got .*8520.*: "
                                          r"'8520 rpm'\?"):
        load_variant(path)


def test_a_no_load_speed_with_a_unit_is_read_in_that_unit():
    speed = load_variant(overrides=[("motor.no_load.speed", "8520 rpm")]).params.motor.no_load
    assert speed.speed == pytest.approx(8520 * 2 * math.pi / 60, rel=1e-12)  # 1 rpm = 2π/60 rad/s
    with pytest.raises(ConfigError, match=r"'1000 rpm'\?"):
        load_variant(overrides=[parse_set_option("motor.no_load.speed=1000")])


def test_a_bare_tolerance_width_of_the_no_load_speed_is_refused():
    with pytest.raises(ConfigError, match=r"'100 rpm'\?"):
        parse_tolerance("motor.no_load.speed=100")
    assert parse_tolerance("motor.no_load.speed=60 rpm").absolute == pytest.approx(2 * math.pi)


# The same data, and the same errors, from libyaml's parser (what _Loader uses where PyYAML has
# it) and from PyYAML's pure-Python one (what it falls back to): the constructors and resolvers
# are the same Python code on both, so only the scanning and parsing differ.
SNIPPETS = [
    "a: 020\nb: 0o17\nc: 0x1f\nd: yes\ne: .inf\nf: -.Inf\ng: 1e-6\nh: 20:1\ni: ~\nj: True\n",
    "base: &b {x: 1, y: [1, 2.5, null]}\nother:\n  <<: *b\n  y: 3\n",
    "a: !!float 1.5\nb: !!int 0x10\nc: !!str 12\n",
    "key: 1\nother: 2\nkey: 3\n",  # duplicate key
    "a: !!int 1:30\n",  # an explicit tag needs the core form
    "a: [1, 2\n",  # not YAML
    "a: 1\n b: 2\n",  # bad indentation
]


@pytest.mark.skipif(not getattr(yaml, "__with_libyaml__", False), reason="PyYAML without libyaml")
@pytest.mark.parametrize("text", [*SNIPPETS, "shipped"])
def test_libyaml_and_the_pure_python_parser_read_the_same(text, monkeypatch):
    from cas_freq.config import loader

    if text == "shipped":
        text = default_config_path().read_text(encoding="utf-8")

    def outcome():
        try:
            return "data", loader._load_yaml(text, "x.yaml")
        except ConfigError as error:
            return "refused", str(error)
        except yaml.YAMLError as error:  # read_config_file says "not valid YAML at line ..."
            mark = error.problem_mark
            return "not YAML", (mark.line, mark.column)

    assert loader._Loader.__mro__[2] is yaml.CSafeLoader
    with_libyaml = outcome()
    monkeypatch.setattr(loader, "_Loader", loader._core_schema_loader(yaml.SafeLoader))
    pure = outcome()
    assert repr(with_libyaml) == repr(pure)  # repr: nan == nan
