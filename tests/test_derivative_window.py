"""The position PID's derivative over m periods (``position_loop.derivative_window``; issue 41,
item 1; docs/model.md §14, "The velocity from the encoder"), on the QT-CAS sampled as the EPOS4
samples it (current loop 25 kHz, position loop 2.5 kHz).

A sampled PID's derivative differences its input over one period; over m periods it
differences the mean of the last m samples, A_m(z) = (1/m) sum_{k<m} z^-k. With the method's
s -> (1 - z^-1)/(T (alpha + (1 - alpha) z^-1)) the controller is, written here from
docs/model.md,

    C_m(z) = Kp + Ki T (alpha + (1 - alpha) z^-1)/(1 - z^-1)
             + Kd (1 - z^-1) A_m(z) / ((Tf + alpha T) - (Tf - (1 - alpha) T) z^-1)

so the position loop with the window is the loop without it times C_m/C_1 (1e-12); checked
too against the discrete state space (a second realisation, from the gains in z: 1e-10),
against the recursion (Tf + T) D_k = Tf D_(k-1) + Kd (v_k - v_(k-1)), v_k the mean of the last
m errors, in the simulation (1e-9 of the current command), both engines alike, and the
continuous figures unchanged (the window's limit is the derivative itself).
"""

import math

import numpy as np
import pytest

import cas_freq as cf
from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import simulate_batch
from cas_freq.simulation.commands import Step

QT = "configs/qt_cas.yaml"
RATES = {"sampling.current_loop": "25 kHz", "sampling.position_loop": "2.5 kHz"}
PERIOD = 1.0 / 2.5e3
OMEGA = np.array([10.0, 300.0, 1000.0, 3000.0, 7000.0])


def _params(window, method="backward", **changes):
    overrides = {**RATES, "sampling.method": method, "position_loop.derivative_window": window,
                 **changes}
    return LoopParameters.from_config(load_variant(QT, overrides=tuple(overrides.items())).params)


def _controller(p, window, method):
    """C_m(e^(jwT)) of the module notes."""
    alpha = {"backward": 1.0, "tustin": 0.5}[method]
    z1 = np.exp(-1j * OMEGA * PERIOD)
    kp, ki, kd, tf = (float(getattr(p, name)[0]) for name in ("cp_Kp", "cp_Ki", "cp_Kd", "Tf"))
    average = np.mean([z1 ** k for k in range(window)], axis=0)
    filtered = (tf + alpha * PERIOD) - (tf - (1.0 - alpha) * PERIOD) * z1
    return (kp + ki * PERIOD * (alpha + (1.0 - alpha) * z1) / (1.0 - z1)
            + kd * (1.0 - z1) * average / filtered)


@pytest.mark.parametrize("method", ["backward", "tustin"])
def test_the_loop_is_the_one_period_loop_times_the_controllers_ratio(method):
    from cas_freq.model import sampled
    from cas_freq.model.loops import Selector

    loops = {m: sampled.responses(Selector(_params(m, method))(), 1j * OMEGA).loops
             for m in (1, 3)}
    p = _params(3, method)
    expected = _controller(p, 3, method) / _controller(p, 1, method)
    np.testing.assert_allclose(loops[3]["position_loop"] / loops[1]["position_loop"], expected,
                               rtol=1e-12)
    np.testing.assert_allclose(loops[3]["current_loop"], loops[1]["current_loop"], rtol=1e-14)


@pytest.mark.parametrize("method, on", [("backward", "error"), ("tustin", "error"),
                                        ("backward", "measurement")])
def test_the_discrete_state_space_gives_the_same_loops(method, on):
    from cas_freq.analysis.systems import linear_model
    from cas_freq.model import sampled
    from cas_freq.model.loops import Selector

    p = _params(3, method, **{"position_loop.derivative_on": on})
    found = sampled.responses(Selector(p)(), 1j * OMEGA)
    model = linear_model(p)
    for name, expected in (("position_loop", found.loops["position_loop"]),
                           ("closed_loop", found.closed_loop)):
        system = getattr(model, name)
        values = system(np.exp(1j * OMEGA * system.dt))
        assert np.max(np.abs(values / expected - 1.0)) < 1e-10, name


@pytest.mark.parametrize("window", [1, 4])
def test_the_simulated_derivative_differences_the_mean_of_the_last_errors(window):
    kp, kd, tf = 0.5, 0.004, 1e-3
    p = _params(window, **{"position_loop.Kp": kp, "position_loop.Ki": 0.0,
                           "position_loop.Kd": kd, "position_loop.Tf": tf,
                           "position_loop.delay": 0.0, "position_loop.ff_v": 0.0,
                           "position_loop.ff_a": 0.0})
    step = math.radians(0.5)
    run = simulate_batch(p, Step(step), t_end=0.02, extend=False)
    every = int(round(PERIOD / run.dt_s))
    k = np.arange(0, run.t.size, every)  # the position loop's instants
    error = step * p.ratio[0] - run.theta[0, k]
    history, mean_before, derivative = [0.0] * window, 0.0, 0.0  # at rest before the step
    ours = np.empty(k.size)
    for index, e in enumerate(error):
        history.append(e)
        mean = float(np.mean(history[-window:]))
        derivative = (tf * derivative + kd * (mean - mean_before)) / (tf + PERIOD)
        mean_before = mean
        ours[index] = kp * e + derivative
    command = run.current_command[0, k]
    unclamped = np.abs(command) < 0.999 * float(p.i_max[0])
    assert unclamped[1:].sum() > 20 and np.max(np.abs(command)) > 0.1
    np.testing.assert_allclose(command[1:][unclamped[1:]], ours[1:][unclamped[1:]], rtol=0,
                               atol=1e-9 * np.max(np.abs(ours)))


def test_both_engines_agree_with_the_window_and_the_encoder():
    p = _params(3, **{"sensors.counts_per_rev": 2048})
    ours = simulate_batch(p, Step(math.radians(10.0)), t_end=0.05, extend=False)
    reference = simulate_batch(p, Step(math.radians(10.0)), t_end=0.05, extend=False,
                               engine="reference")
    np.testing.assert_allclose(ours.theta, reference.theta, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.current_command, reference.current_command, rtol=0,
                               atol=1e-9)


def test_the_continuous_figures_are_the_one_period_loop_s():
    one = cf.load(QT, set={**RATES, "position_loop.derivative_window": 1}).analyze().to_dict()
    three = cf.load(QT, set={**RATES, "position_loop.derivative_window": 3}).analyze().to_dict()
    for key in ("phase_margin_deg", "crossover_rad_s", "gain_margin_db"):
        assert three["continuous"]["position_loop"][key] == pytest.approx(
            one["continuous"]["position_loop"][key], rel=1e-12)
    # the mean of three samples lags the derivative by a period: the sampled margin falls
    assert three["position_loop"]["phase_margin_deg"] < one["position_loop"][
        "phase_margin_deg"] - 5.0


@pytest.mark.parametrize("changes, message", [
    ({"position_loop.derivative_window": 2}, "position loop must be sampled"),
    ({**RATES, "position_loop.derivative_window": 2, "position_loop.Kd": 0.0}, "but Kd = 0"),
    ({**RATES, "position_loop.derivative_window": 1.5}, "position_loop.derivative_window"),
    ({**RATES, "position_loop.derivative_window": 65}, "<= 64"),
])
def test_refused_where_it_has_no_meaning(changes, message):
    with pytest.raises(ConfigError, match=message):
        cf.load(QT, set=changes)


def test_a_cascade_refuses_it():
    with pytest.raises(ConfigError, match="derivative_window: .*P or PI"):
        cf.load("configs/cascade_axis.yaml", set={"position_loop.derivative_window": 2})
