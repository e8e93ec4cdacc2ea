"""``cas-freq simulate``: JSON keys, CSV output, exit codes (figures are tested in
test_simulation*.py; here only the command's contract)."""

import csv
import json
import math

import numpy as np
import pytest

from cas_freq.cli import main

STEP_KEYS = {"amplitude_deg", "rise_time_s", "overshoot_pct", "settling_time_s",
             "settling_time_5pct_s", "peak_time_s", "max_current_a", "max_voltage_v",
             "current_limited", "voltage_limited"}
FIT_KEYS = {"wn_rad_s", "zeta", "td_s", "bandwidth_closed_form_rad_s", "rms_residual"}


def _strict(text):
    def reject(name):
        raise ValueError(f"non-strict JSON constant {name}")

    return json.loads(text, parse_constant=reject)


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    import contextlib
    import io

    out = tmp_path_factory.mktemp("sim") / "step.csv"
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = main(["simulate", "--step", "10deg", "--json", "--csv", str(out)])
    return code, _strict(buffer.getvalue()), out


def test_json_has_step_and_fit(simulated):
    code, data, _ = simulated
    assert code == 0
    assert STEP_KEYS <= set(data["step"]) and FIT_KEYS <= set(data["fit"])
    assert data["step"]["amplitude_deg"] == pytest.approx(10.0)
    # docs/model.md: a 10° step asks Kp * 3.49 rad ~ 22 A of a 20 A limit
    assert data["step"]["current_limited"] is True
    # the closed form of the fitted (wn, zeta), recomputed here from the report's formula
    wn, zeta = data["fit"]["wn_rad_s"], data["fit"]["zeta"]
    expected = wn * math.sqrt((1 - 2 * zeta**2) + math.sqrt(4 * zeta**4 - 4 * zeta**2 + 2))
    assert data["fit"]["bandwidth_closed_form_rad_s"] == pytest.approx(expected, rel=1e-12)


def test_csv_time_series(simulated):
    _, data, path = simulated
    with open(path, newline="") as stream:
        rows = list(csv.reader(stream))
    assert rows[0][:3] == ["t [s]", "command_output [deg]", "delta [deg]"]
    final = [float(value) for value in rows[-1]]
    assert final[1] == pytest.approx(10.0)
    assert abs(final[2] - 10.0) < 0.2  # settled within ±2 % by the end of the horizon
    assert not list(path.parent.glob(".*.tmp"))  # atomic write left no temporary behind


@pytest.mark.parametrize("step", ["10", "10m", "0deg", "200deg", "ten"])
def test_bad_step_exits_2(capsys, step):
    assert main(["simulate", "--step", step]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--step" in err and "Traceback" not in err


def test_bad_config_exits_2(capsys):
    assert main(["simulate", "--step", "1deg", "--set", "motor.J=-1"]) == 2
    assert "motor.J" in capsys.readouterr().err


def test_limit_activity_times(simulated):
    """The 10 deg step drives the current command into its clamp right after the step (the
    filtered derivative's kick, Kd/Tf = 63 A/rad on 3.49 rad) for a few ms; the voltage stays
    inside 30 V. limit_activity itself: worked example on a hand-made flag series."""
    from cas_freq.studies.run import limit_activity

    _, data, _ = simulated
    current, voltage = data["limits"]["current"], data["limits"]["voltage"]
    assert current["first_s"] == 0.0 and 0.0 < current["active_s"] < 0.01
    assert 0.0 < current["last_s"] < 0.01
    assert voltage == {"active_s": 0.0, "first_s": None, "last_s": None}
    t = np.arange(10) * 0.5
    flags = np.array([0, 0, 1, 1, 0, 1, 0, 0, 0, 0], dtype=bool)
    assert limit_activity(t, flags) == {"active_s": 1.5, "first_s": 1.0, "last_s": 2.5}


def test_command_table_is_the_ramp_it_draws(tmp_path):
    """A table rising 1 deg in 10 ms and holding is the library's Ramp(100 deg/s, stop 10 ms):
    same angle, rate (feed-forward) and corners, so the fin follows the same trajectory on the
    common times, to rounding."""
    from clirun import run_cli

    from cas_freq.config import load_variant
    from cas_freq.simulation import simulate
    from cas_freq.simulation.commands import Ramp

    table = tmp_path / "cmd.csv"
    table.write_text("t [s],delta [deg]\n0,0\n0.01,1\n0.05,1\n")
    out_csv = tmp_path / "run.csv"
    code, out, err = run_cli(["simulate", "--command", str(table), "--csv", str(out_csv),
                              "--json"])
    assert code == 0, err
    followed = np.loadtxt(out_csv, delimiter=",", skiprows=1)
    ramp = simulate(load_variant().params, Ramp(np.radians(100.0), 0.0, 0.01), t_end=0.1)
    n = min(len(followed), ramp.t.size)
    np.testing.assert_allclose(followed[:n, 0], ramp.t[:n], rtol=0, atol=1e-12)
    # the CSV keeps 9 significant digits: 1e-8 deg on angles of about 1 deg
    np.testing.assert_allclose(followed[:n, 2], np.degrees(ramp.delta[:n]), rtol=0, atol=2e-8)
    data = json.loads(out)
    assert 0.0 < data["tracking"]["max_abs_error_deg"] < 1.0
    assert abs(data["tracking"]["final_error_deg"]) < 0.02  # settled within 2 % of 1 deg


def test_command_errors_exit_2(tmp_path):
    from clirun import run_cli

    bad = tmp_path / "bad.csv"
    bad.write_text("0,1\n0.01,x\n")
    code, _, err = run_cli(["simulate", "--command", str(bad)])
    assert code == 2 and "row 2" in err
    code, _, err = run_cli(["simulate", "--command", str(bad), "--step", "1deg"])
    assert code == 2 and "not allowed with" in err  # argparse: both is a usage error
