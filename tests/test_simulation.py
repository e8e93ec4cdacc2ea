"""Nonlinear time-domain simulator: linear cross-check, limits, anti-windup, batch, dt, sampling.

References: the linear Padé model of :mod:`cas_freq.analysis.systems` (python-control),
docs/model.md's
numbers (20 A / 30 V limits, Kp * 3.49 rad = 22 A) and sample-exact discrete loops built here.
The 10 deg runs of both shipped variants are simulated once per module, as one batch at the
default step and one at half of it (a batch costs about what one run costs).
"""

import dataclasses
import math
import subprocess
import sys

import control
import numpy as np
import pytest

import cas_freq.simulation.controllers as controllers
from cas_freq.analysis.systems import linear_model
from cas_freq.config.loader import load_variant
from cas_freq.core.exceptions import ConfigError, ModelError
from cas_freq.simulation import (
    LoopParameters,
    Ramp,
    Sine,
    Step,
    default_time_step,
    fit_second_order,
    simulate,
    simulate_batch,
    simulation_step_figures,
    step_bound,
)

VARIANTS = ("base", "fitted")
SMALL = math.radians(0.05)  # small enough for no limit: ~1 A and ~0.9 V at most (checked below)
LARGE = math.radians(10.0)  # docs/model.md's 10 deg step at the fin


def with_sampling(runs, rates, method="backward"):
    """``runs`` (LoopParameters) declaring their sampling: the static fields ``sample_rates``
    ((loop name, rate [Hz]) pairs) and ``sampling_method`` of issue 26, set on a copy where
    LoopParameters does not have them yet (the simulator reads them with getattr)."""
    if "sampling_method" in {f.name for f in dataclasses.fields(runs)}:
        return dataclasses.replace(runs, sample_rates=tuple(rates), sampling_method=method)
    runs = dataclasses.replace(runs)
    object.__setattr__(runs, "sample_rates", tuple(rates))
    object.__setattr__(runs, "sampling_method", method)
    return runs


def params(variant="base", overrides=()):
    return load_variant(variant=variant, overrides=overrides).params


def rms(x):
    return float(np.sqrt(np.mean(np.square(x))))


def linear_step(config, t, pade_order=8):
    """Step response of the Padé-8 linear closed loop on the grid ``t`` (unit step)."""
    closed = linear_model(config, pade_order).closed_loop
    return control.forced_response(closed, t, np.ones_like(t)).outputs


@pytest.fixture(scope="module")
def large_steps():
    """10 deg steps of both variants, default dt (5 us) and dt/2, with the default horizon."""
    lp = LoopParameters.from_configs([params(v) for v in VARIANTS])
    full = simulate_batch(lp, Step(LARGE))
    half = simulate_batch(lp, Step(LARGE), dt=full.dt_s / 2, t_end=full.t_end_s, extend=False)
    return full, half


@pytest.mark.parametrize("variant", VARIANTS)
@pytest.mark.parametrize("derivative_on", ["error", "measurement"])
def test_small_step_matches_linear_pade_model(variant, derivative_on):
    # docs/model.md / issue: with no limit active the loop is linear, so the simulation must equal
    # the linear Padé-8 closed loop. Requirement 0.5 % of the step (RMS); found ~1e-5 at the
    # default dt (second order in dt; Padé-8 vs exact delay is below that), so the test also
    # asserts 1e-4 to catch a regression to a first-order scheme (which gave ~1e-3).
    config = params(variant, [("position_loop.derivative_on", derivative_on)])
    run = simulate(config, Step(SMALL), t_end=0.06, extend=False)
    assert not run.current_limited.any() and not run.voltage_limited.any()
    error = run.delta - SMALL * linear_step(config, run.t)
    assert rms(error) / SMALL < 0.005
    assert rms(error) / SMALL < 1e-4


def test_delays_off_the_grid_and_zero():
    # tau not a multiple of dt (interpolated delay line) and zero delays, against the same
    # linear model. A delayed jump landing between samples is smeared over one step: O(dt),
    # found 4e-4 of the step RMS; zero delays found 6e-5. Bound: the 0.5 % requirement / 5.
    for overrides in (
        [("position_loop.delay", "0.4013 ms"), ("current_loop.delay", "0.0637 ms")],
        [("position_loop.delay", 0.0), ("current_loop.delay", 0.0)],
    ):
        config = params("base", overrides)
        run = simulate(config, Step(SMALL), t_end=0.04, extend=False)
        assert run.dt_s == pytest.approx(5e-6)
        error = run.delta - SMALL * linear_step(config, run.t)
        assert rms(error) / SMALL < 1e-3, overrides


@pytest.mark.parametrize("index", [0, 1])
def test_large_step_hits_current_limit_only(large_steps, index):
    # docs/model.md: a 10 deg step asks Kp * 3.49 rad ~ 22 A of the 20 A limit (and the derivative
    # kick Kd/Tf * 3.49 rad ~ 220 A at t = 0), so the current command is clamped; the voltage
    # stays well inside 30 V. The commanded current never exceeds 20 A (clamp, exact) and the
    # terminal voltage never 30 V. The motor current itself may overshoot the command by the
    # current loop's own overshoot: allow 2 % (found 19.98 A base, 20.16 A fitted).
    run = large_steps[0].run(index)
    assert abs(22.1 - 6.3435 * LARGE * 20) < 0.1  # docs/model.md's 22 A
    assert run.current_limited.any() and not run.voltage_limited.any()
    assert np.max(np.abs(run.current_command)) <= 20.0
    assert np.max(np.abs(run.V)) <= 30.0
    assert np.max(np.abs(run.i)) <= 20.0 * 1.02
    figures = simulation_step_figures(run)
    assert figures.current_limited and not figures.voltage_limited
    assert figures.max_current_a == pytest.approx(20.0, rel=0.02)


def test_large_step_settles_on_command_and_horizon_extends(large_steps):
    # The 2 % settling time of the 10 deg steps is ~80 ms (slow integrator tail), more than half
    # the default 0.1 s horizon, so the horizon was doubled once and every run then settled.
    full = large_steps[0]
    assert full.extended and full.t_end_s == pytest.approx(0.2)
    assert full.settled.all()
    assert np.allclose(full.delta[:, -1], LARGE, rtol=0.02)
    short = simulate(params(), Step(SMALL), t_end=0.01, max_t_end=0.015)
    assert short.extended and short.t_end_s == pytest.approx(0.015) and not short.settled


def naive_integration(integral, e_start, e_end, rest_start, rest_end, ki, limit, period, locate,
                      backward=False):
    """A clamp without anti-windup: the integral always integrates (trapezoidal rule, or a
    sampled controller's backward difference)."""
    return integral + (period * e_end if backward else 0.5 * period * (e_start + e_end))


def test_second_order_fit_of_large_and_small_steps(large_steps):
    # docs/model.md: the bandwidth inferred from a 10 deg step (limits active) differs from the
    # small-signal one. The report's §7 fit applied to both: the 10 deg step fits with a much
    # lower closed-form bandwidth (found 270 rad/s base, 299 fitted) than the 0.05 deg step
    # (1196 and 713 rad/s). The model fits the 10 deg step to ~2 % of the step (RMS; found
    # 2.0 % and 1.8 %: the slow integrator tail is not second order); bound 2.5 %.
    lp = LoopParameters.from_configs([params(v) for v in VARIANTS])
    small = simulate_batch(lp, Step(SMALL), t_end=0.06, extend=False)
    for j in range(len(VARIANTS)):
        big = large_steps[0].run(j)
        fit_big = fit_second_order(big.t, big.delta, LARGE)
        fit_small = fit_second_order(small.t, small.delta[j], SMALL)
        assert fit_big.success and fit_small.success
        assert fit_big.rms_residual < 0.025 * LARGE
        assert fit_big.bandwidth_closed_form_rad_s < 0.5 * fit_small.bandwidth_closed_form_rad_s


def test_anti_windup(monkeypatch):
    # Three 10 deg runs of the base variant: with anti-windup (as built), with a naive clamp
    # (the integrator never holds: naive_integration, here in the test only) and with
    # limits so large that they never act. Without limits the loop is linear (overshoot 47.8 %,
    # the Padé model's) and draws ~200 A: limits change the behaviour completely. The naive
    # clamp winds the integrator up during the clamp: larger integral (found 1.23 A vs 0.84 A)
    # and larger overshoot (4.9 % vs 3.3 %).
    base = LoopParameters.from_config(params())
    guarded = simulate(base, Step(LARGE), t_end=0.12, extend=False)
    free = simulate(base.replace(i_max=1e6, v_max=1e6), Step(LARGE), t_end=0.12, extend=False)
    monkeypatch.setattr(controllers, "integrate_with_anti_windup", naive_integration)
    # the numpy reference engine, whose controllers the patch reaches (not the compiled kernel)
    naive = simulate(base, Step(LARGE), t_end=0.12, extend=False, engine="reference")
    f_guarded, f_free, f_naive = map(simulation_step_figures, (guarded, free, naive))
    assert f_free.max_current_a > 100 and not f_free.current_limited
    assert f_free.overshoot_pct == pytest.approx(47.8, abs=0.1)
    assert f_guarded.overshoot_pct < f_free.overshoot_pct / 5
    assert f_naive.overshoot_pct > f_guarded.overshoot_pct + 1.0
    wound = np.max(np.abs(naive.position_integral))
    held = np.max(np.abs(guarded.position_integral))
    assert wound > 1.3 * held
    # Wherever the output is clamped, the integrator did not move outwards in that update. The
    # controller output u_p at step k is the current command at step k + tau_p/dt.
    shift = round(0.4e-3 / guarded.dt_s)
    clamped = np.flatnonzero(guarded.current_limited[1:-shift]) + 1
    moved = guarded.position_integral[clamped] - guarded.position_integral[clamped - 1]
    assert np.all(moved * np.sign(guarded.current_command[clamped + shift]) <= 0.0)


def test_batch_equals_single_runs():
    # Three different runs (two variants, two commands, a swept gain) in one batch must equal
    # the three single runs: same arithmetic per run, so to rounding (1e-12 of the step).
    configs = [params("base"), params("fitted"), params("base")]
    lp = LoopParameters.from_configs(configs).replace(cp_Kp=[6.3435, 6.3435, 5.0])
    commands = [Step(LARGE), Step(SMALL), Sine(SMALL, 300.0)]
    batch = simulate_batch(lp, commands, t_end=0.03)
    for j, command in enumerate(commands):
        single = simulate(lp.run(j), command, t_end=0.03, extend=False)
        scale = np.max(np.abs(single.delta))
        assert np.max(np.abs(batch.run(j).delta - single.delta)) <= 1e-12 * scale
        assert np.max(np.abs(batch.run(j).i - single.i)) <= 1e-12 * np.max(np.abs(single.i))
        assert np.array_equal(batch.run(j).current_limited, single.current_limited)
    # One command whose amplitude is an array of n_runs: the same as a list of commands.
    kw = {"t_end": 0.01, "extend": False}
    arrayed = simulate_batch(lp, Step(np.array([LARGE, SMALL, SMALL])), **kw)
    listed = simulate_batch(lp, [Step(LARGE), Step(SMALL), Step(SMALL)], **kw)
    assert np.array_equal(arrayed.delta, listed.delta)
    # Recording every 10th step keeps exactly those samples; a sine has no "settled".
    sparse = simulate_batch(lp, Step(np.array([LARGE, SMALL, SMALL])), record_every=10, **kw)
    assert np.array_equal(sparse.t, arrayed.t[::10])
    assert np.array_equal(sparse.i, arrayed.i[:, ::10])
    assert batch.settled is None and batch.run(2).settled is None


@pytest.mark.parametrize("rates", [(None, None), (25e3, 2.5e3)])
def test_batch_with_per_run_delays(rates):
    # Different delays per run take the delay lines' general path (per-run indices, fractional
    # delays), a single run with a whole-step delay the fast path: they must agree to 1e-12.
    lp = LoopParameters.from_configs([params()] * 3).replace(
        tau_p=[0.4e-3, 0.4013e-3, 0.2e-3], tau_c=[0.06e-3, 0.06e-3, 0.1e-3]
    )
    kw = {"t_end": 0.02, "extend": False, "dt": 5e-6,
          "current_rate_hz": rates[0], "position_rate_hz": rates[1]}
    batch = simulate_batch(lp, Step(SMALL), **kw)
    for j in range(3):
        single = simulate(lp.run(j), Step(SMALL), **kw)
        assert np.max(np.abs(batch.run(j).delta - single.delta)) <= 1e-12 * SMALL


def _changes(figures_a, figures_b):
    names = ("rise_time_s", "overshoot_pct", "settling_time_s", "settling_time_5pct_s",
             "peak_time_s")
    return {n: abs(getattr(figures_b, n) / getattr(figures_a, n) - 1) for n in names}


def test_dt_convergence(large_steps):
    # The default dt (5 us) is chosen so that halving it changes no step figure of the 10 deg
    # step by more than 0.5 % (the requirement). Found <= 0.0004 % for both variants; the
    # second bound (0.01 %) guards the second-order scheme (a first-order one gave 0.06 %).
    full, half = large_steps
    assert full.dt_s == pytest.approx(5e-6)
    for j in range(len(full)):
        a, b = simulation_step_figures(full.run(j)), simulation_step_figures(half.run(j))
        for name, change in _changes(a, b).items():
            assert change < 0.005, (VARIANTS[j], name, change)
            assert change < 1e-4, (VARIANTS[j], name, change)


@pytest.mark.slow
def test_dt_convergence_study(large_steps):
    # The study behind the default dt: 20, 10, 5, 2.5, 1.25 us. The change per halving shrinks
    # about fourfold (second order): found 0.006 %, 0.0015 %, 0.0004 %, 0.0001 % at most.
    # Asserted: below the 0.5 % requirement at every halving, and shrinking by at least 2.5x.
    lp = LoopParameters.from_configs([params(v) for v in VARIANTS])
    t_end = large_steps[0].t_end_s
    runs = {dt: simulate_batch(lp, Step(LARGE), dt=dt, t_end=t_end, extend=False)
            for dt in (2e-5, 1e-5, 1.25e-6)}
    runs[5e-6], runs[2.5e-6] = large_steps
    steps = sorted(runs, reverse=True)
    for j in range(len(lp.R)):
        worst = []
        for coarse, fine in zip(steps[:-1], steps[1:], strict=True):
            a = simulation_step_figures(runs[coarse].run(j))
            b = simulation_step_figures(runs[fine].run(j))
            worst.append(max(_changes(a, b).values()))
        assert max(worst) < 0.005, (VARIANTS[j], worst)
        ratios = [w / w_next for w, w_next in zip(worst[:-1], worst[1:], strict=True)]
        assert min(ratios) > 2.5, (VARIANTS[j], worst)


def _sampled_position_reference(config, rate, t_end, method="backward"):
    """Sample-exact small step of a 2.5 kHz position PID around the continuous current loop.

    The current loop and motor (i_cmd -> theta, Padé-10 tau_c) are discretised with a zero-order
    hold (python-control c2d); the PID is written out as the design of issue 26 discretises it
    (docs/model.md "Sampled controllers"): backward, Kp + Ki T z/(z-1) + Kd (z-1)/((Tf+T) z -
    Tf); tustin, s -> (2/T)(z-1)/(z+1) in Kp + Ki/s + Kd s/(Tf s + 1), i.e. the trapezoidal
    integral and 2 Kd (z-1)/((2Tf+T) z - (2Tf-T)); tau_p = whole samples of delay. Unit step.
    """
    lm = linear_model(config, 10)
    motor, loop = config.motor, config.position_loop
    mech = control.tf([motor.Km], [motor.J, motor.viscous_friction, 0.0])
    g = control.c2d(control.series(lm.current_closed_loop, control.ss(mech)), 1.0 / rate, "zoh")
    period, tf = 1.0 / rate, loop.filter_time_constant
    delay = [0.0] * int(round(loop.delay * rate))
    x = np.zeros((g.A.shape[0], 1))
    integral = derivative = e_prev = 0.0
    out = []
    for _ in range(int(round(t_end * rate)) + 1):
        theta = (g.C @ x).item()
        out.append(theta)
        e = 1.0 - theta
        if method == "backward":  # (Tf+T) D_n - Tf D_n-1 = Kd (e_n - e_n-1)
            integral += period * e
            derivative = (tf * derivative + loop.Kd * (e - e_prev)) / (tf + period)
        else:  # (2Tf+T) D_n - (2Tf-T) D_n-1 = 2 Kd (e_n - e_n-1)
            integral += 0.5 * period * (e_prev + e)
            derivative = (2 * loop.Kd * (e - e_prev) + (2 * tf - period) * derivative) / (
                2 * tf + period)
        e_prev = e
        delay.append(loop.Kp * e + loop.Ki * integral + derivative)
        x = g.A @ x + g.B * delay.pop(0)
    return np.array(out)


@pytest.mark.parametrize("method", ["backward", "tustin"])
@pytest.mark.parametrize("variant", VARIANTS)
def test_sampled_position_loop_is_sample_exact(variant, method):
    # Position PID sampled at 2.5 kHz (zero-order hold), current loop continuous: at the
    # samples the simulation equals the discrete reference above. Found 2e-5 of the step (the
    # reference's Padé-10 current delay); bound 1e-4. (Before issue 26 the simulator's
    # integral was the trapezoidal rule beside a backward derivative: 7.8e-4 off the backward
    # reference.)
    config = params(variant)
    runs = with_sampling(LoopParameters.from_config(config), (), method)
    run = simulate(runs, Step(SMALL), t_end=0.04, extend=False, position_rate_hz=2.5e3)
    every = int(round(1 / (2.5e3 * run.dt_s)))
    reference = _sampled_position_reference(config, 2.5e3, 0.04, method)
    assert np.max(np.abs(run.delta[::every] / SMALL - reference)) < 1e-4


@pytest.mark.parametrize("variant, vs_continuous, vs_half_period", [
    ("base", 0.085, 0.045), ("fitted", 0.045, 0.025),
])
def test_sampled_controllers_small_step(variant, vs_continuous, vs_half_period):
    # Current loop at 25 kHz, position loop at 2.5 kHz, on top of the report's delays. A
    # zero-order hold delays by half a period on average, so the sampled loop is close to the
    # continuous-time one with tau_c + 20 us and tau_p + 200 us (found RMS over 60 ms: 3.6 %
    # base, 2.1 % fitted, of the step) than to the continuous loop (found 7.2 % and 3.6 %): at
    # 2.5 kHz the extra 0.2 ms costs ~9 deg of phase margin, so the small-step overshoot grows
    # from 48 % to 72 % (base), 35 % to 49 % (fitted). So "close" means within ~7 % RMS, and
    # the difference is the hold's delay, not an error. Bounds: the found values + ~20 %.
    config = params(variant)
    kw = {"t_end": 0.06, "extend": False}
    sampled = simulate(config, Step(SMALL), current_rate_hz=25e3, position_rate_hz=2.5e3, **kw)
    continuous = simulate(config, Step(SMALL), **kw)
    assert sampled.dt_s == continuous.dt_s == pytest.approx(5e-6)
    longer = params(variant, [("position_loop.delay", 0.4e-3 + 0.2e-3),
                              ("current_loop.delay", 0.06e-3 + 0.02e-3)])
    half_period = SMALL * linear_step(longer, sampled.t)
    assert rms(sampled.delta - continuous.delta) / SMALL < vs_continuous
    assert rms(sampled.delta - half_period) / SMALL < vs_half_period
    assert not sampled.current_limited.any()


def test_sampled_controllers_converge_to_continuous():
    # Ten times faster sampling (250 kHz / 25 kHz) must come roughly ten times closer: the
    # hold's half-period delay is first order in the period. Found 0.77 % of the step RMS over
    # 30 ms (7.2 % over 60 ms at 25 kHz / 2.5 kHz); bound 1 %.
    config = params("base")
    kw = {"t_end": 0.03, "extend": False, "dt": 1e-6}
    sampled = simulate(config, Step(SMALL), current_rate_hz=250e3, position_rate_hz=25e3, **kw)
    continuous = simulate(config, Step(SMALL), **kw)
    assert rms(sampled.delta - continuous.delta) / SMALL < 0.01


def test_feed_forward_reaches_current_loop_after_tau_p():
    # A ramp of 1 rad/s at the fin is 20 rad/s at the motor: ff_v * 20 = 0.192 A, added to the
    # current command and delayed by tau_p = 0.4 ms. Until the motor moves (tau_p + tau_c) the
    # feedback terms are the same with and without feed-forward, so the difference is exactly
    # the feed-forward.
    base = LoopParameters.from_config(params())
    kw = {"t_end": 0.002}
    with_ff = simulate(base, Ramp(1.0), **kw)
    without = simulate(base.replace(ff_v=0.0, ff_a=0.0), Ramp(1.0), **kw)
    diff = with_ff.current_command - without.current_command
    window = (with_ff.t >= 0.4e-3) & (with_ff.t <= 0.45e-3)
    assert np.allclose(diff[window], 0.0096 * 20.0, rtol=1e-12)
    assert np.all(diff[with_ff.t < 0.4e-3 - 1e-9] == 0.0)


def test_default_time_step_and_argument_errors():
    # Shipped config: current-loop crossover ~ Kp/L = 0.6163/7.1e-5 = 8680 rad/s, bound
    # 0.05/8680 = 5.76 us, so 5 us: 60 us and 400 us are 12 and 80 steps; 25 kHz and 2.5 kHz
    # are 8 and 80. A four times faster current loop lowers it to 1 us (bound 1.44 us).
    lp = LoopParameters.from_config(params())
    assert step_bound(lp) == pytest.approx(0.05 * 7.1e-5 / 0.6163)
    assert default_time_step([60e-6, 400e-6], [40e-6, 400e-6], step_bound(lp)) == 5e-6
    assert default_time_step([60e-6, 400e-6], [], step_bound(lp.replace(ci_Kp=2.4652))) == (
        pytest.approx(1e-6))
    assert default_time_step([3e-6]) == pytest.approx(1e-6)
    assert default_time_step([0.4013e-3]) == pytest.approx(5e-6)  # no fit: interpolated
    config = params()
    with pytest.raises(ModelError, match="current_rate_hz"):
        simulate(config, Step(SMALL), dt=5e-6, current_rate_hz=30e3, t_end=0.001)
    with pytest.raises(ConfigError, match="t_end"):
        simulate(config, Sine(SMALL, 10.0))
    with pytest.raises(ConfigError, match="dt"):
        simulate(config, Step(SMALL), dt=-1.0)
    with pytest.raises(ConfigError, match="Tf"):
        LoopParameters.from_config(config).replace(Tf=0.0)
    # (the keys' ranges are checked where a user's value enters; LoopParameters wants finite)
    with pytest.raises(ConfigError, match=r"R: must be finite, got nan \(runs \[1\]\)"):
        LoopParameters.from_config(config).replace(R=[0.3, np.nan])


def test_simulation_imports_neither_control_nor_matplotlib():
    code = (
        "import sys, cas_freq.simulation as s; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in ('control', 'matplotlib')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_batches_recording_into_kept_buffers_give_the_same_runs():
    # A study's chunks record into one RecordingBuffers: each batch must give exactly what it
    # gives in fresh memory, whatever the batch before left there (a longer horizon, more
    # runs), and the buffers then start each batch at the longest horizon seen (no copy).
    from cas_freq.simulation.simulator import RecordingBuffers

    base = params()
    stiff = params(overrides=[("position_loop.Kp", 2.0), ("position_loop.Kd", 0.01)])
    batches = [LoopParameters.from_configs(configs)
               for configs in ([base, stiff, base], [stiff], [base, base])]
    buffers = RecordingBuffers()
    for batch in batches:
        kept = simulate_batch(batch, Step(LARGE), buffers=buffers)
        fresh = simulate_batch(batch, Step(LARGE))
        assert kept.t_end_s == fresh.t_end_s
        for name in ("t", "delta", "theta", "omega", "i", "V", "command", "current_command",
                     "position_integral", "current_limited", "voltage_limited"):
            np.testing.assert_array_equal(getattr(kept, name), getattr(fresh, name), name)
        assert buffers.capacity >= kept.t.size
