"""The nonlinear simulation of every drive architecture: velocity loop, filters, output feedback.

References and tolerances
-------------------------
- **Small amplitude is linear.** Below every limit the simulated loop is the linear loop of the
  declared structure (:mod:`cas_freq.model.structure`), so its sine dwell equals the
  exact-delay closed loop T(jw) (:func:`~cas_freq.simulation.sinedwell.linear_reference`,
  the frequency domain's own evaluation) and its step the Padé-8 python-control closed loop
  (:func:`cas_freq.analysis.systems.linear_model`). The issue asks 0.2 dB; the simulator's error
  is second order in dt (exact plant and filter steps for inputs linear over a step,
  trapezoidal controllers, interpolated delays), observed below 0.006 dB and 0.05 deg at the
  default dt (the largest at 3000 rad/s on the notch of the PID-on-PI case), so the tests hold
  it to 0.02 dB and 0.2 deg and the steps to 2e-4 of the step (observed 1.7e-6 to 3.5e-5,
  the largest on the compliant QT-CAS at 5 us).
  The cases are linearised where the simulator is nonlinear by design (docs/model.md, "Load
  and drivetrain": the gear's efficiency scales the reaction by 1/eta forward and eta_b
  backward, Coulomb friction, the hinge bias): eta = eta_b = 1, no friction, no bias. With the
  shipped cascade's eta = 0.9 the sine dwell departs from T by up to 0.075 dB at 200 rad/s,
  which is that nonlinearity (it is 6e-5 dB with eta = 1), not the loops.
- **Both engines** perform the same operations per run (tests/test_simulation_kernel.py): the
  same trajectories to 1e-9 of each signal's scale, here with the limits acting.
- **Clamps.** omega_max clamps the velocity command, so the motor speed stays within it plus
  the velocity loop's overshoot (20 % here: its step overshoot at these gains is a few %);
  i_max clamps the velocity controller's output, the current command (no filter after it).
- **Unstable.** cascade_axis's no_notch variant has closed-loop poles in the right half-plane
  (tests/test_architectures.py); simulated, its oscillation at the resonance grows until the
  current clamp holds it in a limit cycle (the output moves little: the motor swings), a
  result and not an error (``cas-freq simulate`` prints its warning and exits 0).
"""

import dataclasses
import math

import control
import numpy as np
import pytest

from cas_freq.analysis.systems import linear_model
from cas_freq.config.loader import load_variant, shipped_configs_dir
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import Step, simulate_batch
from cas_freq.simulation.sinedwell import linear_reference, sine_dwell
from tests.clirun import run_cli

pytest.importorskip("numba")

SMALL = math.radians(0.05)  # [rad] at the output: far below every limit


def _cascade(variant="base"):
    path = shipped_configs_dir() / "cascade_axis.yaml"
    return LoopParameters.from_config(load_variant(path, variant).params)


def _linear(p):
    """The runs ``p`` without the simulator's nonlinear drivetrain terms (module notes)."""
    ones, zeros = np.ones(p.n_runs), np.zeros(p.n_runs)
    return dataclasses.replace(p, eta=ones, eta_b=ones, F_c=zeros, tau_h=zeros)


def cascade_axis():
    """The shipped cascade: P-PI-PI, compliant coupling, notch, velocity filters."""
    return _linear(_cascade())


def pid_with_filters():
    """The QT-CAS's PID-on-PI with a notch and a second-order low-pass at the current
    command (in the current loop's band, so they shape the position loop)."""
    p = LoopParameters.from_config(load_variant().params)
    return dataclasses.replace(p, filters=(
        Filter("current_command", "notch", 3000.0, width=1500.0, depth_db=-20.0),
        Filter("current_command", "lowpass2", 8000.0, damping=0.7)))


def qt_cas_output_feedback():
    """The QT-CAS's loaded variant (compliant worm gear) closing the position loop on the
    output encoder (N delta)."""
    p = LoopParameters.from_config(load_variant(None, "loaded").params)
    return _linear(dataclasses.replace(p, feedback_output=True))


CASES = {
    "cascade_axis": (cascade_axis, [20.0, 80.0, 200.0], 0.3),
    "pid_notch_lowpass2": (pid_with_filters, [300.0, 1500.0, 3000.0], 0.03),
    "qt_cas_output_feedback": (qt_cas_output_feedback, [300.0, 1200.0, 2500.0], 0.03),
}


@pytest.mark.parametrize("case", CASES)
def test_small_sine_dwell_matches_the_linear_closed_loop(case):
    build, frequencies, _ = CASES[case]
    p = build()
    frequencies = np.array(frequencies)
    result = sine_dwell(p, [SMALL], frequencies)
    linear = linear_reference(p, frequencies)
    assert not result.limit_hit.any()
    np.testing.assert_allclose(result.magnitude_db[0], 20 * np.log10(np.abs(linear)), atol=0.02)
    np.testing.assert_allclose(result.phase_deg[0], np.degrees(np.unwrap(np.angle(linear))),
                               atol=0.2)


@pytest.mark.parametrize(("case", "feedforward"), [
    ("cascade_axis", dict(ff_v=0.8, ff_a=2e-3)),  # into omega_cmd [-] and i_cmd [A*s^2/rad]
    ("pid_notch_lowpass2", dict(ff_v=0.02, ff_a=1e-6)),  # into i_cmd, before the filters
])
def test_small_sine_dwell_with_feedforward_matches_the_linear_loop(case, feedforward):
    # the feed-forward enters where the structure declares it (T with it: linear_reference);
    # it moves T by up to 11.8 dB here, and the simulation follows to < 0.002 dB
    build, frequencies, _ = CASES[case]
    p = build().replace(**{key: np.array([value]) for key, value in feedforward.items()})
    frequencies = np.array(frequencies)
    result = sine_dwell(p, [SMALL], frequencies)
    linear = linear_reference(p, frequencies, feedforward=True)
    assert np.max(np.abs(20 * np.log10(np.abs(linear / linear_reference(
        p, frequencies, feedforward=False))))) > 4.0  # the feed-forward matters
    np.testing.assert_allclose(result.magnitude_db[0], 20 * np.log10(np.abs(linear)), atol=0.02)
    np.testing.assert_allclose(result.phase_deg[0], np.degrees(np.unwrap(np.angle(linear))),
                               atol=0.2)


@pytest.mark.parametrize("case", CASES)
def test_small_step_matches_the_linear_pade_model(case):
    build, _, horizon = CASES[case]
    p = build()
    result = simulate_batch(p, Step(SMALL), t_end=horizon, extend=False)
    closed = linear_model(p, 8).closed_loop  # with the feed-forward off: a step has none
    linear = control.step_response(closed, result.t).outputs
    error = result.delta[0] / SMALL - linear
    assert np.max(np.abs(error)) < 2e-4
    assert np.max(np.abs(linear - linear[-1])) > 0.05  # the step moves: the test can fail


def _cascade_batch():
    """Two cascades differing in a gain, the speed clamp and the notch's frequency."""
    p = _cascade().take([0, 0])
    filters = tuple(f.replace(frequency=np.array([800.0, 700.0]))
                    if f.kind == "notch" else f for f in p.filters)
    return dataclasses.replace(p, filters=filters).replace(
        cv_Kp=np.array([1.3, 0.9]), omega_max=np.array([np.inf, 30.0]))


def test_a_run_of_a_batch_is_the_run_alone():
    # per-run filter matrices and gains: each run of the batch is simulated as alone
    batch = _cascade_batch()
    together = simulate_batch(batch, Step(math.radians(10.0)), t_end=0.02, extend=False)
    for index in (0, 1):
        alone = simulate_batch(batch.take([index]), Step(math.radians(10.0)), t_end=0.02,
                               extend=False)
        np.testing.assert_allclose(together.delta[index], alone.delta[0], rtol=0,
                                   atol=1e-12 * math.radians(10.0))
    assert np.max(np.abs(together.delta[0] - together.delta[1])) > 1e-3


def _engines(p, amplitude_rad, t_end, **rates):
    return [simulate_batch(p, Step(amplitude_rad), t_end=t_end, extend=False, engine=engine,
                           **rates) for engine in ("compiled", "reference")]


def _assert_same(compiled, reference):
    for name in ("delta", "theta", "omega", "i", "V", "current_command", "position_integral"):
        a, b = getattr(compiled, name), getattr(reference, name)
        scale = np.max(np.abs(b), axis=1, keepdims=True)
        assert np.all(np.abs(a - b) <= 1e-9 * scale), name
    for name in ("current_limited", "voltage_limited"):
        assert np.array_equal(getattr(compiled, name), getattr(reference, name)), name


def _shipped_output_feedback():
    p = LoopParameters.from_config(load_variant(None, "loaded").params)
    return dataclasses.replace(p, feedback_output=True)  # friction, efficiencies, bias kept


@pytest.mark.parametrize("build", [
    _cascade, pid_with_filters, _shipped_output_feedback,
    lambda: _cascade_batch(),
], ids=["cascade_axis", "pid_notch_lowpass2", "qt_cas_loaded_output", "cascade_batch"])
def test_both_engines_agree_on_every_architecture(build):
    # 10 deg asks more than the limits give (both clamps act in the cascade); 20 ms is 2000
    # steps of the cascade's 10 us and 4000 of the QT-CAS's 5 us
    compiled, reference = _engines(build(), math.radians(10.0), 0.02)
    assert compiled.current_limited.any()
    _assert_same(compiled, reference)


def test_both_engines_agree_on_sampled_controllers_with_output_feedback():
    # sampled controllers (the QT-CAS's 25 kHz / 2.5 kHz) on the output encoder
    runs = _engines(_shipped_output_feedback(), math.radians(10.0), 0.02,
                    current_rate_hz=25_000.0, position_rate_hz=2_500.0)
    _assert_same(*runs)


def _rigid_cascade(**changes):
    """cascade_axis with a rigid coupling (no resonance) and no notch: stable without it;
    without its spring load (20 N*m/rad would stall a 90 deg step at the current limit)."""
    p = _cascade()
    filters = tuple(f for f in p.filters if f.at == "velocity_feedback")
    zero = np.zeros(1)
    return dataclasses.replace(p, K_g=zero, c_g=zero, K_h=zero, filters=filters).replace(
        **changes)


def test_omega_max_limits_the_motor_speed_and_i_max_the_current():
    step = math.radians(90.0)  # 15.7 rad at the motor: Kp asks 628 rad/s
    free = simulate_batch(_rigid_cascade(), Step(step), t_end=0.3, extend=False)
    limited = simulate_batch(_rigid_cascade(omega_max=np.array([50.0])), Step(step),
                             t_end=0.3, extend=False)
    assert np.max(np.abs(free.omega)) > 100.0  # without the clamp
    peak = np.max(np.abs(limited.omega))
    assert 0.95 * 50.0 < peak < 1.2 * 50.0
    for run in (free, limited):  # the velocity PI's output is the current command
        assert np.max(np.abs(run.current_command)) <= 10.0 * (1 + 1e-12)
        assert run.current_limited.any()
    # meanwhile the output slews at omega_max / N = 5 rad/s
    middle = (limited.t >= 0.05) & (limited.t <= 0.15)
    slope = np.polyfit(limited.t[middle], limited.delta[0, middle], 1)[0]
    assert slope == pytest.approx(50.0 / 10.0, rel=0.02)


def _swing(result, start, length=0.01):
    """Peak-to-peak motor speed over [start, start + length) [rad/s]."""
    window = (result.t >= start) & (result.t < start + length)
    return np.ptp(result.omega[0, window])


def test_the_unstable_variant_oscillates_as_a_result():
    # no_notch's Padé closed loop has poles at 28.8 +- 1288j rad/s: a small step's oscillation
    # at the resonance grows (x2.5 per 50 ms here, the current clamp already acting at times)
    # until the current clamp holds it in a limit cycle; the notched base decays instead
    unstable = simulate_batch(_cascade("no_notch"), Step(SMALL), t_end=0.2, extend=False)
    swings = [_swing(unstable, start) for start in (0.05, 0.1, 0.15)]
    assert swings[1] > 2 * swings[0] and swings[2] > 2 * swings[1]
    stable = simulate_batch(_cascade(), Step(SMALL), t_end=0.2, extend=False)
    swings = [_swing(stable, start) for start in (0.05, 0.1, 0.15)]
    assert swings[1] < 0.5 * swings[0] and swings[2] < 0.5 * swings[1]
    # a 1 deg step: the limit cycle, +-9 rad/s at the motor, the clamp active ~30 % of the time
    cycle = simulate_batch(_cascade("no_notch"), Step(math.radians(1.0)), t_end=0.5,
                           extend=False)
    assert np.all(np.isfinite(cycle.delta))
    assert _swing(cycle, 0.45, 0.05) > 10.0
    assert cycle.current_limited[0, cycle.t > 0.4].mean() > 0.1


@pytest.mark.parametrize("args", [
    ["simulate", "{config}", "--step", "5deg"],
    ["simulate", "{config}", "--variant", "no_notch", "--step", "1deg"],
    ["sinedwell", "{config}", "--amplitudes", "0.5deg", "--frequencies", "20,80", "-q"],
])
def test_the_cli_simulates_the_cascade(args):
    config = str(shipped_configs_dir() / "cascade_axis.yaml")
    code, out, err = run_cli([a.format(config=config) for a in args])
    assert code == 0, err
