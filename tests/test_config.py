"""Config layer: the shipped file, variants, --set overrides, and every validation error."""

import math

import pytest

from cas_freq.config import (
    load_all_variants,
    load_variant,
    parse_set_option,
    read_config_file,
    variant_names,
)
from cas_freq.core.exceptions import CasFreqError, ConfigError, ConfigTypeError

# Values given in SI in the report are stored as they are: compare to rel 1e-12 (only the pint
# conversion of the file's unit strings, e.g. 0.071 mH, adds rounding of a few ulps).
RTOL = 1e-12

# Report Table 3, catalog motor (docs/model.md: J in kg*m^2, n0 in rpm).
CATALOG_MOTOR = {"R": 0.361, "L": 7.1e-5, "Km": 0.0105, "Ke": 0.0105, "J": 5.54e-7}
NO_LOAD_SPEED = 16300 * 2 * math.pi / 60  # n0 = 16,300 rpm [rad/s]
NO_LOAD_CURRENT = 0.218  # I0 [A]
# Report Table 4, fitted motor; the rest of the motor stays at Table 3 (docs/model.md "Plant").
FITTED_MOTOR = {"Km": 0.0075, "J": 7.19e-7, "mu_v": 1.2e-6}
# Report Table 1 (gains, V_max) and §4 (delay 0.06 ms).
CURRENT_LOOP = {"Kp": 0.6163, "Ki": 2835.3, "v_max": 30.0, "delay": 6e-5}
# Report Table 2 (gains, feed-forward, I_max) and §4 (delay 0.4 ms).
POSITION_LOOP = {
    "Kp": 6.3435, "Ki": 70.2619, "Kd": 0.0381, "ff_v": 0.0096, "ff_a": 1.2e-4,
    "i_max": 20.0, "delay": 4e-4,
}
GEAR_RATIO = 20.0  # report §3: 20-tooth gear, single-lead worm


@pytest.fixture(scope="module")
def shipped_variants():
    return {loaded.variant: loaded for loaded in load_all_variants()}


# --- the shipped config -------------------------------------------------------------------------


def test_shipped_variants_in_file_order(shipped_raw, shipped_variants):
    # "base" first, then the file's variants in file order.
    names = ["base", "fitted", "relaxed", "loaded", "fin_encoder", "sampled"]
    assert variant_names(shipped_raw) == names
    assert [v.variant for v in load_all_variants()] == names
    assert list(shipped_variants) == names


@pytest.mark.parametrize("variant", ["base", "fitted"])
def test_shipped_common_values_in_si(shipped_variants, variant):
    params = shipped_variants[variant].params
    assert params.name == "qt_cas"
    assert params.motor.R == pytest.approx(CATALOG_MOTOR["R"], rel=RTOL)
    assert params.motor.L == pytest.approx(CATALOG_MOTOR["L"], rel=RTOL)
    assert params.motor.Ke == pytest.approx(CATALOG_MOTOR["Ke"], rel=RTOL)
    assert params.gear.ratio == GEAR_RATIO
    for key, value in CURRENT_LOOP.items():
        assert getattr(params.current_loop, key) == pytest.approx(value, rel=RTOL), key
    for key, value in POSITION_LOOP.items():
        assert getattr(params.position_loop, key) == pytest.approx(value, rel=RTOL), key
    assert params.position_loop.derivative_on == "error"  # as report Fig. 7 draws it
    # Tf is not set in the file: the default Kd/(10 Kp) of docs/model.md = 0.0381/63.435 s.
    assert params.position_loop.Tf is None
    assert params.position_loop.filter_time_constant == pytest.approx(
        POSITION_LOOP["Kd"] / (10 * POSITION_LOOP["Kp"]), rel=RTOL
    )


def test_shipped_base_is_catalog_motor(shipped_variants):
    motor = shipped_variants["base"].params.motor
    assert motor.Km == pytest.approx(CATALOG_MOTOR["Km"], rel=RTOL)
    assert motor.J == pytest.approx(CATALOG_MOTOR["J"], rel=RTOL)
    assert motor.mu_v is None
    assert motor.no_load.speed == pytest.approx(NO_LOAD_SPEED, rel=RTOL)
    assert motor.no_load.current == pytest.approx(NO_LOAD_CURRENT, rel=RTOL)
    # Table 3 prints mu_v = 1.341e-6 (4 significant digits: rel 3.7e-4 at most, so 5e-4).
    assert motor.viscous_friction == pytest.approx(1.341e-6, rel=5e-4)


def test_shipped_fitted_is_table_4_motor(shipped_variants):
    motor = shipped_variants["fitted"].params.motor
    for key, value in FITTED_MOTOR.items():
        assert getattr(motor, key) == pytest.approx(value, rel=RTOL), key
    assert motor.no_load is None  # mu_v replaces the no-load derivation
    assert motor.viscous_friction == pytest.approx(1.2e-6, rel=RTOL)
    # Everything else is the catalog value.
    assert motor.R == CATALOG_MOTOR["R"]
    assert motor.Ke == CATALOG_MOTOR["Ke"]


def test_loaded_variant_records_its_origin(shipped_config_path, shipped_variants):
    loaded = shipped_variants["fitted"]
    assert loaded.source == str(shipped_config_path)
    assert loaded.variant == "fitted"
    assert loaded.overrides == ()


def test_default_path_is_the_shipped_config(shipped_config_path):
    assert load_variant().source == str(shipped_config_path)
    assert load_variant(None, "fitted").params == load_variant(shipped_config_path, "fitted").params


# --- overrides ----------------------------------------------------------------------------------


def test_set_override_number(shipped_config_path):
    loaded = load_variant(shipped_config_path, "base", overrides=[("position_loop.Kp", 5.0)])
    assert loaded.params.position_loop.Kp == 5.0
    assert loaded.overrides == (("position_loop.Kp", 5.0),)
    # The default filter follows the new Kp: Kd/(10*5).
    assert loaded.params.position_loop.filter_time_constant == pytest.approx(0.0381 / 50, rel=RTOL)


def test_set_override_unit_string(shipped_config_path):
    loaded = load_variant(shipped_config_path, overrides=[("current_loop.delay", "0.1 ms")])
    assert loaded.params.current_loop.delay == pytest.approx(1e-4, rel=RTOL)


def test_set_overrides_apply_after_the_variant(shipped_config_path):
    loaded = load_variant(
        shipped_config_path, "fitted", overrides=[("motor.Km", 0.009), ("motor.Km", 0.008)]
    )
    assert loaded.params.motor.Km == 0.008  # last one wins, and wins over the variant's 0.0075
    assert loaded.params.motor.J == pytest.approx(7.19e-7, rel=RTOL)  # rest of the variant kept


def test_overrides_apply_to_every_variant(shipped_config_path):
    loaded = load_all_variants(shipped_config_path, [("position_loop.Ki", 0.0)])
    assert [lv.params.position_loop.Ki for lv in loaded] == [0.0] * 6


def test_setting_mu_v_removes_no_load(shipped_config_path):
    loaded = load_variant(shipped_config_path, "base", overrides=[("motor.mu_v", 1e-6)])
    assert loaded.params.motor.mu_v == 1e-6
    assert loaded.params.motor.no_load is None
    assert loaded.params.motor.viscous_friction == 1e-6


def test_setting_no_load_removes_mu_v(shipped_config_path):
    loaded = load_variant(
        shipped_config_path, "fitted",
        overrides=[("motor.no_load", {"speed": "16300 rpm", "current": 0.218})],
    )
    assert loaded.params.motor.mu_v is None
    assert loaded.params.motor.no_load.speed == pytest.approx(NO_LOAD_SPEED, rel=RTOL)
    # Table 4 Km with the no-load point: mu_v = 0.0075*0.218/w0 (formula of report §6).
    assert loaded.params.motor.viscous_friction == pytest.approx(
        0.0075 * 0.218 / NO_LOAD_SPEED, rel=RTOL
    )


def test_setting_a_no_load_field_removes_mu_v(shipped_config_path):
    # fitted has mu_v and no no_load; setting both no-load fields by dotted key replaces mu_v.
    loaded = load_variant(
        shipped_config_path, "fitted",
        overrides=[("motor.no_load.speed", "1000 rad/s"), ("motor.no_load.current", 0.5)],
    )
    assert loaded.params.motor.mu_v is None
    assert loaded.params.motor.viscous_friction == pytest.approx(0.0075 * 0.5 / 1000, rel=RTOL)


def test_variant_may_set_mu_v_over_no_load(shipped_raw, write_config):
    shipped_raw.pop("load_envelope")  # it names the shipped variants replaced here
    shipped_raw["variants"] = {"lossy": {"motor.mu_v": "2e-6 N*m*s/rad"}}
    loaded = load_variant(write_config(shipped_raw), "lossy")
    assert loaded.params.motor.mu_v == pytest.approx(2e-6, rel=RTOL)
    assert loaded.params.motor.no_load is None


def test_nested_dict_variant_overrides(shipped_raw, write_config):
    shipped_raw.pop("load_envelope")  # it names the shipped variants replaced here
    shipped_raw["variants"] = {
        "heavy": {"motor": {"J": "1 g*cm^2"}, "position_loop": {"Kp": 5, "Tf": "0.5 ms"}},
        "empty": None,
    }
    path = write_config(shipped_raw)
    heavy = load_variant(path, "heavy").params
    assert heavy.motor.J == pytest.approx(1e-7, rel=RTOL)  # 1 g*cm^2 = 1e-3 kg * 1e-4 m^2
    assert heavy.position_loop.Kp == 5.0
    assert heavy.position_loop.filter_time_constant == pytest.approx(5e-4, rel=RTOL)
    assert heavy.motor.Km == CATALOG_MOTOR["Km"]  # sibling keys untouched
    assert heavy.position_loop.Kd == POSITION_LOOP["Kd"]
    # A variant with no overrides is the base.
    assert load_variant(path, "empty").params == load_variant(path, "base").params
    assert variant_names(read_config_file(path)) == ["base", "heavy", "empty"]


def test_nested_no_load_variant_replaces_mu_v(shipped_raw, write_config):
    shipped_raw["motor"].pop("no_load")
    shipped_raw["motor"]["mu_v"] = 1.2e-6
    shipped_raw.pop("load_envelope")  # it names the shipped variants replaced here
    no_load = {"speed": "1000 rad/s", "current": 0.5}
    shipped_raw["variants"] = {"catalog": {"motor": {"no_load": no_load}}}
    motor = load_variant(write_config(shipped_raw), "catalog").params.motor
    assert motor.mu_v is None
    assert motor.no_load.speed == 1000.0


def test_nested_partial_no_load_variant_merges_like_dotted(shipped_raw, write_config):
    shipped_raw.pop("load_envelope")  # it names the shipped variants replaced here
    shipped_raw["variants"] = {
        "nested": {"motor": {"no_load": {"current": 0.3}}},
        "dotted": {"motor.no_load.current": 0.3},
    }
    path = write_config(shipped_raw)
    dotted = load_variant(path, "dotted").params.motor
    assert dotted.no_load.current == 0.3
    assert dotted.no_load.speed == pytest.approx(NO_LOAD_SPEED, rel=RTOL)
    assert load_variant(path, "nested").params.motor == dotted


def test_kd_with_zero_kp_is_fine_when_tf_is_given(shipped_config_path):
    loaded = load_variant(
        shipped_config_path, overrides=[("position_loop.Kp", 0), ("position_loop.Tf", "0.6 ms")]
    )
    assert loaded.params.position_loop.filter_time_constant == pytest.approx(6e-4, rel=RTOL)


def test_no_derivative_means_no_filter(shipped_config_path):
    loaded = load_variant(shipped_config_path, overrides=[("position_loop.Kd", 0)])
    assert loaded.params.position_loop.filter_time_constant == 0.0


def test_derivative_on_measurement_is_accepted(shipped_config_path):
    loaded = load_variant(shipped_config_path, overrides=[("position_loop.derivative_on",
                                                           "measurement")])
    assert loaded.params.position_loop.derivative_on == "measurement"


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("position_loop.Kp=5", ("position_loop.Kp", 5)),
        ("position_loop.Kp=6.3", ("position_loop.Kp", 6.3)),
        ("current_loop.delay=0.1 ms", ("current_loop.delay", "0.1 ms")),
        (" motor.R = 0.4 ", ("motor.R", 0.4)),
        ("position_loop.derivative_on=measurement", ("position_loop.derivative_on",
                                                     "measurement")),
    ],
)
def test_parse_set_option(text, expected):
    assert parse_set_option(text) == expected


def test_set_option_with_exponent_without_dot(shipped_config_path):
    loaded = load_variant(shipped_config_path, overrides=[parse_set_option("motor.mu_v=1e-6")])
    assert loaded.params.motor.mu_v == 1e-6


@pytest.mark.parametrize("text", ["position_loop.Kp", "=5", ""])
def test_parse_set_option_needs_key_and_value(text):
    with pytest.raises(ConfigError, match="expected KEY=VALUE"):
        parse_set_option(text)


# --- the input file is never touched ------------------------------------------------------------


def test_loading_never_modifies_the_file(shipped_config_path):
    before_bytes = shipped_config_path.read_bytes()
    before_mtime = shipped_config_path.stat().st_mtime_ns
    load_variant(
        shipped_config_path, "fitted",
        overrides=[("position_loop.Kp", 5.0),
                   ("motor.no_load", {"speed": "1 rad/s", "current": 0})],
    )
    load_all_variants(shipped_config_path, [("current_loop.delay", "0.1 ms")])
    assert shipped_config_path.read_bytes() == before_bytes
    assert shipped_config_path.stat().st_mtime_ns == before_mtime


def test_loading_never_modifies_a_user_file(shipped_raw, write_config):
    shipped_raw["variants"]["nested"] = {"motor": {"J": 1e-6}}
    path = write_config(shipped_raw)
    before = (path.read_bytes(), path.stat().st_mtime_ns)
    for name in ("base", "fitted", "nested"):
        load_variant(path, name, overrides=[("motor.mu_v", 1e-6), ("gear.ratio", 10)])
    assert (path.read_bytes(), path.stat().st_mtime_ns) == before


# --- YAML is loaded safely ----------------------------------------------------------------------


def test_python_tags_are_rejected_and_never_run(tmp_path, write_config):
    marker = tmp_path / "pwned"
    path = write_config(
        f'name: !!python/object/apply:os.system ["touch {marker}"]\n'
        f'motor: !!python/object/apply:os.system ["echo hi"]\n'
    )
    with pytest.raises(ConfigError, match=r"not valid YAML at line 1.*python/object/apply"):
        load_variant(path)
    assert not marker.exists()


# --- every validation error ---------------------------------------------------------------------


def _set(data, dotted, value):
    *sections, leaf = dotted.split(".")
    for section in sections:
        data = data[section]
    data[leaf] = value


def _delete(data, dotted):
    *sections, leaf = dotted.split(".")
    for section in sections:
        data = data[section]
    del data[leaf]


# (id, change to the shipped raw data, exception type, fragments the message must contain:
#  the dotted key, the offending value and what is accepted).
VALUE_ERRORS = [
    ("unknown-top-key", lambda d: _set(d, "foo", 1), ConfigError,
     ["foo: unknown key", "1"]),
    ("unknown-nested-key", lambda d: _set(d, "motor.Rr", 0.4), ConfigError,
     ["motor.Rr: unknown key", "0.4"]),
    ("unknown-no-load-key", lambda d: _set(d, "motor.no_load.torque", 1), ConfigError,
     ["motor.no_load.torque: unknown key"]),
    ("missing-R", lambda d: _delete(d, "motor.R"), ConfigError,
     ["motor.R: required key is missing"]),
    ("missing-gear-ratio", lambda d: _delete(d, "gear.ratio"), ConfigError,
     ["gear.ratio: required key is missing"]),
    ("missing-section", lambda d: _delete(d, "current_loop"), ConfigError,
     ["current_loop: required key is missing"]),
    ("missing-no-load-current", lambda d: _delete(d, "motor.no_load.current"), ConfigError,
     ["motor.no_load.current: required key is missing"]),
    ("negative-R", lambda d: _set(d, "motor.R", -1), ConfigError,
     ["motor.R: must be >= 1e-06 and <= 1e+06 ohm, got -1 ohm"]),
    ("negative-L-string", lambda d: _set(d, "motor.L", "-0.071 mH"), ConfigError,
     ["motor.L: must be >= 1e-12 and <= 1 H", "'-0.071 mH'"]),
    ("zero-L", lambda d: _set(d, "motor.L", 0), ConfigError,
     ["motor.L: must be >= 1e-12 and <= 1 H, got 0 H"]),
    ("negative-J", lambda d: _set(d, "motor.J", -5.54e-7), ConfigError,
     ["motor.J: must be >= 1e-15 and <= 1000 kg*m^2, got -5.54e-07 kg*m^2"]),
    ("negative-Km", lambda d: _set(d, "motor.Km", -0.0105), ConfigError,
     ["motor.Km: must be >= 1e-09 and <= 1000 N*m/A", "-0.0105"]),
    ("zero-gear-ratio", lambda d: _set(d, "gear.ratio", 0), ConfigError,
     ["gear.ratio: must be >= 0.001 and <= 1e+06 dimensionless", "got 0"]),
    ("negative-current-delay", lambda d: _set(d, "current_loop.delay", -6e-5), ConfigError,
     ["current_loop.delay: must be 0 or within 1e-09..0.1 s, got -6e-05 s"]),
    ("negative-position-delay", lambda d: _set(d, "position_loop.delay", "-0.4 ms"), ConfigError,
     ["position_loop.delay: must be 0 or within 1e-09..0.1 s", "'-0.4 ms'"]),
    ("negative-current-Kp", lambda d: _set(d, "current_loop.Kp", -0.6163), ConfigError,
     ["current_loop.Kp: must be 0 or within 1e-09..1e+09 V/A, got -0.6163 V/A"]),
    ("negative-current-Ki", lambda d: _set(d, "current_loop.Ki", -1), ConfigError,
     ["current_loop.Ki: must be 0 or within 1e-09..1e+09 V/(A*s)", "got -1"]),
    ("negative-position-Kp", lambda d: _set(d, "position_loop.Kp", -6.3435), ConfigError,
     ["position_loop.Kp: must be 0 or within 1e-09..1e+09 A/rad, got -6.3435 A/rad"]),
    ("negative-position-Ki", lambda d: _set(d, "position_loop.Ki", -70), ConfigError,
     ["position_loop.Ki: must be 0 or within 1e-09..1e+09 A/(rad*s)", "got -70"]),
    # The exact example message of STYLE.md "Errors".
    ("negative-Kd", lambda d: _set(d, "position_loop.Kd", -0.1), ConfigError,
     ["position_loop.Kd: must be 0 or within 1e-09..1e+09 A*s/rad, got -0.1 A*s/rad"]),
    ("zero-Tf", lambda d: _set(d, "position_loop.Tf", 0), ConfigError,
     ["position_loop.Tf: must be >= 1e-09 and <= 1 s, got 0 s"]),
    ("zero-v-max", lambda d: _set(d, "current_loop.v_max", 0), ConfigError,
     ["current_loop.v_max: must be >= 1e-06 and <= 1e+06 V, got 0 V"]),
    ("negative-i-max", lambda d: _set(d, "position_loop.i_max", "-20 A"), ConfigError,
     ["position_loop.i_max: must be >= 1e-06 and <= 1e+06 A", "'-20 A'"]),
    ("zero-no-load-speed", lambda d: _set(d, "motor.no_load.speed", "0 rpm"), ConfigError,
     ["motor.no_load.speed: must be >= 0.001 and <= 1e+07 rad/s", "'0 rpm'"]),
    ("negative-no-load-current", lambda d: _set(d, "motor.no_load.current", -0.2), ConfigError,
     ["motor.no_load.current: must be 0 or within 1e-09..1e+06 A, got -0.2 A"]),
    ("wrong-dimension", lambda d: _set(d, "motor.R", "0.4 m"), ConfigError,
     ["motor.R:", "'0.4 m'", "[length]", "ohm"]),
    ("unparsable-unit", lambda d: _set(d, "position_loop.Kp", "6.3 blorps"), ConfigError,
     ["position_loop.Kp:", "cannot read '6.3 blorps'"]),
    ("kd-without-kp-or-tf", lambda d: _set(d, "position_loop.Kp", 0), ConfigError,
     ["position_loop:", "Kd/(10*Kp)", "Kp = 0 and Kd > 0", "set Tf"]),
    ("no-current-gain", lambda d: (_set(d, "current_loop.Kp", 0), _set(d, "current_loop.Ki", 0)),
     ConfigError, ["current_loop:", "Kp and Ki are both 0"]),
    ("no-position-gain", lambda d: [_set(d, f"position_loop.{k}", 0) for k in ("Kp", "Ki", "Kd")],
     ConfigError, ["position_loop:", "Kp, Ki and Kd are all 0"]),
    ("both-mu-v-and-no-load", lambda d: _set(d, "motor.mu_v", 1.341e-6), ConfigError,
     ["motor:", "exactly one of motor.mu_v or motor.no_load", "got both"]),
    ("neither-mu-v-nor-no-load", lambda d: _delete(d, "motor.no_load"), ConfigError,
     ["motor:", "exactly one of motor.mu_v or motor.no_load", "got neither"]),
    ("negative-mu-v", lambda d: (_delete(d, "motor.no_load"), _set(d, "motor.mu_v", -1e-6)),
     ConfigError, ["motor.mu_v: must be 0 or within 1e-15..1000 N*m*s/rad", "got -1e-06"]),
    ("derivative-on", lambda d: _set(d, "position_loop.derivative_on", "output"), ConfigError,
     ["position_loop.derivative_on: must be one of 'error' or 'measurement', got 'output'"]),
    ("empty-name", lambda d: _set(d, "name", ""), ConfigError, ["name:", "''"]),
]

TYPE_ERRORS = [
    ("list-for-R", lambda d: _set(d, "motor.R", [0.361, 0.4]), ConfigTypeError,
     ["motor.R: expected a number in ohm or a string with a unit, got list"]),
    ("bool-for-gear-ratio", lambda d: _set(d, "gear.ratio", True), ConfigTypeError,
     ["gear.ratio: expected a number", "got bool"]),
    ("null-for-Kp", lambda d: _set(d, "position_loop.Kp", None), ConfigTypeError,
     ["position_loop.Kp: expected a number in A/rad", "got NoneType"]),
    ("section-not-a-mapping", lambda d: _set(d, "gear", [20]), ConfigTypeError,
     ["gear: must be a mapping, got [20]"]),
    ("name-not-a-string", lambda d: _set(d, "name", 3), ConfigTypeError,
     ["name: must be a string, got 3"]),
    ("variant-not-a-mapping", lambda d: _set(d, "variants.fitted", 3), ConfigTypeError,
     ["variants.fitted: must be a mapping", "got 3"]),
]


@pytest.mark.parametrize(
    ("change", "kind", "fragments"),
    [case[1:] for case in VALUE_ERRORS + TYPE_ERRORS],
    ids=[case[0] for case in VALUE_ERRORS + TYPE_ERRORS],
)
def test_validation_error(shipped_raw, write_config, change, kind, fragments):
    change(shipped_raw)
    path = write_config(shipped_raw)
    with pytest.raises(kind) as info:
        load_variant(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ")  # the file is named first
    for fragment in fragments:
        assert fragment in message
    assert "\n" not in message
    # The exception types subclass the built-ins (exceptions.py), so callers can catch those.
    assert isinstance(info.value, CasFreqError)
    assert isinstance(info.value, TypeError if kind is ConfigTypeError else ValueError)
    assert type(info.value) is kind


def test_unknown_key_message_lists_the_accepted_keys(shipped_raw, write_config):
    _set(shipped_raw, "motor.Rr", 0.4)
    with pytest.raises(ConfigError) as info:
        load_variant(write_config(shipped_raw))
    for key in ("Km", "Ke", "mu_v", "no_load"):
        assert key in str(info.value)


@pytest.mark.parametrize(
    ("old", "new", "fragments"),
    [
        ("R: 0.361 ohm", "R: .nan", ["motor.R: must be finite, got nan ohm"]),
        ("J: 5.54e-7 kg*m^2", "J: .inf", ["motor.J: must be finite, got inf kg*m^2"]),
        ("delay: 0.4 ms", "delay: -.inf", ["position_loop.delay: must be finite, got -inf s"]),
        ("Kp: 6.3435 A/rad", "Kp: .NaN", ["position_loop.Kp: must be finite, got nan A/rad"]),
        ("R: 0.361 ohm", "R: nan ohm", ["motor.R:", "'nan ohm'", "does not start with a number"]),
    ],
)
def test_non_finite_yaml_values(shipped_config_path, write_config, old, new, fragments):
    text = shipped_config_path.read_text(encoding="utf-8")
    assert text.count(old) == 1
    path = write_config(text.replace(old, new))
    with pytest.raises(ConfigError) as info:
        load_variant(path)
    for fragment in fragments:
        assert fragment in str(info.value)


def test_every_problem_is_listed(shipped_raw, write_config):
    _set(shipped_raw, "motor.R", -1)
    _delete(shipped_raw, "gear.ratio")
    _set(shipped_raw, "motor.L", [1])  # a type error among value errors: still a ConfigError
    with pytest.raises(ConfigError) as info:
        load_variant(write_config(shipped_raw))
    assert not isinstance(info.value, TypeError)
    message = str(info.value)
    for fragment in ("motor.R: must be >= 1e-06 and <= 1e+06 ohm", "gear.ratio: required",
                     "motor.L: expected a number"):
        assert fragment in message


def test_override_error_names_the_override(shipped_config_path):
    with pytest.raises(ConfigError) as info:
        load_variant(shipped_config_path, "fitted", overrides=[("position_loop.Kd", -0.1)])
    message = str(info.value)
    assert "(variant 'fitted') with --set position_loop.Kd=-0.1" in message
    assert "position_loop.Kd: must be 0 or within 1e-09..1e+09 A*s/rad, got -0.1 A*s/rad" in message


def test_override_error_names_the_base_variant_too(shipped_config_path):
    # --set applies to each selected variant; with --all-variants docs/cli.md's backlash
    # override fails in base (no gear stiffness) and the error named no variant, as if the
    # loaded variant docs/cli.md pairs it with were at fault.
    from cas_freq.config import load_all_variants

    with pytest.raises(ConfigError) as info:
        load_all_variants(shipped_config_path, [("gear.backlash", "0.1 deg")])
    assert "(variant 'base') with --set gear.backlash=0.1 deg: gear.backlash:" in str(info.value)


def test_override_unknown_key(shipped_config_path):
    with pytest.raises(ConfigError, match=r"motor\.Rr: unknown key \(value 0\.4\)"):
        load_variant(shipped_config_path, overrides=[("motor.Rr", 0.4)])


@pytest.mark.parametrize(
    ("key", "fragment"),
    [
        ("motor.R.x", "--set: motor.R.x: motor.R is a value, not a section"),
        ("motor..R", "--set: 'motor..R' is not a dotted key"),
    ],
)
def test_override_bad_dotted_key(shipped_config_path, key, fragment):
    with pytest.raises(ConfigError) as info:
        load_variant(shipped_config_path, overrides=[(key, 1)])
    assert fragment in str(info.value)


def test_error_inside_a_variant_names_the_variant(shipped_raw, write_config):
    shipped_raw["variants"]["broken"] = {"motor.R": -1}
    path = write_config(shipped_raw)
    # issue 16: every variant is checked when the file is loaded, whichever one is used
    with pytest.raises(ConfigError, match=r"\(variant 'broken'\): motor\.R: must be >= 1e-06"):
        load_variant(path, "fitted")
    with pytest.raises(ConfigError) as info:
        load_variant(path, "broken")
    assert (f"{path} (variant 'broken'): motor.R: must be >= 1e-06 and <= 1e+06 ohm, got -1 ohm"
            in str(info.value))
    with pytest.raises(ConfigError, match="variant 'broken'"):
        load_all_variants(path)


def test_variants_not_a_mapping(shipped_raw, write_config):
    shipped_raw["variants"] = ["fitted"]
    path = write_config(shipped_raw)
    with pytest.raises(ConfigTypeError, match=r"variants: must be a mapping .*\['fitted'\]"):
        load_variant(path)


def test_unknown_variant(shipped_config_path):
    with pytest.raises(ConfigError) as info:
        load_variant(shipped_config_path, "fited")
    message = str(info.value)
    assert "unknown variant 'fited'" in message
    # what is accepted
    assert "['base', 'fitted', 'relaxed', 'loaded', 'fin_encoder', 'sampled']" in message


def test_bad_yaml_syntax_names_the_line(shipped_config_path, write_config):
    lines = shipped_config_path.read_text(encoding="utf-8").splitlines()
    number = next(i for i, line in enumerate(lines) if line.startswith("  Ki: 2835.3")) + 1
    lines[number - 1] = "  Ki: [2835.3"  # an unclosed flow sequence, found on the next line
    path = write_config("\n".join(lines) + "\n")
    with pytest.raises(ConfigError) as info:
        load_variant(path)
    message = str(info.value)
    assert message.startswith(f"{path}: not valid YAML at line {number + 1}, column ")


def test_bad_yaml_tab_indent_names_the_line(write_config):
    path = write_config("name: x\nmotor:\n\tR: 1\n")
    with pytest.raises(ConfigError, match=r"not valid YAML at line 3, column 1"):
        read_config_file(path)


@pytest.mark.parametrize(
    ("text", "type_name"), [("- name: x\n- motor: {}\n", "list"), ("", "NoneType"), ("3\n", "int")]
)
def test_yaml_that_is_not_a_mapping(write_config, text, type_name):
    path = write_config(text)
    with pytest.raises(ConfigError) as info:
        load_variant(path)
    assert str(info.value) == f"{path}: a config must be a YAML mapping, got {type_name}"


def test_missing_file(tmp_path):
    path = tmp_path / "nope.yaml"
    with pytest.raises(ConfigError) as info:
        load_variant(path)
    assert str(info.value) == f"{path}: config file not found"
    with pytest.raises(ConfigError, match="not found"):
        load_all_variants(path)


def test_directory_instead_of_file(tmp_path):
    with pytest.raises(ConfigError, match="cannot read config file"):
        load_variant(tmp_path)


def test_not_utf8(tmp_path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes("name: caf\xe9\n".encode("latin-1"))
    with pytest.raises(ConfigError, match="cannot read config file"):
        read_config_file(path)
