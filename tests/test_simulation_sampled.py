"""Sampled controllers in the nonlinear simulator, every architecture, both engines (issue 26).

References and tolerances
-------------------------
- **The discrete controllers by hand.** A PI at a fixed error e from rest: backward
  (Kp + Ki T z/(z-1)) gives after its n-th update (n = 0 at t = 0) Kp e + Ki T (n + 1) e; Tustin
  (the trapezoid, the samples before t = 0 being 0) Kp e + Ki T (n + 1/2) e. Checked on the
  reference engine's Controller and on the compiled kernel's update to 1e-12 (rounding).
- **Filters** after a sampled controller are the continuous chain discretised by the
  generalised bilinear transform at the controller's period (alpha 1 backward, 1/2 Tustin):
  checked against ``scipy.signal.cont2discrete(method="gbt")`` of each block's transfer
  function, ``lfilter`` in series (an independent route: not the simulator's scaled
  realisation of the whole chain) to 1e-9 of the output's scale (found 1e-14),
  and in the loop: the current command read after tau_p is the filtered position-controller
  output, sample by sample.
- **Held outputs.** Between its updates a sampled controller's output (and the filters after it)
  is constant: with current 20 kHz (5 steps of 10 us), velocity 5 kHz (20 steps), position
  2.5 kHz (40 steps) and cascade_axis's whole-step delays (tau_c 5, tau_v 10 steps), the
  terminal voltage may change only at steps k = 0 mod 5 and the current command read by the
  current loop only at k = 10 mod 20; exactly (no tolerance: a held value is the same float).
- **Both engines** perform the same operations: the same trajectories to 1e-9 of each signal's
  scale (tests/test_simulation_kernel.py's tolerance), with the clamps acting.
- **A sampled cascade by hand** (single rate and 20/5/2.5 kHz): the simulation at the sampling
  instants against the discrete loop written out in the test (plant discretised by scipy's
  zero-order hold from the structure's transfer functions), to 1e-6 of the step (found
  4e-13).
- **Convergence.** Sampling five times faster brings the sampled cascade about five times
  closer to the continuous one (the hold's half-period delay is first order in the period).
"""

import dataclasses
import math

import numpy as np
import pytest
from scipy import signal

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import Filter
from cas_freq.model import structure
from cas_freq.simulation import Step, simulate_batch
from cas_freq.simulation.architecture import FilterState, filter_chain
from cas_freq.simulation.controllers import Controller
from tests.test_simulation import with_sampling
from tests.test_simulation_architectures import _assert_same, _cascade, pid_with_filters

pytest.importorskip("numba")

#: cascade_axis's multirate sampling (its step is 10 us: 5, 20 and 40 steps).
CASCADE_RATES = {"current_rate_hz": 20e3, "velocity_rate_hz": 5e3, "position_rate_hz": 2.5e3}
LARGE = math.radians(10.0)
SMALL = math.radians(0.05)


@pytest.mark.parametrize("method, offset", [("backward", 1.0), ("tustin", 0.5)])
def test_a_sampled_pi_at_a_fixed_error_is_the_staircase_by_hand(method, offset):
    from cas_freq.simulation import kernel

    kp, ki, period, e = 2.0, 300.0, 4e-4, 0.25
    expected = kp * e + ki * period * (np.arange(6) + offset) * e
    one = np.ones(1)
    pi = Controller(kp * one, ki * one, 0 * one, one, 1e9 * one, period, sampled=True,
                    method=method)
    errors = np.full(1, e)
    outputs = [pi.start(errors, errors)[1][0]]
    outputs += [pi.update(errors, errors)[1][0] for _ in range(5)]
    np.testing.assert_allclose(outputs, expected, rtol=1e-12)
    # the compiled kernel's update, from rest (its first call is the update at t = 0)
    state = (0.0, 0.0, 0.0, 0.0, 0.0)
    compiled = []
    for _ in range(6):
        out = kernel._controller_update(*state, e, e, 0.0, 0.0, 0.0, 0.0, True, kp, ki, 0.0,
                                        0.0, 0.0, 0.0, False, 1e9, period, False,
                                        method == "backward")
        state = out[:5]
        compiled.append(out[6])
    np.testing.assert_allclose(compiled, expected, rtol=1e-12)


def _discrete_response(blocks, period, alpha, u):
    """``u`` through the blocks (first run) each discretised by scipy's generalised bilinear
    transform (the map s -> z is a substitution, so the series of the discretised blocks is
    the discretised series; block by block, each of order <= 2, stays well-conditioned)."""
    for block in blocks:
        num = [float(np.ravel(c)[0]) for c in block.numerator]
        den = [float(np.ravel(c)[0]) for c in block.denominator]
        b, a, _ = signal.cont2discrete((num, den), period, method="gbt", alpha=alpha)
        u = signal.lfilter(np.ravel(b), a, u)
    return u


@pytest.mark.parametrize("method, alpha", [("backward", 1.0), ("tustin", 0.5)])
def test_a_sampled_filter_chain_is_its_bilinear_discretisation(method, alpha):
    # cascade_axis's velocity feedback: the first-order feedback filter and the lowpass2, and
    # a notch in series with them (orders 1 + 2 + 2), at the velocity loop's 5 kHz
    loops = structure.build(_cascade()).loops
    blocks = (*loops[1].sensor, *loops[1].path)
    dt, every = 1e-5, 20
    chain = filter_chain(blocks, 1, dt, every, method)
    u = np.random.default_rng(26).standard_normal(200)
    state = FilterState(chain)
    y = [state.start(u[:1], u[:1])[1][0]]
    y += [state.step(u[n:n + 1], u[n:n + 1])[1][0] for n in range(1, u.size)]
    expected = _discrete_response(blocks, every * dt, alpha, u)
    assert np.max(np.abs(np.array(y) - expected)) <= 1e-9 * np.max(np.abs(expected))


@pytest.mark.parametrize("method, alpha", [("backward", 1.0), ("tustin", 0.5)])
def test_a_filter_after_a_sampled_position_pi_filters_its_samples(method, alpha):
    # The QT-CAS's position loop as a PI (Kd = 0) at 2.5 kHz (80 steps of 5 us), a lowpass2 at
    # the current command, current loop continuous: the current command read after tau_p
    # (80 steps, whole) is the filter's discrete response to the PI's output samples
    # Kp e_n + Ki I_n (rebuilt from the recorded error and integral term).
    p = dataclasses.replace(pid_with_filters(), cp_Kd=np.zeros(1), filters=(
        Filter("current_command", "lowpass2", 3000.0, damping=0.5),))
    p = with_sampling(p, (), method)
    run = simulate_batch(p, Step(SMALL), t_end=0.01, extend=False, dt=5e-6,
                         position_rate_hz=2.5e3)
    every = delay = 80
    assert p.tau_p[0] == pytest.approx(delay * run.dt_s)
    error = p.ratio[0] * run.command[0] - run.theta[0]
    u = p.cp_Kp[0] * error[::every] + run.position_integral[0, ::every]
    expected = _discrete_response(structure.build(p).loops[1].path, every * run.dt_s, alpha, u)
    read = run.current_command[0, delay::every]
    n = read.size
    assert np.max(np.abs(read - expected[:n])) <= 1e-9 * np.max(np.abs(expected))


def test_held_outputs_change_only_at_their_updates():
    # cascade_axis at 20/5/2.5 kHz: the voltage at the terminals (current controller, tau_c =
    # 5 steps) changes only at k = 0 mod 5; the current command read by the current loop (the
    # notch after the velocity controller, held over 20 steps, tau_v = 10 steps) only at
    # k = 10 mod 20
    run = simulate_batch(_cascade(), Step(SMALL), t_end=0.01, extend=False, **CASCADE_RATES)
    assert run.dt_s == pytest.approx(1e-5)
    k = np.arange(1, run.t.size)
    voltage_changes = k[np.diff(run.V[0]) != 0]
    command_changes = k[np.diff(run.current_command[0]) != 0]
    assert voltage_changes.size > 100 and command_changes.size > 30
    assert np.all(voltage_changes % 5 == 0)
    assert np.all(command_changes % 20 == 10)


@pytest.mark.parametrize("method", ["backward", "tustin"])
@pytest.mark.parametrize("build, rates", [
    (_cascade, CASCADE_RATES),
    (pid_with_filters, {"current_rate_hz": 25e3, "position_rate_hz": 2.5e3}),
], ids=["cascade_axis", "pid_notch_lowpass2"])
def test_both_engines_agree_on_sampled_architectures(build, rates, method):
    # 10 deg asks more than the limits give: the sampled controllers' anti-windup acts
    p = with_sampling(build(), (), method)
    compiled, reference = [simulate_batch(p, Step(LARGE), t_end=0.02, extend=False,
                                          engine=engine, **rates)
                           for engine in ("compiled", "reference")]
    assert compiled.current_limited.any()
    _assert_same(compiled, reference)
    assert compiled.sampling_method == method


def test_a_sampled_cascade_converges_to_the_continuous_one():
    # 20/5/2.5 kHz against 100/25/12.5 kHz (1, 4 and 8 steps): the RMS difference to the
    # continuous cascade over 20 ms shrinks with the period. Found 0.53 % and 0.11 % of the
    # step (ratio 4.7); asserted: below 1 %, and at least 3.5 times smaller.
    p = _cascade()
    kw = {"t_end": 0.02, "extend": False, "dt": 1e-5}
    continuous = simulate_batch(p, Step(SMALL), **kw).delta[0]
    slow = simulate_batch(p, Step(SMALL), **kw, **CASCADE_RATES).delta[0]
    fast = simulate_batch(p, Step(SMALL), current_rate_hz=100e3, velocity_rate_hz=25e3,
                          position_rate_hz=12.5e3, **kw).delta[0]
    rms = [np.sqrt(np.mean(np.square(run - continuous))) / SMALL for run in (slow, fast)]
    assert rms[0] < 0.01
    assert rms[1] < rms[0] / 3.5


def test_the_runs_declared_sampling_is_what_the_simulator_runs():
    # loop_sampling, the one place: the runs' sample_rates and sampling_method (issue 26's
    # LoopParameters fields) without any rate argument give the run of the explicit rates
    declared = with_sampling(_cascade(), (("current_loop", 20e3), ("velocity_loop", 5e3),
                                          ("position_loop", 2.5e3)), "tustin")
    kw = {"t_end": 0.005, "extend": False}
    run = simulate_batch(declared, Step(SMALL), **kw)
    explicit = simulate_batch(with_sampling(_cascade(), (), "tustin"), Step(SMALL), **kw,
                              **CASCADE_RATES)
    assert np.array_equal(run.delta, explicit.delta)
    assert (run.current_rate_hz, run.velocity_rate_hz, run.position_rate_hz) == (20e3, 5e3, 2.5e3)
    assert run.sampling_method == "tustin"
    # the same rates given again agree; a different one is an error naming the loop
    simulate_batch(declared, Step(SMALL), current_rate_hz=20e3, **kw)
    with pytest.raises(ConfigError, match="position_loop: .* 5000"):
        simulate_batch(declared, Step(SMALL), position_rate_hz=5e3, **kw)


def test_a_velocity_rate_needs_a_velocity_loop():
    with pytest.raises(ConfigError, match="velocity_loop: .*without a velocity loop"):
        simulate_batch(pid_with_filters(), Step(SMALL), t_end=0.001, velocity_rate_hz=5e3)


def _discrete_blocks(blocks, period):
    """Each block (first run) as a backward-difference state space (A, B, C, D), and its state."""
    out = []
    for block in blocks:
        num = [float(np.ravel(c)[0]) for c in block.numerator]
        den = [float(np.ravel(c)[0]) for c in block.denominator]
        a, b, c, d, _ = signal.cont2discrete(signal.tf2ss(num, den), period, method="gbt",
                                             alpha=1.0)
        out.append([a, b, c, d, np.zeros((a.shape[0], 1))])
    return out


def _through(blocks, u):
    """One sample ``u`` through the discretised blocks in series (their states advanced)."""
    for block in blocks:
        a, b, c, d, z = block
        y = (c @ z + d * u).item()
        block[4] = a @ z + b * u
        u = y
    return u


@pytest.mark.parametrize("every", [(1, 1, 1), (1, 4, 8)], ids=["single_rate", "multirate"])
def test_a_sampled_cascade_is_its_discrete_loop_by_hand(every):
    # cascade_axis linearised (eta = 1, no friction or bias), the current loop at 20 kHz (T =
    # 50 us, 5 steps), the velocity and position loops at 20 kHz too or at 5 and 2.5 kHz, a
    # 0.05 deg step. The delays are whole samples of T (tau_c 1, tau_v 2, tau_p 4), so at the
    # sampling instants the simulation is the discrete loop written out here at T: the plant
    # (the structure's voltage -> (i, omega, theta) transfer functions, which the simulator
    # does not use) discretised with a zero-order hold by scipy; backward PIs (Kp + Ki T_k
    # z/(z-1)) updated every every[k] samples and held in between; the velocity sensor's
    # filters and the notch at the current command discretised by the backward difference at
    # the velocity loop's period, block by block. Found 4e-13 of the motor-angle step (both
    # cases); bound 1e-6. Checked to fail: the simulation by Tustin (2e-3 off), the reference
    # with a forward-Euler integral (4e-4) or one more sample of tau_v (3e-3) (single rate);
    # the velocity filters discretised at 20 kHz (0.16) or its integral over 50 us (1.4e-2)
    # (multirate).
    from tests.test_simulation_architectures import cascade_axis

    p = cascade_axis()
    rate, steps = 20e3, 5
    period = 1.0 / rate
    run = simulate_batch(p, Step(SMALL), t_end=0.02, extend=False, current_rate_hz=rate,
                         velocity_rate_hz=rate / every[1], position_rate_hz=rate / every[2])
    assert run.dt_s == pytest.approx(period / steps)
    built = structure.build(p)
    current, velocity, position = built.loops
    plant = built.plant
    numerators = [plant.signals[name] for name in ("current", "motor_velocity", "motor_angle")]
    width = len(plant.denominator) - 1  # strictly proper: no direct term
    num = np.array([[0.0] * (width - len(n)) + [float(np.ravel(c)[0]) for c in n]
                    for n in numerators])
    den = [float(np.ravel(c)[0]) for c in plant.denominator]
    a, b, c, d, _ = signal.cont2discrete(signal.tf2ss(num, den), period, method="zoh")
    sensor = _discrete_blocks(velocity.sensor, every[1] * period)
    path = _discrete_blocks(velocity.path, every[1] * period)
    gains = [tuple(float(np.ravel(k)[0]) for k in loop.controller.numerator)
             for loop in (current, velocity, position)]
    delays = [int(round(float(np.ravel(loop.delay)[0]) / period))
              for loop in (current, velocity, position)]
    assert delays == [1, 2, 4]
    command = p.ratio[0] * SMALL  # the motor-angle step
    x = np.zeros((a.shape[0], 1))
    integrals = [0.0, 0.0, 0.0]
    held = [0.0, 0.0, 0.0]  # the controllers' outputs (the velocity loop's after the notch)
    voltages, currents, speeds = [0.0] * delays[0], [0.0] * delays[1], [0.0] * delays[2]
    theta = []

    def pi(j, error):
        integrals[j] += every[j] * period * error  # backward: Ki T_j z/(z - 1)
        return gains[j][0] * error + gains[j][1] * integrals[j]

    for n in range(int(round(0.02 * rate)) + 1):
        i, w, angle = (c @ x).ravel()
        theta.append(angle)
        if n % every[2] == 0:
            held[2] = pi(2, command - angle)
        speeds.append(held[2])
        speed_command = speeds.pop(0)  # tau_p later
        if n % every[1] == 0:
            held[1] = _through(path, pi(1, speed_command - _through(sensor, w)))
        currents.append(held[1])
        voltages.append(pi(0, currents.pop(0) - i))
        x = a @ x + b * voltages.pop(0)
    simulated = run.theta[0, ::steps]
    assert np.max(np.abs(simulated - np.array(theta))) < 1e-6 * command
