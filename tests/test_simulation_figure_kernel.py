"""The compiled step figures and settling checks of a batch, and the recording choices.

References: :func:`cas_freq.simulation.step_figures.step_figures` (the per-run numpy figures,
docs/model.md "Definitions of the figures") and the numpy settling check
``simulator._settled``. The compiled forms do the same operations in the same order on the
same samples, so they must agree exactly (NaN where the reference has None or NaN). Against a
run simulated alone the batch agrees to rounding (1e-9 relative, as tests/test_studies_steps.py):
each run's arithmetic does not depend on the other runs, and each run is cut (and, with
``stop_settled``, stopped) at the horizon it would have had alone.
"""

import dataclasses
import math

import numpy as np
import pytest

from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import variant_parameters
from cas_freq.simulation import Step, simulate, simulate_batch
from cas_freq.simulation.figure_kernel import (
    FIGURE_COLUMNS,
    settled_runs,
    step_figures_batch,
)
from cas_freq.simulation.second_order import fit_second_order
from cas_freq.simulation.simulator import SETTLE_BAND, _settled
from cas_freq.simulation.step_figures import simulation_step_figures, step_figures
from cas_freq.studies.steps import FIT_FIGURES, STEP_FIGURES, batch_steps

AMPLITUDE = math.radians(10.0)
# position_loop.Kp [A/rad]: the shipped gain (settles at ~83 ms: a 0.2 s horizon), a faster
# one that settles within the first 0.1 s horizon, an overshooting one (~39 %) and one whose
# loop oscillates in a limit cycle and never settles (the horizon runs to its 1 s cap)
GAINS = (6.3435, 9.0, 25.0, 300.0)


def _reference_row(figures):
    """The STEP_FIGURES of a StepFigures as floats (NaN for None)."""
    values = dataclasses.asdict(figures)
    return np.array([math.nan if values[name] is None else float(values[name])
                     for name in FIGURE_COLUMNS])


def _second_order(t, zeta, wn=300.0):
    """Unit step response of a second-order system (Ogata, Modern Control Engineering, §5-3)."""
    wd = wn * math.sqrt(1.0 - zeta**2)
    return 1.0 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t))


def test_compiled_step_figures_equal_the_reference_on_synthetic_responses():
    t = np.linspace(0.0, 0.1, 2001)
    uneven = t.copy()
    uneven[1000:] += np.linspace(0.0, 1e-4, 1001) ** 2 * 1e3  # spacing not uniform at the peak
    step = 0.2  # [rad]
    responses = {
        "nominal": step * _second_order(t, 0.8),
        "overshooting": step * _second_order(t, 0.2),
        "unsettled (ends outside the band)": step * _second_order(t, 0.02),
        "never reaches 90 %": 0.5 * step * (1.0 - np.exp(-60.0 * t)),
        "diverged": step * np.exp(200.0 * t),  # beyond 1e6 times the step before the end
        "at the final value from t = 0": np.full(t.size, step),
        "not finite": np.where(t > 0.05, np.nan, step * _second_order(t, 0.5)),
    }
    names = list(responses)
    delta = np.array([responses[name] for name in names])
    rng = np.random.default_rng(4)
    current = rng.normal(0.0, 5.0, delta.shape)
    current[2, 7] = np.nan  # a NaN current: the largest |current| is NaN, as np.max gives
    voltage = rng.normal(0.0, 20.0, delta.shape)
    current_limited = rng.random(delta.shape) > 0.999
    voltage_limited = np.zeros(delta.shape, dtype=bool)
    sizes = np.array([t.size, t.size, t.size, 1500, t.size, t.size, 1200])  # runs cut short
    for times in (t, uneven):
        table = step_figures_batch(times, delta, sizes, step, current, voltage,
                                   current_limited, voltage_limited)
        for run, name in enumerate(names):
            cut = slice(0, sizes[run])
            expected = _reference_row(step_figures(
                times[cut], delta[run, cut], step, current=current[run, cut],
                voltage=voltage[run, cut], current_limited=current_limited[run, cut],
                voltage_limited=voltage_limited[run, cut]))
            np.testing.assert_array_equal(table[run], expected, err_msg=name)
    # the cases above do what their names say (so the comparison covers them)
    assert table[1, 1] > 40.0 and np.isnan(table[2, 2]) and np.isnan(table[3, 0])
    assert np.isnan(table[4, :7]).all() and table[5, 2] == t[0]


def test_compiled_settling_check_equals_numpy():
    rng = np.random.default_rng(7)
    t = np.linspace(0.0, 0.2, 401)
    final = np.array([1.0, 1.0, -0.5, 2.0, 1.0])
    command = np.broadcast_to(final[:, None], (5, t.size)).copy()
    delta = final[:, None] * (1.0 + rng.normal(0.0, 0.005, (5, t.size)))
    delta[1, 390] = 1.05  # leaves the band late: not settled
    delta[3, 50] = 0.0  # outside the band before the window only: settled
    delta[4, 300] = np.nan  # a NaN sample in the window: not settled
    for t_from in (0.0, 0.1, 0.2, 0.3):  # 0.3: an empty window, never settled
        expected = _settled(t, delta, command, final, t_from)
        got = _settled(t, delta, command, final, t_from, compiled=True)
        np.testing.assert_array_equal(got, expected)
    assert list(_settled(t, delta, command, final, 0.1, compiled=True)) == [
        True, False, True, True, False]
    start = int(np.searchsorted(t, 0.1))
    assert settled_runs(delta, command, final, start, SETTLE_BAND)[0]


@pytest.fixture(scope="module")
def gains_batch():
    return variant_parameters(load_variant().params, {"position_loop.Kp": list(GAINS)})


def test_batch_figures_and_fits_equal_each_run_alone(gains_batch):
    figures = batch_steps(gains_batch, AMPLITUDE)
    base = load_variant()
    for index, kp in enumerate(GAINS):
        alone = simulate(variant_parameters(base.params, {"position_loop.Kp": [kp]}),
                         Step(AMPLITUDE))
        row = _reference_row(simulation_step_figures(alone, AMPLITUDE))
        expected = dict(zip(STEP_FIGURES, row, strict=True))
        fit = fit_second_order(alone.t, alone.delta, AMPLITUDE)
        expected.update({name: getattr(fit, name.split(".")[1]) for name in FIT_FIGURES})
        for name, value in expected.items():
            got = figures[name][index]
            assert (math.isnan(got) if math.isnan(value) else
                    got == pytest.approx(value, rel=1e-9, abs=1e-15)), (kp, name, got, value)
    # the runs are what GAINS says: 0.2 s, 0.1 s, overshooting, never settled
    assert figures["step.overshoot_pct"][2] > 30 and math.isnan(figures["step.settling_time_s"][3])


def test_stopping_settled_runs_changes_no_run(gains_batch):
    full = simulate_batch(gains_batch, Step(AMPLITUDE))
    stopped = simulate_batch(gains_batch, Step(AMPLITUDE), stop_settled=True,
                             signals=("i", "V", "current_limited", "voltage_limited"))
    np.testing.assert_array_equal(stopped.t_end_runs, full.t_end_runs)
    assert list(stopped.t_end_runs) == [0.2, 0.1, 0.1, 1.0]
    for index in range(len(GAINS)):
        a, b = full.run(index), stopped.run(index)
        for name in ("t", "delta", "theta", "i", "V", "command", "current_limited"):
            np.testing.assert_array_equal(getattr(b, name), getattr(a, name), err_msg=name)
        assert b.omega is None and b.current_command is None  # not recorded
        # after its own horizon a stopped run has no samples (NaN), not stale memory
        after = stopped.t > stopped.t_end_runs[index] + 0.5 * stopped.dt_s
        assert np.isnan(stopped.delta[index, after]).all()
        assert not stopped.current_limited[index, after].any()


def test_recording_only_some_signals_keeps_them_exact(gains_batch):
    one = gains_batch.take([0])
    full = simulate_batch(one, Step(AMPLITUDE), t_end=0.01, extend=False)
    theta = simulate_batch(one, Step(AMPLITUDE), t_end=0.01, extend=False, signals=("theta",))
    np.testing.assert_array_equal(theta.theta, full.theta)
    np.testing.assert_array_equal(theta.command, full.command)
    assert theta.i is None and theta.V is None and theta.voltage_limited is None
    with pytest.raises(ConfigError, match="signals: unknown signal 'current'"):
        simulate_batch(one, Step(AMPLITUDE), t_end=0.01, signals=("theta", "current"))


@pytest.mark.parametrize("hinge", [0.0, 50.0])  # N*m/rad: unloaded, and loaded (the 5-state
def test_a_held_command_row_gives_the_same_run(hinge, monkeypatch):  # plant's branch)
    # after its start a step holds its value: the compiled engine passes one command row for
    # all the steps of a call instead of one per step; every signal must be the same to the bit
    from cas_freq.core.parameters import LoopParameters
    from cas_freq.simulation.engine import CommandSet

    runs = LoopParameters.from_config(load_variant().params).take([0, 0])
    runs = dataclasses.replace(runs, K_h=np.array([0.0, hinge]))
    held = simulate_batch(runs, Step(AMPLITUDE), t_end=0.02, extend=False, engine="compiled")
    monkeypatch.setattr(CommandSet, "held_from", lambda self: math.inf)
    rows = simulate_batch(runs, Step(AMPLITUDE), t_end=0.02, extend=False, engine="compiled")
    for name in ("delta", "theta", "omega", "i", "V", "command", "current_command",
                 "position_integral", "current_limited", "voltage_limited"):
        np.testing.assert_array_equal(getattr(held, name), getattr(rows, name), err_msg=name)
    assert np.isfinite(held.delta).all()


def test_fit_sums_of_chosen_rows_equal_those_of_copied_rows():
    # the Levenberg-Marquardt iteration passes the rows of the runs still iterating instead of
    # copies of their data: the same sums to the bit (each run's sums are its own)
    from cas_freq.core.jit import use_compiled

    if not use_compiled():
        pytest.skip("numba is not importable: the numpy reference copies the rows")
    from cas_freq.simulation.fit_kernel import normal_equations_of

    t = np.tile(np.linspace(0.0, 0.05, 400), (4, 1))
    unit = np.array([_second_order(t[0], zeta) for zeta in (0.3, 0.6, 0.8, 0.95)])
    rows = np.array([3, 1, 1, 0])
    p = np.array([[1.0, 0.5, 0.1], [0.9, 0.6, 0.0], [1.1, 0.7, 0.2], [1.0, 1.3, 0.05]])
    scale = np.tile([300.0, 1.0, 1e-3], (4, 1))
    got = normal_equations_of(t, unit, rows, p, scale)
    expected = normal_equations_of(t[rows], unit[rows], np.arange(rows.size), p, scale)
    for a, b in zip(got, expected, strict=True):
        np.testing.assert_array_equal(a, b)
