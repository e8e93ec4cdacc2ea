"""The actuator's figures cross-checked against python-control and a brute-force grid."""

import math
import warnings

import control
import numpy as np
import pytest

from cas_freq.analysis import analyze, to_dict
from cas_freq.analysis.stability import pole_verdict
from cas_freq.analysis.systems import linear_model
from cas_freq.config import load_variant
from cas_freq.model import ActuatorLoops, DelayModel


@pytest.fixture(scope="module", params=["base", "fitted"])
def variant(request):
    return load_variant(variant=request.param)


@pytest.fixture(scope="module")
def exact(variant):
    return analyze(variant, pade_orders=6)


def _pc_margins(system):
    """python-control's stability_margins (polynomial method) as sorted arrays."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gm, pm, _, w180, wc, _ = control.stability_margins(system, returnall=True)
    return np.asarray(gm), np.asarray(pm), np.asarray(w180), np.asarray(wc)


def test_python_control_margins_on_pade_model_agree(variant, exact):
    # python-control's stability_margins on the rational Padé-4 model (state space composed by
    # cas_freq) against cas_freq's margins of the same model and of the exact delays.
    # Same model -> agreement to root-finding precision (1e-7). Padé 4 vs exact: the delays'
    # phase at the crossovers (omega*tau <= 0.6) is matched by Padé 4 to ~1e-9 rad, so 1e-5
    # relative is a loose bound; the third phase crossover (omega*tau ~ 5) is outside Padé 4's
    # accuracy and is not compared.
    model = linear_model(variant.params, 4)
    pade = analyze(variant, DelayModel(4))
    for name in ("current_loop", "position_loop"):
        gm, pm, w180, wc = _pc_margins(getattr(model, name))
        ours_pade, ours_exact = getattr(pade, name), getattr(exact, name)
        assert len(wc) == len(ours_pade.gain_crossovers) == 1
        assert ours_pade.crossover_rad_s == pytest.approx(wc[0], rel=1e-7)
        assert ours_pade.phase_margin_deg == pytest.approx(pm[0], rel=1e-7)
        assert ours_exact.phase_margin_deg == pytest.approx(pm[0], rel=1e-5)
        assert ours_exact.crossover_rad_s == pytest.approx(wc[0], rel=1e-5)
        # the lowest-frequency phase crossovers, which decide the gain margins
        count = 2 if name == "position_loop" else 1
        ours = [c.frequency_rad_s for c in ours_pade.phase_crossovers[:count]]
        np.testing.assert_allclose(ours, w180[:count], rtol=1e-7)
        # python-control's GM is 1/|L| at the phase crossover; cas_freq's is -20 log10 |L|
        np.testing.assert_allclose([c.gain_margin_db for c in ours_pade.phase_crossovers[:count]],
                                   [20 * math.log10(g) for g in gm[:count]], rtol=1e-7)
        assert ours_exact.gain_margin_db == pytest.approx(20 * math.log10(gm[count - 1]), rel=1e-3)


def test_position_loop_is_type_two_with_lower_gain_margin(exact):
    # docs/model.md: two integrators, phase starting at -180°, so a lower (negative-dB) gain margin
    # at a phase crossover below the gain crossover, besides the upper one above it.
    p = exact.position_loop
    assert p.gain_margin_low_db < 0 < p.gain_margin_db
    assert p.phase_crossover_low_rad_s < p.crossover_rad_s < p.phase_crossover_rad_s
    assert exact.current_loop.gain_margin_low_db is None  # type 1: phase starts at -90°


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_disk_margin_matches_python_control(variant, exact):
    # python-control's disk_margins (skew 0) on the Padé-6 model, on a dense log grid around the
    # sensitivity peak; its max is read off the grid (2e5 points over 3 decades -> relative
    # step 3.5e-5, so alpha is within ~1e-8 of the refined value), Padé 6 vs exact < 1e-6.
    model = linear_model(variant.params, 6)
    omega = np.logspace(1.5, 4.5, 200_000)
    alpha, gain_db, phase_deg = control.disk_margins(model.position_loop, omega)
    p = exact.position_loop
    assert p.disk_margin_alpha == pytest.approx(alpha, rel=1e-6)
    assert p.disk_margin_gain_db == pytest.approx(gain_db, rel=1e-6)
    assert p.disk_margin_phase_deg == pytest.approx(phase_deg, rel=1e-6)


def test_peaks_and_bandwidth_against_brute_force_grid(variant, exact):
    # Second method: a dense linear grid (0.05 rad/s steps) read without refinement. The
    # refined values must sit within one grid step of the grid's own answers.
    loops = ActuatorLoops(variant.params)
    omega = np.arange(1.0, 5000.0, 0.05)
    t = np.abs(loops.closed_loop(1j * omega))
    s = np.abs(loops.sensitivity(1j * omega))
    below = omega[np.argmax(t < 1 / math.sqrt(2))]
    assert exact.closed_loop.bandwidth_rad_s == pytest.approx(below, abs=0.05)
    assert exact.closed_loop.peak_db == pytest.approx(20 * math.log10(t.max()), abs=1e-6)
    assert exact.closed_loop.peak_rad_s == pytest.approx(omega[np.argmax(t)], abs=0.05)
    assert exact.position_loop.sensitivity_peak_db == pytest.approx(20 * math.log10(s.max()),
                                                                    abs=1e-6)


def test_pade_study_converges_to_exact(exact):
    rows = exact.pade_vs_exact
    assert [r.delay_model for r in rows] == [f"pade:{n}" for n in range(1, 7)] + ["exact"]
    reference = rows[-1]
    for field in ("position_phase_margin_deg", "position_gain_margin_db", "bandwidth_rad_s",
                  "current_phase_margin_deg", "current_gain_margin_db"):
        errors = [abs(getattr(r, field) - getattr(reference, field)) for r in rows[:-1]]
        # monotone down to rounding, and tiny at order 6
        assert all(b <= a or b < 1e-9 * abs(getattr(reference, field))
                   for a, b in zip(errors, errors[1:], strict=False)), field
        assert errors[-1] < 1e-6 * abs(getattr(reference, field)), field
    assert rows[-1].closed_loop_max_error == 0.0
    assert rows[0].closed_loop_max_error > rows[-2].closed_loop_max_error


def test_pade_ten_is_finite_and_matches_exact(variant, exact):
    # docs/model.md: orders 8 and more must work. At the crossovers omega*tau <= 0.6, where Padé 10
    # is exact to rounding, so every figure agrees with exact to 1e-9 relative.
    high = analyze(variant, DelayModel(10))
    assert high.stable and high.stability.pade_order == 10
    for name in ("crossover_rad_s", "phase_margin_deg", "gain_margin_db", "gain_margin_low_db"):
        assert getattr(high.position_loop, name) == pytest.approx(
            getattr(exact.position_loop, name), rel=1e-9
        )
    assert high.closed_loop.bandwidth_rad_s == pytest.approx(exact.closed_loop.bandwidth_rad_s,
                                                             rel=1e-9)


def test_unstable_loop_is_a_result():
    # Kp = 200 A/rad puts the position crossover where the delays have eaten the phase:
    # the closed loop is unstable; the margins still exist and say so. The phase of L_p falls
    # below -180° at ~77 rad/s and stays below up to the gain crossover (~1960 rad/s), so the
    # phase margin is negative and the only phase crossover below it is a lower one.
    result = analyze(load_variant(overrides=[("position_loop.Kp", 200.0)]))
    assert not result.stable and result.stability.verdict == "unstable"
    assert result.closed_loop is None
    p = result.position_loop
    assert p.phase_margin_deg is not None and p.phase_margin_deg < 0
    # the delay that turns L onto -1 at the crossover: 360° + PM the way a delay turns
    assert p.delay_margin_s == pytest.approx(
        math.radians(360 + p.phase_margin_deg) / p.crossover_rad_s, rel=1e-12)
    below = [c for c in p.phase_crossovers if c.frequency_rad_s < p.crossover_rad_s]
    assert len(below) == 1 and below[0].gain_margin_db < 0
    assert p.disk_margin_alpha is None and p.sensitivity_peak_db is None
    data = to_dict(result)
    assert data["stable"] is False
    assert all(value is None for value in data["closed_loop"].values())
    assert any("unstable" in note for note in result.notes)


def test_unstable_current_loop_is_reported():
    # A current-loop gain far above its ~9.7 dB margin (Kp x 10 = +20 dB) destabilises it.
    # Its crossover moves to ~87 krad/s, where the 0.06 ms delay alone turns the phase by
    # -298°: the continuous phase there is about -385°, 180° - 385° = -205° from the -180°
    # line, i.e. PM = +155° from the -540° line (a PM lies in (-180°, 180°], as
    # python-control's does). The margins do not hide the instability: the verdict says it.
    result = analyze(load_variant(overrides=[("current_loop.Kp", 6.163)]))
    assert result.stability.current_loop_verdict == "unstable"
    current = result.current_loop
    kp, ki, resistance, inductance, tau = 6.163, 2835.3, 0.361, 7.1e-5, 0.06e-3
    wc = current.crossover_rad_s
    assert wc == pytest.approx(kp / inductance, rel=0.01)  # |L| ~ Kp/(L w) up there
    # Up there Y ~ 1/(L s + R) (back-EMF term Ke Km/(J s) is ~1e-5 of L s), so the phase is
    # -atan(L w/R) (winding) - atan(Ki/(Kp w)) (PI lag) - w tau (delay); 0.05° covers the
    # neglected back-EMF.
    expected = 180 - math.degrees(
        math.atan2(inductance * wc, resistance) + math.atan(ki / (kp * wc)) + wc * tau
    )
    (headline,) = [c for c in current.gain_crossovers if c.frequency_rad_s == wc]
    assert headline.phase_deg == pytest.approx(expected - 180, abs=0.05)
    assert current.phase_margin_deg == pytest.approx(expected + 360, abs=0.05)
    assert current.delay_margin_s == pytest.approx(
        math.radians(current.phase_margin_deg) / wc, rel=1e-12)
    assert not result.stable


def test_pole_verdict():
    assert pole_verdict([-1.0, -2 + 3j, -2 - 3j]) == "stable"
    assert pole_verdict([-1.0, 1j, -1j]) == "marginal"
    assert pole_verdict([-1.0, 1e-3]) == "unstable"
    assert pole_verdict([]) == "stable"


def test_json_is_strict_and_complete(exact):
    import json

    text = json.dumps(to_dict(exact), allow_nan=False)
    data = json.loads(text)
    assert data["delay_model"] == "exact" and data["stability"] == "stable"
    assert len(data["pade_vs_exact"]) == 7
