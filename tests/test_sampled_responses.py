"""cas_freq.model.sampled.responses against the independent oracle tests/sampled_oracle.py
(issue 26), and the issue's own figures reproduced by the oracle.

The parameters are those of the shipped configs with the static fields of the shared design set
directly (``sample_rates``: (loop, rate [Hz]) pairs innermost first; ``sampling_method``), and
``p = cas_freq.model.loops.Selector(params)()`` as every caller builds it. Responses are
compared at s = j omega for omega up to 0.999 of the slowest loop's Nyquist frequency:
``loops['current_loop']`` is L_i(e^{j omega T_i}), ``loops['position_loop']``
L_p(e^{j omega T_p}) broken at the position controller's output with the current loop closed,
``closed_loop`` T = output samples / command samples at the position loop's rate.

Tolerances: where the oracle is exact (sample_system and z^-d, the fractional-delay state
space, the lifted state space) both computations are exact up to rounding, so they must agree
to 1e-9 relative (a wrong sample of delay, hold or controller moves them by > 1e-3); where the
oracle is the aliasing sum, to its returned truncation bound plus 1e-9 relative.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from sampled_oracle import (
    controllers,
    current_voltage_to_current,
    drive_of,
    evaluate,
    hold_equivalent_by_aliasing,
    issue_position_loop,
    lifted,
    margins,
    sampled_margins,
    single_rate,
)

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
QT_CAS = CONFIGS / "qt_cas.yaml"
DC_SERVO = CONFIGS / "dc_servo.yaml"
KEYS = ("current_loop", "position_loop", "closed_loop")


def _params(config, variant, rates, method, **changes):
    """The LoopParameters of a shipped config's variant with the sampling of the shared design
    (and any array fields changed)."""
    from cas_freq.config import load_variant
    from cas_freq.core.parameters import LoopParameters

    params = LoopParameters.from_config(load_variant(config, variant).params)
    return dataclasses.replace(params, sample_rates=rates, sampling_method=method, **changes)


def _cas_freq(params, omega):
    """cas_freq's sampled responses at s = j omega, as {key: array}."""
    from cas_freq.model import loops, sampled

    result = sampled.responses(loops.Selector(params)(), 1j * omega, closed=True)
    return {"current_loop": np.asarray(result.loops["current_loop"]).reshape(omega.shape),
            "position_loop": np.asarray(result.loops["position_loop"]).reshape(omega.shape),
            "closed_loop": np.asarray(result.closed_loop).reshape(omega.shape)}


def _omega(slow_rate_hz, points=300):
    return np.geomspace(1.0, 0.999 * math.pi * slow_rate_hz, points)


def _assert_close(ours, theirs, tolerance=1e-9):
    for key in KEYS:
        error = np.max(np.abs(theirs[key] - ours[key]) / np.abs(ours[key]))
        assert error < tolerance, f"{key}: relative error {error:.3g}"


# ------------------------------------------------------------------------------ single rate

@pytest.mark.parametrize("variant, method", [("base", "backward"), ("fitted", "tustin")])
def test_single_rate_qt_cas(variant, method):
    """Both QT-CAS loops at 50 kHz (tau_c = 3 samples, tau_p = 20): cas_freq against the
    oracle's sample_system + z^-d composition (exact), 1e-9 relative; backward and tustin."""
    rate = 50e3
    omega = _omega(rate)
    params = _params(QT_CAS, variant, (("current_loop", rate), ("position_loop", rate)),
                     method)
    ours = single_rate(drive_of(QT_CAS, variant), 1 / rate, method).responses(omega)
    _assert_close(ours, _cas_freq(params, omega))


def test_single_rate_dc_servo():
    """dc_servo, both loops at 20 kHz (tau_c = 1 sample, tau_p = 4), backward."""
    rate = 20e3
    omega = _omega(rate)
    params = _params(DC_SERVO, "base", (("current_loop", rate), ("position_loop", rate)),
                     "backward")
    ours = single_rate(drive_of(DC_SERVO, "base"), 1 / rate, "backward").responses(omega)
    _assert_close(ours, _cas_freq(params, omega))


def test_single_rate_fractional_current_delay():
    """Both QT-CAS loops at 25 kHz: tau_c = 60 us = 1.5 samples (a fractional delay, the
    modified z-transform), tau_p = 10 samples. Against the oracle's exact fractional-delay
    state space (lifted with ratio 1), 1e-9; and L_i against the aliasing sum C_i P_h, within
    |C_i| times its truncation bound plus 1e-9 relative."""
    rate = 25e3
    omega = _omega(rate)
    d = drive_of(QT_CAS, "base")
    theirs = _cas_freq(_params(QT_CAS, "base", (("current_loop", rate),
                                                ("position_loop", rate)), "backward"), omega)
    _assert_close(lifted(d, 1 / rate, 1).responses(omega), theirs)
    c_i = evaluate(controllers(d, 1 / rate, 1 / rate)[0], omega)
    p_h, tail = hold_equivalent_by_aliasing(current_voltage_to_current(d), 1 / rate, d.tau_c,
                                            omega)
    ours = c_i * p_h
    assert np.all(np.abs(theirs["current_loop"] - ours)
                  <= np.abs(c_i) * tail + 1e-9 * np.abs(ours))


# -------------------------------------------------------------------------------- multirate

@pytest.mark.parametrize("config, variant, changes, method", [
    (QT_CAS, "base", {}, "backward"), (QT_CAS, "fitted", {}, "tustin"),
    (QT_CAS, "base", {"derivative_on_measurement": np.array([True])}, "backward"),
    (DC_SERVO, "base", {}, "backward")])
def test_multirate_epos4_rates(config, variant, changes, method):
    """The EPOS4 rates: current loop 25 kHz, position loop 2.5 kHz (ratio 10); QT-CAS
    tau_c = 1.5 fast samples, tau_p = 10 fast samples (one slow period); dc_servo
    tau_c = 1.25, tau_p = 5. Against the oracle's lifted state space, 1e-9 relative, up to
    the position loop's Nyquist frequency; with the derivative on the measurement T changes
    and the loops do not; fitted with tustin controllers."""
    omega = _omega(2.5e3)
    d = drive_of(config, variant)
    if changes:
        d = dataclasses.replace(d, derivative_on_measurement=True)
    params = _params(config, variant, (("current_loop", 25e3), ("position_loop", 2.5e3)),
                     method, **changes)
    _assert_close(lifted(d, 40e-6, 10, method).responses(omega), _cas_freq(params, omega))


# ------------------------------------------------------------------- the issue's own figures

def _position_margins(loop, period):
    return margins(loop, 1.0, (1 - 1e-9) * math.pi / period, 800)


def test_issue_figures(capsys):
    """The issue's figures, by the oracle alone (cas_freq not involved).

    (a) The issue's own setup: the position loop sampled at 2.5 kHz (backward PID, zero-order
    hold, the report's 0.4 ms kept as a transport delay), the current loop CONTINUOUS with its
    exact 0.06 ms delay: L_p = C_p(z) P_h(z), P_h by the aliasing sum of e^{-s tau_p} T_i M
    (K = 300; T_i M ~ 1/s^3, the truncation below 1e-12). Reproduced: PM 34.7 -> 21.26 deg on
    base (issue 21.3), 43.35 -> 34.32 deg on fitted (issue 34.3), base GM 8.35 -> 4.79 dB
    (issue 4.76: 0.03 dB apart; neither Tf = 0.6 ms nor tau_c = 0 explains it, 4.79/4.90).

    (b) The EPOS4 setup of the shared design: both loops sampled (current 25 kHz, tau_c = 1.5
    samples exact; position 2.5 kHz, tau_p = 10 fast samples) by the lifted system: base PM
    22.04 deg, GM 5.02 dB; fitted PM 34.81 deg, GM 9.87 dB; both stable. With tau_p = 0 (the
    other reading: the report's 0.4 ms is the one-period delay of the 2.5 kHz loop, already
    in the sampling) base PM 37.74 deg, GM 12.08 dB; fitted 44.68 deg, 16.85 dB.
    Tolerance 0.01 deg / 0.01 dB on our own figures (regression); the issue's to its digits.
    """
    period = 1 / 2.5e3
    expected = {  # variant: (a) PM, GM; (b) PM, GM; (b, tau_p = 0) PM, GM
        "base": ((21.26, 4.79), (22.04, 5.02), (37.74, 12.08)),
        "fitted": ((34.32, 9.64), (34.81, 9.87), (44.68, 16.85)),
    }
    issue = {"base": (21.3, 4.76), "fitted": (34.3, None)}
    for variant, (a, b, b0) in expected.items():
        d = drive_of(QT_CAS, variant)
        m_a = _position_margins(issue_position_loop(d, period, k_max=300), period)
        loops = lifted(d, 40e-6, 10)
        m_b = sampled_margins(loops.position, points=800)
        m_b0 = sampled_margins(lifted(dataclasses.replace(d, tau_p=0.0), 40e-6, 10).position,
                               points=800)
        with capsys.disabled():
            print(f"\n{variant}: (a) PM {m_a.phase_margin_deg:.2f} deg, GM "
                  f"{m_a.gain_margin_db:.2f} dB; (b) PM {m_b.phase_margin_deg:.2f} deg, GM "
                  f"{m_b.gain_margin_db:.2f} dB, stable {loops.stable()}; (b, tau_p = 0) PM "
                  f"{m_b0.phase_margin_deg:.2f} deg, GM {m_b0.gain_margin_db:.2f} dB")
        for m, (pm, gm) in ((m_a, a), (m_b, b), (m_b0, b0)):
            assert m.phase_margin_deg == pytest.approx(pm, abs=0.01)
            assert m.gain_margin_db == pytest.approx(gm, abs=0.01)
        assert loops.stable()
        pm_issue, gm_issue = issue[variant]
        assert m_a.phase_margin_deg == pytest.approx(pm_issue, abs=0.05)
        if gm_issue is not None:
            assert m_a.gain_margin_db == pytest.approx(gm_issue, abs=0.05)
