"""Step figures of sampled responses, against closed forms worked out here."""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from cas_freq.simulation import second_order_step, step_figures
from cas_freq.simulation.step_figures import settling_time

WN, ZETA = 100.0, 0.5  # an underdamped second-order step, no delay


def unit(t):
    return second_order_step(t, WN, ZETA, 0.0)


def test_second_order_closed_forms():
    # Ogata, Modern Control Engineering, 5th ed., §5-3: overshoot exp(-pi zeta/sqrt(1-zeta^2))
    # = 16.303 % at zeta = 0.5, peak time pi/wd. The rise and settling times have no closed
    # form: they are solved here with brentq on the analytic curve. Sampled at 0.1 ms (~725
    # samples per damped period), the parabola through the peak and linear interpolation of the
    # crossings are good to ~1e-6 relative, the rise time (a difference of two crossings) to
    # 1.2e-5 (found); the tolerances are 1e-5, 1e-4 for the rise time.
    t = np.arange(0.0, 0.2, 1e-4)
    step = math.radians(10.0)
    figures = step_figures(t, step * unit(t), step)
    wd = WN * math.sqrt(1 - ZETA**2)
    closed_form = 100 * math.exp(-math.pi * ZETA / math.sqrt(1 - ZETA**2))
    assert closed_form == pytest.approx(16.303, abs=5e-4)
    assert figures.overshoot_pct == pytest.approx(16.303, abs=1e-3)
    assert figures.peak_time_s == pytest.approx(math.pi / wd, rel=1e-5)
    peak = math.pi / wd
    t10 = brentq(lambda s: unit(s) - 0.1, 1e-9, peak)
    t90 = brentq(lambda s: unit(s) - 0.9, 1e-9, peak)
    assert figures.rise_time_s == pytest.approx(t90 - t10, rel=1e-4)
    fine = np.arange(0.0, 0.2, 1e-6)
    for band, got in ((0.02, figures.settling_time_s), (0.05, figures.settling_time_5pct_s)):
        k = np.flatnonzero(np.abs(unit(fine) - 1) > band)[-1]
        exact = brentq(lambda s, b=band: abs(unit(s) - 1) - b, fine[k], fine[k + 1])
        assert got == pytest.approx(exact, rel=1e-5)
    assert figures.amplitude_deg == pytest.approx(10.0)
    assert figures.max_current_a is None and figures.current_limited is None


def test_first_order_has_no_overshoot():
    # y = 1 - exp(-t/tau): rise time tau ln 9, settling time tau ln(1/0.02) (and ln 20 for 5 %).
    tau = 0.01
    t = np.arange(0.0, 0.1, 1e-5)
    figures = step_figures(t, 2.0 * (1 - np.exp(-t / tau)), 2.0)
    assert figures.overshoot_pct == 0.0
    assert figures.rise_time_s == pytest.approx(tau * math.log(9), rel=1e-6)
    assert figures.settling_time_s == pytest.approx(tau * math.log(50), rel=1e-6)
    assert figures.settling_time_5pct_s == pytest.approx(tau * math.log(20), rel=1e-6)


def test_negative_step_and_limits():
    t = np.arange(0.0, 0.2, 1e-4)
    up = step_figures(t, unit(t), 1.0)
    down = step_figures(t, -unit(t), -1.0, current=[0.0, -21.0, 3.0], voltage=[1.0, -2.0],
                        current_limited=[False, True], voltage_limited=[False, False])
    for name in ("rise_time_s", "overshoot_pct", "settling_time_s", "peak_time_s"):
        assert getattr(down, name) == pytest.approx(getattr(up, name), rel=1e-12)
    assert down.max_current_a == 21.0 and down.max_voltage_v == 2.0
    assert down.current_limited is True and down.voltage_limited is False


def test_not_settled_and_never_left():
    t = np.linspace(0.0, 1.0, 11)
    assert math.isnan(settling_time(t, np.linspace(0.0, 0.9, 11), 0.02))
    assert settling_time(t, np.ones(11), 0.02) == 0.0
    with pytest.raises(ValueError, match="final value"):
        step_figures(t, t, 0.0)
