"""``cas-freq verify``: exit codes, the table, JSON, JUnit XML, and that it stays light
(no matplotlib, no python-control).

Configs with only frequency-domain requirements keep these tests fast; one module-scoped run of
the shipped config covers the step requirements.
"""

import json
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
from clirun import run_cli

_run = run_cli


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    junit = tmp_path_factory.mktemp("verify") / "junit.xml"
    code, out, err = _run(["verify", "--all-variants", "--json", "--junit", str(junit)])
    return code, json.loads(out), junit


def test_shipped_config_passes(shipped):
    """The shipped variants meet both required requirements (BW-1 linear bandwidth and OS-1
    overshoot of the 10 deg step); exit 0 although advisories are not met."""
    code, data, _ = shipped
    assert code == 0 and data["passed"] is True
    statuses = {(v["variant"], v["id"]): v["status"] for v in data["verdicts"]}
    assert statuses[("base", "BW-1")] == "PASS" and statuses[("base", "OS-1")] == "PASS"
    # base PM 34.7 deg < 45 deg (analyze): an advisory, not a failure
    assert statuses[("base", "PM-P")] == "ADVISORY"
    assert {v["variant"] for v in data["verdicts"]} == {"base", "fitted", "relaxed", "loaded",
                                                         "fin_encoder", "sampled"}


def test_verdicts_are_the_commands_figures(shipped):
    """Each value is the figure ``analyze``/``simulate`` print (same code path, same run)."""
    _, data, _ = shipped
    values = {(v["variant"], v["id"]): v["value"] for v in data["verdicts"]}
    code, out, _ = _run(["analyze", "--variant", "fitted", "--json"])
    analysis = json.loads(out)
    assert values[("fitted", "BW-1")] == analysis["closed_loop"]["bandwidth_rad_s"]
    assert values[("fitted", "PM-P")] == analysis["position_loop"]["phase_margin_deg"]
    code, out, _ = _run(["simulate", "--variant", "fitted", "--step", "10deg", "--json"])
    step = json.loads(out)
    assert values[("fitted", "OS-1")] == step["step"]["overshoot_pct"]
    assert values[("fitted", "BW-2")] == step["fit"]["bandwidth_closed_form_rad_s"]


def test_junit_is_valid_and_complete(shipped):
    _, data, junit = shipped
    root = ET.parse(junit).getroot()
    assert root.tag == "testsuites" and root.get("failures") == "0"
    suites = root.findall("testsuite")
    assert [s.get("name") for s in suites] == ["qt_cas/base", "qt_cas/fitted", "qt_cas/relaxed",
                                                   "qt_cas/loaded", "qt_cas/fin_encoder",
                                                   "qt_cas/sampled"]
    cases = suites[0].findall("testcase")
    assert int(suites[0].get("tests")) == len(cases) == len(data["verdicts"]) // 6
    assert all(case.find("failure") is None for case in cases)
    assert "ADVISORY" in "".join(case.findtext("system-out") for case in cases)


def _failing_config(shipped_raw, write_config):
    shipped_raw["requirements"] = [
        {"id": "BW-9", "metric": "closed_loop.bandwidth_rad_s", "min": "5000 rad/s",
         "source": "test"},
        {"id": "PK", "metric": "closed_loop.peak_db", "max": "6 dB", "severity": "advisory"},
    ]
    return write_config(shipped_raw)


def test_failing_requirement_exits_1_with_junit_failure(shipped_raw, write_config, tmp_path):
    path = _failing_config(shipped_raw, write_config)
    junit = tmp_path / "out" / "j.xml"
    junit.parent.mkdir()
    code, out, err = _run(["verify", str(path), "--junit", str(junit)])
    assert code == 1, err
    assert "FAIL BW-9 (base)" in out and "1385 rad/s violates >= 5000 rad/s" in out
    failure = ET.parse(junit).getroot().find("testsuite/testcase/failure")
    assert failure is not None and "5000" in failure.get("message")


def test_table_columns(shipped_raw, write_config):
    code, out, _ = _run(["verify", str(_failing_config(shipped_raw, write_config))])
    header = out.splitlines()[1].split()
    assert header == ["requirement", "variant", "measured", "bound", "margin", "status"]
    assert "-3615 rad/s" in out  # margin 1385.3 - 5000, to 4 digits
    assert "PASS (advisory)" in out  # peak 4.56 dB <= 6 dB


def test_null_figure_fails(shipped_raw, write_config):
    """The current loop has no lower gain margin (analyze gives null): a requirement on it is a
    failure, never a silent pass."""
    shipped_raw["requirements"] = [
        {"id": "GL", "metric": "current_loop.gain_margin_low_db", "max": "-6 dB"},
    ]
    code, out, _ = _run(["verify", str(write_config(shipped_raw)), "--json"])
    verdict = json.loads(out)["verdicts"][0]
    assert code == 1 and verdict["value"] is None and verdict["status"] == "FAIL"
    assert "has no value" in verdict["message"]


def test_unstable_variant_fails_every_requirement(shipped_raw, write_config):
    """Position Kp x 20 (analyze: unstable). Even a margin that would 'pass' is not trusted."""
    shipped_raw["requirements"] = [
        {"id": "GM", "metric": "current_loop.gain_margin_db", "min": "1 dB"},
    ]
    path = write_config(shipped_raw)
    code, out, _ = _run(["verify", str(path), "--set", "position_loop.Kp=127", "--json"])
    verdict = json.loads(out)["verdicts"][0]
    assert code == 1 and verdict["status"] == "FAIL" and "unstable" in verdict["message"]


@pytest.mark.parametrize(
    ("argv", "expect"),
    [
        (["verify", "--variant", "nope"], "nope"),
        (["verify", "--set", "position_loop.Kp=-1"], "position_loop.Kp"),
    ],
)
def test_bad_input_exits_2(argv, expect):
    code, out, err = _run(argv)
    assert code == 2 and expect in err and "Traceback" not in err


def test_config_without_requirements_exits_2(shipped_raw, write_config):
    shipped_raw.pop("requirements")
    code, _, err = _run(["verify", str(write_config(shipped_raw))])
    assert code == 2 and "no 'requirements:'" in err


def test_bad_requirement_exits_2(shipped_raw, write_config):
    shipped_raw["requirements"] = [{"id": "X", "metric": "closed_loop.bandwidth_rad_s",
                                    "min": "300 V"}]
    code, _, err = _run(["verify", str(write_config(shipped_raw))])
    assert code == 2 and "requirements.0.min" in err


def test_never_imports_matplotlib_or_control(shipped_raw, write_config):
    path = _failing_config(shipped_raw, write_config)
    script = (
        "import sys\nfrom cas_freq.cli import main\n"
        f"code = main(['verify', {str(path)!r}])\n"
        "heavy = sorted(m for m in ('matplotlib', 'control') if m in sys.modules)\n"
        "print('HEAVY', heavy)\nsys.exit(code)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 1, done.stderr
    assert "HEAVY []" in done.stdout


def test_sinedwell_requirement_is_the_sinedwell_figure(shipped_raw, write_config):
    """An opt-in sine-dwell requirement measures what ``cas-freq sinedwell`` prints for the
    same amplitude and grid (feed-forward off in both)."""
    shipped_raw["requirements"] = [
        {"id": "BW-3", "metric": "sinedwell.bandwidth_rad_s", "min": "300 rad/s",
         "amplitude": "10 deg", "frequencies": "300,450,700", "severity": "advisory"},
    ]
    path = str(write_config(shipped_raw))
    code, out, _ = _run(["verify", path, "--json"])
    verdict = json.loads(out)["verdicts"][0]
    code_s, out_s, _ = _run(["sinedwell", path, "--amplitudes", "10deg",
                             "--frequencies", "300,450,700", "--json"])
    assert code == 0 and code_s == 0
    assert verdict["value"] == json.loads(out_s)["amplitudes"][0]["bandwidth_rad_s"]
    assert verdict["status"] == "PASS" and "sine-dwell at 10 deg" in verdict["message"]
