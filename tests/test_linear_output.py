"""A linear output (``gear.screw_lead``, docs/model.md "Linear output"): configs/ball_screw.yaml.

Derivation of the reflection (MODEL.md "Drive architectures", "Linear output"). The rod moves
x = θ · lead / (2π · ratio) = n θ with n = lead / (2π ratio) [m/rad]. A mass m at the rod has
the kinetic energy m ẋ²/2 = (m n²) θ̇²/2, a damper b the power b ẋ² = (b n²) θ̇², a spring K the
energy K x²/2 = (K n²) θ²/2, a force F the torque F n on the screw's input; through a forward
efficiency η the motor sees them divided by η. The rotary model reflects J_L/(η N²), b_L/(η N²),
K_h/(η N²) and a moment τ/N with δ = θ/N. With N = 1/n [rad/m], J_L = m, b_L = b, K_h = K,
τ = F (and the gear's axial stiffness K_g [N/m] for the rotary one [N·m/rad]) the two are the
same equations, and δ = θ/N = x: a rotary config with those numbers must give the same loop
parameters, every frequency figure and the same step (of 0.005 rad for a 5 mm step), to the
last bits of the ratio's arithmetic (tolerance 1e-12 relative).

The analytic case, by hand: the 2:1 belt and the 5 mm lead give n = 0.005/(2π·2) =
3.979e-4 m/rad, so a 5 mm step is one screw revolution, two motor revolutions: θ = 4π rad at
rest (the PID's integral removes the spring's offset). With only the mass on a rigid screw
J_eff = J + m n²/η = 1.5e-5 + 20·(3.979e-4)²/0.9 = 1.852e-5 kg·m².
"""

import json
import math
import re

import numpy as np
import pytest
import yaml
from clirun import run_cli

from cas_freq.analysis import analyze
from cas_freq.config import load_variant
from cas_freq.core.parameters import LoopParameters

CONFIG = "configs/ball_screw.yaml"
LEAD, BELT, MASS, ETA, J_MOTOR = 0.005, 2.0, 20.0, 0.9, 1.5e-5


@pytest.fixture(scope="module")
def linear():
    return load_variant(CONFIG)


@pytest.fixture(scope="module")
def rotary(tmp_path_factory):
    """configs/ball_screw.yaml written as a rotary actuator with N = 1/n and the load's numbers
    as rotary ones (module docstring)."""
    data = yaml.safe_load(open(CONFIG, encoding="utf-8"))
    data["gear"] = {"ratio": 2 * math.pi * BELT / LEAD, "efficiency": ETA}
    data["load"] = {"inertia": MASS, "damping": 200.0, "hinge_stiffness": 1e5}
    data["requirements"] = [r for r in data["requirements"]  # in mm: not for a rotary output
                            if "step" not in r and "profile" not in r]
    path = tmp_path_factory.mktemp("rotary") / "rotary.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return load_variant(str(path))


def test_linear_config_is_the_rotary_model_with_n_equal_one_over_n(linear, rotary):
    a = LoopParameters.from_config(linear.params)
    b = LoopParameters.from_config(rotary.params)
    assert a.ratio[0] == pytest.approx(2 * math.pi * BELT / LEAD, rel=1e-15)
    for name in ("ratio", "J_L", "b_L", "K_h", "eta", "J", "cp_Kp", "K_g", "tau_h"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-15, err_msg=name)


def test_linear_figures_equal_the_equivalent_rotary_ones(linear, rotary):
    fa, fb = analyze(linear), analyze(rotary)
    for section, name in (("closed_loop", "bandwidth_rad_s"), ("closed_loop", "peak_db"),
                          ("position_loop", "phase_margin_deg"),
                          ("position_loop", "gain_margin_db"),
                          ("current_loop", "phase_margin_deg")):
        value_a = getattr(getattr(fa, section), name)
        assert value_a == pytest.approx(getattr(getattr(fb, section), name), rel=1e-12)
    assert fa.closed_loop.bandwidth_rad_s > 100  # the example's requirement BW-1


def test_linear_step_equals_the_rotary_step_and_turns_the_motor_two_revolutions(linear, rotary):
    from cas_freq.studies.run import step_runs

    run_a, run_b = step_runs([linear, rotary], LEAD)  # 5 mm; 0.005 rad
    for name in ("rise_time_s", "overshoot_pct", "settling_time_s", "max_current_a"):
        assert getattr(run_a.step, name) == pytest.approx(getattr(run_b.step, name), rel=1e-9)
    # by hand: 5 mm = one screw revolution = two motor revolutions behind the 2:1 belt
    assert run_a.result.theta[-1] == pytest.approx(4 * math.pi, rel=2e-3)
    assert run_a.result.delta[-1] == pytest.approx(LEAD, rel=2e-3)


def test_reflected_inertia_of_the_moving_mass_by_hand(linear):
    n = LEAD / (2 * math.pi * BELT)  # [m/rad]
    load = analyze(linear).drivetrain
    assert load.reflected_inertia_kg_m2 == pytest.approx(J_MOTOR + MASS * n * n / ETA, rel=1e-12)
    assert load.reflected_stiffness_n_m_rad == pytest.approx(1e5 * n * n / ETA, rel=1e-12)
    assert J_MOTOR + MASS * n * n / ETA == pytest.approx(1.852e-5, rel=1e-3)  # the docstring's


#: Words of an output angle that a linear output's text must not hold (phase figures are
#: angles of a response, not of the output, and stay in deg).
_PHASE = re.compile(r"phase|PM|margin|∠|Nichols|−90°|-90 deg")


def _output_lines_in_degrees(text):
    return [line for line in text.splitlines()
            if re.search(r"\bdeg\b|°", line) and not _PHASE.search(line)]


def test_cli_analyze_simulate_verify_in_mm():
    code, out, err = run_cli(["analyze", CONFIG])
    assert code == 0, err
    assert "N/m" in out and "N*m/rad at the rod" not in out and "fin" not in out
    code, out, err = run_cli(["simulate", CONFIG, "--step", "5mm"])
    assert code == 0, err
    assert "nonlinear step of 5 mm at the rod" in out
    assert _output_lines_in_degrees(out) == [] and "fin" not in out
    code, out, err = run_cli(["simulate", CONFIG, "--step", "5mm", "--json"])
    data = json.loads(out)
    assert data["step"]["amplitude_mm"] == 5.0 and "amplitude_deg" not in data["step"]
    assert "rms_residual_mm" in data["fit"] and not re.search(r"_deg\"", json.dumps(
        {k: v for k, v in data.items() if k in ("step", "fit")}))
    code, out, err = run_cli(["verify", CONFIG, "--json"])
    assert code == 0, err
    conditions = [r["condition"] for r in json.loads(out)["verdicts"]]
    assert "nonlinear step of 5 mm" in conditions


def test_cli_profile_move_in_mm():
    argv = ["simulate", CONFIG, "--profile", "5mm", "--velocity", "100mm/s",
            "--acceleration", "2000mm/s^2"]
    code, out, err = run_cli(argv)
    assert code == 0, err
    assert "profile move of 5 mm at 100 mm/s, 2000 mm/s^2 at the rod" in out
    # 5 mm = 2 motor revolutions; 100 mm/s = 20 screw rev/s = 40 motor rev/s = 2400 rpm
    assert "2 rev, profile velocity 2400 rpm" in out
    assert "largest tracking error during the move [mm]" in out
    assert _output_lines_in_degrees(out) == []
    code, out, err = run_cli([*argv, "--json"])
    data = json.loads(out)
    assert data["move"]["distance_mm"] == 5.0
    assert "tracking_error_max_mm" in data["profile"] and "_deg" not in json.dumps(data)


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_cli_report_in_mm(tmp_path):
    code, out, err = run_cli(["report", CONFIG, "-o", str(tmp_path / "r"), "-q",
                              "--amplitudes", "0.1mm,5mm", "--frequencies", "100:1000:3"])
    assert code == 0, err
    text = (tmp_path / "r" / "report.md").read_text(encoding="utf-8")
    assert "5 mm step" in text and "load spring K" in text
    assert _output_lines_in_degrees(text) == []
    assert not re.search(r"\bfin\b", text)
    results = (tmp_path / "r" / "results.json").read_text(encoding="utf-8")
    assert "amplitude_mm" in results and "amplitude_deg" not in results


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_cli_compare_of_two_linear_actuators_in_mm(tmp_path):
    heavy = tmp_path / "heavy.yaml"
    text = open(CONFIG, encoding="utf-8").read()
    heavy.write_text(text.replace("name: ball_screw", "name: heavy").replace(
        "mass: 20 kg ", "mass: 40 kg "), encoding="utf-8")
    code, out, err = run_cli(["compare", CONFIG, str(heavy), "-o", str(tmp_path / "c"), "-q",
                              "--amplitudes", "0.1mm,5mm", "--frequencies", "100:1000:3"])
    assert code == 0, err
    text = (tmp_path / "c" / "report.md").read_text(encoding="utf-8")
    assert "nonlinear step 5 mm: rise time" in text and "amplitudes at the rod: 0.1 mm, 5 mm" \
        in text
    assert _output_lines_in_degrees(text) == []
    assert "amplitude_deg" not in (tmp_path / "c" / "results.json").read_text(encoding="utf-8")


@pytest.mark.parametrize(("argv", "words"), [
    # rotary load keys on a linear output, and the other way round: key, value, what it takes
    (["analyze", CONFIG, "--set", "load.inertia=1e-4"],
     ("load.inertia:", "takes load.mass [kg]", "0.0001")),
    (["analyze", CONFIG, "--set", "load.hinge_stiffness=3"],
     ("load.hinge_stiffness:", "takes load.stiffness [N/m]", "3")),
    (["analyze", "configs/dc_servo.yaml", "--set", "load.mass=20 kg"],
     ("load.mass:", "rotary output takes load.inertia [kg*m^2]", "'20 kg'")),
    (["analyze", "configs/dc_servo.yaml", "--set", "load.bias=3"],
     ("load.bias:", "rotary output takes load.hinge_bias [N*m]", "3")),
    # a linear output's gear stiffness is axial
    (["analyze", CONFIG, "--set", "gear.stiffness=1e6 N*m/rad"],
     ("gear.stiffness:", "'1e6 N*m/rad'", "N/m")),
    # a step of the other kind
    (["simulate", CONFIG, "--step", "10deg"],
     ("--step: 10deg is an angle; this actuator's output is linear: give a length, e.g. 5mm",)),
    (["simulate", "configs/dc_servo.yaml", "--step", "5mm"],
     ("--step: 5mm is a length; this actuator's output is rotary: give an angle, e.g. 10deg",)),
    (["sinedwell", CONFIG, "--amplitudes", "1deg"],
     ("--amplitudes: 1deg is an angle", "give a length, e.g. 5mm")),
    (["simulate", CONFIG, "--profile", "5deg", "--velocity", "100mm/s", "--acceleration",
      "2000mm/s^2"], ("--profile: 5deg is an angle", "give a length, e.g. 5mm")),
    (["simulate", CONFIG, "--profile", "5mm", "--velocity", "100deg/s", "--acceleration",
      "2000mm/s^2"], ("--velocity:", "'100deg/s'", "100mm/s")),
    # the load envelope sweeps a rotary output's hinge spring
    (["analyze", CONFIG, "--set", "load_envelope.hinge_stiffness=0:1:3"],
     ("load_envelope: the load envelope sweeps a rotary output's load.hinge_stiffness",)),
    # command tables are read as angles: refused at a linear output, not misread
    (["simulate", CONFIG, "--command", "tests/no_such_command.csv"],
     ("--command: ball_screw has a linear output (gear.screw_lead)",)),
])
def test_bad_linear_input_names_key_value_and_what_is_accepted(argv, words):
    code, out, err = run_cli(argv)
    assert code == 2
    assert err.count("\n") == 1, err  # one line
    for word in words:
        assert word in err


@pytest.mark.parametrize(("config", "metric", "words"), [
    (CONFIG, "profile.tracking_error_max_deg",
     "profile.tracking_error_max_deg is an angle of the output; this actuator's output is "
     "linear: use profile.tracking_error_max_mm"),
    ("configs/dc_servo.yaml", "profile.tracking_error_max_mm",
     "profile.tracking_error_max_mm is a length of the output; this actuator's output is "
     "rotary: use profile.tracking_error_max_deg"),
])
def test_requirement_on_an_output_quantity_of_the_other_kind(tmp_path, config, metric, words):
    data = yaml.safe_load(open(config, encoding="utf-8"))
    data["requirements"] = [{"id": "T", "metric": metric, "max": 1, "profile": {
        "distance": "5 mm", "velocity": "100 mm/s", "acceleration": "2000 mm/s^2"}}]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    code, out, err = run_cli(["verify", str(path)])
    assert code == 2
    assert f"requirements.0.metric: {words}" in err


def test_requirement_step_in_degrees_on_a_linear_output(tmp_path):
    data = yaml.safe_load(open(CONFIG, encoding="utf-8"))
    data["requirements"][3]["step"] = "0.3 deg"  # OS-1
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    code, out, err = run_cli(["verify", str(path)])
    assert code == 2
    assert "requirements.3.step: 0.3 deg is an angle; this actuator's output is linear: give " \
           "a length, e.g. 5mm" in err
