"""A filter at the velocity command (``at: velocity_command``, docs/model.md "Filters at any
point"): in a cascade, after the position controller and before the velocity loop's error.

Oracles, each derived here from docs/model.md:

- **In series.** The filter sits in the position loop's path, so the position loop broken at
  its controller's output is the loop without it times F(jw); the velocity and current loops,
  broken at their own controllers with the position loop open, do not see it. Checked to 1e-12
  relative: both sides are the same products, in another order. Without feed-forward the
  closed loop is T = n L/(1 + L) of the outermost loop (the command enters only there; n the
  output's share of the measured angle, which the filter leaves alone), to 1e-10.
- **The simulator** steps it as any block of a loop's path: a small sine dwell follows the
  linear closed loop with the filter (0.02 dB, 0.2 deg: the tolerances of
  tests/test_simulation_architectures.py), and the filter moves T by far more than that. Both
  engines step it the same way, continuous and sampled (1e-9 of each signal's scale, the
  tolerance of tests/test_simulation_kernel.py).
- **The config**: it loads on a cascade and is refused, naming the point, where there is no
  velocity loop.
"""

import dataclasses
import math

import numpy as np
import pytest
from architectures import with_filter

from cas_freq.config.loader import load_variant, shipped_configs_dir
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import LoopParameters
from cas_freq.model.loops import Selector, responses

W = np.array([3.0, 30.0, 100.0, 300.0, 1000.0])  # [rad/s]
CORNER = 150.0  # [rad/s]: a lowpass1 near the position loop's crossover
LEAD = (60.0, 600.0)  # (w_z, w_p) [rad/s] of a lead-lag


def _cascade(filters=(), **changes):
    path = shipped_configs_dir() / "cascade_axis.yaml"
    p = LoopParameters.from_config(load_variant(path).params)
    return dataclasses.replace(p, filters=(*p.filters, *filters), **changes)


def _linear(p):
    """``p`` without the simulator's nonlinear drivetrain terms (the cases of
    tests/test_simulation_architectures.py)."""
    ones, zeros = np.ones(p.n_runs), np.zeros(p.n_runs)
    return dataclasses.replace(p, eta=ones, eta_b=ones, F_c=zeros, tau_h=zeros)


def _lowpass(corner=CORNER):
    return Filter("velocity_command", "lowpass1", corner)


def _leadlag(zero, pole):
    return Filter("velocity_command", "leadlag", zero=zero, pole=pole)


def _loops(p, w=W):
    return responses(Selector(p)(), 1j * w)


@pytest.mark.parametrize(("item", "oracle"), [
    (_lowpass(), 1.0 / (1.0 + 1j * W / CORNER)),
    (_leadlag(*LEAD), (1.0 + 1j * W / LEAD[0]) / (1.0 + 1j * W / LEAD[1])),
], ids=["lowpass1", "leadlag"])
def test_a_filter_at_the_velocity_command_multiplies_the_position_loop(item, oracle):
    without, with_filter = _loops(_cascade()), _loops(_cascade([item]))
    np.testing.assert_allclose(with_filter.loops["position_loop"],
                               without.loops["position_loop"] * oracle, rtol=1e-12)
    for inner in ("velocity_loop", "current_loop"):
        np.testing.assert_allclose(with_filter.loops[inner], without.loops[inner], rtol=1e-12)


def test_without_feedforward_the_closed_loop_is_l_over_1_plus_l():
    # T = n(s) L/(1 + L): n = N delta/theta, the compliant coupling's (the position loop
    # measures the motor), which the filter does not change
    without, with_filter = (_loops(_cascade(filters, ff_v=np.zeros(1), ff_a=np.zeros(1)))
                            for filters in ((), [_lowpass()]))
    top, top_with = without.loops["position_loop"], with_filter.loops["position_loop"]
    np.testing.assert_allclose(with_filter.closed_loop * (1.0 + top_with) / top_with,
                               without.closed_loop * (1.0 + top) / top, rtol=1e-10)


def test_the_simulator_follows_the_linear_loop_with_the_filter():
    pytest.importorskip("numba")
    from cas_freq.simulation.sinedwell import linear_reference, sine_dwell

    p = _linear(_cascade([_lowpass()]))
    frequencies = np.array([20.0, 80.0])
    result = sine_dwell(p, [math.radians(0.05)], frequencies)
    linear = linear_reference(p, frequencies)
    assert not result.limit_hit.any()
    moved = np.abs(20 * np.log10(np.abs(linear / linear_reference(_linear(_cascade()),
                                                                   frequencies))))
    assert np.max(moved) > 0.5  # the filter matters
    np.testing.assert_allclose(result.magnitude_db[0], 20 * np.log10(np.abs(linear)), atol=0.02)
    np.testing.assert_allclose(result.phase_deg[0], np.degrees(np.unwrap(np.angle(linear))),
                               atol=0.2)


@pytest.mark.parametrize("rates", [{}, dict(current_rate_hz=20000.0, velocity_rate_hz=10000.0,
                                            position_rate_hz=2500.0)],
                         ids=["continuous", "sampled"])
def test_both_engines_step_the_filter_alike(rates):
    pytest.importorskip("numba")
    from cas_freq.simulation import Step, simulate_batch

    p = _cascade([_lowpass()])
    runs = [simulate_batch(p, Step(math.radians(5.0)), t_end=0.03, extend=False, engine=engine,
                           **rates) for engine in ("compiled", "reference")]
    plain = simulate_batch(_cascade(), Step(math.radians(5.0)), t_end=0.03, extend=False,
                           engine="reference", **rates)
    assert np.max(np.abs(runs[1].delta - plain.delta)) > 1e-3 * np.max(np.abs(plain.delta))
    for name in ("delta", "omega", "i", "V", "current_command"):
        a, b = (np.asarray(getattr(run, name)) for run in runs)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.max(np.abs(b)))


def test_the_config_takes_a_velocity_command_filter_on_a_cascade(tmp_path):
    path = with_filter(tmp_path, "cascade_axis.yaml",
                   "{at: velocity_command, type: lowpass1, frequency: 150 rad/s}")
    p = LoopParameters.from_config(load_variant(path).params)
    assert [f.at for f in p.filters].count("velocity_command") == 1


def test_a_velocity_command_filter_needs_a_velocity_loop(tmp_path):
    path = with_filter(tmp_path, "qt_cas.yaml",
                   "{at: velocity_command, type: lowpass1, frequency: 150 rad/s}")
    with pytest.raises(ConfigError, match="velocity_command needs a velocity loop"):
        load_variant(path)


SAMPLING = (("sampling.current_loop", "20 kHz"), ("sampling.velocity_loop", "10 kHz"),
            ("sampling.position_loop", "2.5 kHz"))


@pytest.mark.parametrize("sampled", [False, True], ids=["continuous", "sampled"])
def test_the_state_space_assembly_has_the_filter(sampled):
    # the one assembly (model/state_space.py) against the frequency responses with the same
    # delay model, to 1e-9 (the tolerance of tests/test_state_space.py), and the filter moves
    # the position loop by far more
    from cas_freq.model import sampled as sampled_model
    from cas_freq.model import state_space
    from cas_freq.model.delay import DelayModel
    from cas_freq.model.parts import one_variant

    path = shipped_configs_dir() / "cascade_axis.yaml"
    loaded = load_variant(path, "base", list(SAMPLING) if sampled else [])
    base = one_variant(LoopParameters.from_config(loaded.params))
    p = dataclasses.replace(base, filters=(*base.filters, _lowpass()))
    omega = W[W < 0.99 * math.pi * 2.5e3]
    if sampled:
        expected = sampled_model.responses(Selector(p)(), 1j * omega)
        closings = state_space.closings(p, sampled=True)
    else:
        expected = responses(p, 1j * omega, delay=DelayModel(6))
        closings = state_space.closings(p, 6)
    for name, closing in closings.items():
        x = 1j * omega if closing.period is None else np.exp(1j * omega * closing.period)
        a, b, c, d = closing.loop()
        found = np.array([(c @ np.linalg.solve(v * np.eye(a.shape[0]) - a, b) + d)[0, 0]
                          for v in x])
        np.testing.assert_allclose(found, expected.loops[name], rtol=1e-9)
    plain = (sampled_model.responses(Selector(base)(), 1j * omega) if sampled
             else responses(base, 1j * omega, delay=DelayModel(6)))
    assert np.max(np.abs(expected.loops["position_loop"] / plain.loops["position_loop"] - 1)) > 0.1
