"""The linear model with load and drivetrain (docs/model.md, "Load and drivetrain").

Every expected value here is computed independently of cas_freq.model: the plant is written out
in the test from the model's differential equations as a state matrix (numpy, by hand), its
frequency response is solved per frequency, the loops are closed by hand, and crossings are
found with scipy's brentq. The closed forms (reflected inertia and spring, two-mass resonance
and anti-resonance) are the textbook ones, worked out in the tests.
"""

import json
import math

import numpy as np
import pytest
from clirun import run_cli
from scipy.optimize import brentq

from cas_freq.analysis.drivetrain import drivetrain
from cas_freq.analysis.stability import closed_loop_poles, stability_verdicts
from cas_freq.analysis.systems import plant_system
from cas_freq.config import load_variant
from cas_freq.core.parameters import LoopParameters
from cas_freq.model.actuator_loops import ActuatorLoops

CONFIG = "configs/qt_cas.yaml"


def _params(variant="fitted", **changes):
    base = LoopParameters.from_config(load_variant(CONFIG, variant).params)
    return base.replace(**{name: np.array([value]) for name, value in changes.items()})


def _hand_plant(p):
    """(A, B, C_theta, C_fin) of the loaded plant written out from the model's equations.

    Rigid: J_eff w' = Km i - mu_eff w - k_eff theta. Compliant: J w' = Km i - mu w
    - (K_g/(eta N)) (theta/N - delta); J_L w_L' = K_g (theta/N - delta) - b_L w_L - K_h delta.
    """
    v = {name: float(getattr(p, name)[0]) for name in (
        "R", "L", "Ke", "Km", "J", "mu_v", "ratio", "eta", "K_g", "c_g", "J_L", "b_L", "K_h")}
    n, eta = v["ratio"], v["eta"]
    if v["K_g"] == 0:
        j = v["J"] + v["J_L"] / (eta * n * n)
        mu = v["mu_v"] + v["b_L"] / (eta * n * n)
        k = v["K_h"] / (eta * n * n)
        a = np.array([[-v["R"] / v["L"], -v["Ke"] / v["L"], 0.0],
                      [v["Km"] / j, -mu / j, -k / j],
                      [0.0, 1.0, 0.0]])
        c_fin = np.array([0.0, 0.0, 1.0])
    else:
        # gear torque K_g (theta/N - delta) + c_g (omega/N - omega_L)
        kg, cg, jl = v["K_g"], v["c_g"], v["J_L"]
        a = np.zeros((5, 5))
        a[0, :2] = [-v["R"] / v["L"], -v["Ke"] / v["L"]]
        a[1, :] = [v["Km"] / v["J"], -v["mu_v"] / v["J"] - cg / (eta * n * n * v["J"]),
                   -kg / (eta * n * n * v["J"]), cg / (eta * n * v["J"]), kg / (eta * n * v["J"])]
        a[2, 1] = 1.0
        a[3, :] = [0.0, cg / (n * jl), kg / (n * jl), -(v["b_L"] + cg) / jl,
                   -(kg + v["K_h"]) / jl]
        a[4, 3] = 1.0
        c_fin = np.array([0.0, 0.0, 0.0, 0.0, n])  # N delta
    b = np.zeros(a.shape[0])
    b[0] = 1.0 / v["L"]
    c_theta = np.zeros(a.shape[0])
    c_theta[2] = 1.0
    return a, b, c_theta, c_fin


def _hand_loops(p, w):
    """(L_i, L_p, T) at frequencies ``w`` [rad/s], exact delays, derivative on the error."""
    a, b, c_theta, c_fin = _hand_plant(p)
    v = {name: float(getattr(p, name)[0]) for name in (
        "ci_Kp", "ci_Ki", "cp_Kp", "cp_Ki", "cp_Kd", "Tf", "tau_c", "tau_p")}
    out = []
    for omega in np.atleast_1d(w):
        s = 1j * omega
        x = np.linalg.solve(s * np.eye(a.shape[0]) - a, b)  # states per volt
        y, theta_v, fin_v = x[0], c_theta @ x, c_fin @ x
        c_i = v["ci_Kp"] + v["ci_Ki"] / s
        l_i = c_i * np.exp(-s * v["tau_c"]) * y
        t_i = l_i / (1 + l_i)
        # per current command: i = T_i i_cmd, so theta = (theta/V)/(i/V) * T_i i_cmd
        m_theta, m_fin = theta_v / y * t_i, fin_v / y * t_i
        c_p = v["cp_Kp"] + v["cp_Ki"] / s + v["cp_Kd"] * s / (v["Tf"] * s + 1)
        l_p = c_p * np.exp(-s * v["tau_p"]) * m_theta
        t = c_p * np.exp(-s * v["tau_p"]) * m_fin / (1 + l_p)
        out.append((l_i, l_p, t))
    return np.array(out).T


def _hand_figures(p):
    """Position-loop crossover and phase margin and the -3.0103 dB bandwidth of T, by brentq
    on the hand-written loops (T(0) from a very low frequency)."""
    lp = lambda w: abs(_hand_loops(p, w)[1][0]) - 1.0  # noqa: E731
    w = np.geomspace(10, 1e5, 2000)
    values = np.array([lp(x) for x in w])
    k = int(np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:]))[0])
    crossover = brentq(lp, w[k], w[k + 1], xtol=1e-12, rtol=1e-13)
    phase = math.degrees(np.angle(_hand_loops(p, crossover)[1][0]))
    pm = 180.0 + phase if phase < 0 else phase - 180.0
    t0 = abs(_hand_loops(p, 1e-3)[2][0])
    t_drop = lambda x: abs(_hand_loops(p, x)[2][0]) - t0 / math.sqrt(2.0)  # noqa: E731
    values = np.array([t_drop(x) for x in w])
    k = int(np.flatnonzero(values < 0)[0])
    bandwidth = brentq(t_drop, w[k - 1], w[k], xtol=1e-12, rtol=1e-13)
    return crossover, pm, bandwidth


def test_rigid_load_reflects_inertia_damping_and_spring():
    # docs/model.md: J_eff = J + J_L/(eta N^2), mu_eff = mu_v + b_L/(eta N^2), k_eff = K_h/(eta
    # N^2); theta/i = Km / (J_eff s^2 + mu_eff s + k_eff). N = 20, eta = 0.7: eta N^2 = 280.
    p = _params(J_L=5e-5, b_L=2e-3, K_h=2.0, eta=0.7)
    j_eff = 7.19e-7 + 5e-5 / 280.0
    mu_eff = 1.2e-6 + 2e-3 / 280.0
    k_eff = 2.0 / 280.0
    s = 1j * np.geomspace(1, 1e5, 50)
    response = plant_system(p)(s)
    theta_per_i = response[2, 0] / response[0, 0]
    np.testing.assert_allclose(theta_per_i, 0.0075 / (j_eff * s * s + mu_eff * s + k_eff),
                               rtol=1e-10)  # one model, rounding only
    load = drivetrain(p)
    assert load.reflected_inertia_kg_m2 == pytest.approx(j_eff, rel=1e-14)
    assert load.reflected_damping_n_m_s_rad == pytest.approx(mu_eff, rel=1e-14)
    assert load.reflected_stiffness_n_m_rad == pytest.approx(k_eff, rel=1e-14)
    assert load.plant_stable and not load.compliant


def test_aiding_hinge_moment_makes_the_plant_statically_unstable():
    # k_eff < 0: the root (-mu + sqrt(mu^2 - 4 J k)) / (2 J) of J s^2 + mu s + k is positive.
    p = _params(J_L=5e-5, K_h=-30.0)
    j, mu, k = 7.19e-7 + 5e-5 / 400, 1.2e-6, -30.0 / 400
    pole = (-mu + math.sqrt(mu * mu - 4 * j * k)) / (2 * j)
    load = drivetrain(p)
    assert not load.plant_stable
    assert load.plant_unstable_pole_rad_s == pytest.approx(pole, rel=1e-9)


@pytest.mark.parametrize("hinge", [0.0, 40.0])
def test_two_mass_resonance_and_anti_resonance_in_closed_form(hinge):
    # Undamped two-mass model (mu_v = b_L = 0), e = 1/eta. K_h = 0: the textbook
    # w_r^2 = K_g (1/J_L + e/(N^2 J)), w_a^2 = K_g/J_L. With K_h: the determinant of the
    # undamped equations, J J_L w^4 - (J (K_g + K_h) + e K_g J_L/N^2) w^2 + e K_g K_h/N^2 = 0,
    # and w_a^2 = (K_g + K_h)/J_L (the load resonating against the gear and hinge springs).
    kg, jl, j, n, eta = 3000.0, 5e-5, 7.19e-7, 20.0, 0.8
    p = _params(J_L=jl, K_g=kg, K_h=hinge, eta=eta, mu_v=0.0)
    e = 1.0 / eta
    a, b, c = j * jl, -(j * (kg + hinge) + e * kg * jl / n**2), e * kg * hinge / n**2
    roots = sorted(r for r in ((-b - math.sqrt(b * b - 4 * a * c)) / (2 * a),
                               (-b + math.sqrt(b * b - 4 * a * c)) / (2 * a)) if r > 0)
    load = drivetrain(p)
    assert load.compliant
    assert [m.frequency_rad_s for m in load.resonances] == pytest.approx(
        [math.sqrt(r) for r in roots], rel=1e-9)
    if hinge == 0:
        assert load.resonances[0].frequency_rad_s == pytest.approx(
            math.sqrt(kg * (1 / jl + e / (n * n * j))), rel=1e-9)
    assert [m.frequency_rad_s for m in load.anti_resonances] == pytest.approx(
        [math.sqrt((kg + hinge) / jl)], rel=1e-9)
    assert all(m.damping == pytest.approx(0.0, abs=1e-9) for m in load.resonances)


def test_stiff_gear_tends_to_the_rigid_model():
    # K_g -> infinity: the two-mass loops tend to the rigid ones; the difference is of order
    # (w_loop/w_resonance)^2: with K_g = 1e9 N*m/rad the resonance is ~5e6 rad/s, so at
    # <= 3000 rad/s the relative difference is below ~1e-5 (measured ~1e-6).
    rigid = _params(J_L=5e-5, b_L=1e-3, K_h=2.0, eta=0.7)
    stiff = _params(J_L=5e-5, b_L=1e-3, K_h=2.0, eta=0.7, K_g=1e9)
    s = 1j * np.geomspace(1, 3000, 40)
    for name in ("current_loop", "position_loop", "closed_loop"):
        np.testing.assert_allclose(getattr(ActuatorLoops(stiff), name)(s),
                                   getattr(ActuatorLoops(rigid), name)(s), rtol=1e-5)


@pytest.mark.parametrize("changes", [
    {},
    {"J_L": 5e-5, "K_h": 2.0, "eta": 0.7},
    {"J_L": 5e-5, "K_h": 2.0, "eta": 0.7, "K_g": 3000.0, "b_L": 1e-3},
    {"J_L": 5e-5, "K_h": -5.0, "K_g": 3000.0},
    {"J_L": 5e-5, "K_h": 2.0, "eta": 0.7, "K_g": 3000.0, "c_g": 0.04, "b_L": 1e-3},
])
def test_loops_equal_the_hand_written_plant(changes):
    # Polynomials of the drivetrain (cas_freq.model) vs a per-frequency solve of the state
    # matrix written in this test: same model, different arithmetic; rounding only.
    p = _params(**changes)
    w = np.geomspace(1, 1e5, 30)
    l_i, l_p, t = _hand_loops(p, w)
    loops = ActuatorLoops(p)
    np.testing.assert_allclose(loops.current_loop(1j * w), l_i, rtol=1e-8)
    np.testing.assert_allclose(loops.position_loop(1j * w), l_p, rtol=1e-8)
    np.testing.assert_allclose(loops.closed_loop(1j * w), t, rtol=1e-8)


@pytest.mark.parametrize("sets", [
    ["load.hinge_stiffness=2", "load.inertia=5e-5", "gear.efficiency=0.7"],
    ["load.hinge_stiffness=2", "load.inertia=5e-5", "gear.efficiency=0.7",
     "gear.stiffness=3000", "load.damping=1e-3"],
])
def test_analyze_json_agrees_with_an_independent_computation(sets):
    # The command (base variant), and a compliant gear: crossover, phase margin and
    # bandwidth of the JSON vs brentq on the hand-written loops. The engine refines its
    # crossings to ~1e-10 relative; 1e-7 allows for the hand computation's T(0) at 1e-3 rad/s.
    argv = ["analyze", CONFIG]
    for item in sets:
        argv += ["--set", item]
    code, out, err = run_cli([*argv, "--json"])
    assert code == 0, err
    data = json.loads(out)
    overrides = dict(item.split("=") for item in sets)
    names = {"load.hinge_stiffness": "K_h", "load.inertia": "J_L", "gear.efficiency": "eta",
             "gear.stiffness": "K_g", "load.damping": "b_L"}
    p = _params("base", **{names[k]: float(v) for k, v in overrides.items()})
    crossover, pm, bandwidth = _hand_figures(p)
    assert data["stability"] == "stable"
    assert data["position_loop"]["crossover_rad_s"] == pytest.approx(crossover, rel=1e-7)
    assert data["position_loop"]["phase_margin_deg"] == pytest.approx(pm, rel=1e-7)
    assert data["closed_loop"]["bandwidth_rad_s"] == pytest.approx(bandwidth, rel=1e-7)
    assert data["drivetrain"]["compliant"] == ("gear.stiffness=3000" in sets)


def test_absent_load_keys_give_the_unloaded_figures_exactly():
    # docs/model.md: all load keys absent (or explicitly at their defaults) = the unloaded
    # model. On the DC servo config (another actuator; the shipped QT-CAS file's loaded variant
    # needs its stiffness and inertia, and every variant is checked with the overrides).
    dc = "configs/dc_servo.yaml"
    plain = run_cli(["analyze", dc, "--json"])
    explicit = run_cli(["analyze", dc, "--json", "--set", "load.inertia=0",
                        "--set", "gear.efficiency=1", "--set", "load.hinge_stiffness=0",
                        "--set", "gear.stiffness=0", "--set", "load.damping=0",
                        "--set", "gear.backlash=0", "--set", "motor.coulomb_friction=0",
                        "--set", "load.hinge_bias=0", "--set", "gear.backdrive_efficiency=1"])
    assert plain[0] == explicit[0] == 0, explicit[2]
    a, b = json.loads(plain[1]), json.loads(explicit[1])
    for data in (a, b):
        data.pop("overrides")
    assert a == b
    assert "drivetrain" not in a


def test_stable_hinge_range_brackets_the_stability_boundary():
    # Second method: the sign of the largest real part of the closed-loop poles either side of
    # each reported bound (0.1 % of the bound away).
    p = _params(J_L=5e-5, K_h=2.0, eta=0.7)
    low, high = drivetrain(p).stable_hinge_stiffness_n_m_rad
    assert low < 0 < 2.0 < high
    for bound in (low, high):
        for factor, stable in ((0.999, True), (1.001, False)):
            poles = closed_loop_poles(p.replace(K_h=np.array([bound * factor])), 6)
            assert (poles.real.max() < 0) == stable
    verdict = stability_verdicts(p.replace(K_h=np.array([low * 1.01])), 6)[0][0]
    assert verdict == "unstable"


@pytest.mark.parametrize("path, variant", [
    ("configs/qt_cas.yaml", "loaded"), ("configs/qt_cas.yaml", "fin_encoder"),
    ("configs/cascade_axis.yaml", "base"), ("configs/ball_screw.yaml", "base"),
])
def test_batched_bisection_is_the_one_step_bisection_to_the_bit(path, variant, monkeypatch):
    # The hinge range's boundaries come from batches of verdicts that decide four halvings
    # each (drivetrain._boundary); here one halving per verdict, as written before: the same
    # midpoints and verdicts, so the same floats.
    from cas_freq.analysis import drivetrain as module

    def one_halving_per_verdict(p, unstable, stable, pade_order):
        for _ in range(module._BISECTIONS):
            middle = 0.5 * (unstable + stable)
            if module._stable(p, [middle], pade_order)[0]:
                stable = middle
            else:
                unstable = middle
        return float(0.5 * (unstable + stable))

    p = LoopParameters.from_config(load_variant(path, variant).params)
    batched = module.stable_hinge_range(p)
    assert any(bound is not None for bound in batched)
    monkeypatch.setattr(module, "_boundary", one_halving_per_verdict)
    assert module.stable_hinge_range(p) == batched


@pytest.mark.parametrize("sets, words", [
    (["gear.stiffness=300"], "a compliant gear needs load.inertia > 0"),
    (["gear.backlash=0.01"], "needs gear.stiffness > 0"),
    (["gear.damping=0.01"], "gear.damping: the mesh damping acts in parallel"),
    (["gear.efficiency=0"], "gear.efficiency: must be >= 0.01 and <= 1"),
    (["gear.efficiency=1e-300"], "gear.efficiency: must be >= 0.01 and <= 1"),
    (["gear.backdrive_efficiency=1.5"], "gear.backdrive_efficiency: must be >= 0 and <= 1"),
])
def test_bad_drivetrain_values_exit_2_naming_the_key(sets, words):
    argv = ["analyze", CONFIG]
    for item in sets:
        argv += ["--set", item]
    code, _, err = run_cli(argv)
    assert code == 2
    assert words in err


def test_plant_matrices_of_a_mixed_batch_are_each_runs_own():
    # A 5-state batch of a rigid run (N = 20) and a compliant one: each row of the batch must be
    # the run's own matrices (the rigid run's slaved fin rows omega_L' = omega'/N, delta' =
    # omega/N with its own N); once, the (n,) ratios were broadcast against (n, 5) rows.
    from cas_freq.model import parts

    rigid = _params(J_L=5e-5, K_h=2.0)
    compliant = _params(J_L=5e-5, K_h=2.0, K_g=3000.0, ratio=30.0)
    both = LoopParameters(**{f: np.concatenate([getattr(rigid, f), getattr(compliant, f)])
                             for f in ("R", "L", "Km", "Ke", "J", "mu_v", "ratio", "ci_Kp",
                                       "ci_Ki", "v_max", "tau_c", "cp_Kp", "cp_Ki", "cp_Kd",
                                       "Tf", "ff_v", "ff_a", "i_max", "tau_p",
                                       "derivative_on_measurement", "K_g", "J_L", "K_h")})
    for options in ({}, {"backdrive": True}, {"engaged": False}):
        a, b = parts.plant_matrices(both, **options)
        a0, b0 = parts.plant_matrices(rigid, states=5, **options)
        a1, b1 = parts.plant_matrices(compliant, **options)
        np.testing.assert_array_equal(a[0], a0[0])
        np.testing.assert_array_equal(a[1], a1[0])
        np.testing.assert_array_equal(b[0], b0[0])
        np.testing.assert_array_equal(b[1], b1[0])
        np.testing.assert_allclose(a[0, 3], a[0, 1] / 20.0, rtol=1e-15)
        np.testing.assert_allclose(a[0, 4, 1], 1.0 / 20.0, rtol=1e-15)


def test_mesh_damping_damps_the_two_mass_resonance():
    # With a mesh damper c_g across the gear (and nothing else damping), the resonance's
    # damping ratio tends to c_g w_r / (2 K_g) for light damping (a Kelvin-Voigt spring: loss
    # factor c_g w / K_g = 2 zeta); and the anti-resonance's to c_g w_a / (2 K_g).
    kg, jl, j, n = 3000.0, 5e-5, 7.19e-7, 20.0
    cg = 2e-3
    p = _params(J_L=jl, K_g=kg, c_g=cg, mu_v=0.0)
    load = drivetrain(p)
    w_r = math.sqrt(kg * (1 / jl + 1 / (n * n * j)))
    w_a = math.sqrt(kg / jl)
    assert load.resonances[0].frequency_rad_s == pytest.approx(w_r, rel=1e-3)
    assert load.resonances[0].damping == pytest.approx(cg * w_r / (2 * kg), rel=1e-3)
    assert load.anti_resonances[0].damping == pytest.approx(cg * w_a / (2 * kg), rel=1e-9)


@pytest.mark.parametrize("changes", [
    {"mu_v": 0.0, "J_L": 5e-5},  # frictionless: the integrator's pole cancels Y's zero at 0
    {"J_L": 5e-5, "K_h": 2.0, "eta": 0.7},
    {"J_L": 5e-5, "K_g": 3000.0, "c_g": 0.03},
])
def test_current_loop_poles_equal_python_controls(changes):
    # The current loop's poles (state matrix of cas_freq.analysis.stability, unobservable
    # modes removed) against python-control's T_i of the loaded plant; python-control keeps
    # the modes i does not see as poles at 0 (dropped here). Rounding-level tolerance.
    from cas_freq.analysis.stability import current_loop_poles
    from cas_freq.analysis.systems import linear_model

    p = _params(**changes)
    ours = np.sort_complex(current_loop_poles(p, 6))
    theirs = np.asarray(linear_model(p, 6).current_closed_loop.poles())
    theirs = np.sort_complex(theirs[np.abs(theirs) > 1e-6])
    np.testing.assert_allclose(ours, theirs, rtol=1e-7)
