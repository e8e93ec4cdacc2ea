"""A filter on the position command (``at: position_command``, docs/model.md "Filters at any
point"): it shapes the command before every loop, so it multiplies T and changes no loop.

Oracles, each derived here from docs/model.md:

- **Outside every loop.** Every loop's response is the same to the bit with and without it,
  and T is T without it times W(jw) (the filter's formula written out here), to 1e-12: both
  sides are the same products in another order. The same through the compiled grid kernel and
  with the feed-forward (the filter shapes the command the feed-forward reads). Sampled, W is
  the filter at the outermost loop's equivalent s (the backward difference written out here).
- **The state-space T** (``closed_loop_matrices``, python-control's ``closed_loop``) against the
  frequency responses with the same delay model, to 1e-9 (tests/test_state_space.py's
  tolerance), continuous and sampled.
- **The figures.** The margins are unchanged; the bandwidth is that of |W T| found on a dense
  grid here (0.1 %: the grid's spacing).
- **The simulator.** Continuous: the command the loops read is the filter's step response (the
  second-order formula, to 1e-12 of the step) and a sine dwell follows W T (0.02 dB, 0.2 deg,
  tests/test_simulation_architectures.py's tolerances). Sampled: the command is the digital
  filter (scipy's ``cont2discrete``, backward difference) of the sampled step, held. Both
  engines alike (1e-9 of each signal's scale, tests/test_simulation_kernel.py).
- **The config** takes it on the report's drive and on a cascade.
"""

import dataclasses
import math

import numpy as np
import pytest
from architectures import with_filter

from cas_freq.config.loader import load_variant, shipped_configs_dir
from cas_freq.core.filters_config import Filter
from cas_freq.core.parameters import LoopParameters
from cas_freq.model.loops import Selector, responses
from cas_freq.model.parts import one_variant

W = np.array([3.0, 30.0, 100.0, 300.0, 1000.0])  # [rad/s]
CORNER, DAMPING = 300.0, 0.5  # a lowpass2 near the report's bandwidth [rad/s], [-]
CONFIGS = ("qt_cas.yaml", "cascade_axis.yaml")
SAMPLING = {"qt_cas.yaml": [("sampling.current_loop", "20 kHz"),
                            ("sampling.position_loop", "2.5 kHz")],
            "cascade_axis.yaml": [("sampling.current_loop", "20 kHz"),
                                  ("sampling.velocity_loop", "10 kHz"),
                                  ("sampling.position_loop", "2.5 kHz")]}


def _lowpass2(s):
    return CORNER ** 2 / (s * s + 2.0 * DAMPING * CORNER * s + CORNER ** 2)


ITEMS = {
    "lowpass2": (Filter("position_command", "lowpass2", CORNER, damping=DAMPING), _lowpass2),
    "notch": (Filter("position_command", "notch", 200.0, width=100.0, depth_db=-20.0),
              lambda s: (s * s + 2 * 0.1 * 0.25 * 200.0 * s + 200.0 ** 2)
              / (s * s + 2 * 0.25 * 200.0 * s + 200.0 ** 2)),
    "leadlag": (Filter("position_command", "leadlag", zero=100.0, pole=400.0),
                lambda s: (1 + s / 100.0) / (1 + s / 400.0)),
}


def _params(name, filters=(), sampled=False, **changes):
    loaded = load_variant(shipped_configs_dir() / name, "base",
                          SAMPLING[name] if sampled else [])
    p = LoopParameters.from_config(loaded.params)
    return dataclasses.replace(p, filters=(*p.filters, *filters), **changes)


@pytest.mark.parametrize("kind", ITEMS)
@pytest.mark.parametrize("name", CONFIGS)
@pytest.mark.parametrize("feedforward", [False, True], ids=["T", "T with feed-forward"])
def test_the_filter_multiplies_t_and_no_loop(name, kind, feedforward):
    item, formula = ITEMS[kind]
    without, with_filter = (responses(Selector(_params(name, filters))(), 1j * W,
                                      feedforward=feedforward) for filters in ((), [item]))
    for loop, value in without.loops.items():
        np.testing.assert_array_equal(with_filter.loops[loop], value)
    np.testing.assert_allclose(with_filter.closed_loop, without.closed_loop * formula(1j * W),
                               rtol=1e-12)


@pytest.mark.parametrize("name", CONFIGS)
def test_the_compiled_grid_has_the_filter(name):
    pytest.importorskip("numba")
    from cas_freq.analysis.response_kernel import grid_responses
    from cas_freq.model.delay import EXACT

    item, formula = ITEMS["lowpass2"]
    without, with_filter = (grid_responses(Selector(_params(name, filters))(column=True), W, 1,
                                           EXACT) for filters in ((), [item]))
    np.testing.assert_allclose(with_filter.closed_loop[0],
                               without.closed_loop[0] * formula(1j * W), rtol=1e-12)


@pytest.mark.parametrize("name", CONFIGS)
def test_sampled_the_filter_is_digital_at_the_outermost_rate(name):
    from cas_freq.model import sampled

    item, formula = ITEMS["lowpass2"]
    without, with_filter = (sampled.responses(Selector(_params(name, filters, True))(), 1j * W)
                            for filters in ((), [item]))
    period = 1.0 / 2.5e3
    backward = (1.0 - np.exp(-1j * W * period)) / period  # s of the backward difference
    for loop, value in without.loops.items():
        np.testing.assert_array_equal(with_filter.loops[loop], value)
    np.testing.assert_allclose(with_filter.closed_loop, without.closed_loop * formula(backward),
                               rtol=1e-12)


@pytest.mark.parametrize("sampled", [False, True], ids=["continuous", "sampled"])
@pytest.mark.parametrize("name", CONFIGS)
def test_the_state_space_t_has_the_filter(name, sampled):
    from cas_freq.analysis.systems import closed_loop_matrices
    from cas_freq.model import sampled as sampled_model
    from cas_freq.model.delay import DelayModel

    p = one_variant(_params(name, [ITEMS["notch"][0]], sampled))
    if sampled:
        expected = sampled_model.responses(Selector(p)(), 1j * W).closed_loop
    else:
        expected = responses(p, 1j * W, delay=DelayModel(6)).closed_loop
    closed = closed_loop_matrices(p, 6)
    x = 1j * W if closed.period is None else np.exp(1j * W * closed.period)
    found = np.array([(closed.c @ np.linalg.solve(v * np.eye(closed.a.shape[0]) - closed.a,
                                                  closed.b) + closed.d)[0, 0] for v in x])
    np.testing.assert_allclose(found, expected, rtol=1e-9)


def test_the_margins_stay_and_the_bandwidth_is_that_of_w_t():
    from cas_freq.analysis.analyze import batch_analyze

    item, formula = ITEMS["lowpass2"]
    base, shaped = (batch_analyze(_params("qt_cas.yaml", filters)).figures
                    for filters in ((), [item]))
    for name, value in base.items():
        if not name.startswith("closed_loop."):
            np.testing.assert_array_equal(shaped[name], value, err_msg=name)
    omega = np.geomspace(1.0, 1e4, 40001)  # 0.023 % apart
    t = responses(Selector(_params("qt_cas.yaml"))(), 1j * omega).closed_loop * formula(
        1j * omega)
    db = 20 * np.log10(np.abs(t) / np.abs(t[0]))
    bandwidth = omega[np.argmax(db < -20 * math.log10(math.sqrt(2)))]
    found = shaped["closed_loop.bandwidth_rad_s"][0]
    assert found == pytest.approx(bandwidth, rel=1e-3)
    assert found < 0.9 * base["closed_loop.bandwidth_rad_s"][0]


def _step(p, engine, **rates):
    from cas_freq.simulation import Step, simulate_batch

    return simulate_batch(p, Step(math.radians(5.0)), t_end=0.03, extend=False, engine=engine,
                          **rates)


def _shaped_step(p, every=None):
    """The shaped command's angle at the steps of 0.03 s (right limits) as the engines read
    it, and the times [s]."""
    from cas_freq.model.structure import build
    from cas_freq.simulation import Step
    from cas_freq.simulation.engine import CommandSet
    from cas_freq.simulation.shaping import ShapedCommands

    dt = 5e-6
    commands = ShapedCommands(CommandSet(Step(math.radians(5.0)), p.ratio), build(p).command,
                              dt, every)
    t = np.arange(6001) * dt
    angle = np.concatenate([commands.fin_limits(chunk)[0][0][:, 0]
                            for chunk in np.array_split(t, 7)])  # in chunks, as the engines
    return angle, t


def test_the_continuous_command_is_the_filters_step_response():
    angle, t = _shaped_step(_params("qt_cas.yaml", [ITEMS["lowpass2"][0]]))
    h = math.radians(5.0)
    wd = CORNER * math.sqrt(1.0 - DAMPING ** 2)
    shaped = h * (1.0 - np.exp(-DAMPING * CORNER * t) * (
        np.cos(wd * t) + DAMPING / math.sqrt(1.0 - DAMPING ** 2) * np.sin(wd * t)))
    np.testing.assert_allclose(angle, shaped, rtol=0, atol=1e-12 * h)


def test_the_sampled_command_is_the_digital_filter_held():
    from scipy.signal import cont2discrete, dlsim

    every = 80  # 2.5 kHz in steps of 5 us
    angle, t = _shaped_step(_params("qt_cas.yaml", [ITEMS["lowpass2"][0]]), every)
    period, h = every * 5e-6, math.radians(5.0)
    numerator, denominator, _ = cont2discrete(
        ([CORNER ** 2], [1.0, 2 * DAMPING * CORNER, CORNER ** 2]), period, method="backward_diff")
    _, digital = dlsim((numerator[0], denominator, period), np.full(t.size // every + 1, h))
    np.testing.assert_allclose(angle, digital[np.arange(t.size) // every, 0], rtol=0,
                               atol=1e-12 * h)


def test_a_sine_dwell_follows_w_t():
    pytest.importorskip("numba")
    from cas_freq.simulation.sinedwell import linear_reference, sine_dwell

    item, formula = ITEMS["lowpass2"]
    ones, zeros = np.ones(1), np.zeros(1)
    p = _params("cascade_axis.yaml", [item], eta=ones, eta_b=ones, F_c=zeros, tau_h=zeros)
    frequencies = np.array([20.0, 80.0])  # [rad/s]
    result = sine_dwell(p, [math.radians(0.05)], frequencies)
    linear = linear_reference(p, frequencies)
    np.testing.assert_allclose(linear, linear_reference(dataclasses.replace(p, filters=p.filters[
        :-1]), frequencies) * formula(1j * frequencies), rtol=1e-12)
    assert not result.limit_hit.any()
    np.testing.assert_allclose(result.magnitude_db[0], 20 * np.log10(np.abs(linear)), atol=0.02)
    np.testing.assert_allclose(result.phase_deg[0], np.degrees(np.unwrap(np.angle(linear))),
                               atol=0.2)


@pytest.mark.parametrize("sampled", [False, True], ids=["continuous", "sampled"])
@pytest.mark.parametrize("name", CONFIGS)
def test_both_engines_read_the_shaped_command_alike(name, sampled):
    pytest.importorskip("numba")
    p = _params(name, [ITEMS["notch"][0]])
    rates = dict(current_rate_hz=20000.0, position_rate_hz=2500.0) if sampled else {}
    if sampled and name == "cascade_axis.yaml":
        rates["velocity_rate_hz"] = 10000.0
    runs = [_step(p, engine, **rates) for engine in ("compiled", "reference")]
    plain = _step(_params(name), "reference", **rates)
    assert np.max(np.abs(runs[1].delta - plain.delta)) > 1e-3 * np.max(np.abs(plain.delta))
    for field in ("delta", "omega", "i", "V", "current_command", "command"):
        a, b = (np.asarray(getattr(run, field)) for run in runs)
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.max(np.abs(b)))


@pytest.mark.parametrize("name", CONFIGS)
def test_the_config_takes_a_position_command_filter(tmp_path, name):
    path = with_filter(tmp_path, name, "{at: position_command, type: lowpass2, "
                                        "frequency: 300 rad/s, damping: 0.5}")
    p = LoopParameters.from_config(load_variant(path).params)
    (shaping,) = [f for f in p.filters if f.at == "position_command"]
    assert (shaping.kind, float(shaping.frequency[0])) == ("lowpass2", CORNER)


def test_a_batch_with_a_filter_number_per_run_gives_each_run_its_solo_step():
    # the lead-lag's pole shared and its zero per run: its state matrix is the same in every
    # run, its output row is not (the shaped command then has a column per run)
    pytest.importorskip("numba")
    from cas_freq.core.parameters import variant_parameters

    zeros = np.array([100.0, 200.0, 300.0])  # [rad/s]
    loaded = load_variant(shipped_configs_dir() / "qt_cas.yaml")
    kp = loaded.params.position_loop.Kp
    three = variant_parameters(loaded.params, {"position_loop.Kp": np.full(3, kp)})
    batch = _step(dataclasses.replace(three, filters=(*three.filters, Filter(
        "position_command", "leadlag", zero=zeros, pole=np.full(3, 400.0)))), "compiled")
    for r, zero in enumerate(zeros):
        solo = _step(_params("qt_cas.yaml", [Filter("position_command", "leadlag", zero=zero,
                                                    pole=400.0)]), "compiled")
        np.testing.assert_allclose(batch.delta[r], solo.delta[0], rtol=0,
                                   atol=1e-12 * np.max(np.abs(solo.delta)))
    assert np.max(np.abs(batch.delta[0] - batch.delta[2])) > 1e-3 * np.max(batch.delta)
