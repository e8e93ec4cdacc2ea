"""Command line: ``cas-freq analyze`` in-process (cas_freq.cli.main) and once as ``python -m``."""

import contextlib
import io
import json
import math
import subprocess
import sys

import pytest
from clirun import SHIPPED_NOTE

from cas_freq.cli import main
from cas_freq.core.figures import FIGURES

LOOP_KEYS = (
    "crossover_rad_s", "phase_margin_deg", "delay_margin_s", "gain_margin_db",
    "phase_crossover_rad_s",
)
POSITION_ONLY_KEYS = (
    "gain_margin_low_db", "phase_crossover_low_rad_s", "sensitivity_peak_db",
    "disk_margin_gain_db", "disk_margin_phase_deg",
)
CLOSED_LOOP_KEYS = ("bandwidth_rad_s", "peak_db", "peak_rad_s", "phase_90_rad_s")


def _reject_constant(name):
    raise ValueError(f"not strict JSON: {name}")


def strict_json(text):
    """json.loads that refuses NaN, Infinity and -Infinity (not JSON, though Python emits them)."""
    return json.loads(text, parse_constant=_reject_constant)


def _exit_code(argv):
    """main(argv)'s exit status, whether returned or raised by argparse as SystemExit."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


def run(argv):
    """(exit status, stdout, stderr) of main(argv); for module-scoped fixtures (no capsys)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = _exit_code(argv)
    return code, out.getvalue(), err.getvalue()


def _ok_json(argv):
    code, out, err = run(argv)
    assert code == 0, err
    assert err == SHIPPED_NOTE  # CONFIG omitted: the one line saying so, nothing else
    return strict_json(out)


# Each analyze call takes ~0.3-1 s: run each configuration once per module.


@pytest.fixture(scope="module")
def base_json():
    return _ok_json(["analyze", "--json"])


@pytest.fixture(scope="module")
def all_variants_json():
    return _ok_json(["analyze", "--all-variants", "--json"])


@pytest.fixture(scope="module")
def pade_json():
    return _ok_json(["analyze", "--delay", "pade:10", "--json"])


# Kp = 200 A/rad (31x the tuned 6.3435 of report Table 2) pushes the gain crossover past the
# phase crossover at ~1.47 krad/s: the closed loop is unstable.
UNSTABLE = ["--set", "position_loop.Kp=200"]


@pytest.fixture(scope="module")
def unstable_json():
    return _ok_json(["analyze", *UNSTABLE, "--json"])


@pytest.fixture(scope="module")
def unstable_text():
    code, out, err = run(["analyze", *UNSTABLE])
    assert code == 0, err
    return out


@pytest.fixture(scope="module")
def base_text():
    code, out, err = run(["analyze"])
    assert code == 0, err
    return out


# --- successful runs ----------------------------------------------------------------------------


def _assert_has_keys(data):
    for key in ("config", "variant", "delay_model", "stable"):
        assert key in data, key
    for key in LOOP_KEYS:
        assert key in data["current_loop"], f"current_loop.{key}"
    for key in LOOP_KEYS + POSITION_ONLY_KEYS:
        assert key in data["position_loop"], f"position_loop.{key}"
    for key in CLOSED_LOOP_KEYS:
        assert key in data["closed_loop"], f"closed_loop.{key}"


def _is_number(value):
    return isinstance(value, float) and math.isfinite(value)


def test_analyze_json_keys(base_json):
    _assert_has_keys(base_json)
    assert base_json["config"] == "qt_cas"
    assert base_json["variant"] == "base"
    assert base_json["delay_model"] == "exact"
    assert base_json["stable"] is True


def test_analyze_json_figures_are_numbers(base_json):
    for key in LOOP_KEYS:
        assert _is_number(base_json["current_loop"][key]), f"current_loop.{key}"
    for key in LOOP_KEYS + POSITION_ONLY_KEYS:
        assert _is_number(base_json["position_loop"][key]), f"position_loop.{key}"
    for key in CLOSED_LOOP_KEYS:
        assert _is_number(base_json["closed_loop"][key]), f"closed_loop.{key}"


@pytest.mark.parametrize("loop", ["current_loop", "position_loop"])
def test_analyze_json_margins_are_consistent(base_json, loop):
    margins = base_json[loop]
    # docs/model.md: delay margin = PM [rad] / crossover; the JSON rounds nothing, so rel 1e-12.
    assert margins["delay_margin_s"] == pytest.approx(
        math.radians(margins["phase_margin_deg"]) / margins["crossover_rad_s"], rel=1e-12
    )
    # A stable loop has positive margins, and its phase crossover lies above the gain crossover.
    assert margins["phase_margin_deg"] > 0
    assert margins["gain_margin_db"] > 0
    assert margins["phase_crossover_rad_s"] > margins["crossover_rad_s"]
    # Disk margins are never larger than the loop-at-a-time ones (Seiler, Packard and Gahinet,
    # "An introduction to disk margins", IEEE CSM 40(5), 2020): a disk perturbation contains the
    # pure gain and pure phase perturbations.
    assert margins["disk_margin_gain_db"] <= margins["gain_margin_db"]
    assert margins["disk_margin_phase_deg"] <= margins["phase_margin_deg"]


def test_analyze_json_position_loop_has_lower_gain_margin(base_json):
    # docs/model.md: the position loop is type 2, so its phase starts at -180 deg and there is a
    # lower gain margin (negative dB) at a phase crossover below the gain crossover.
    position = base_json["position_loop"]
    assert position["gain_margin_low_db"] < 0
    assert position["phase_crossover_low_rad_s"] < position["crossover_rad_s"]


def test_analyze_all_variants_json(all_variants_json, base_json):
    assert isinstance(all_variants_json, list)
    variants = [item["variant"] for item in all_variants_json]
    assert variants == ["base", "fitted", "relaxed", "loaded", "fin_encoder", "sampled"]
    for item in all_variants_json:
        _assert_has_keys(item)
    # The same computation as the single-variant run, so the same numbers.
    assert all_variants_json[0] == base_json
    # Table 4's motor is another plant: the figures differ.
    assert all_variants_json[1]["position_loop"]["crossover_rad_s"] != pytest.approx(
        base_json["position_loop"]["crossover_rad_s"], rel=1e-3
    )


def test_analyze_pade_delay_matches_exact(pade_json, base_json):
    # Padé [10/10] of exp(-x) errs by about (10!)^2 / (20! 21!) x^21 (x = w*tau): at the 1.4 krad/s
    # bandwidth x = 1.4e3 * 0.4e-3 = 0.56 and at the current crossover (8.7 krad/s, 0.06 ms)
    # x = 0.52, so the error is < 1e-20. 0.1 % is a loose bound that still catches a wrong order
    # or a delay left out.
    assert pade_json["delay_model"] == "pade:10"
    _assert_has_keys(pade_json)
    for section, key in [
        ("closed_loop", "bandwidth_rad_s"),
        ("position_loop", "phase_margin_deg"),
        ("current_loop", "phase_margin_deg"),
    ]:
        value = pade_json[section][key]
        assert _is_number(value), f"{section}.{key}"
        assert value == pytest.approx(base_json[section][key], rel=1e-3), f"{section}.{key}"


def test_analyze_text(base_text):
    assert base_text.startswith("qt_cas / base\n")
    assert "closed loop STABLE" in base_text
    assert "UNSTABLE" not in base_text
    assert FIGURES["closed_loop.bandwidth_rad_s"].label in base_text


def test_unstable_loop_json(unstable_json):
    _assert_has_keys(unstable_json)
    assert unstable_json["stable"] is False
    assert unstable_json["overrides"] == ["position_loop.Kp=200"]
    # Closed-loop figures of an unstable loop do not exist: JSON null, not a number.
    for key in CLOSED_LOOP_KEYS:
        assert unstable_json["closed_loop"][key] is None, key
    # The open-loop margins are still reported: they say how far the loop is from stability.
    position = unstable_json["position_loop"]
    for key in LOOP_KEYS:
        assert _is_number(position[key]), f"position_loop.{key}"
    assert position["phase_margin_deg"] < 0


def test_unstable_loop_text(unstable_text):
    assert "closed loop UNSTABLE" in unstable_text
    assert "not reported: the closed loop is not stable" in unstable_text
    assert "phase margin" in unstable_text


def test_version(capsys):
    assert _exit_code(["--version"]) == 0
    assert capsys.readouterr().out.startswith("cas-freq ")


def test_python_dash_m_entry_point(tmp_path, base_json):
    # The one subprocess test: the module entry point (cas_freq/__main__.py) works from any
    # directory and prints the same JSON as main() in-process.
    result = subprocess.run(
        [sys.executable, "-m", "cas_freq", "analyze", "--json"],
        capture_output=True, text=True, cwd=tmp_path, timeout=120, check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stderr == SHIPPED_NOTE
    assert strict_json(result.stdout) == base_json


# --- bad input: exit 2, one line on stderr, no traceback ----------------------------------------

BAD_INPUT = [
    ("set-negative", ["analyze", "--set", "position_loop.Kp=-1"],
     "position_loop.Kp: must be 0 or within 1e-09..1e+09 A/rad, got -1 A/rad"),
    ("set-not-a-number", ["analyze", "--set", "position_loop.Kp=abc"],
     "position_loop.Kp: cannot read 'abc'"),
    ("set-wrong-type", ["analyze", "--set", "motor.R=[1, 2]"],
     "motor.R: expected a number in ohm"),
    ("set-unknown-key", ["analyze", "--set", "motor.Rr=1"], "motor.Rr: unknown key"),
    ("set-no-equals", ["analyze", "--set", "position_loop.Kp"], "expected KEY=VALUE"),
    ("unknown-variant", ["analyze", "--variant", "nope"], "unknown variant 'nope'"),
    ("missing-config", ["analyze", "{tmp}/missing.yaml"],
     "{tmp}/missing.yaml: config file not found"),
    ("bad-yaml", ["analyze", "{tmp}/bad.yaml"], "not valid YAML at line 2, column 9"),
    ("delay-word", ["analyze", "--delay", "foo"], "--delay: expected 'exact' or 'pade:N'"),
    ("delay-order-text", ["analyze", "--delay", "pade:x"], "--delay: expected"),
    ("delay-order-zero", ["analyze", "--delay", "pade:0"], "Padé order must be 1..30, got 0"),
    ("delay-order-huge", ["analyze", "--delay", "pade:99"], "Padé order must be 1..30, got 99"),
    ("pade-study-negative", ["analyze", "--pade-study", "-1"],
     "--pade-study: must be >= 0, got -1"),
    ("pade-study-text", ["analyze", "--pade-study", "x"], "argument --pade-study"),
    ("range-reversed", ["analyze", "--range", "5:1"], "need 0 < MIN < MAX, got '5:1'"),
    ("range-zero", ["analyze", "--range", "0:10"], "need 0 < MIN < MAX"),
    ("range-infinite", ["analyze", "--range", "1:inf"], "need 0 < MIN < MAX"),
    ("range-text", ["analyze", "--range", "abc"], "expected MIN:MAX in rad/s"),
    ("range-three-parts", ["analyze", "--range", "1:2:3"], "expected MIN:MAX"),
    ("unknown-option", ["analyze", "--bogus"], "unrecognized arguments: --bogus"),
    ("unknown-top-option", ["--bogus"], "error:"),
    ("unknown-command", ["analyse"], "invalid choice: 'analyse'"),
    ("no-command", [], "required: command"),
    ("variant-and-all", ["analyze", "--variant", "fitted", "--all-variants"], "not allowed with"),
]


@pytest.mark.parametrize(
    ("argv", "fragment"), [case[1:] for case in BAD_INPUT], ids=[case[0] for case in BAD_INPUT]
)
def test_bad_input_exits_2_with_one_line(capsys, tmp_path, argv, fragment):
    (tmp_path / "bad.yaml").write_text("name: x\nmotor: a: b\ngear: {}\n", encoding="utf-8")
    argv = [arg.replace("{tmp}", str(tmp_path)) for arg in argv]
    fragment = fragment.replace("{tmp}", str(tmp_path))
    assert _exit_code(argv) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "Traceback" not in captured.err
    assert captured.err.endswith("\n")
    assert captured.err.count("\n") == 1, captured.err
    assert captured.err.startswith("cas-freq")
    assert fragment in captured.err


@pytest.mark.parametrize("value", ["(", "1/0 ohm"])
def test_malformed_set_value_exits_2(capsys, value):
    assert _exit_code(["analyze", "--set", f"motor.R={value}"]) == 2
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1
    assert "motor.R" in captured.err
