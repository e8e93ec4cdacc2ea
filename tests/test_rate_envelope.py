"""The rate and torque envelope (docs/model.md §15, cas_freq.analysis.rate_envelope).

Reference values are worked out here by hand from the QT-CAS motor constants of
configs/qt_cas.yaml (R = 0.361 ohm, Km = Ke = 0.0105, mu_v = Km*I0/n0 with I0 = 0.218 A and
n0 = 16,300 rpm, N = 20, eta = 1, v_max = 30 V, i_max = 20 A); the sine limits are checked
against the nonlinear simulator's own clamp flags (the sine-dwell), a second method.
"""

import math

import numpy as np
import pytest

import cas_freq as cf
from cas_freq.analysis.rate_envelope import limit_responses, rate_envelope
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation.sinedwell import sine_dwell

R, KM, KE, N, V_MAX, I_MAX = 0.361, 0.0105, 0.0105, 20.0, 30.0, 20.0
MU = KM * 0.218 / (16300.0 * 2.0 * math.pi / 60.0)  # report §6: 1.341e-6 N*m*s/rad


def _envelope(overrides=None, variant="base"):
    act = cf.load("configs/qt_cas.yaml", variant=variant, set=overrides)
    analysis = act.analyze()
    return analysis.envelope, analysis, act


def test_no_load_rate_and_stall_torque_by_hand():
    envelope, _, _ = _envelope()
    # steady state at 30 V with no load: Km i = mu w and 30 = R i + Ke w, so
    # w0 = Km V / (Km Ke + R mu) at the motor (V/Ke less what the friction takes), / N at the fin
    w0 = KM * V_MAX / (KM * KE + R * MU) / N
    assert w0 == pytest.approx(142.23, abs=0.01)  # the worked number: 2844.6 rad/s / 20
    assert envelope.no_load_rate_rad_s == pytest.approx(w0, rel=1e-12)
    # stall at the current limit through the gear: Km i_max N eta = 0.0105 * 20 * 20 * 1
    assert envelope.stall_torque_N_m == pytest.approx(4.2, rel=1e-12)
    assert envelope.stall_limited_by == "current"
    # the curve runs from stall to no load
    assert envelope.curve_torque_N_m[0] == pytest.approx(4.2, rel=1e-12)
    assert envelope.curve_rate_rad_s[-1] == pytest.approx(w0, rel=1e-12)
    assert envelope.curve_torque_N_m[-1] == pytest.approx(0.0, abs=1e-9)


def test_supply_resistance_sags_the_envelope():
    # a 24 V supply behind 1.639 ohm: R + R_s = 2.0 ohm, so stall takes 24/2 = 12 A < i_max
    envelope, _, _ = _envelope({"supply.voltage": "24 V", "supply.resistance": "1.639 ohm"})
    assert envelope.stall_torque_N_m == pytest.approx(KM * 12.0 * N, rel=1e-12)  # 2.52 N*m
    assert envelope.stall_limited_by == "voltage"
    w0 = KM * 24.0 / (KM * KE + 2.0 * MU) / N  # the sagging supply's line is the lower one
    assert envelope.no_load_rate_rad_s == pytest.approx(w0, rel=1e-12)
    # the gear efficiency scales the torque, not the rate (fitted variant: Km 0.0075, mu 1.2e-6)
    fitted, _, _ = _envelope({"gear.efficiency": 0.7}, variant="fitted")
    assert fitted.stall_torque_N_m == pytest.approx(0.0075 * I_MAX * N * 0.7, rel=1e-12)
    assert fitted.no_load_rate_rad_s == pytest.approx(
        0.0075 * V_MAX / (0.0075 * KE + R * 1.2e-6) / N, rel=1e-12)


def test_voltage_per_command_is_the_plant_seen_from_the_current():
    # V = (L s + R) i + Ke omega: at a frequency far below the electrical pole and with the
    # current and speed from T itself, the voltage must equal R i + Ke * s * N delta
    act = cf.load("configs/qt_cas.yaml")
    p = LoopParameters.from_config(act.params)
    w = np.array([5.0])
    _, voltage, current = limit_responses(p, w)
    from cas_freq.model import ActuatorLoops

    loops = ActuatorLoops(p)
    output = loops.closed_loop(1j * w, feedforward=True)  # N delta / N delta_cmd (rigid gear)
    expected = (p.L[0] * 1j * w + R) * current + KE * 1j * w * N * output
    np.testing.assert_allclose(voltage, expected, rtol=1e-9)


@pytest.mark.parametrize("config, frequency, limit", [
    ("configs/qt_cas.yaml", 100.0, "voltage"),
    ("configs/qt_cas.yaml", 4156.0, "current"),
    # the cascade's notch (800 rad/s, -20 dB) sits between the clamp and the current loop: the
    # clamped command is 13x the current there (335 vs 25 A/rad), which the simulator confirms
    ("configs/cascade_axis.yaml", 800.0, "current"),
])
def test_sine_inside_the_envelope_does_not_saturate_and_outside_does(config, frequency, limit):
    # the second method: the nonlinear simulator's own clamp flags over the steady state of a
    # sine-dwell (the feed-forward acting in both, as the simulator applies the config's). At
    # 100 rad/s the voltage clamp is predicted first (80.7 deg, the current's at 101.7 deg),
    # at 3 x w_BW the current clamp (the derivative's current); 0.8 x the predicted amplitude
    # touches no clamp, 1.25 x reaches the predicted one: the envelope is sharp to 25 %.
    act = cf.load(config)
    p = LoopParameters.from_config(act.params)
    w = np.array([frequency])
    limits = rate_envelope(act.params, p, w)
    a_max = float(limits.amplitude_rad[0])
    assert limits.limited_by[0] == limit
    result = sine_dwell(p, [0.8 * a_max, 1.25 * a_max], w, periods_settle=3, periods_measure=2,
                        min_settle_s=0.005)
    assert not result.limit_hit[0, 0]  # inside: no clamp acts
    flags = result.voltage_limited if limit == "voltage" else result.current_limited
    assert flags[1, 0]  # outside: the predicted clamp acts
    # outside, the clamp cuts the first harmonic below the unclamped one
    assert result.magnitude_db[1, 0] < result.magnitude_db[0, 0] - 0.1


def test_envelope_in_json_at_a_linear_output():
    act = cf.load("configs/ball_screw.yaml")
    data = act.analyze().to_dict()["envelope"]
    assert "no_load_rate_m_s" in data and "stall_force_N" in data
    assert data["no_load_rate_mm_s"] == pytest.approx(1e3 * data["no_load_rate_m_s"])
    assert "amplitude_mm" in data["sine_limit"]
    assert not any("_deg" in key for key in data["sine_limit"])


def test_sinedwell_figure_draws_the_envelope_map():
    # structure, not pixels: a third panel with the two limit curves (the same numbers as
    # rate_envelope at the drawn frequencies), the dwell points at their amplitudes
    from cas_freq.config.loader import load_variant
    from cas_freq.plots.report import sinedwell
    from cas_freq.report.data import ReportSettings, gather_variant

    settings = ReportSettings(amplitudes_rad=(math.radians(0.5), math.radians(10.0)),
                              frequencies_rad_s=(600.0, 2400.0), pade_order=6)
    data = gather_variant(load_variant(None, "base"), settings, verdicts=[])
    fig = sinedwell(data)
    amp = fig.axes[2]
    assert amp.get_yscale() == "log" and amp.get_ylabel() == "amplitude [deg]"
    labels = [line.get_label() for line in amp.get_lines()]
    assert "current limit ±20 A" in labels and "voltage limit ±30 V" in labels
    current = amp.get_lines()[labels.index("current limit ±20 A")]
    w, a = current.get_data()
    p = LoopParameters.from_config(data.loaded.params)
    expected = np.degrees(rate_envelope(data.loaded.params, p, w[[0, -1]],
                                        feedforward=False).current_amplitude_rad)
    np.testing.assert_allclose(a[[0, -1]], expected, rtol=1e-5)  # plotted rounded to 6 digits
    levels = {round(float(line.get_ydata()[0]), 6) for line in amp.get_lines()
              if line.get_marker() == "o" and len(line.get_ydata())}
    assert levels == {0.5, 10.0}


def test_a_cascades_velocity_clamp_limits_the_rate():
    # the cascade axis: position_loop.omega_max = 100 rad/s at the
    # motor is below the supply's no-load speed, so the output rate is omega_max / N
    act = cf.load("configs/cascade_axis.yaml", set={"position_loop.omega_max": "100 rad/s"})
    envelope = act.analyze().envelope
    ratio = LoopParameters.from_config(act.params).ratio[0]
    assert envelope.no_load_rate_rad_s == pytest.approx(100.0 / ratio, rel=1e-12)
    assert envelope.rate_limited_by == "velocity command"
    free = cf.load("configs/cascade_axis.yaml").analyze().envelope
    assert free.rate_limited_by == "supply" and free.no_load_rate_rad_s > 100.0 / ratio
