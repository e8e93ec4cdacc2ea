"""Dynamic stiffness, control effort and encoder-noise current (issue 27; docs/model.md §15).

cas_freq derives all three from the declared loop structure (cas_freq/model/disturbance.py:
the plant's numerators per load torque and their couplings over Delta, the cascade's terms).
The references here share none of that algebra:

* rigid gear: the closed form of the issue, written out below from the loop equations;
* compliant gear, output encoder and the velocity-loop cascade: the signal equations of
  tests/architecture_oracle.py (Newton's equations of the two masses, one row per block),
  with a unit load torque (or a unit measurement noise) added to their right-hand sides, solved
  at each frequency by numpy.linalg.solve;
* the noise RMS: scipy.integrate.quad of |i/noise|^2 of the closed form.

Tolerances: the two exact-delay computations agree to ~1e-12 (rounding); 1e-9 relative still
catches any modelling slip (an efficiency, a sign, a sensor move them by far more).
"""

import json
import math

import numpy as np
import pytest
import yaml
from architecture_oracle import _diagram, _Equations, example_cascade, qt_cas_drive, replace
from clirun import run_cli
from scipy.integrate import quad

import cas_freq as cf
from cas_freq.analysis.disturbance import disturbance_figures, noise
from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import LoopParameters
from cas_freq.model import parts
from cas_freq.model.actuator_loops import ActuatorLoops
from cas_freq.model.disturbance import encoder_weights, load_response, noise_current
from cas_freq.model.loops import Selector
from cas_freq.model.structure import build
from cas_freq.studies.sweep import evaluate_figures

QT = "configs/qt_cas.yaml"
AXIS = "configs/cascade_axis.yaml"
BALL = "configs/ball_screw.yaml"
W = np.geomspace(0.1, 1e5, 301)


def _p(path, variant="base", **changes):
    """One run's parameters (a namespace of scalars), with ``changes`` to its fields."""
    p = Selector(LoopParameters.from_config(cf.load(path, variant).params))()
    for key, value in changes.items():
        setattr(p, key, value)
    return p


def _rigid_terms(p, s):
    """The blocks of the report's PID-on-PI, written out (docs/model.md §2-§4)."""
    e = 1.0 / p.eta
    n = p.ratio
    mech = (p.J * s**2 + p.mu_v * s + e * (p.J_L * s**2 + p.b_L * s + p.K_h) / n**2)
    ci = (p.ci_Kp * s + p.ci_Ki) / s * np.exp(-s * p.tau_c)
    cp = (p.cp_Kp + p.cp_Ki / s + p.cp_Kd * s / (p.Tf * s + 1.0)) * np.exp(-s * p.tau_p)
    return e, n, mech, ci, cp, p.L * s + p.R


def _rigid_stiffness_reference(p, s):
    """The issue's closed form on the motor, theta/tau_m = 1/(P + Km (C_i C_p + Ke s)/(L s + R
    + C_i)) (delays in C_i, C_p), the load torque reflected to the motor as e tau/N and the
    output delta = theta/N: delta/tau = (e/N^2) theta/tau_m."""
    e, n, mech, ci, cp, z_e = _rigid_terms(p, s)
    return e / n**2 / (mech + p.Km * (ci * cp + p.Ke * s) / (z_e + ci))


@pytest.mark.parametrize("variant,changes", [
    ("fitted", {}),
    ("base", {}),
    ("fitted", {"K_h": 30.0, "eta": 0.8, "J_L": 2e-5, "b_L": 1e-3}),  # a reflected load
])
def test_rigid_gear_stiffness_equals_the_closed_form(variant, changes):
    p = _p(QT, variant, **changes)
    s = 1j * W
    assert load_response(p, s) == pytest.approx(_rigid_stiffness_reference(p, s), rel=1e-9)


def test_fitted_qt_cas_minimum_is_km_kp_n2_near_56_rad_s():
    # the reference figure: about Km*Kp*N^2 = 0.0075*6.3435*20^2 = 19.0 N*m/rad (the
    # proportional path alone); the delays and the current loop's lag bring it to 18.5
    ours = cf.load(QT, "fitted").analyze()
    assert ours.stiffness.min_N_m_per_rad == pytest.approx(18.5, abs=0.05)
    assert ours.stiffness.min_at_rad_s == pytest.approx(56.0, abs=1.0)
    # the minimum refined: no grid point of a dense grid lies below it
    p = _p(QT, "fitted")
    dense = np.geomspace(30.0, 100.0, 20001)
    assert np.min(1.0 / np.abs(_rigid_stiffness_reference(p, 1j * dense))) >= \
        ours.stiffness.min_N_m_per_rad * (1 - 1e-9)


def _oracle_solve(d, omega, load=0.0, noise=0.0):
    """The oracle's signal equations with every loop closed, no command, a load torque ``load``
    at the output and a noise ``noise`` on the encoder's angle (the motor's: on y_p and, as
    s*noise, on the velocity w before its filters; the output's: on y_p) added to their
    right-hand sides; returns every signal."""
    s = 1j * np.asarray(omega, dtype=float)
    eq = _Equations(s)
    _diagram(eq, d, dict.fromkeys(d.loops, "closed"), 0.0, "exact")
    names = {j: name for name, j in eq.index.items()}
    for k, (terms, _) in enumerate(eq.rows):
        signals = {names[j] for j, _ in terms}
        if d.K_g == 0.0 and signals == {"theta", "i"}:  # rigid: the motor's equation
            eq.rows[k] = (terms, load / (d.eta * d.N))
        elif d.K_g > 0.0 and signals == {"y_out", "theta"}:  # compliant: the output's
            eq.rows[k] = (terms, load)
        elif signals == {"y_p", "theta"} or signals == {"y_p", "y_out"}:
            eq.rows[k] = (terms, noise * (1.0 if d.feedback == "motor" else d.N))
        elif signals == {"w", "theta"} and d.feedback == "motor":
            eq.rows[k] = (terms, noise * s)
    return eq.solve()


CASES = [  # (config, variant, --set, the oracle's drive)
    (QT, "loaded", {}, lambda: qt_cas_drive("loaded")),
    (QT, "fin_encoder", {}, lambda: replace(qt_cas_drive("loaded"), feedback="output")),
    (AXIS, "base", {}, lambda: example_cascade(cv_Kp=1.3)),
    (AXIS, "base", {"K_g": 0.0, "c_g": 0.0},
     lambda: replace(example_cascade(cv_Kp=1.3), K_g=0.0, c_g=0.0)),
    (AXIS, "base", {"feedback_output": True},
     lambda: replace(example_cascade(cv_Kp=1.3), feedback="output")),
]


@pytest.mark.parametrize("path,variant,changes,drive", CASES)
def test_stiffness_equals_the_signal_equations(path, variant, changes, drive):
    p = _p(path, variant, **changes)
    d = drive()
    reference = _oracle_solve(d, W, load=1.0)["y_out"] / d.N
    assert load_response(p, 1j * W) == pytest.approx(reference, rel=1e-9)


@pytest.mark.parametrize("path,variant,changes,drive", CASES)
def test_encoder_noise_current_equals_the_signal_equations(path, variant, changes, drive):
    p = _p(path, variant, **changes)
    d = drive()
    reference = _oracle_solve(d, W, noise=1.0)["i"]
    ours = noise_current(p, 1j * W, encoder_weights(p))
    assert ours == pytest.approx(reference, rel=1e-9, abs=1e-12 * np.max(np.abs(reference)))


@pytest.mark.parametrize("path,variant", [(QT, "loaded"), (AXIS, "base")])
def test_the_couplings_are_the_plants_minors(path, variant):
    # coupling_y * Delta = n^M_out n^V_y - n^V_out n^M_y, as polynomials (at random s)
    plant = build(_p(path, variant)).plant
    s = np.array([0.3 + 2j, -5.0 + 40j, 100.0 + 3e3j])
    value = lambda poly: parts.polyval(poly, s)  # noqa: E731
    for name, coupling in plant.coupling.items():
        minor = (value(plant.load["output_angle"]) * value(plant.signals[name])
                 - value(plant.signals["output_angle"]) * value(plant.load[name]))
        assert value(coupling) * value(plant.denominator) == pytest.approx(minor, rel=1e-9)


def _rigid_noise_reference(p, s):
    """i per unit noise on the motor encoder's angle, PID-on-PI, rigid: the position
    controller acts on -(theta + n); (Z_e + C_i) i = C_i i_cmd - Ke s theta; theta = Km i/P."""
    _, _, mech, ci, cp, z_e = _rigid_terms(p, s)
    return -ci * cp / (z_e + ci + p.Km * (p.Ke * s + ci * cp) / mech)


@pytest.mark.parametrize("variant,band", [("sampled", math.pi * 2500.0), ("fitted", 1e6)])
def test_noise_rms_equals_a_direct_integration(variant, band):
    counts = 2048
    loaded = cf.load(QT, variant, set={"sensors.counts_per_rev": counts})
    p = _p(QT, variant)
    ours = loaded.analyze().noise
    assert ours.band_rad_s == pytest.approx(band, rel=1e-12)

    def power(w):
        return abs(_rigid_noise_reference(p, 1j * max(w, 1e-2))) ** 2

    edges = np.geomspace(1e-2, band, 60)
    integral = power(1e-2) * 1e-2 + sum(quad(power, a, b, limit=200, epsrel=1e-10)[0]
                                        for a, b in zip(edges[:-1], edges[1:], strict=True))
    q = 2.0 * math.pi / counts
    reference = q / math.sqrt(12.0) * math.sqrt(integral / band)
    # 400 points per decade by the trapezoid rule: ~1e-5 relative on these smooth curves
    assert ours.current_rms_A == pytest.approx(reference, rel=1e-4)


def test_noise_needs_the_encoders_resolution():
    ours = cf.load(QT, "fitted").analyze()
    assert ours.noise.current_rms_A is None
    assert "counts_per_rev" in ours.noise.note
    assert ours.to_dict()["noise"]["current_rms_A"] is None


def test_effort_is_the_closed_loop_read_at_the_current():
    p = _p(QT, "fitted")
    ours = cf.load(QT, "fitted").analyze().effort
    dense = np.geomspace(100.0, 1e5, 40001)
    _, n, mech, ci, cp, z_e = _rigid_terms(p, 1j * dense)
    # i/theta_cmd = C_i C_p/(Z_e + C_i + Km (Ke s + C_i C_p)/P); delta_cmd = theta_cmd/N
    current = n * np.abs(ci * cp / (z_e + ci + p.Km * (p.Ke * 1j * dense + ci * cp) / mech))
    assert ours.peak_A_per_rad == pytest.approx(np.max(current), rel=1e-6)
    assert ours.peak_at_rad_s == pytest.approx(dense[np.argmax(current)], rel=1e-3)
    # and cas_freq's own view of it: ActuatorLoops.current_response
    loops = ActuatorLoops(LoopParameters.from_config(cf.load(QT, "fitted").params))
    assert abs(loops.current_response(1j * ours.peak_at_rad_s)) == \
        pytest.approx(ours.peak_A_per_rad, rel=1e-9)


def test_a_linear_output_gives_newtons_per_metre(tmp_path):
    data = cf.load("configs/ball_screw.yaml").analyze().to_dict()
    assert set(data["stiffness"]) >= {"min_N_per_m", "min_at_rad_s"}
    assert "min_N_m_per_rad" not in data["stiffness"]
    assert data["stiffness"]["min_N_per_m"] > 0
    assert "peak_A_per_m" in data["effort"]


def test_an_unstable_loop_reports_no_figures_with_the_reason():
    ours = cf.load(AXIS, "no_notch").analyze()
    assert ours.stiffness.minimum is None and "not stable" in ours.stiffness.note
    assert ours.to_dict()["stiffness"]["min_N_m_per_rad"] is None


def test_sampled_controllers_say_the_figures_are_the_continuous_loops():
    sampled = cf.load(QT, "sampled").analyze().stiffness
    base = cf.load(QT).analyze().stiffness
    assert "continuous loops" in sampled.note and "continuous" not in base.note
    assert sampled.minimum == pytest.approx(base.minimum, rel=1e-12)


def test_counts_per_rev_is_checked(tmp_path):
    config = yaml.safe_load(open(QT, encoding="utf-8"))
    config["sensors"] = {"counts_per_rev": 0}
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(config), encoding="utf-8")
    with pytest.raises(ConfigError, match="sensors.counts_per_rev"):
        cf.load(path)


def test_disturbance_figures_honour_the_grid_ends():
    params = LoopParameters.from_config(cf.load(QT, "fitted").params)
    omega = np.geomspace(1.0, 1e4, 2001)
    stiff, push, _ = disturbance_figures(params, omega)
    assert omega[0] <= stiff.min_at_rad_s <= omega[-1]
    assert omega[0] <= push.peak_at_rad_s <= omega[-1]
    # the noise's scaling: RMS proportional to q = 2 pi/counts
    p = _p(QT, "fitted")
    one, two = noise(p, 1.0, 1e4, 1000.0), noise(p, 1.0, 1e4, 2000.0)
    assert one.quantum_rad == pytest.approx(2 * math.pi / 1000.0)
    assert one.current_rms_A == pytest.approx(2.0 * two.current_rms_A, rel=1e-12)


def test_analyze_prints_and_refuses_on_the_command_line():
    code, out, _ = run_cli(["analyze", QT, "--variant", "fitted",
                            "--set", "sensors.counts_per_rev=2048"])
    assert code == 0
    assert "dynamic stiffness  min 18.5 N*m/rad at 55.9" in out
    assert "encoder noise      8.7" in out or "encoder noise      8.8" in out
    code, out, _ = run_cli(["analyze", QT, "--variant", "fitted", "--json"])
    data = json.loads(out)
    assert data["stiffness"]["min_N_m_per_rad"] == pytest.approx(18.496, abs=1e-3)
    assert data["noise"]["current_rms_A"] is None
    code, _, err = run_cli(["analyze", QT, "--set", "sensors.counts_per_rev=0.5"])
    assert code == 2 and "sensors.counts_per_rev" in err and "0.5" in err


@pytest.mark.parametrize("path, variant, changes", [
    # the cascade (compliant gear, spring load, notch): two keys of its loops
    (AXIS, "base", {"motor.J": [9.5e-5, 1e-4, 1.05e-4], "velocity_loop.Kp": [1.17, 1.3, 1.43]}),
    # the QT-CAS sampled, with its current loop's delay varied: each variant alone has a grid of
    # its own delay, the batch one of the largest
    (QT, "sampled", {"motor.Km": [0.0095, 0.0105, 0.0115],
                     "current_loop.delay": [4e-5, 6e-5, 8e-5]}),
    (BALL, "base", {"motor.J": [0.9, 1.0, 1.1]}),  # a linear output: per m
])
def test_a_batch_s_figures_are_each_variant_s_own(path, variant, changes):
    """evaluate_figures(disturbance=True) (every run at once:
    batch_disturbance_figures) against analyze of each variant alone. The extrema are refined
    to 1e-9 in log frequency on each one's grid, so the values agree to ~1e-12 (a smooth
    extremum's value is second order in the frequency's error) and the frequencies to 1e-6;
    the noise integral's grid is the same for both (1e-12)."""
    loaded = load_variant(path, variant, overrides=[("sensors.counts_per_rev", 2048)])
    if path == BALL:
        changes = {"motor.J": loaded.params.motor.J * np.array(changes["motor.J"])}
    figures, stability = evaluate_figures(loaded.params, {k: np.asarray(v, dtype=float) for
                                                          k, v in changes.items()},
                                          fit=False, disturbance=True)
    assert np.all(stability == "stable")
    for run in range(3):
        alone = cf.load(path, variant, set={"sensors.counts_per_rev": 2048, **{
            key: float(values[run]) for key, values in changes.items()}}).analyze().to_dict()
        for section, names in (("stiffness", ("min_N_m_per_rad", "min_N_per_m")),
                               ("effort", ("peak_A_per_rad", "peak_A_per_m"))):
            name = next(n for n in names if n in alone[section])
            assert figures[f"{section}.{name}"][run] == pytest.approx(
                alone[section][name], rel=1e-12)
        assert figures["stiffness.min_at_rad_s"][run] == pytest.approx(
            alone["stiffness"]["min_at_rad_s"], rel=1e-6)
        assert figures["effort.peak_at_rad_s"][run] == pytest.approx(
            alone["effort"]["peak_at_rad_s"], rel=1e-6)
        if alone["noise"]["current_rms_A"] is None:  # a linear output's encoder on the output
            assert math.isnan(figures["noise.current_rms_A"][run])
        else:
            assert figures["noise.current_rms_A"][run] == pytest.approx(
                alone["noise"]["current_rms_A"], rel=1e-12)


def test_a_batch_gives_no_figures_where_a_run_is_not_stable():
    loaded = load_variant(AXIS)
    figures, stability = evaluate_figures(loaded.params, {"motor.J": np.array([1e-4, 2e-5])},
                                          fit=False, disturbance=True)
    assert list(stability.astype(str) == "stable") == [True, False]
    assert np.isfinite(figures["stiffness.min_N_m_per_rad"][0])
    assert np.isnan(figures["stiffness.min_N_m_per_rad"][1])
    assert np.isnan(figures["effort.peak_A_per_rad"][1])
