"""``cas-freq sweep``: grid parsing, JSON/CSV/report outputs, exit codes.

The figures themselves are checked against the single path in test_batch_analyze.py; here the
command's contract, and that a grid point's figures equal ``analyze --json`` of that variant
(rel 1e-6, as there).
"""

import csv
import json

import numpy as np
import pytest

from cas_freq.cli import main
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameter_keys import parse_grid_values
from cas_freq.studies.sweep import grid


def _strict(text):
    def reject(name):
        raise ValueError(f"non-strict JSON constant {name}")

    return json.loads(text, parse_constant=reject)


def test_grid_specs():
    np.testing.assert_allclose(parse_grid_values("position_loop.Kp", "2:12:6"),
                               [2, 4, 6, 8, 10, 12])
    np.testing.assert_allclose(parse_grid_values("current_loop.delay", "0.05ms, 0.1 ms"),
                               [5e-5, 1e-4], rtol=1e-12)
    np.testing.assert_allclose(parse_grid_values("position_loop.Kp", "5"), [5])
    points = grid({"a": np.array([1.0, 2.0]), "b": np.array([10.0, 20.0, 30.0])})
    assert points["a"].tolist() == [1, 1, 1, 2, 2, 2]
    assert points["b"].tolist() == [10, 20, 30, 10, 20, 30]


@pytest.mark.parametrize("key, spec, message", [
    ("position_loop.Kp", "2:12", "START:STOP:COUNT"),
    ("position_loop.Kp", "2:12:x", "START:STOP:COUNT"),
    ("position_loop.Kp", "2:12:0", "START:STOP:COUNT"),
    ("position_loop.Kp", "1,,2", "START:STOP:COUNT"),
    ("current_loop.delay", "1 V:2 V:3", "cannot read"),
    ("position_loop.derivative_on", "1:2:3", "cannot be varied"),
])
def test_bad_grid_specs(key, spec, message):
    with pytest.raises(ConfigError, match=message):
        parse_grid_values(key, spec)


@pytest.mark.parametrize("argv", [
    ["sweep", "--set", "position_loop.Kp=2:12"],
    ["sweep", "--set", "motor.nothing=1:2:3"],
    ["sweep", "--set", "position_loop.Kp=-1:2:3"],
    ["sweep"],
])
def test_bad_sweeps_exit_2_with_one_line(capsys, argv):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error" in err[0]


def test_sweep_json_matches_analyze(capsys):
    assert main(["sweep", "--set", "position_loop.Kp=4,8", "--set", "motor.J=6e-7",
                 "--json"]) == 0
    data = _strict(capsys.readouterr().out)
    assert data["count"] == 2 and list(data["swept"]) == ["position_loop.Kp"]
    assert data["overrides"] == ["motor.J=6e-07"]  # YAML 1.2 reads 6e-7 as a number
    point = data["points"][1]
    assert point["position_loop.Kp"] == 8.0 and point["stability"] == "stable"
    assert main(["analyze", "--set", "position_loop.Kp=8", "--set", "motor.J=6e-7",
                 "--json"]) == 0
    single = _strict(capsys.readouterr().out)
    for name in ("position_loop.phase_margin_deg", "closed_loop.bandwidth_rad_s",
                 "current_loop.gain_margin_db"):
        group, figure = name.split(".")
        assert point[name] == pytest.approx(single[group][figure], rel=1e-6)


def test_csv_and_report(tmp_path, capsys):
    out_csv = tmp_path / "sweep.csv"
    report = tmp_path / "report"
    assert main(["sweep", "--set", "position_loop.Kp=3:9:3", "--set", "position_loop.Kd=0.03,0.04",
                 "--csv", str(out_csv), "-o", str(report)]) == 0
    table = capsys.readouterr().out
    assert "sweep of 6 points" in table
    rows = list(csv.DictReader(out_csv.open()))
    assert len(rows) == 6
    assert "position_loop.Kp [A/rad]" in rows[0] and "closed_loop.bandwidth_rad_s" in rows[0]
    names = sorted(p.name for p in report.iterdir())
    assert names == [".cas-freq-output", "sweep.csv", "sweep.json", "sweep.svg"]
    svg = (report / "sweep.svg").read_text()
    assert svg.startswith("<?xml") and "position_loop.Kp" in svg


def test_sweep_figure_structure():
    from cas_freq.plots.studies import sweep_figure

    points = {"position_loop.Kp": np.array([1.0, 1.0, 2.0, 2.0]),
              "position_loop.Kd": np.array([0.1, 0.2, 0.1, 0.2])}
    figures = {"closed_loop.bandwidth_rad_s": np.array([1.0, 2.0, 3.0, 4.0]),
               "position_loop.phase_margin_deg": np.array([30.0, 31.0, np.nan, 33.0])}
    figure = sweep_figure(points, figures, list(points))
    axes = [axis for axis in figure.axes if axis.get_visible()]
    assert [axis.get_ylabel() for axis in axes] == ["position_loop.phase_margin_deg",
                                                    "closed_loop.bandwidth_rad_s"]
    assert all(len(axis.lines) == 2 for axis in axes)  # one line per Kd value
    assert axes[0].get_xlabel() == "position_loop.Kp"


# --- several variants (issue 11: one grammar) ---------------------------------------------

GRID = ["sweep", "--set", "position_loop.Kp=4,8", "--set", "motor.J=6e-7"]


def test_single_variant_output_unchanged_by_the_variant_options(capsys):
    # the default, an explicit --variant base and the same name twice print the same bytes
    outputs = []
    for extra in ([], ["--variant", "base"], ["--variant", "base", "--variant", "base"]):
        assert main([*GRID, *extra, "--json"]) == 0
        outputs.append(capsys.readouterr().out)
    assert outputs[0] == outputs[1] == outputs[2]
    assert isinstance(_strict(outputs[0]), dict)


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_several_variants_json_text_csv_and_report(tmp_path, capsys):
    assert main([*GRID, "--variant", "relaxed", "--variant", "base", "--json"]) == 0
    data = _strict(capsys.readouterr().out)
    assert [item["variant"] for item in data] == ["base", "relaxed"]  # the file's order
    assert main([*GRID, "--variant", "base", "--json"]) == 0
    assert data[0] == _strict(capsys.readouterr().out)  # each entry is that variant's sweep
    # the same grid on each: the swept key overrides the variant's own value
    assert [p["position_loop.Kp"] for p in data[1]["points"]] == [4.0, 8.0]

    out_csv, report = tmp_path / "s.csv", tmp_path / "rep"
    assert main([*GRID, "--all-variants", "--csv", str(out_csv), "-o", str(report)]) == 0
    text = capsys.readouterr().out
    assert text.count("sweep of 2 points") == 6 and "qt_cas (relaxed)" in text
    rows = list(csv.DictReader(out_csv.open()))
    assert [row["variant"] for row in rows] == ["base", "base", "fitted", "fitted",
                                                "relaxed", "relaxed", "loaded", "loaded",
                                                "fin_encoder", "fin_encoder", "sampled", "sampled"]
    assert list(rows[0])[:2] == ["variant", "position_loop.Kp [A/rad]"]
    assert (report / "sweep.csv").read_text() == out_csv.read_text()
    assert sorted(p.name for p in report.iterdir()) == [
        ".cas-freq-output", "sweep.base.svg", "sweep.csv", "sweep.fin_encoder.svg",
        "sweep.fitted.svg", "sweep.json", "sweep.loaded.svg", "sweep.relaxed.svg",
        "sweep.sampled.svg"]
    assert len(_strict((report / "sweep.json").read_text())) == 6


def test_step_and_fit_figures_of_an_unstable_point_are_not_shown(tmp_path, capsys):
    """Issue 24 review: at a sweep point whose closed loop is unstable (the shipped loaded
    variant with K_h = -20 N·m/rad; analyze says unstable) the step's overshoot and the fit's
    bandwidth were shown beside "unstable"; they are runs the limits hold in a limit cycle.
    As the load envelope does (one rule, cas_freq.studies.shown), they are "-" / null / empty
    with the reason, while the stable point keeps them; the margins of both points stay."""
    argv = ["sweep", "--variant", "loaded", "--set", "load.hinge_stiffness=-20,0",
            "--step", "2deg"]
    csv_path, out_dir = tmp_path / "s.csv", tmp_path / "report"
    assert main([*argv, "--csv", str(csv_path)]) == 0
    text = capsys.readouterr().out
    unstable_row = next(line for line in text.splitlines() if "unstable" in line and "-20" in line)
    assert unstable_row.split()[-2:] == ["-", "-"]  # OS [%], BW fit [rad/s]
    assert "(- not shown: closed loop unstable" in text
    assert main([*argv, "--json", "-o", str(out_dir)]) == 0
    unstable, stable = _strict(capsys.readouterr().out)["points"]
    assert unstable["stability"] == "unstable" and stable["stability"] == "stable"
    assert unstable["run_figures_not_shown"] == "closed loop unstable"
    assert stable["run_figures_not_shown"] is None
    for key in ("step.overshoot_pct", "fit.bandwidth_closed_form_rad_s", "fit.rms_residual"):
        assert unstable[key] is None and stable[key] is not None
    assert unstable["position_loop.phase_margin_deg"] < 0  # the margins exist: shown
    saved = json.loads((out_dir / "sweep.json").read_text())["points"][0]
    assert saved["step.overshoot_pct"] is None
    for path in (csv_path, out_dir / "sweep.csv"):
        rows = list(csv.DictReader(path.open()))
        assert rows[0]["step.overshoot_pct"] == "" and rows[1]["step.overshoot_pct"] != ""
        assert rows[0]["run_figures_not_shown"] == "closed loop unstable"
        assert rows[1]["run_figures_not_shown"] == ""
