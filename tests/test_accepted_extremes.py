"""Values at the ends of the accepted ranges are results or clear errors, never tracebacks.

Issue 24: ``gear.efficiency: 1e-300`` (or 5e-324) and ``load.hinge_stiffness: -1e9`` were
accepted and raised numpy's LinAlgError in simulate, sinedwell, report, compare and tune. Now:

- the forward efficiency has a physical lower bound (cas_freq.core.parameters.MIN_EFFICIENCY, 1 %:
  below it the reflected load 1/eta overflowed the plant's matrices), so such a value is bad
  input (exit 2, naming the key, the value and the range);
- K_h = -1e9 N*m/rad (an aiding hinge spring 1e8 times the loop's own stiffness) is an
  unstable closed loop whose nonlinear step diverges within a millisecond: every command reports
  that (the run's step figures and fit do not exist: null in JSON, "—" in text), the diverged
  response no longer reaches the fit (whose Newton refinement raised on its NaN sums).

Short runs only: one 1 deg step, two sine-dwell frequencies, one tuning round; the report and
compare run on the shipped config without its load envelope (17 more steps).
"""

import json
import math

import pytest
from clirun import run_cli

from cas_freq.simulation.second_order import fit_second_order_batch, second_order_step
from cas_freq.simulation.step_figures import step_figures

CONFIG = "configs/qt_cas.yaml"
AIDING = "load.hinge_stiffness=-1e9"
SHORT = ["--amplitudes", "1deg", "--frequencies", "100,1000"]


@pytest.fixture(scope="module")
def config(tmp_path_factory):
    """The shipped config without its load_envelope: section (the report's slowest part)."""
    text = open(CONFIG, encoding="utf-8").read()
    start = text.index("load_envelope:")
    end = text.index("\n\n", start)
    path = tmp_path_factory.mktemp("config") / "qt_cas.yaml"
    path.write_text(text[:start] + text[end + 2:], encoding="utf-8")
    return str(path)


@pytest.mark.parametrize("value", ["1e-300", "5e-324", "0.009"])
@pytest.mark.parametrize("command", [
    ["simulate", "--step", "1deg"], ["sinedwell", *SHORT], ["report", "-o", "OUT"],
    ["compare", "--variants", "base,loaded", "-o", "OUT"],
    ["tune", "--free", "position_loop.Kp", "--candidates", "4", "--rounds", "1"],
])
def test_efficiency_below_one_percent_is_bad_input(tmp_path, command, value):
    argv = [str(tmp_path / "out") if arg == "OUT" else arg for arg in command]
    if command[0] != "compare":
        argv += ["--variant", "loaded"]
    code, _, err = run_cli([*argv, "--set", f"gear.efficiency={value}"])
    assert code == 2, err
    assert "gear.efficiency: must be >= 0.01 and <= 1" in err and value in err
    assert "Traceback" not in err


def test_simulate_reports_a_diverging_run():
    code, out, err = run_cli(["simulate", "--variant", "loaded", "--set", AIDING,
                              "--step", "1deg", "--json"])
    assert code == 0, err
    data = json.loads(out)
    assert data["linear_closed_loop"] == "unstable"
    # the fin angle passes 1e6 steps (or overflows) within a millisecond: the aiding spring's
    # pole is at about sqrt(1e9 / J_L) ~ 5e6 rad/s
    assert 0 < data["simulation"]["diverged_at_s"] < 1e-3
    assert data["step"]["overshoot_pct"] is None and data["step"]["rise_time_s"] is None
    assert data["fit"]["wn_rad_s"] is None and data["fit"]["success"] is False
    code, out, _ = run_cli(["simulate", "--variant", "loaded", "--set", AIDING,
                            "--step", "1deg"])
    assert code == 0 and "the run DIVERGED" in out


def test_sinedwell_reports_diverging_runs():
    code, out, err = run_cli(["sinedwell", "--variant", "loaded", "--set", AIDING, *SHORT])
    assert code == 0, err
    assert "UNSTABLE" in out and "no first harmonic: the run diverged" in out


@pytest.mark.parametrize("command", [["report", "--variant", "loaded"],
                                     ["compare", "--variants", "loaded,fitted"]])
def test_report_and_compare_of_an_unstable_diverging_variant(tmp_path, config, command):
    out = tmp_path / "out"
    code, _, err = run_cli([command[0], config, *command[1:], "--set", AIDING, *SHORT, "-o",
                            str(out), "-q"])
    assert code == 0, err
    assert "Warning" not in err  # the overflowing responses are results, not numpy warnings
    results = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert results  # a complete document
    if command[0] == "report":
        assert "The 1° step diverged" in (out / "report.md").read_text(encoding="utf-8")


def test_tune_of_an_unstable_variant_is_a_failed_requirement():
    code, out, err = run_cli(["tune", "--variant", "loaded", "--set", AIDING, "--free",
                              "position_loop.Kp", "--candidates", "4", "--rounds", "1"])
    assert code == 1, err  # a requirement that cannot be met, not a crash (exit 2 or 1 + trace)
    assert "INFEASIBLE" in out


def test_a_diverged_response_has_no_step_figures_or_fit():
    # the functions under the commands: a response that overflowed, or one 1e6 times past the
    # step, has no figure (NaN) and no fit (NaN, success False); a finite neighbour in the same
    # batch keeps its own fit (the batch's fits are independent)
    t = [k * 1e-3 for k in range(200)]
    good = second_order_step(t, 100.0, 0.5, 0.0)
    for bad in ([math.exp(s * 2e5) if s < 3e-3 else math.inf for s in t],
                [math.exp(s * 1e2) * 1e5 for s in t]):
        figures = step_figures(t, bad, 1.0)
        assert math.isnan(figures.overshoot_pct) and math.isnan(figures.rise_time_s)
        lost, kept = fit_second_order_batch([t, t], [bad, good], 1.0)
        assert math.isnan(lost.wn_rad_s) and not lost.success
        # the model itself, noise-free: recovered to the fit's precision (~1e-12; 1e-9 here)
        assert kept.success and kept.wn_rad_s == pytest.approx(100.0, rel=1e-9)
