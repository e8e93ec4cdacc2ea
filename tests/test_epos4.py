"""EPOS4 parameters (cas_freq.drive.epos4, cas-freq epos4): unit conversions worked out by
hand, the example file, the round trip config -> parameter file -> variant, and the CLI's
refusals.

Reference values: the gains of configs/qt_cas.yaml (ARL-TR-9136 Tables 1-2) converted to the
drive's units by hand below. Tolerances: a drive value is a whole number, so a round trip
returns the SI value to within half a unit of the drive (stated per test); values that are
whole numbers in the drive's unit come back to floating-point noise (1e-12 relative).
"""

import hashlib
import json
import shutil
from pathlib import Path

import pytest
import yaml
from clirun import run_cli

from cas_freq.config import load_all_variants, load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import base_values
from cas_freq.drive import epos4, insert_variant

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "epos4" / "qt_cas_tuned.dcf"
QT_CAS = ROOT / "configs" / "qt_cas.yaml"
DC_SERVO = ROOT / "configs" / "dc_servo.yaml"

# The report's gains in the drive's units, by hand (1 uV = 1e-6 V, 1 uA = 1e-6 A, 1 ms = 1e-3 s):
#   Kp,i 0.6163 V/A         = 0.6163e6 uV/A                          = 616300 uV/A
#   Ki,i 2835.3 V/(A*s)     = 2835.3e6 uV/(A*s) = 2835.3e6 * 1e-3 uV/(A*ms)
#                                                                    = 2835300 uV/(A*ms)
#        (1 uV/(A*ms) = 1e-6 V / 1e-3 (A*s) = 1e-3 V/(A*s), so the number grows by 1000, not
#        1e6, and is NOT 2835.3 uV/(A*ms))
#   Kp   6.3435 A/rad       = 6.3435e6 uA/rad                        = 6343500 uA/rad
#   Ki   70.2619 A/(rad*s)  = 70.2619e6 uA/(rad*s)                   = 70261900 uA/(rad*s)
#   Kd   0.0381 A*s/rad     = 0.0381e6 uA*s/rad                      = 38100 uA*s/rad
#   FFv  0.0096 A*s/rad     = 0.0096e6 uA*s/rad                      = 9600 uA*s/rad
#   FFa  1.2e-4 A*s^2/rad   = 1.2e-4 * 1e6 uA*s^2/rad                = 120 uA*s^2/rad
#   Imax 20 A               = 20 * 1e3 mA                            = 20000 mA
REPORT_GAINS = {
    (0x30A0, 1): 616_300, (0x30A0, 2): 2_835_300,
    (0x30A1, 1): 6_343_500, (0x30A1, 2): 70_261_900, (0x30A1, 3): 38_100,
    (0x30A1, 4): 9_600, (0x30A1, 5): 120, (0x3001, 2): 20_000,
}
# relaxed variant (x 0.6): Kp 3.8061 A/rad = 3806100 uA/rad, Ki 42.1571 = 42157100 uA/(rad*s),
# Kd 0.02286 A*s/rad = 22860 uA*s/rad
RELAXED = {(0x30A1, 1): 3_806_100, (0x30A1, 2): 42_157_100, (0x30A1, 3): 22_860}


def _digest(path):
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _by_address(settings):
    return {(s.obj.index, s.obj.subindex): s for s in settings}


def _dcf(tmp_path, body, name="drive.dcf"):
    path = tmp_path / name
    path.write_text(body, encoding="utf-8")
    return path


def _section(section, value, name="x", extra=""):
    return (f"[{section}]\nParameterName={name}\nObjectType=0x7\nDataType=0x0007\n{extra}"
            f"ParameterValue={value}\n\n")


def _full_dcf(values=None, skip=()):
    """A minimal parameter file of every object of the PID-on-PI (the report's gains by
    default)."""
    values = {**REPORT_GAINS, **(values or {})}
    return "".join(_section(obj.section, values[(obj.index, obj.subindex)], obj.name)
                   for obj in epos4.objects_of(epos4.PID_ON_PI)
                   if (obj.index, obj.subindex) not in skip)


# --------------------------------------------------------------------------- conversions


def test_the_report_gains_in_the_drive_units_as_worked_out_by_hand():
    settings = _by_address(epos4.settings_of(load_variant(QT_CAS, "base").params))
    assert {address: s.value for address, s in settings.items()} == REPORT_GAINS
    assert not any(s.rounded for s in settings.values())
    assert settings[(0x30A0, 2)].obj.unit == "uV/(A*ms)"
    relaxed = _by_address(epos4.settings_of(load_variant(QT_CAS, "relaxed").params))
    assert {a: relaxed[a].value for a in RELAXED} == RELAXED


def test_rounding_to_the_drive_resolution_is_half_up_and_reported():
    # Kd 0.03812345 A*s/rad = 38123.45 uA*s/rad -> 38123 (change -0.45/38123.45 = -1.18e-5);
    # FFa 1.23456e-4 A*s^2/rad = 123.456 uA*s^2/rad -> 123 (-0.456/123.456 = -3.69e-3)
    loaded = load_variant(QT_CAS, "base", (("position_loop.Kd", 0.03812345),
                                           ("position_loop.ff_a", 1.23456e-4)))
    settings = _by_address(epos4.settings_of(loaded.params))
    kd, ffa = settings[(0x30A1, 3)], settings[(0x30A1, 5)]
    assert (kd.value, ffa.value) == (38123, 123)
    assert kd.rounded and ffa.rounded
    assert kd.relative_change == pytest.approx(-0.45 / 38123.45, rel=1e-6)
    assert ffa.relative_change == pytest.approx(-0.456 / 123.456, rel=1e-6)
    table = epos4.settings_table(list(settings.values()), "t")
    assert "38123.45 -> 38123 uA*s/rad" in table and "123.456 -> 123 uA*s^2/rad" in table


def test_import_values_convert_with_pint_to_the_config_si_units():
    values = epos4.import_values(epos4.read_export(EXAMPLE))
    # the hand conversions above, backwards; 1e-12 relative: float noise of the unit factors
    expected = {"current_loop.Kp": 0.6163, "current_loop.Ki": 2835.3, "position_loop.Kp": 6.3435,
                "position_loop.Ki": 70.2619, "position_loop.Kd": 0.0381,
                "position_loop.ff_v": 0.0096, "position_loop.ff_a": 1.2e-4,
                "position_loop.i_max": 20.0}
    assert {k: v[1] for k, v in values.items()} == pytest.approx(expected, rel=1e-12)
    assert values["current_loop.Ki"][0] == "2835300 uV/(A*ms)"


# --------------------------------------------------------------------------- the example file


def test_the_example_file_is_labelled_as_made_by_us_and_reads_as_the_report_gains():
    text = EXAMPLE.read_text(encoding="utf-8")
    assert "MADE BY cas_freq's DEVELOPERS" in text and "NOT EXPORTED FROM A REAL DRIVE" in text
    assert "ARL-TR-9136" in text and "Tables 1-2" in text
    export = epos4.read_export(EXAMPLE)
    assert {(r.obj.index, r.obj.subindex): r.value for r in export.values} == REPORT_GAINS
    assert export.absent == ()
    assert export.ignored > 0  # FileInfo, DeviceInfo, records, 3001sub1, 30A2sub1, ...
    assert not any(r.from_default for r in export.values)
    current_limit = next(r for r in export.values if r.obj.key == "position_loop.i_max")
    assert current_limit.value == 20000  # written as 0x4E20
    assert EXAMPLE.read_text(encoding="utf-8").splitlines()[current_limit.line - 1] == \
        "ParameterValue=0x4E20"


@pytest.mark.parametrize("config", [QT_CAS, DC_SERVO], ids=["qt_cas", "dc_servo"])
def test_import_of_the_example_adds_a_variant_that_analyses(tmp_path, config):
    out = tmp_path / "out.yaml"
    before = (_digest(config), _digest(EXAMPLE))
    code, _, err = run_cli(["epos4", "import", str(EXAMPLE), str(config), "--variant",
                            "epos4_tuned", "-o", str(out)])
    assert code == 0, err
    assert (_digest(config), _digest(EXAMPLE)) == before  # inputs never modified
    original, written = config.read_text(), out.read_text()
    # every line of the original is kept, in order (comments included)
    lines = iter(written.splitlines())
    assert all(line in lines for line in original.splitlines())
    loaded = {v.variant: v for v in load_all_variants(out)}
    got = base_values(loaded["epos4_tuned"].params)
    for key, (_, si) in epos4.import_values(epos4.read_export(EXAMPLE)).items():
        assert got[key] == pytest.approx(si, rel=1e-12), key
    code, stdout, err = run_cli(["analyze", str(out), "--variant", "epos4_tuned", "--json"])
    assert code == 0, err
    result = json.loads(stdout)
    if config == QT_CAS:
        # the example holds the base variant's gains (report Tables 1-2): same figures
        code, base_out, _ = run_cli(["analyze", "--json"])
        assert code == 0
        base = json.loads(base_out)
        assert result["closed_loop"]["bandwidth_rad_s"] == pytest.approx(
            base["closed_loop"]["bandwidth_rad_s"], rel=1e-9)


# --------------------------------------------------------------------------- round trip


@pytest.mark.parametrize(("config", "variant", "sets"), [
    (QT_CAS, "base", ()), (QT_CAS, "fitted", ()), (QT_CAS, "relaxed", ()),
    (DC_SERVO, "base", ()),
    (QT_CAS, "base", ("position_loop.Kd=0.03812345", "position_loop.ff_a=1.23456e-4",
                      "current_loop.Ki=2835.3004", "position_loop.i_max=12.3456")),
], ids=["qt_cas-base", "qt_cas-fitted", "qt_cas-relaxed", "dc_servo-base", "rounded"])
def test_round_trip_config_to_file_to_variant(tmp_path, config, variant, sets):
    dcf, out = tmp_path / "gains.dcf", tmp_path / "back.yaml"
    argv = ["epos4", "export", str(config), "--variant", variant, "-o", str(dcf)]
    for text in sets:
        argv += ["--set", text]
    code, table, err = run_cli(argv)
    assert code == 0, err
    assert "0x30A1:03" in table and "Position controller D gain" in table
    code, _, err = run_cli(["epos4", "import", str(dcf), str(config), "--variant", "roundtrip",
                            "-o", str(out)])
    assert code == 0, err
    original = load_variant(config, variant, tuple(tuple(t.split("=")) for t in sets))
    back = base_values(load_variant(out, "roundtrip").params)
    for setting in epos4.settings_of(original.params):
        # back in SI within half a unit of the drive (the rounding), plus float noise
        half_unit = epos4._quantity(0.5, setting.obj.unit).to(setting.si_unit).magnitude
        assert abs(back[setting.obj.key] - setting.si_value) <= half_unit * (1 + 1e-9), \
            setting.obj.key
        if not setting.rounded:
            assert back[setting.obj.key] == pytest.approx(setting.si_value, rel=1e-12)


def test_export_file_reads_back_to_the_same_drive_values(tmp_path):
    settings = epos4.settings_of(load_variant(QT_CAS, "fitted").params)
    path = _dcf(tmp_path, epos4.export_text(settings, "configs/qt_cas.yaml (variant 'fitted')"))
    assert "NOT exported from a drive" in path.read_text()
    export = epos4.read_export(path)
    assert [(r.obj, r.value) for r in export.values] == [(s.obj, s.value) for s in settings]


def test_export_json_and_table(tmp_path):
    code, stdout, err = run_cli(["epos4", "export", "--json"])
    assert code == 0, err
    data = json.loads(stdout)
    assert data["variant"] == "base" and data["output"] is None
    first = data["objects"][0]
    assert (first["object"], first["drive_value"], first["drive_unit"], first["si_value"]) == \
        ("0x30A0:01", 616300, "uV/A", 0.6163)
    assert "§6.2.61" in first["source"]
    code, stdout, _ = run_cli(["epos4", "export", "--all-variants", "--json"])
    names = ["base", *yaml.safe_load(QT_CAS.read_text())["variants"]]
    assert code == 0 and [d["variant"] for d in json.loads(stdout)] == names


# --------------------------------------------------------------------------- refusals (exit 2)


@pytest.mark.parametrize(("body", "words"), [
    ("ParameterValue=616300\n", ["line 1", "before any [section]"]),
    (_full_dcf() + "[30a0sub01]\nParameterValue=1\n", ["[30a0sub01]", "0x30A0:01 again",
                                                       "first as [30A0sub1]"]),
    (_full_dcf() + "[30A0sub1]\nParameterValue=1\n", ["[30A0sub1]", "appears twice"]),
    (_full_dcf({(0x30A1, 3): "0.0381"}), ["[30A1sub3] ParameterValue", "'0.0381'",
                                           "not a whole number", "uA*s/rad"]),
    (_full_dcf({(0x30A1, 1): "-5"}), ["[30A1sub1]", "'-5'", "UNSIGNED32", "0..4294967295"]),
    (_full_dcf({(0x30A1, 1): "$NODEID+1"}), ["[30A1sub1]", "not a whole number"]),
    (_full_dcf(skip={(0x30A1, 3), (0x30A0, 2)}),
     ["missing objects", "0x30A0:02 Current controller I gain ([30A0sub2])",
      "0x30A1:03 Position controller D gain ([30A1sub3])"]),
    (_full_dcf() + _section("30A1sub9", "0xFD040300"), ["[30A1sub9]", "0xFD040300",
                                                         "0xFA040300"]),
    (_full_dcf().replace("DataType=0x0007", "DataType=0x0008", 1),
     ["DataType=0x0008", "0x0007 (UNSIGNED32)"]),
    ("[30A0sub1]\nParameterValue\n", ["line 2", "cannot read"]),
], ids=["no-section", "same-object-twice", "duplicate-section", "decimal-point", "negative",
        "node-id-expression", "missing", "i-gain-unit", "data-type", "no-equals"])
def test_malformed_files_exit_2_naming_line_section_value_and_what_is_accepted(
        tmp_path, body, words):
    path = _dcf(tmp_path, body)
    code, stdout, err = run_cli(["epos4", "import", str(path), "--variant", "x"])
    assert code == 2 and stdout == ""
    assert err.startswith("cas-freq epos4 import: error: ") and err.count("\n") == 1
    assert str(path) in err
    for word in words:
        assert word in err, (word, err)


def test_default_value_is_read_when_there_is_no_parameter_value(tmp_path):
    body = _full_dcf().replace("ParameterValue=120", "DefaultValue=120")
    export = epos4.read_export(_dcf(tmp_path, body))
    ffa = next(r for r in export.values if r.obj.key == "position_loop.ff_a")
    assert ffa.value == 120 and ffa.from_default
    assert [e for e in epos4.variant_entries(export) if "DefaultValue" in e[2]]


def test_the_current_limit_is_optional(tmp_path):
    export = epos4.read_export(_dcf(tmp_path, _full_dcf(skip={(0x3001, 2)})))
    assert [obj.key for obj in export.absent] == ["position_loop.i_max"]


def test_cli_refusals(tmp_path):
    out = tmp_path / "out.yaml"
    code, _, err = run_cli(["epos4", "import", str(EXAMPLE), "--variant", "fitted",
                            "-o", str(out)])
    assert code == 2 and "variant 'fitted' exists" in err and "--force" in err
    assert not out.exists()
    code, _, err = run_cli(["epos4", "import", str(EXAMPLE), "--variant", "bad name"])
    assert code == 2 and "--variant 'bad name'" in err
    code, _, err = run_cli(["epos4", "import", str(tmp_path / "none.dcf"), "--variant", "x"])
    assert code == 2 and "not found" in err
    code, _, err = run_cli(["epos4", "export", "--variant", "nope"])
    assert code == 2 and "unknown variant 'nope'" in err and "'relaxed'" in err
    code, _, err = run_cli(["epos4", "export", "--set", "position_loop.ff_v=-0.01"])
    assert code == 2 and "position_loop.ff_v" in err and "0..4294967295 uA*s/rad" in err
    # errors name the command as typed (issue 24 review: they began "cas-freq epos4:")
    assert err.startswith("cas-freq epos4 export: error: ")
    code, _, err = run_cli(["epos4", "export", "--set", "position_loop.Ki=5000"])
    assert code == 2 and "position_loop.Ki = 5000 A/(rad*s)" in err and "4294.97" in err
    code, _, err = run_cli(["epos4", "export", "--all-variants", "-o", str(tmp_path / "a.dcf")])
    assert code == 2 and "one variant" in err
    # a value the config refuses: a current limit of 0 mA
    path = _dcf(tmp_path, _full_dcf({(0x3001, 2): 0}))
    code, _, err = run_cli(["epos4", "import", str(path), "--variant", "x", "-o", str(out)])
    assert code == 2 and "position_loop.i_max" in err and not out.exists()


def test_force_replaces_a_variant_and_the_input_is_never_written(tmp_path):
    config = tmp_path / "qt.yaml"
    shutil.copy(QT_CAS, config)
    before = _digest(config)
    code, _, err = run_cli(["epos4", "import", str(EXAMPLE), str(config), "--variant", "relaxed",
                            "--force", "-o", str(config)])
    assert code == 2 and "inputs are never modified" in err and _digest(config) == before
    out = tmp_path / "out.yaml"
    code, _, err = run_cli(["epos4", "import", str(EXAMPLE), str(config), "--variant", "relaxed",
                            "--force", "-o", str(out)])
    assert code == 0, err
    data, shipped = yaml.safe_load(out.read_text()), yaml.safe_load(QT_CAS.read_text())
    assert list(data["variants"]) == list(shipped["variants"])  # replaced in place
    assert data["variants"]["relaxed"] == {
        key: text for key, text, _ in epos4.variant_entries(epos4.read_export(EXAMPLE))}
    others = {k: v for k, v in shipped["variants"].items() if k != "relaxed"}
    assert {k: data["variants"][k] for k in others} == others
    assert data["reference"] == shipped["reference"]
    assert "# What ARL-TR-9136 measured on the bench" in out.read_text()


def test_import_json_needs_an_output_and_reports_the_objects(tmp_path):
    code, _, err = run_cli(["epos4", "import", str(EXAMPLE), "--variant", "x", "--json"])
    assert code == 2 and "-o" in err
    out = tmp_path / "o.yaml"
    code, stdout, err = run_cli(["epos4", "import", str(EXAMPLE), "--variant", "x", "--json",
                                 "-o", str(out)])
    assert code == 0, err
    data = json.loads(stdout)
    assert data["variant"] == "x" and data["absent"] == [] and data["ignored_sections"] > 0
    assert data["objects"][1]["drive_value"] == 2835300
    assert data["objects"][1]["si_value"] == pytest.approx(2835.3, rel=1e-12)


# --------------------------------------------------------------------------- variant text


ENTRIES = [("position_loop.Kp", "6343500 uA/rad", "0x30A1:01")]


def test_insert_variant_without_a_variants_section_appends_one():
    text = "name: a  # keep me\nmotor:\n  R: 1 ohm\n\n\n"
    new = insert_variant(text, "v", ENTRIES, "c")
    assert new.startswith("name: a  # keep me\nmotor:\n  R: 1 ohm\n")
    assert yaml.safe_load(new)["variants"] == {"v": {"position_loop.Kp": "6343500 uA/rad"}}


def test_insert_variant_into_an_empty_or_flow_style_variants_section():
    new = insert_variant("name: a\nvariants: {}\nmotor: {}\n", "v", ENTRIES)
    assert yaml.safe_load(new)["variants"] == {"v": {"position_loop.Kp": "6343500 uA/rad"}}
    with pytest.raises(ConfigError, match="flow-style"):
        insert_variant("name: a\nvariants: {w: {motor.R: 1}}\n", "v", ENTRIES)
    with pytest.raises(ConfigError, match="base is the file without a variant"):
        insert_variant("name: a\n", "base", ENTRIES)


def test_insert_variant_with_four_space_indentation_and_a_trailing_comment():
    text = ("variants:\n    w:\n        motor.R: 1\n        # about w\n\n# next section\n"
            "reference: {}\n")
    new = insert_variant(text, "v", ENTRIES)
    assert "    v:\n        position_loop.Kp: 6343500 uA/rad" in new
    assert new.index("# about w") < new.index("    v:") < new.index("# next section")
    assert list(yaml.safe_load(new)["variants"]) == ["w", "v"]


# --------------------------------------------------------------------------- any input


def test_any_text_is_read_or_refused_with_a_config_error(tmp_path):
    """Whatever the file holds, the reader returns or raises ConfigError (exit 2), never
    another exception: random INI-ish text built from the pieces of a parameter file."""
    hypothesis = pytest.importorskip("hypothesis")
    from hypothesis import strategies as st

    pieces = st.sampled_from([
        "[30A0sub1]", "[30a1sub03]", "[30A1sub9]", "[3001sub2]", "[FileInfo]", "[", "]", "=",
        "ParameterValue=", "DefaultValue=", "DataType=0x0007", "DataType=", "0x", "616300",
        "-1", "4294967296", "0xFA040300", "$NODEID+1", ";c", "#c", " ", "\t", "\n", "\r\n",
        "é", "\x00", "1.5", "ParameterValue=0x4E20", "DataType=0x0004",
    ])
    path = tmp_path / "fuzz.dcf"

    @hypothesis.settings(max_examples=300, deadline=None, database=None,
                         suppress_health_check=list(hypothesis.HealthCheck))
    @hypothesis.given(st.lists(pieces, max_size=40))
    def check(parts):
        path.write_text("".join(parts), encoding="utf-8", errors="surrogatepass")
        try:
            epos4.read_export(path)
        except ConfigError:
            pass

    check()


# --------------------------------------------------------------------------- a cascade (issue 25)

AXIS = ROOT / "configs" / "cascade_axis.yaml"
# configs/cascade_axis.yaml in the drive's units, by hand (1 uA = 1e-6 A, 1 uV = 1e-6 V):
#   velocity Kp 1.3 A*s/rad = 1.3e6 uA*s/rad = 1300000; Ki 15 A/rad = 15e6 uA/rad = 15000000
#   current Kp 4 V/A = 4000000 uV/A; Ki 2000 V/(A*s) = 2000e6 uV/(A*s) * 1e-3 = 2000000
#   uV/(A*ms); velocity_loop.i_max 10 A = 10000 mA
AXIS_GAINS = {(0x30A0, 1): 4_000_000, (0x30A0, 2): 2_000_000, (0x30A2, 1): 1_300_000,
              (0x30A2, 2): 15_000_000, (0x3001, 2): 10_000}


def test_a_cascade_maps_its_velocity_controller_to_object_0x30A2():
    params = load_variant(AXIS, "base").params
    settings = epos4.settings_of(params)
    assert {(s.obj.index, s.obj.subindex): s.value for s in settings} == AXIS_GAINS
    keys = {(s.obj.index, s.obj.subindex): s.obj.key for s in settings}
    assert keys[(0x30A2, 1)] == "velocity_loop.Kp" and keys[(0x30A2, 2)] == "velocity_loop.Ki"
    assert keys[(0x3001, 2)] == "velocity_loop.i_max"
    # the PID-on-PI's position objects carry no key of a cascade
    assert not [s for s in settings if s.obj.index == 0x30A1]


def test_a_cascade_round_trips_through_a_parameter_file(tmp_path):
    # settings -> parameter file -> read for a cascade config -> SI values: the velocity gains
    # come back exactly (whole numbers in the drive's units), the 0x30A1 objects are not read
    loaded = load_variant(AXIS, "base", (("velocity_loop.Kp", 0.8), ("velocity_loop.Ki", 12.5)))
    settings = epos4.settings_of(loaded.params)
    path = _dcf(tmp_path, epos4.export_text(settings, "cascade_axis", None,
                                            epos4.not_exported(loaded.params))
                + _section("30A1sub1", 6_343_500))
    export = epos4.read_export(path, epos4.CASCADE)
    values = {key: si for key, (_, si) in epos4.import_values(export).items()}
    assert values == pytest.approx({"current_loop.Kp": 4.0, "current_loop.Ki": 2000.0,
                                    "velocity_loop.Kp": 0.8, "velocity_loop.Ki": 12.5,
                                    "velocity_loop.i_max": 10.0}, rel=1e-12)
    assert export.ignored >= 2  # FileInfo and 30A1sub1
    # a cascade's parameter file lacking the velocity gains is refused, naming them
    with pytest.raises(ConfigError, match=r"0x30A2:01 Velocity controller P gain.*cascade"):
        epos4.read_export(_dcf(tmp_path, _full_dcf(), "pid.dcf"), epos4.CASCADE)


def test_blocks_without_an_epos4_object_are_named_not_dropped(tmp_path):
    lines = epos4.not_exported(load_variant(AXIS, "base").params)
    assert any(line.startswith("no EPOS4 object for filters.0 (notch at the current command): "
                               "not exported") for line in lines)
    assert any(line.startswith("no EPOS4 object for filters.1 (lowpass2 at the velocity "
                               "feedback): not exported") for line in lines)
    assert any("velocity_loop.feedback_filter" in line and "0x30A2:05" in line for line in lines)
    assert any("position loop" in line and "not exported" in line for line in lines)
    assert epos4.not_exported(load_variant(QT_CAS, "base").params) == []
    output = epos4.not_exported(load_variant(
        QT_CAS, "base", (("position_loop.feedback", "output"),)).params)
    assert output and output[0].startswith(
        "no EPOS4 object for position_loop.feedback: output") and "0x30AE" in output[0]
    # the command prints them, and the parameter file says them in its header
    out = tmp_path / "axis.dcf"
    code, text, err = run_cli(["epos4", "export", str(AXIS), "-o", str(out)])
    assert code == 0, err
    assert "no EPOS4 object for filters.0 (notch at the current command): not exported" in text
    assert "1300000 uA*s/rad" in text and "15000000 uA/rad" in text
    assert "; no EPOS4 object for filters.0" in out.read_text()
    code, text, err = run_cli(["epos4", "export", str(AXIS), "--json"])
    assert code == 0, err
    assert len(json.loads(text)["not_exported"]) == len(lines)


def test_import_into_a_cascade_config_writes_velocity_gains(tmp_path):
    dcf = tmp_path / "axis.dcf"
    code, _, err = run_cli(["epos4", "export", str(AXIS), "--set", "velocity_loop.Kp=0.9",
                            "-o", str(dcf)])
    assert code == 0, err
    out = tmp_path / "axis.yaml"
    code, _, err = run_cli(["epos4", "import", str(dcf), str(AXIS), "--variant", "drive",
                            "-o", str(out)])
    assert code == 0, err
    variant = yaml.safe_load(out.read_text())["variants"]["drive"]
    assert variant["velocity_loop.Kp"] == "900000 uA*s/rad"
    assert load_variant(out, "drive").params.velocity_loop.Kp == pytest.approx(0.9, rel=1e-12)
