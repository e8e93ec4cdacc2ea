"""An unstable linear loop is a result everywhere, never a silent pass; inputs the simulation
cannot honour are refused with a clear error.

The unstable case is the base variant with position_loop.Kd = 0.5 A*s/rad (13x the tuned
0.0381): ``analyze`` reports it unstable (its Padé-6 closed loop has poles in the right half
plane), so no requirement may pass on it.
"""

import json
import math

import numpy as np
import pytest
from clirun import run_cli

from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.tolerances import parse_tolerance
from cas_freq.studies.montecarlo import draw, requirement_results, run_montecarlo
from cas_freq.studies.run import sinedwell_run, step_run

UNSTABLE = [("position_loop.Kd", "0.5 A*s/rad")]


def test_the_case_is_unstable():
    code, out, _ = run_cli(["analyze", "--set", "position_loop.Kd=0.5", "--json"])
    assert code == 0 and json.loads(out)["stability"] == "unstable"


def test_step_and_sinedwell_say_the_linear_loop_is_unstable():
    loaded = load_variant(None, "base", UNSTABLE)
    run = step_run(loaded, math.radians(1))
    assert run.linear_stability == "unstable"
    dwell = sinedwell_run(loaded, [math.radians(1)], [300.0, 600.0])
    assert dwell.linear_bandwidth_rad_s is None  # no frequency response to measure
    code, out, _ = run_cli(["simulate", "--step", "1deg", "--set", "position_loop.Kd=0.5"])
    assert code == 0 and "WARNING: the linear closed loop is UNSTABLE" in out
    assert "nan" not in out


def test_montecarlo_yield_counts_unstable_samples_as_failures():
    """All samples unstable (a 0.001 % tolerance around the unstable case): every evaluated
    requirement has 0 % yield, as verify fails every requirement of an unstable variant."""
    loaded = load_variant(None, "base", UNSTABLE)
    mc = run_montecarlo(loaded, [parse_tolerance("motor.R=0.001%")], 3, seed=1, simulate=False)
    assert set(mc.stability.astype(str)) == {"unstable"}
    evaluated = [r for r in requirement_results(mc) if r["evaluated"]]
    assert evaluated and all(r["yield_pct"] == 0.0 for r in evaluated)


def test_montecarlo_yield_is_the_count_of_passing_samples():
    """GM-P (position-loop gain margin >= 6 dB) over Kd samples from x0.05 to x1.95: the yield
    is the share of stable samples whose gain margin, from the same run's figures, is >= 6."""
    loaded = load_variant()
    mc = run_montecarlo(loaded, [parse_tolerance("position_loop.Kd=95%")], 30, seed=3,
                        distribution="uniform", simulate=False)
    margin = mc.figures["position_loop.gain_margin_db"]
    stable = mc.stability.astype(str) == "stable"
    expected = 100.0 * np.mean(stable & (margin >= 6.0))
    by_id = {r["id"]: r for r in requirement_results(mc)}
    assert by_id["GM-P"]["yield_pct"] == pytest.approx(expected, abs=1e-12)
    assert 0.0 < expected < 100.0  # the draw spans the requirement, so the check is not vacuous


def test_negative_seed_is_refused():
    params = load_variant().params
    with pytest.raises(ConfigError, match="--seed: must be an integer >= 0"):
        draw(params, [parse_tolerance("motor.Km=1%")], 3, seed=-1)
    code, _, err = run_cli(["montecarlo", "--samples", "3", "--seed", "-1",
                            "--tolerance", "motor.Km=1%"])
    assert code == 2 and "--seed" in err


def test_sine_faster_than_the_step_allows_is_refused():
    """At dt = 5 us a sine needs 20 steps per period: at most 2 pi / (20 * 5 us) = 62,832 rad/s;
    faster ones would be aliased, not measured."""
    code, out, err = run_cli(["sinedwell", "--amplitudes", "1deg", "--frequencies", "1e6"])
    assert code == 2 and out == ""
    assert "1e+06 rad/s is too fast" in err and "62832 rad/s" in err


def test_requirements_must_be_a_list():
    code, _, err = run_cli(["verify", "--set", "requirements=3"])
    assert code == 2 and "requirements: must be a list" in err


def test_negative_requirement_step_is_refused(shipped_raw, write_config):
    shipped_raw["requirements"] = [{"id": "OS", "metric": "step.overshoot_pct", "max": 15,
                                    "step": "-10 deg"}]
    code, _, err = run_cli(["verify", str(write_config(shipped_raw))])
    assert code == 2 and "requirements.0.step: must be > 0" in err


def test_verify_shows_the_margins_of_an_unstable_loop_and_never_passes_them():
    """The open-loop margins of an unstable loop exist: verify shows them (the same numbers as
    analyze) but none passes, even one inside its bounds (issue 11: verify printed "—" where
    analyze gave a negative phase margin). Case: the DC servo with Kp = 500 A/rad, whose
    closed loop is unstable while its current loop alone is stable."""
    args = ["configs/dc_servo.yaml", "--set", "position_loop.Kp=500", "--json"]
    code, out, _ = run_cli(["analyze", *args])
    analysis = json.loads(out)
    assert code == 0 and analysis["stability"] == "unstable"
    code, out, _ = run_cli(["verify", *args])
    verdicts = {v["id"]: v for v in json.loads(out)["verdicts"]}
    assert code == 1
    pm, gm, pm_i = verdicts["PM-P"], verdicts["GM-P"], verdicts["PM-I"]
    assert pm["value"] == pytest.approx(analysis["position_loop"]["phase_margin_deg"], rel=1e-9)
    assert pm["value"] < 0 and pm["status"] != "PASS"
    # inside its bounds (>= 6 dB) but on an unstable loop: shown, not passed, no margin
    assert gm["value"] >= gm["min"] and gm["status"] != "PASS" and gm["margin"] is None
    assert "unstable" in gm["message"]
    # no requirement passes on an unstable actuator, not even the current loop's (stable alone)
    assert pm_i["status"] != "PASS" and "current loop alone: stable" in pm_i["condition"]
    assert verdicts["BW-1"]["value"] is None and verdicts["BW-1"]["status"] == "FAIL"


#: The shipped loaded variant with a negative hinge spring K_h = -20 N·m/rad: its linear closed
#: loop is unstable (analyze), and its position loop's gain crossover is a few rad/s, so the
#: default sine-dwell grid would need a horizon beyond the simulation budget.
UNSTABLE_HINGE = ["--variant", "loaded", "--set", "load.hinge_stiffness=-20"]


def test_sinedwell_of_an_unstable_loop_is_a_result_not_a_budget_error():
    """Issue 24 review: the default sine-dwell of an unstable variant exited 2 with the
    simulation-budget refusal (its grid centred on the position loop's crossover). It is a
    result: the loop is unstable, no sine-dwell bandwidth exists (null with the reason), and
    the nonlinear step of each amplitude is still given."""
    code, out, err = run_cli(["sinedwell", *UNSTABLE_HINGE, "--amplitudes", "1deg", "--json"])
    assert code == 0, err
    data = json.loads(out)
    assert data["linear_closed_loop"] == "unstable"
    assert "linear closed loop is unstable" in data["not_computed"]["sinedwell"]
    assert "CAS_FREQ_BUDGET" not in data["not_computed"]["sinedwell"]
    assert data["frequencies_rad_s"] == [] and data["linear"]["bandwidth_rad_s"] is None
    (entry,) = data["amplitudes"]
    assert entry["bandwidth_rad_s"] is None and entry["step"]["amplitude_deg"] == 1.0
    assert data["bandwidth_three_ways"][0]["sinedwell_rad_s"] is None
    code, out, err = run_cli(["sinedwell", *UNSTABLE_HINGE, "--amplitudes", "1deg"])
    assert code == 0, err
    assert "the linear closed loop is UNSTABLE" in out
    assert "no sine-dwell bandwidth exists" in out and "sine-dwell not computed" in out


def test_report_data_of_an_unstable_loop_says_why_its_sinedwell_is_missing():
    """The report's default grid follows the same rule: the sine-dwell of an unstable variant is
    not computed because the loop is unstable (before: because of the simulation budget)."""
    from cas_freq.report.data import ReportSettings, gather_variant, not_computed_notice

    loaded = load_variant(None, "loaded", [("load.hinge_stiffness", "-20")])
    data = gather_variant(loaded, ReportSettings(amplitudes_rad=(math.radians(1.0),)))
    assert data.dwell.result is None and data.dwell.steps
    assert "linear closed loop is unstable" in not_computed_notice(data)
