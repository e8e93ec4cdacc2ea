"""Limit cycles (docs/model.md, "15. Stiffness, effort and noise", "Limit cycles").

The describing functions against their closed forms and a Fourier integral written here; the
loops each nonlinearity sees against a derivation written here from the signal equations;
the harmonic balance and Loeb's criterion on a textbook loop; the predictions against the
nonlinear simulation (QT-CAS `fin_encoder` with backlash, Coulomb friction with integral action).
"""

import json
import math

import numpy as np
import pytest
from clirun import run_cli

from cas_freq.analysis import describing
from cas_freq.analysis.limit_cycles import (
    CONFIRM_TOLERANCE,
    limit_cycles,
    loeb_stable,
    negative_real_crossings,
)
from cas_freq.cli.common import selected_variants
from cas_freq.core.parameters import LoopParameters
from cas_freq.model.loops import Selector

#: fin_encoder with the play and nothing else nonlinear in the gear: no hinge bias preloading
#: it, no friction, efficiencies 1 (below 1 the load's reflection depends on the direction of
#: power: a nonlinearity too).
CLEAN_BACKLASH = ["gear.backlash=0.1 deg", "load.hinge_bias=0 N*m",
                  "motor.coulomb_friction=0 N*m", "gear.efficiency=1",
                  "gear.backdrive_efficiency=1"]


def _stdout(argv):
    code, out, _ = run_cli(argv)
    assert code == 0
    return out


def _params(variant, sets, config=None):
    return LoopParameters.from_config(selected_variants(config, [variant], sets)[0].params)


def _first_harmonic(function, amplitude):
    """N(A) = b1/A, b1 = (1/pi) * integral over a period of f(A sin phi) sin phi (midpoint
    rule on 20,000 points: exact to ~1e-8 for these piecewise-smooth functions)."""
    phi = (np.arange(20000) + 0.5) * 2 * np.pi / 20000
    return np.mean(function(amplitude * np.sin(phi)) * np.sin(phi)) * 2 / amplitude


def test_describing_functions_closed_forms_and_fourier():
    # Closed forms (Gelb & Vander Velde 1968, App. B; Slotine & Li 1991, sec. 5.3): at A = 2a
    # the saturation's N = (2/pi)(asin(1/2) + (1/2) sqrt(3/4)) = 1/3 + sqrt(3)/(2 pi), and the
    # dead zone of half-width d at A = 2d is 1 minus that.
    assert describing.saturation(2.0, 1.0) == pytest.approx(1 / 3 + math.sqrt(3) / (2 * math.pi),
                                                            rel=1e-14)
    assert describing.dead_zone(2.0, 1.0) == pytest.approx(2 / 3 - math.sqrt(3) / (2 * math.pi),
                                                           rel=1e-14)
    assert describing.saturation(0.5, 1.0) == 1.0 and describing.dead_zone(0.5, 1.0) == 0.0
    a, d = 1.0, 0.7  # a clamp at ±1; half of a play b = 1.4
    for amplitude in (1.01, 1.5, 3.0, 30.0):
        assert describing.saturation(amplitude, a) == pytest.approx(
            _first_harmonic(lambda x: np.clip(x, -a, a), amplitude), abs=1e-7)
        assert describing.dead_zone(amplitude, d) == pytest.approx(
            _first_harmonic(lambda x: x - np.clip(x, -d, d), amplitude), abs=1e-7)
        assert describing.relay(amplitude, 0.3) == pytest.approx(
            _first_harmonic(lambda x: 0.3 * np.sign(x), amplitude), rel=1e-7)
    # Coulomb friction on a shaft turning theta = X sin(w t): the torque -F sign(omega) has the
    # first harmonic -(4F/pi) cos(w t), in phase with the speed X w cos(w t): per unit speed
    # 4F/(pi X w), the relay's N at the speed amplitude X w.
    x_amp, w, f = 0.02, 30.0, 1e-3
    t = (np.arange(20000) + 0.5) / 20000 * 2 * np.pi / w
    speed = x_amp * w * np.cos(w * t)
    b1 = 2 * np.mean(f * np.sign(speed) * np.cos(w * t))
    assert b1 / (x_amp * w) == pytest.approx(4 * f / (math.pi * x_amp * w), rel=1e-6)
    assert describing.relay(x_amp * w, f) == pytest.approx(4 * f / (math.pi * x_amp * w))
    # the inverses
    assert describing.saturation(describing.saturation_amplitude(0.2, 2.0), 2.0) == \
        pytest.approx(0.2, rel=1e-10)
    assert describing.dead_zone(describing.dead_zone_amplitude(0.03, 1e-3), 1e-3) == \
        pytest.approx(0.03, rel=1e-10)


def test_speed_loop_rigid_against_the_closed_form():
    # The closed form on the motor (rigid gear, PID-on-PI): theta/tau =
    # 1/(P + Km (C_i e^(-s tau_c) C_p e^(-s tau_p) + Ke s)/(L s + R + C_i e^(-s tau_c))).
    p = Selector(_params("base", []))()
    s = 1j * np.geomspace(0.1, 1e5, 50)
    ci = (p.ci_Kp + p.ci_Ki / s) * np.exp(-s * p.tau_c)
    cp = (p.cp_Kp + p.cp_Ki / s + p.cp_Kd * s / (p.Tf * s + 1)) * np.exp(-s * p.tau_p)
    theta = 1 / (p.J * s**2 + p.mu_v * s
                 + p.Km * (ci * cp + p.Ke * s) / (p.L * s + p.R + ci))
    speed, delta = describing.speed_loop(p, s)
    np.testing.assert_allclose(speed, s * theta, rtol=1e-12)
    np.testing.assert_allclose(delta, theta / p.ratio, rtol=1e-12)


def _signal_equations(p, s, kind):
    """The PID-on-PI closed on the output angle N delta, its signal equations solved at each
    frequency (unknowns i, theta, delta; V eliminated): with an injected gear torque
    (K_g + c_g s) y (``twist``, the spring acting only through y) or a torque on the motor
    shaft (``speed``)."""
    ci = (p.ci_Kp + p.ci_Ki / s) * np.exp(-s * p.tau_c)
    cp = (p.cp_Kp + p.cp_Ki / s + p.cp_Kd * s / (p.Tf * s + 1)) * np.exp(-s * p.tau_p)
    n, gear = p.ratio, p.K_g + p.c_g * s
    out = []
    for k, sk in enumerate(s):
        spring = 0.0 if kind == "twist" else gear[k]
        # V = C_i (C_p (0 - N delta) - i); (L s + R) i = V - Ke s theta
        # J s^2 theta + mu s theta = Km i - tau_g/(eta N) + tau; tau_g = spring*(theta/N - delta)
        # + injected; J_L s^2 delta + b_L s delta + K_h delta = tau_g
        a = np.array([
            [p.L * sk + p.R + ci[k], p.Ke * sk, ci[k] * cp[k] * n],
            [-p.Km, p.J * sk**2 + p.mu_v * sk + spring / (p.eta * n * n), -spring / (p.eta * n)],
            [0.0, -spring / n, p.J_L * sk**2 + p.b_L * sk + p.K_h + spring],
        ], dtype=complex)
        if kind == "twist":
            b = np.array([0.0, -gear[k] / (p.eta * n), gear[k]], dtype=complex)
            i, theta, delta = np.linalg.solve(a, b)
            out.append((-(theta / n - delta), delta))
        else:
            i, theta, delta = np.linalg.solve(a, np.array([0.0, 1.0, 0.0], dtype=complex))
            out.append((sk * theta, delta))
    return np.array(out).T


@pytest.mark.parametrize("kind", ["twist", "speed"])
def test_loops_seen_against_the_signal_equations(kind):
    p = Selector(_params("fin_encoder", ["gear.backlash=0.1 deg"]))()
    s = 1j * np.geomspace(1.0, 3e4, 40)
    expected = _signal_equations(p, s, kind)
    got = (describing.twist_loop if kind == "twist" else describing.speed_loop)(p, s)
    np.testing.assert_allclose(got[0], expected[0], rtol=1e-9)
    np.testing.assert_allclose(got[1], expected[1], rtol=1e-9)


def test_harmonic_balance_textbook_loop():
    # G = K/(s (s+1)(s+2)): Im G = 0 at w = sqrt(2), where G = -K/6 (Slotine & Li, Example
    # 5.13's loop). With a saturation (1/N grows with A) the cycle is stable (Loeb), as the
    # relay autotuner's is.
    k = 10.0

    def g(w):
        s = 1j * np.asarray(w)
        return k / (s * (s + 1) * (s + 2))

    (omega, value), = negative_real_crossings(g, 0.01, 100.0)
    assert omega == pytest.approx(math.sqrt(2), rel=1e-12)
    assert value == pytest.approx(-k / 6, rel=1e-10)
    assert loeb_stable(g, omega, +1.0)
    assert not loeb_stable(g, omega, -1.0)  # a dead zone there: unstable
    # G with a stable first-order lag never reaches the negative real axis
    assert negative_real_crossings(lambda w: 1 / (1j * np.asarray(w) + 1), 0.01, 100) == []


@pytest.fixture(scope="module")
def clean_backlash():
    return limit_cycles(_params("fin_encoder", CLEAN_BACKLASH), simulate=True)


def test_backlash_in_the_output_encoder_loop(clean_backlash):
    cycles = [c for c in clean_backlash.cycles if c.nonlinearity == "backlash"]
    assert len(cycles) == 2
    barely, engaged = sorted(cycles, key=lambda c: c.frequency_rad_s)
    # the low one barely touches the flanks: outside the assumptions, and not what a run does
    assert not barely.assumptions_hold and "barely engages" in barely.notes[0]
    assert barely.simulated.verdict == "refuted"
    # the high one (figures of 2026-11-26: predicted 1390 rad/s, twist 9.60e-4 rad, output
    # 0.0614 deg; simulated 1166 rad/s, 7.90e-4 rad, 0.0549 deg)
    assert engaged.assumptions_hold and engaged.stability == "stable"
    assert engaged.frequency_rad_s == pytest.approx(1390, rel=0.01)
    sim = engaged.simulated
    assert sim.sustained and sim.verdict == "confirmed"
    assert abs(sim.frequency_rad_s / engaged.frequency_rad_s - 1) <= CONFIRM_TOLERANCE
    assert abs(sim.amplitude / engaged.amplitude - 1) <= CONFIRM_TOLERANCE
    assert abs(sim.output_amplitude_rad / engaged.output_amplitude_rad - 1) <= CONFIRM_TOLERANCE


def test_backlash_as_shipped_says_the_assumptions_fail():
    # the shipped fin_encoder's hinge moment preloads the play, and its friction and
    # self-locking worm are nonlinear too: every backlash cycle says so
    result = limit_cycles(_params("fin_encoder", ["gear.backlash=0.1 deg"]))
    cycles = [c for c in result.cycles if c.nonlinearity == "backlash"]
    assert cycles and not any(c.assumptions_hold for c in cycles)
    assert all(any("preloads the play" in note for note in c.notes) for c in cycles)
    assert all(any("other nonlinearities" in note for note in c.notes) for c in cycles)


def test_coulomb_friction_threshold_confirmed():
    # Integral action strong enough that the loop without friction is unstable: the friction
    # holds it still below a speed amplitude, the describing function's unstable cycle
    # (figures of 2026-11-26: predicted 40.9 rad/s at 284.2 rad/s; simulated 43.0 rad/s at
    # 290 rad/s)
    result = limit_cycles(_params("fitted", ["motor.coulomb_friction=1 mN*m",
                                             "position_loop.Ki=3000 A/(rad*s)"]), simulate=True)
    cycle, = [c for c in result.cycles if c.nonlinearity == "coulomb_friction"]
    assert cycle.stability == "unstable" and cycle.assumptions_hold
    assert cycle.frequency_rad_s == pytest.approx(284.2, rel=0.01)
    sim = cycle.simulated
    assert sim.method == "threshold" and sim.verdict == "confirmed"
    assert abs(sim.amplitude / cycle.amplitude - 1) <= CONFIRM_TOLERANCE
    assert abs(sim.frequency_rad_s / cycle.frequency_rad_s - 1) <= CONFIRM_TOLERANCE


def test_coulomb_friction_hunting_outside_the_assumptions():
    # Friction with integral action in a stable cascade: the describing function finds the
    # "hunting" cycle where the loop seen rises as w^2 (its 3rd harmonic is amplified: the
    # tool says the low-pass hypothesis fails) and the run sticks and creeps instead.
    result = limit_cycles(_params("base", ["motor.coulomb_friction=0.02 N*m"],
                                  "configs/cascade_axis.yaml"), simulate=True)
    cycle, = [c for c in result.cycles if c.nonlinearity == "coulomb_friction"]
    assert cycle.stability == "stable" and not cycle.assumptions_hold
    assert cycle.harmonics[1] > 1
    assert any("low-pass hypothesis fails" in note for note in cycle.notes)
    assert cycle.simulated.verdict == "refuted"


def test_none_predicted_is_an_empty_list_with_the_reason():
    result = limit_cycles(_params("loaded", []))
    assert result.cycles == () and "coulomb_friction" in result.checked
    assert "no solution" in result.reason
    data = json.loads(_stdout(["analyze", "--variant", "loaded", "--json"]))
    assert data["limit_cycles"] == [] and "no solution" in data["limit_cycles_reason"]


def test_cli_text_and_json():
    args = ["analyze", "--variant", "fin_encoder", "--set", "gear.backlash=0.1 deg"]
    text = _stdout(args)
    assert "limit cycles (describing functions: backlash" in text
    data = json.loads(_stdout([*args, "--json"]))
    kinds = [c["nonlinearity"] for c in data["limit_cycles"]]
    assert kinds.count("backlash") == 2 and data["limit_cycles_reason"] is None
    first = data["limit_cycles"][0]
    assert first["simulated"] is None and first["output_amplitude_deg"] > 0
    # sampled controllers: the figure is of the continuous loops, and says so
    sampled = json.loads(_stdout(["analyze", "--variant", "sampled", "--json"]))
    assert any("continuous loops" in note for note in sampled["limit_cycles_notes"])


def test_report_sentence():
    from cas_freq.analysis.limit_cycles import report_sentence

    none = report_sentence(limit_cycles(_params("loaded", [])))
    assert none.startswith("Limit cycles (describing functions of coulomb_friction")
    assert "none: no loop seen by" in none
    some = report_sentence(limit_cycles(_params("base", [])))
    assert "saturation.position_loop unstable at 40.04 rad/s, output ±804.5 deg" in some


def test_linear_output_backlash_in_metres():
    # ball_screw with a compliant screw, play, efficiencies 1 and the loop closed on the rod
    # (figures of 2026-11-26: a stable cycle at 818.5 rad/s, twist ±1.43e-5 m, output
    # ±0.0166 mm; simulated 788.8 rad/s, ±1.33e-5 m, ±0.0156 mm: confirmed)
    sets = ["gear.backlash=0.02 mm", "gear.stiffness=2e7 N/m", "load.mass=5 kg",
            "position_loop.feedback=output", "gear.efficiency=1", "gear.backdrive_efficiency=1"]
    data = json.loads(_stdout(["analyze", "configs/ball_screw.yaml", "--json",
                               *(x for item in sets for x in ("--set", item))]))
    backlash = [c for c in data["limit_cycles"] if c["nonlinearity"] == "backlash"]
    assert {c["unit"] for c in backlash} == {"m"}
    held = [c for c in backlash if c["assumptions_hold"]]
    assert len(held) == 1 and held[0]["frequency_rad_s"] == pytest.approx(818.5, rel=0.01)
    assert held[0]["output_amplitude_mm"] == pytest.approx(0.0165, rel=0.02)
    assert "output_amplitude_deg" not in held[0]


def test_speed_loop_of_the_cascade_against_the_oracle():
    # The cascade (P-PI-PI, notch at the current command, low-passes on the measured speed,
    # compliant coupling): every signal equation of tests/architecture_oracle.py (written
    # without cas_freq) solved per frequency with a unit torque on the motor shaft (the
    # right-hand side of its motor row) gives the speed and the output per unit torque.
    import architecture_oracle as oracle

    p = Selector(_params("base", [], "configs/cascade_axis.yaml"))()
    drive = oracle.Drive(
        R=p.R, L=p.L, Km=p.Km, Ke=p.Ke, J=p.J, mu_v=p.mu_v, N=p.ratio, eta=p.eta, J_L=p.J_L,
        b_L=p.b_L, K_h=p.K_h, K_g=p.K_g, c_g=p.c_g, ci_Kp=p.ci_Kp, ci_Ki=p.ci_Ki,
        tau_c=p.tau_c, structure="cascade", cp_Kp=p.cp_Kp, cp_Ki=p.cp_Ki, cv_Kp=p.cv_Kp,
        cv_Ki=p.cv_Ki, tau_v=p.tau_v, tau_vf=p.tau_vf, tau_p=p.tau_p,
        filters=(oracle.Filter("current_command", "notch", 800.0, width=400.0, depth_db=-20.0),
                 oracle.Filter("velocity_feedback", "lowpass2", 3000.0, damping=0.7)))
    omega = np.geomspace(0.5, 2e4, 30)
    eq = oracle._Equations(1j * omega)
    oracle._diagram(eq, drive, {loop: "closed" for loop in drive.loops}, 0.0, "exact")
    motor_row = len(drive.loops) + 1  # after the loops' rows and the winding's
    terms, _ = eq.rows[motor_row]
    assert any(eq.index["theta"] == j for j, _ in terms)
    eq.rows[motor_row] = (terms, 1.0)
    x = eq.solve()
    speed, delta = describing.speed_loop(p, 1j * omega)
    np.testing.assert_allclose(speed, 1j * omega * x["theta"], rtol=1e-8)
    np.testing.assert_allclose(delta, x["y_out"] / p.ratio, rtol=1e-8)
