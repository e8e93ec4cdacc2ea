"""The analysis engine on many variants: every figure checked against its definition.

The engine (:func:`cas_freq.analysis.batch_analyze`) is the one behind ``analyze``; here each
figure of random variants is checked against its definition (docs/model.md) by evaluating the
loops again at and around the reported frequency (:class:`cas_freq.model.ActuatorLoops`, the
same responses) and on a dense grid around it (a second method for every maximum):

- at a gain crossover |L| = 1 (to the 1e-12 root tolerance, 1e-9 allowed); the phase margin
  is 180° + the phase there, in (-180°, 180°]; the smallest delay margin is at most the
  headline crossover's own and is the one of its crossover (the delay that turns L onto -1);
- at a phase crossover L is real and negative and the gain margin is -20 log10 |L|;
- |T| at the bandwidth is 1/sqrt(2) of |T(0)|, and above that line at every point below it;
- the peaks (|T|, |S|) are not exceeded anywhere on a grid 20 times denser than the engine's
  around them (a maximum is located to ~1e-9, its value to ~1e-15 relative).
"""

import math

import numpy as np
import pytest

from cas_freq.analysis import FIGURES, analyze, batch_analyze
from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.parameters import variant_parameters
from cas_freq.model import ActuatorLoops


def _random_changes(params, rng, n):
    """Gains and motor values drawn around the config's, x0.6..x1.5."""
    base = {
        "position_loop.Kp": params.position_loop.Kp,
        "position_loop.Ki": params.position_loop.Ki,
        "position_loop.Kd": params.position_loop.Kd,
        "current_loop.Kp": params.current_loop.Kp,
        "motor.Km": params.motor.Km,
        "motor.J": params.motor.J,
        "current_loop.delay": params.current_loop.delay,
    }
    return {key: value * rng.uniform(0.6, 1.5, n) for key, value in base.items()}


def _wrapped(degrees):
    return (degrees + 180.0) % 360.0 - 180.0


@pytest.mark.parametrize("variant, fixed", [
    ("base", []),
    ("fitted", []),
    ("base", [("position_loop.derivative_on", "measurement"), ("position_loop.Tf", 0.0005)]),
])
def test_figures_meet_their_definitions_on_random_variants(variant, fixed):
    loaded = load_variant(None, variant, fixed)
    rng = np.random.default_rng(20261122)
    n = 6
    changes = _random_changes(loaded.params, rng, n)
    params = variant_parameters(loaded.params, changes)
    batch = batch_analyze(params)
    for i in range(n):
        loops = ActuatorLoops(params.run(i))
        figure = {name: batch.figures[name][i] for name in FIGURES}
        for loop_name, loop in (("current_loop", loops.current_loop),
                                ("position_loop", loops.position_loop)):
            w = figure[f"{loop_name}.crossover_rad_s"]
            value = loop(1j * w)
            assert abs(value) == pytest.approx(1.0, rel=1e-9), loop_name
            pm = figure[f"{loop_name}.phase_margin_deg"]
            assert -180 < pm <= 180
            assert _wrapped(pm) == pytest.approx(
                _wrapped(180.0 + math.degrees(np.angle(value))), abs=1e-7)
            own = math.radians(pm if pm >= 0 else pm + 360) / w
            delay = figure[f"{loop_name}.delay_margin_s"]
            assert 0 <= delay <= own * (1 + 1e-12)
            at = figure[f"{loop_name}.delay_margin_crossover_rad_s"]
            turn = np.angle(loop(1j * at) * np.exp(-1j * at * delay))  # L e^(-j w tau) = -1
            assert abs(abs(turn) - math.pi) < 1e-6, loop_name
            for key in ("", "_low"):
                w = figure[f"{loop_name}.phase_crossover{key}_rad_s"]
                if math.isnan(w):
                    continue
                value = loop(1j * w)
                assert abs(value.imag) <= 1e-9 * abs(value) and value.real < 0
                assert figure[f"{loop_name}.gain_margin{key}_db"] == pytest.approx(
                    -20 * math.log10(abs(value)), rel=1e-9)
        if batch.stability[i] != "stable":
            assert math.isnan(figure["closed_loop.bandwidth_rad_s"])
            continue
        dc = abs(loops.closed_loop(1e-5j))
        w_bw = figure["closed_loop.bandwidth_rad_s"]
        assert abs(loops.closed_loop(1j * w_bw)) / dc == pytest.approx(1 / math.sqrt(2),
                                                                      rel=1e-9)
        below = np.geomspace(1e-2, w_bw, 20_000)[:-1]
        assert np.all(np.abs(loops.closed_loop(1j * below)) / dc > 1 / math.sqrt(2))
        w_peak = figure["closed_loop.peak_rad_s"]
        dense = np.geomspace(w_peak / 1.05, w_peak * 1.05, 2_000)
        peak = 10 ** (figure["closed_loop.peak_db"] / 20) * dc
        assert np.max(np.abs(loops.closed_loop(1j * dense))) <= peak * (1 + 1e-12)
        w_s = figure["position_loop.sensitivity_peak_rad_s"]
        dense = np.geomspace(w_s / 1.05, w_s * 1.05, 2_000)
        ms = 10 ** (figure["position_loop.sensitivity_peak_db"] / 20)
        assert np.max(np.abs(loops.sensitivity(1j * dense))) <= ms * (1 + 1e-12)


def test_a_batch_gives_each_variant_its_analysis_alone():
    # The JSON of analyze is the engine on a batch of one; a batch of several must give each
    # variant the same headline figures (to the refinement tolerance: the grid of a batch is
    # densified for its largest delay, so crossings are refined from other brackets).
    loaded = load_variant()
    changes = _random_changes(loaded.params, np.random.default_rng(7), 3)
    batch = batch_analyze(variant_parameters(loaded.params, changes))
    for i in range(3):
        alone = analyze(load_variant(None, "base", [(key, float(values[i]))
                                                    for key, values in changes.items()]))
        data = alone.to_dict()
        for loop in ("current_loop", "position_loop"):
            for name in ("crossover_rad_s", "phase_margin_deg", "gain_margin_db"):
                assert batch.figures[f"{loop}.{name}"][i] == pytest.approx(data[loop][name],
                                                                          rel=1e-9)
        assert batch.figures["closed_loop.bandwidth_rad_s"][i] == pytest.approx(
            data["closed_loop"]["bandwidth_rad_s"], rel=1e-9)


def test_unstable_variant_is_reported_not_raised():
    # Kp = 100 A/rad (x16 the shipped gain): the Padé-6 poles say unstable.
    loaded = load_variant()
    changes = {"position_loop.Kp": np.array([6.3435, 100.0])}
    batch = batch_analyze(variant_parameters(loaded.params, changes))
    assert list(batch.stability) == ["stable", "unstable"]
    assert batch.figures["stable"].tolist() == [1.0, 0.0]
    assert math.isnan(batch.figures["closed_loop.bandwidth_rad_s"][1])
    assert math.isnan(batch.figures["position_loop.sensitivity_peak_db"][1])
    # the open-loop margins are still reported: the phase margin is negative
    assert batch.figures["position_loop.phase_margin_deg"][1] < 0


def test_full_grid_fallback_gives_the_same_figures():
    # A short frequency range ending at 2e5 rad/s: the densified part of the grid is where the
    # current loop's phase crossovers are, so the split check sends runs to the full grid;
    # and a range ending below the dense part (no split at all). Both give what a batch of
    # one gives (always on the full grid, as analyze lists every crossing).
    loaded = load_variant()
    changes = {"position_loop.Kp": np.array([4.0, 8.0])}
    for frequency_range in ((1.0, 2e5), (1.0, 5e4)):
        batch = batch_analyze(variant_parameters(loaded.params, changes), frequency_range)
        for i, kp in enumerate(changes["position_loop.Kp"]):
            data = analyze(load_variant(None, "base", [("position_loop.Kp", float(kp))]),
                           frequency_range=frequency_range).to_dict()
            for loop in ("current_loop", "position_loop"):
                for name in ("gain_margin_db", "phase_margin_deg", "sensitivity_peak_db"):
                    expected = data[loop][name]
                    actual = batch.figures[f"{loop}.{name}"][i]
                    if expected is None:
                        assert math.isnan(actual)
                    else:
                        assert actual == pytest.approx(expected, rel=1e-9)


def test_forced_full_grid_equals_split_grid(monkeypatch):
    # The split (log grid below the densified part, full grid only where needed) must give
    # what the full grid gives: force every run through the full grid and compare.
    import importlib

    module = importlib.import_module("cas_freq.analysis.analyze")

    loaded = load_variant()
    params = variant_parameters(loaded.params, _random_changes(
        loaded.params, np.random.default_rng(3), 4))
    split = batch_analyze(params)
    monkeypatch.setattr(module, "_needs_full_grid",
                        lambda figures, tops, stable: np.ones(stable.shape, dtype=bool))
    full = batch_analyze(params)
    for name in FIGURES:
        np.testing.assert_allclose(split.figures[name], full.figures[name], rtol=1e-12,
                                   atol=1e-12, err_msg=name)


def test_chunks_do_not_change_the_figures():
    loaded = load_variant()
    changes = {"position_loop.Kp": np.linspace(3.0, 9.0, 7)}
    params = variant_parameters(loaded.params, changes)
    whole = batch_analyze(params, chunk_size=100)
    pieces = batch_analyze(params, chunk_size=3, workers=1)
    threaded = batch_analyze(params, chunk_size=2, workers=3)
    for name in FIGURES:
        np.testing.assert_array_equal(whole.figures[name], pieces.figures[name])
        np.testing.assert_array_equal(whole.figures[name], threaded.figures[name])
    np.testing.assert_array_equal(whole.stability, threaded.stability)
    with pytest.raises(ValueError, match="workers"):
        batch_analyze(params, workers=0)


def test_tf_follows_kp_and_kd_unless_set():
    loaded = load_variant()
    params = variant_parameters(loaded.params, {"position_loop.Kp": [5.0, 10.0]})
    expected = loaded.params.position_loop.Kd / (10 * np.array([5.0, 10.0]))
    np.testing.assert_allclose(params.Tf, expected, rtol=1e-15)
    fixed = load_variant(None, "base", [("position_loop.Tf", 0.001)])
    params = variant_parameters(fixed.params, {"position_loop.Kp": [5.0, 10.0]})
    np.testing.assert_array_equal(params.Tf, [0.001, 0.001])


def test_mu_v_follows_km_when_derived_from_no_load():
    # base: mu_v = Km I0 / n0 (report §6); fitted: mu_v given, stays fixed
    base = load_variant()
    params = variant_parameters(base.params, {"motor.Km": [0.0105, 0.021]})
    assert params.mu_v[1] == pytest.approx(2 * params.mu_v[0], rel=1e-12)
    assert params.mu_v[0] == pytest.approx(base.params.motor.viscous_friction, rel=1e-12)
    fitted = load_variant(None, "fitted")
    params = variant_parameters(fitted.params, {"motor.Km": [0.0075, 0.015]})
    np.testing.assert_array_equal(params.mu_v, [1.2e-6, 1.2e-6])


def test_invalid_sample_names_key_value_and_sample():
    loaded = load_variant()
    with pytest.raises(ConfigError, match=r"position_loop\.Kp: must be 0 or within .*-1\.0.*\[1\]"):
        variant_parameters(loaded.params, {"position_loop.Kp": [1.0, -1.0]})
    with pytest.raises(ConfigError, match="derivative_on: cannot be varied"):
        variant_parameters(loaded.params, {"position_loop.derivative_on": [1.0]})
