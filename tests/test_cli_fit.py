"""``cas-freq fit``: the report's §7 fit applied to a step response read from a CSV.

The reference data is the second-order-plus-delay model itself with the report's parameters
(wn 462 rad/s, zeta 0.54, td 2 ms: docs/model.md), so the fit must give them back; with 0.5 % of the
step of seeded white noise added, they must come back within a few percent and inside the
reported confidence intervals.
"""

import json
import math

import numpy as np
import pytest
from clirun import run_cli

from cas_freq.core.figures import FIGURES
from cas_freq.simulation.second_order import second_order_step

_run = run_cli


def _write(path, noise=0.0, t_start=-0.005):
    t = np.arange(t_start, 0.06, 1e-4)
    y = np.degrees(second_order_step(np.clip(t, 0, None), 462.0, 0.54, 2e-3, math.radians(10)))
    y += noise * 10.0 * np.random.default_rng(7).standard_normal(t.size)
    np.savetxt(path, np.column_stack([t, y]), delimiter=",", header="t [s],delta [deg]",
               comments="")
    return path


def test_recovers_the_report_fit_from_clean_data(tmp_path):
    code, out, err = _run(["fit", str(_write(tmp_path / "s.csv")), "--step", "10deg", "--json"])
    assert code == 0, err
    data = json.loads(out)
    fit = data["fit"]
    assert fit["wn_rad_s"] == pytest.approx(462.0, rel=1e-6)
    assert fit["zeta"] == pytest.approx(0.54, rel=1e-6)
    assert fit["td_s"] == pytest.approx(2e-3, rel=1e-6)
    # docs/model.md: wn 462, zeta 0.54 give 566 rad/s in closed form (565.9 unrounded)
    assert fit["bandwidth_closed_form_rad_s"] == pytest.approx(566.0, abs=0.5)
    # the samples before t = 0 are dropped, the step figures are of the model: 13.3 % overshoot
    assert data["samples"] == 600
    assert data["step"]["overshoot_pct"] == pytest.approx(
        100 * math.exp(-math.pi * 0.54 / math.sqrt(1 - 0.54**2)), rel=1e-3
    )


def test_noisy_data_inside_the_confidence_intervals(tmp_path):
    code, out, _ = _run(["fit", str(_write(tmp_path / "n.csv", noise=0.005)), "--step", "10deg",
                         "--json"])
    fit = json.loads(out)["fit"]
    for key, true in (("wn_rad_s", 462.0), ("zeta", 0.54)):
        assert fit[key] == pytest.approx(true, rel=0.03)
    low, high = fit["wn_ci_rad_s"]
    assert low < 462.0 < high
    # the rms residual is the noise level, 0.5 % of 10 deg in rad
    assert fit["rms_residual"] == pytest.approx(0.005 * math.radians(10), rel=0.15)


def test_table(tmp_path):
    code, out, _ = _run(["fit", str(_write(tmp_path / "s.csv")), "--step", "10deg"])
    assert code == 0 and "closed-form bandwidth 565.9 rad/s" in out


@pytest.mark.parametrize(
    ("content", "expect"),
    [
        ("t,delta\n0.01,1\n0.02,2\n", "span the step at t = 0"),
        ("0,0\n0.001,x\n", "not numbers"),
        ("0,0,1\n", "expected 2 columns"),
        # three samples from t = 0: the error named an internal function and its arguments
        # ("fit_second_order: t and response must be 1-D of the same length (>= 4)")
        ("-0.001,0\n0,0\n0.001,5\n0.002,9\n", "bad.csv: 3 samples from t = 0 s on; the fit "
                                                  "needs at least 4"),
    ],
)
def test_bad_files_exit_2(tmp_path, content, expect):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    code, _, err = _run(["fit", str(path), "--step", "10deg"])
    assert code == 2 and expect in err and "Traceback" not in err


def test_missing_file_exits_2(tmp_path):
    code, _, err = _run(["fit", str(tmp_path / "none.csv"), "--step", "10deg"])
    assert code == 2 and "none.csv: step response file not found" in err


def test_td_interval_in_text_and_json(tmp_path):
    path = _write(tmp_path / "n.csv", noise=0.005)
    code, out, _ = _run(["fit", str(path), "--step", "10deg", "--json"])
    low, high = json.loads(out)["fit"]["td_ci_s"]
    assert low < 2e-3 < high  # the true delay of the data, as for wn above
    code, out, _ = _run(["fit", str(path), "--step", "10deg"])
    line = next(line for line in out.splitlines()
                if line.strip().startswith(FIGURES["fit.td_s"].label + " "))
    assert line.strip().endswith(f"[{low * 1e3:.4g}, {high * 1e3:.4g}]")


def test_reads_what_simulate_writes(tmp_path):
    """Round trip: ``simulate --step 10deg --csv F`` then ``fit F --step 10deg``.

    fit reads the time and ``delta [deg]`` columns of simulate's CSV (the others ignored) and
    fits the same samples with the same stride as simulate's own fit, so the two differ only
    by the CSV's 9 significant digits (<= 5e-10 of each value): measured 1.4e-7 relative on
    wn and zeta. rel 1e-5 leaves a margin of ~70 and still catches a wrong column or unit
    (command_output is a flat line; rad for deg is a factor of 57).
    """
    path = tmp_path / "sim.csv"
    code, out, err = _run(["simulate", "--step", "10deg", "--csv", str(path), "--json"])
    assert code == 0, err
    own = json.loads(out)["fit"]
    assert path.read_text().startswith("t [s],command_output [deg],delta [deg],theta [rad]")
    code, out, err = _run(["fit", str(path), "--step", "10deg", "--json"])
    assert code == 0, err
    fit = json.loads(out)["fit"]
    for key in ("wn_rad_s", "zeta", "td_s", "bandwidth_closed_form_rad_s"):
        assert fit[key] == pytest.approx(own[key], rel=1e-5), key


@pytest.mark.parametrize("header, scale_t, scale_y", [
    ("time_s,fin_angle_deg", 1.0, 1.0),
    ("angle [deg],time [s]", None, None),  # named columns in any order
    ("t [ms],delta [rad]", 1e3, math.pi / 180),
    ("T (s),Delta (deg),current [A]", 1.0, 1.0),  # other columns ignored
    ("time,position", 1.0, 1.0),  # two columns: time [s], angle [deg] whatever their names
])
def test_header_names_columns_and_units(tmp_path, header, scale_t, scale_y):
    t = np.arange(0.0, 0.06, 1e-4)
    y = np.degrees(second_order_step(t, 462.0, 0.54, 2e-3, math.radians(10)))
    if scale_t is None:  # swapped columns
        columns = [y, t]
    else:
        columns = [t * scale_t, y * scale_y]
    columns += [np.zeros_like(t)] * (header.count(",") + 1 - 2)
    path = tmp_path / "h.csv"
    np.savetxt(path, np.column_stack(columns), delimiter=",", header=header, comments="",
               fmt="%.12g")
    code, out, err = _run(["fit", str(path), "--step", "10deg", "--json"])
    assert code == 0, err
    assert json.loads(out)["fit"]["wn_rad_s"] == pytest.approx(462.0, rel=1e-6)


@pytest.mark.parametrize(("content", "expect"), [
    ("a,b,c\n0,1,2\n", "row 1: the header names no time column (t or time, in s or ms"),
    ("t [s],x,y\n0,1,2\n", "the header names no output angle column (delta, output_angle"),
    ("x,y,z\n0,1,2\n", "no time column (t or time, in s or ms (e.g. 't [s]', 'time_s')) and "
     "no output angle column"),
    ("time [min],delta [deg]\n0,1\n", "row 1: column 'time [min]': unit 'min' not accepted; "
     "expected t or time, in s or ms"),
    ("t [s],delta [deg],i [A]\n0,0,0\n0.01,1\n", "row 3: expected 3 columns, got 2"),
])
def test_header_errors_name_file_row_and_what_is_expected(tmp_path, content, expect):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    code, _, err = _run(["fit", str(path), "--step", "10deg"])
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert str(path) in err and expect in err
