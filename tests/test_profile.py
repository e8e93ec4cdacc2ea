"""Profile moves: the trapezoidal command, its figures, ``simulate --profile``, ``profile.*``
requirements in ``verify``, the report section and the API.

Reference values:

- the kinematics are worked out by hand in each test from the trapezoid's formulas
  (docs/model.md, "Profile moves"): with limits v, a, d the speed ramps for v/a, cruises, ramps
  down for v/d, and the distance is the area under the speed; every limit is chosen so that the
  times and angles are round numbers, exact to rounding (tolerance 1e-12 relative);
- the tracking error of the nonlinear simulator, for a move that stays within the limits, is
  checked against an independent linear computation: E(s) = (1 - T_ff(s)) Θ_cmd(s), T_ff the
  exact-delay closed loop with the feed-forward in the reference path (docs/model.md), and
  Θ_cmd(s) = A(s)/s², A the Laplace transform of the command's piecewise-constant
  acceleration in closed form, inverted by FFT on the simulator's 5 µs grid. The two agree to
  ~1e-5 of the error when the move's corners fall on the grid and ~1e-3 when they do not (the
  simulator's command then jumps up to a step late); tolerance 2e-3;
- the compiled kernel against the numpy reference engine: 1e-9 of the move, as
  tests/test_simulation_kernel.py for the other commands.
"""

import json
import math
import types

import numpy as np
import pytest
import yaml
from clirun import run_cli

from cas_freq.config.loader import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.model import ActuatorLoops
from cas_freq.simulation import Profile, simulate_batch
from cas_freq.studies.profile_run import make_profile, profile_run, profile_run_dict

DEG = math.pi / 180.0
MOVE_ARGS = ["--profile", "10deg", "--velocity", "2000deg/s", "--acceleration", "1e5deg/s^2"]
CONDITION = {"distance": "10 deg", "velocity": "2000 deg/s", "acceleration": "1e5 deg/s^2"}


def deg(values):
    return np.degrees(values)


# ---- the command --------------------------------------------------------------------------------

def test_trapezoid_by_hand():
    # 60 deg at 1000 deg/s, 2e4 deg/s^2: 50 ms to reach 1000 deg/s (covering 25 deg), 25 deg
    # to stop, so 10 deg of cruise at 1000 deg/s (10 ms); 110 ms in all.
    move = Profile(60 * DEG, 1000 * DEG, 2e4 * DEG)
    t_a, t_c, t_d = (float(x) for x in move.phases())
    assert (t_a, t_c, t_d) == pytest.approx((0.05, 0.01, 0.05), rel=1e-12)
    assert move.move_time_s == pytest.approx(0.11, rel=1e-12)
    assert deg(move.peak_rate_rad_s) == pytest.approx(1000, rel=1e-12)
    angle, rate, accel = (deg(x) for x in move.fin(np.array([0.025, 0.05, 0.055, 0.06, 0.085,
                                                              0.11, 0.2])))
    # 1/2 a t^2 = 6.25 deg at 25 ms; 25 deg at 50 ms; +5 deg cruising; 35 deg at 60 ms; then
    # 60 - 1/2 a (T - t)^2 = 53.75 deg at 85 ms; 60 deg at the end and after
    assert angle == pytest.approx([6.25, 25, 30, 35, 53.75, 60, 60], rel=1e-12)
    assert rate == pytest.approx([500, 0 + 1000, 1000, 1000, 500, 0, 0], rel=1e-12)
    assert accel == pytest.approx([2e4, 0, 0, -2e4, -2e4, 0, 0], rel=1e-12)


def test_trapezoid_with_its_own_deceleration():
    # a = 2e4, d = 4e4 deg/s^2: 25 deg to speed (50 ms), 12.5 deg to stop (25 ms), 22.5 deg
    # cruising (22.5 ms): 97.5 ms
    move = Profile(60 * DEG, 1000 * DEG, 2e4 * DEG, 4e4 * DEG)
    assert [float(x) for x in move.phases()] == pytest.approx([0.05, 0.0225, 0.025], rel=1e-12)
    assert move.move_time_s == pytest.approx(0.0975, rel=1e-12)
    assert deg(move.fin(np.array([0.0725]))[0]) == pytest.approx([47.5], rel=1e-12)


def test_triangle_by_hand():
    # 10 deg at 2000 deg/s, 1e5 deg/s^2: reaching 2000 deg/s takes 20 deg, more than the move,
    # so the peak is sqrt(2 D a d / (a + d)) = sqrt(D a) = 1000 deg/s at 10 ms, stop at 20 ms
    move = Profile(10 * DEG, 2000 * DEG, 1e5 * DEG)
    assert deg(move.peak_rate_rad_s) == pytest.approx(1000, rel=1e-12)
    assert [float(x) for x in move.phases()] == pytest.approx([0.01, 0.0, 0.01], rel=1e-12)
    assert move.move_time_s == pytest.approx(0.02, rel=1e-12)
    # with d = a/2: peak sqrt(2 * 10 * 1e5 * 5e4 / 1.5e5) = 816.5 deg/s; ramps 8.165 ms and
    # 16.33 ms; the area 1/2 peak T is the distance
    slow = Profile(10 * DEG, 2000 * DEG, 1e5 * DEG, 5e4 * DEG)
    peak = math.sqrt(2 * 10 * 1e5 * 5e4 / 1.5e5)
    assert deg(slow.peak_rate_rad_s) == pytest.approx(peak, rel=1e-12)
    assert slow.move_time_s == pytest.approx(peak / 1e5 + peak / 5e4, rel=1e-12)
    assert 0.5 * peak * slow.move_time_s == pytest.approx(10, rel=1e-12)


@pytest.mark.parametrize("move", [
    Profile(60 * DEG, 1000 * DEG, 2e4 * DEG, 4e4 * DEG, start_s=0.01),
    Profile(-10 * DEG, 2000 * DEG, 1e5 * DEG, 5e4 * DEG),
], ids=["trapezoid", "negative-triangle"])
def test_continuity_and_area(move):
    # the angle and rate are continuous at every corner (left limit = right limit), the
    # acceleration jumps there; the area under the rate is the distance; the angle's slope is
    # the rate
    t_a, t_c, t_d = (float(x) for x in move.phases())
    corners = move.start_s + np.array([0.0, t_a, t_a + t_c, t_a + t_c + t_d])
    right, left = move.fin(corners), move.fin(corners, left=True)
    scale = abs(move.distance_rad)
    assert np.allclose(right[0], left[0], rtol=0, atol=1e-12 * scale)
    assert np.allclose(right[1], left[1], rtol=0, atol=1e-12 * float(move.peak_rate_rad_s))
    a, d = move.acceleration_rad_s2, move.deceleration_rad_s2
    sign = np.sign(move.distance_rad)
    assert left[2][1] == pytest.approx(sign * a) and right[2][0] == pytest.approx(sign * a)
    assert left[2][-1] == pytest.approx(-sign * d) and right[2][-1] == 0.0
    t = np.linspace(0.0, move.duration_s + 0.01, 200001)
    angle, rate, accel = move.fin(t)
    assert np.trapezoid(rate, t) == pytest.approx(move.distance_rad, rel=1e-8)
    # the trapezoidal rule misses at most half a jump times a step at each of the 3 jumps
    assert np.trapezoid(accel, t) == pytest.approx(0.0, abs=1.5 * (a + d) * (t[1] - t[0]))
    slope = np.gradient(angle, t)
    assert np.max(np.abs(slope - rate)) < 1e-3 * float(move.peak_rate_rad_s)
    assert angle[-1] == pytest.approx(move.distance_rad, rel=1e-12)
    assert move.final_rad() == pytest.approx(move.distance_rad)
    assert move.settles and move.duration_s == pytest.approx(move.start_s + move.move_time_s)


@pytest.mark.parametrize("args, says", [
    ((0.0, 1.0, 1.0), "distance must be finite and non-zero"),
    ((math.nan, 1.0, 1.0), "distance must be finite and non-zero"),
    ((0.1, 0.0, 1.0), "velocity_rad_s must be a finite number > 0 rad/s, got 0.0"),
    ((0.1, -1.0, 1.0), "velocity_rad_s must be a finite number > 0 rad/s, got -1.0"),
    ((0.1, 1.0, math.inf), "acceleration_rad_s2 must be a finite number > 0 rad/s^2, got inf"),
    ((0.1, 1.0, 1.0, -2.0), "deceleration_rad_s2 must be a finite number > 0 rad/s^2"),
    ((0.1, 1.0, True), "acceleration_rad_s2 must be a finite number > 0"),
])
def test_bad_profile(args, says):
    with pytest.raises(ConfigError, match=says.replace("^", r"\^")):
        Profile(*args)


def test_make_profile_reads_units():
    move = make_profile("-10 deg", "2000 deg/s", "1e5 deg/s^2", "5e4deg/s**2")
    assert move.distance_rad == pytest.approx(-10 * DEG)
    assert move.velocity_rad_s == pytest.approx(2000 * DEG)
    assert move.deceleration_rad_s2 == pytest.approx(5e4 * DEG)
    with pytest.raises(ConfigError, match=r"profile\.acceleration: expected a positive "
                                          r"acceleration at the output"):
        make_profile("10 deg", "2000 deg/s", "1e5 deg/s")


# ---- the simulation and its figures -------------------------------------------------------------

@pytest.fixture(scope="module")
def base():
    return load_variant(None, variant="base")


@pytest.fixture(scope="module")
def shipped_run(base):
    return profile_run(base, Profile(10 * DEG, 2000 * DEG, 1e5 * DEG))


def linear_error(params, move, t, feedforward, dt=5e-6, n=2**19):
    """delta_cmd - delta [rad] of the linear exact-delay closed loop at times ``t`` [s].

    E(jw) = (1 - T_ff(jw)) A(jw) / (jw)^2, A the Fourier transform of the command's
    piecewise-constant acceleration (sum over its pieces of a_k (e^{-jw t_k} -
    e^{-jw t_k+1}) / (jw)), inverted by FFT over n samples of dt (a period of 2.6 s, long
    after the error has decayed). At w = 0, where 1 - T has a double zero (type 2), the value
    at a frequency 1000 times below the first bin stands in.
    """
    w = 2 * np.pi * np.fft.rfftfreq(n, dt)
    w[0] = 1e-3 * w[1]
    s = 1j * w
    t_a, t_c, t_d = (float(x) for x in move.phases())
    corners = move.start_s + np.array([0.0, t_a, t_a + t_c, t_a + t_c + t_d])
    sign = np.sign(move.distance_rad)
    pieces = sign * np.array([move.acceleration_rad_s2, 0.0, -move.deceleration_rad_s2])
    accel = sum(a * (np.exp(-s * lo) - np.exp(-s * hi)) / s
                for a, lo, hi in zip(pieces, corners[:-1], corners[1:], strict=True))
    closed = ActuatorLoops(params).closed_loop(s, feedforward=feedforward)
    samples = np.fft.irfft((1 - closed) * accel / s**2 / dt, n)
    return np.interp(t, np.arange(n) * dt, samples)


@pytest.mark.parametrize("distance_deg", [10.0, -2.0])
def test_tracking_error_is_the_linear_loops(base, distance_deg):
    # a move within the limits is the linear loop's: the simulated error equals the FFT of
    # (1 - T_ff) Θ_cmd with and without the feed-forward (module notes)
    move = Profile(distance_deg * DEG, 2000 * DEG, 1e5 * DEG)
    run = profile_run(base, move)
    for feedforward, result in ((True, run.result), (False, run.result_without_feedforward)):
        assert not result.current_limited.any() and not result.voltage_limited.any()
        simulated = result.command - result.delta
        linear = linear_error(base.params, move, result.t, feedforward)
        scale = np.max(np.abs(simulated))
        assert np.max(np.abs(linear - simulated)) < 2e-3 * scale


def test_ideal_feedforward_tracks(base):
    # With ff_v = mu_v/Km and ff_a = J/Km the feed-forward current makes the motor follow the
    # command by itself (J theta'' + mu_v theta' = Km i_ff), so the error E = S (1 - e^{-s
    # tau_p} T_i) Θ_cmd is left only by the position delay and the current loop's lag: far
    # smaller than without feed-forward (E = S Θ_cmd). Without the delays it is smaller still.
    motor = base.params.motor
    ideal = [("position_loop.ff_v", str(motor.viscous_friction / motor.Km)),
             ("position_loop.ff_a", str(motor.J / motor.Km))]
    move = Profile(10 * DEG, 2000 * DEG, 1e5 * DEG)
    run = profile_run(load_variant(None, variant="base", overrides=ideal), move)
    without = run.without_feedforward.tracking_error_max_deg
    assert run.profile.tracking_error_max_deg < 0.25 * without
    no_delay = ideal + [("current_loop.delay", "0"), ("position_loop.delay", "0")]
    undelayed = profile_run(load_variant(None, variant="base", overrides=no_delay), move)
    assert undelayed.profile.tracking_error_max_deg < 0.5 * run.profile.tracking_error_max_deg


def test_shipped_feedforward(shipped_run):
    # The shipped ff_v = 0.0096 A*s/rad is about 75 times mu_v/Km = 1.28e-4 A*s/rad (and ff_a
    # 2.3 times J/Km): the feed-forward over-drives the motor, so during the move the fin leads
    # the command (a negative error) by more than it lags without feed-forward; its overshoot
    # past the target is far smaller. Both are what the linear loop predicts
    # (test_tracking_error_is_the_linear_loops); stated here as the design finding.
    on, off = shipped_run.profile, shipped_run.without_feedforward
    error = shipped_run.result.command - shipped_run.result.delta
    assert np.min(error) < -abs(np.max(error))
    assert on.tracking_error_max_deg > off.tracking_error_max_deg
    assert on.overshoot_pct < 0.1 * off.overshoot_pct
    assert on.max_current_a > off.max_current_a


def test_figures_definitions(shipped_run):
    # the figures follow from the samples as docs/model.md defines them
    run, figures = shipped_run, shipped_run.profile
    r = run.result
    during = r.t <= run.move.move_time_s * (1 + 1e-12)
    error = deg(r.command - r.delta)
    assert figures.tracking_error_max_deg == pytest.approx(np.max(np.abs(error[during])))
    assert figures.tracking_error_rms_deg == pytest.approx(
        np.sqrt(np.mean(error[during] ** 2)))
    y = r.delta / run.move.distance_rad
    after = r.t > figures.arrival_time_s  # inside the band; the last sample before is not
    assert np.all(np.abs(y[after] - 1) <= 0.02) and np.abs(y[~after][-1] - 1) > 0.02
    assert figures.settling_time_s == pytest.approx(
        max(0.0, figures.arrival_time_s - run.move.move_time_s))
    assert figures.overshoot_pct == pytest.approx(100 * (np.max(y) - 1), abs=1e-3)
    assert figures.max_current_a == pytest.approx(np.max(np.abs(r.i)))
    assert figures.distance_deg == pytest.approx(10) and figures.move_time_s == 0.02


def test_kernel_matches_reference(base):
    # one batch: the profile on base and fitted, with and without the feed-forward, by both
    # engines; a short horizon (the reference engine costs ~50 us per step)
    pytest.importorskip("numba")
    from cas_freq.core.parameters import LoopParameters

    fitted = load_variant(None, variant="fitted")
    params = LoopParameters.from_configs([base.params, fitted.params, base.params])
    params = params.replace(ff_v=params.ff_v * np.array([1, 1, 0]),
                            ff_a=params.ff_a * np.array([1, 1, 0]))
    move = Profile(-10 * DEG, 2000 * DEG, 1e5 * DEG, 5e4 * DEG, start_s=0.001)
    options = {"t_end": 0.03, "extend": False}
    compiled = simulate_batch(params, move, engine="compiled", **options)
    reference = simulate_batch(params, move, engine="reference", **options)
    assert np.array_equal(compiled.t, reference.t)
    for name in ("delta", "command"):
        difference = np.abs(getattr(compiled, name) - getattr(reference, name))
        assert np.max(difference) <= 1e-9 * 10 * DEG, name
    for name in ("i", "V", "omega"):
        ours, theirs = getattr(compiled, name), getattr(reference, name)
        scale = np.max(np.abs(theirs), axis=1, keepdims=True)
        assert np.max(np.abs(ours - theirs) / scale) <= 1e-9, name
    assert np.array_equal(compiled.current_limited, reference.current_limited)


def test_reference_engine_through_the_environment(monkeypatch, base):
    # CAS_FREQ_ENGINE=reference runs the whole profile_run on the numpy engine: same figures
    move = Profile(2 * DEG, 2000 * DEG, 1e5 * DEG)
    compiled = profile_run(base, move)
    monkeypatch.setenv("CAS_FREQ_ENGINE", "reference")
    from cas_freq.simulation.simulator import engine_name

    assert engine_name() == "reference"
    reference = profile_run(base, move)
    for name in ("tracking_error_max_deg", "overshoot_pct", "settling_time_s"):
        assert getattr(reference.profile, name) == pytest.approx(
            getattr(compiled.profile, name), rel=1e-6, abs=1e-9)


# ---- the CLI ------------------------------------------------------------------------------------

def test_simulate_profile_table_and_json(tmp_path):
    code, out, err = run_cli(["simulate", *MOVE_ARGS, "-q"])
    assert code == 0, err
    assert "qt_cas / base" in out and "largest tracking error during the move [deg]" in out
    assert "profile velocity 6667 rpm" in out  # 2000 deg/s x 20 = 40000 deg/s = 6667 rpm
    assert "Triangular" in out
    csv = tmp_path / "move.csv"
    code, out, err = run_cli(["simulate", *MOVE_ARGS, "--json", "--csv", str(csv), "-q"])
    assert code == 0, err
    data = json.loads(out)
    assert data["profile"]["tracking_error_max_deg"] > 0
    assert data["without_feedforward"]["profile"]["overshoot_pct"] > data["profile"][
        "overshoot_pct"]
    assert data["move"]["motor"]["acceleration_rpm_s"] == pytest.approx(1e5 * 20 / 6)
    assert data["feedforward"]["active"] is True
    header = csv.read_text().splitlines()[0]
    assert header.startswith("t [s],command_output [deg],delta [deg]")


def test_simulate_profile_dc_servo():
    # the made-up DC servo has no feed-forward: both runs are the same loop, and it says so
    args = ["simulate", "configs/dc_servo.yaml", "--profile", "-20deg", "--velocity",
            "200deg/s", "--acceleration", "5000deg/s^2", "--json", "-q"]
    code, out, err = run_cli(args)
    assert code == 0, err
    data = json.loads(out)
    assert data["feedforward"]["active"] is False
    assert data["profile"] == data["without_feedforward"]["profile"]
    # 20 deg at 200 deg/s, 5000 deg/s^2: 40 ms ramps (4 deg each), 12 deg cruising (60 ms)
    assert data["profile"]["move_time_s"] == pytest.approx(0.14, rel=1e-12)
    code, out, _ = run_cli(args[:-2])
    assert "no feed-forward" in out and "Trapezoidal" in out


@pytest.mark.parametrize("args, says", [
    (["--profile", "10deg", "--velocity", "2000deg/s"],
     "--profile: needs --acceleration (e.g. --profile 10deg"),
    (["--step", "10deg", "--velocity", "2000deg/s"], "--velocity: only with --profile DIST"),
    (["--profile", "10deg", "--velocity", "-5deg/s", "--acceleration", "1e5deg/s^2"],
     "--velocity: must be > 0, got '-5deg/s'; expected a positive speed at the output"),
    (["--profile", "10deg", "--velocity", "2000deg", "--acceleration", "1e5deg/s^2"],
     "--velocity: expected a positive speed at the output with a unit such as 2000deg/s, got "
     "'2000deg'"),
    (["--profile", "10", "--velocity", "2000deg/s", "--acceleration", "1e5deg/s^2"],
     "--profile: expected an angle at the output with a unit such as 10deg, got '10'"),
    (["--profile", "0deg", "--velocity", "2000deg/s", "--acceleration", "1e5deg/s^2"],
     "--profile: must be non-zero and within ±90 deg at the output, got '0deg'"),
    (["--profile", "10deg", "--velocity", "2000deg/s", "--acceleration", "1e5deg/s^2",
      "--deceleration", "1e5deg/s"], "--deceleration: expected a positive acceleration"),
    (["--profile", "10deg", "--velocity", "1e-4deg/s", "--acceleration", "1e5deg/s^2"],
     "simulation too large"),
])
def test_simulate_profile_bad_input(args, says):
    code, out, err = run_cli(["simulate", *args])
    assert code == 2 and out == ""
    assert says in err and len(err.strip().splitlines()) == 1


# ---- requirements and verify --------------------------------------------------------------------

def config_with(tmp_path, *requirements, name="profile.yaml"):
    """The shipped config with ``requirements`` added, written to ``tmp_path``."""
    with open("configs/qt_cas.yaml", encoding="utf-8") as handle:
        data = yaml.safe_load(handle)
    data["requirements"] = list(requirements)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return str(path)


def requirement(bound, metric="profile.tracking_error_max_deg", **extra):
    return {"id": "PR-1", "metric": metric, "max": bound, "profile": dict(CONDITION), **extra}


@pytest.mark.parametrize("bound, status, code", [("2 deg", "PASS", 0), ("1 deg", "FAIL", 1)])
def test_verify_profile_requirement(tmp_path, shipped_run, bound, status, code):
    # base's largest tracking error with the shipped feed-forward is 1.748 deg
    path = config_with(tmp_path, requirement(bound))
    junit = tmp_path / "verify.xml"
    exit_code, out, err = run_cli(["verify", path, "--json", "--junit", str(junit), "-q"])
    assert exit_code == code, err
    text = json.dumps(json.loads(out))
    assert f'"status": "{status}"' in text
    assert shipped_run.profile.tracking_error_max_deg == pytest.approx(1.748, rel=1e-3)
    assert "profile move of 10 deg at 2000 deg/s" in text
    xml = junit.read_text()
    assert "PR-1: profile.tracking_error_max_deg" in xml
    assert ("<failure" in xml) == (status == "FAIL")


def test_verify_profile_advisory(tmp_path):
    path = config_with(tmp_path, requirement("1 ms", metric="profile.settling_time_s",
                                             severity="advisory"))
    code, out, err = run_cli(["verify", path, "-q"])
    assert code == 0, err
    assert "ADVISORY" in out and "profile.settling_time_s" in out


@pytest.mark.parametrize("changes, says", [
    ({"profile": None}, "PR-1: profile.tracking_error_max_deg needs the test condition "
                        "'profile' (e.g. profile: {distance: 10 deg"),
    ({"metric": "step.overshoot_pct", "step": "10 deg", "max": "15 %"},  # a bound in %
     "PR-1: 'profile' does not apply to step.overshoot_pct"),
    ({"profile": {**CONDITION, "velocity": "-2000 deg/s"}},
     "requirements.0.profile.velocity: must be > 0, got '-2000 deg/s'"),
    ({"profile": {**CONDITION, "distance": 0.17}},
     "requirements.0.profile.distance: give the move at the output with a unit (e.g. '10 deg'), "
     "got 0.17"),
    ({"profile": {**CONDITION, "acceleration": "1e5 deg/s"}},
     "requirements.0.profile.acceleration: give an acceleration at the output with a unit"),
    ({"profile": {"distance": "10 deg", "velocity": "2000 deg/s"}},
     "requirements.0.profile.acceleration: required key is missing"),
    ({"profile": {**CONDITION, "jerk": "1 deg/s^3"}}, "requirements.0.profile.jerk: unknown key"),
    ({"metric": "profile.rise_time_s"}, "unknown figure 'profile.rise_time_s'"),
])
def test_profile_requirement_errors(tmp_path, changes, says):
    item = requirement("2 deg")
    item.update(changes)
    item = {key: value for key, value in item.items() if value is not None}
    code, out, err = run_cli(["verify", config_with(tmp_path, item)])
    assert code == 2 and says in err, err


# ---- the report section and the API -------------------------------------------------------------

def test_report_section(tmp_path, base):
    from cas_freq.config.loader import load_all_variants
    from cas_freq.report.document import Figure, Heading, Table
    from cas_freq.report.profile import profile_section

    def section(path):
        datas = [types.SimpleNamespace(loaded=loaded, analysis=types.SimpleNamespace(
            stable=True, stability=types.SimpleNamespace(verdict="stable")))
            for loaded in load_all_variants(path, []) if loaded.variant == "base"]
        files = {}
        generator = profile_section(datas)
        try:
            while True:
                path_, content = next(generator)
                files[path_] = content
        except StopIteration as stop:
            return files, stop.value

    files, none = section(None)  # the shipped config declares no profile requirement
    assert files == {} and none.blocks == () and none.results == {}
    files, made = section(config_with(tmp_path, requirement("2 deg")))
    assert list(files) == ["figures/base/profile_1.svg"]
    assert files["figures/base/profile_1.svg"].startswith("<?xml")
    kinds = [type(block) for block in made.blocks]
    assert kinds[0] is Heading and Table in kinds and Figure in kinds
    table = next(block for block in made.blocks if isinstance(block, Table))
    assert table.header == ("figure", "unit", "base, with ff", "base, without ff")
    moved = made.results["profile_moves"][0]["variants"][0]
    assert moved["profile"]["tracking_error_max_deg"] == pytest.approx(1.748, rel=1e-3)
    assert moved["figure"] == "figures/base/profile_1.svg"


def test_api_simulate_profile():
    import cas_freq as cf

    act = cf.load()
    move = act.simulate_profile("10 deg", "2000 deg/s", "1e5 deg/s^2")
    assert move.profile.tracking_error_max_deg == pytest.approx(1.748, rel=1e-3)
    assert move.without_feedforward.overshoot_pct > move.profile.overshoot_pct
    assert move.to_dict() == profile_run_dict(move.run)
    assert move.command_deg[-1] == pytest.approx(10)
    fig = move.plot()
    angle, error = fig.axes
    assert [line.get_label() for line in angle.lines] == [
        "command δ_cmd", "δ, with feed-forward", "δ, without feed-forward"]
    assert error.get_ylabel().startswith("tracking error")
    with pytest.raises(ConfigError, match="velocity: must be > 0, got '0 deg/s'"):
        act.simulate_profile("10 deg", "0 deg/s", "1e5 deg/s^2")
