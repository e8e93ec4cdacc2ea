"""cf.loop_margins and cf.closed_loop_figures on the loops they used to get wrong: discrete-time
systems, an integrator the arithmetic leaves just off s = 0, and their printed form."""

import math

import control
import numpy as np
import pytest

import cas_freq as cf
from cas_freq.core.figures import FIGURES

s = control.tf("s")

#: MATLAB's allmargin example with the 0.1 s delay of docs/api.md: ~160 phase crossovers.
DELAYED = control.tf(25, [1, 10, 10, 10])


def test_results_print_a_short_headline_not_every_crossover():
    # Before: print() dumped the dataclass, every one of the ~160 phase crossovers of the
    # docs' delay example.
    m = cf.loop_margins(DELAYED, delay=0.1)
    assert len(m.phase_crossovers) > 100
    text = repr(m)
    assert len(text.splitlines()) <= 8 and len(text) < 600
    assert text.startswith("LoopMarginResult: 1 gain and")
    assert f"phase margin: {m.phase_margin_deg:.4g} deg" in text
    assert "<table>" in m._repr_html_() and "disk margin α" in m._repr_html_()
    t = cf.closed_loop_figures(control.feedback(DELAYED, 1))
    assert len(repr(t).splitlines()) <= 8
    bandwidth = FIGURES["closed_loop.bandwidth_rad_s"].label  # the figure table's label
    assert f"{bandwidth}: {t.bandwidth_rad_s:.4g} rad/s" in repr(t)
    assert "<table>" in t._repr_html_()


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_no_static_margin_when_an_integrator_is_off_zero_by_rounding(sign):
    # A type-2 loop whose second integrator the arithmetic leaves at +-1e-12 rad/s (as the
    # ss -> poles conversion of a PI position loop does): python-control's dcgain is then a
    # finite -5e24 or +5e24, and L(0) "negative" gave a lower gain margin of -494 dB at 0 rad/s.
    # The same loop with the integrators exactly at 0 is the reference: the same crossings.
    exact = 100 * (s + 10) / (s**2 * (s + 100))
    rounded = 100 * (s + 10) / ((s - sign * 1e-12) * (s + 2e-12) * (s + 100))
    ours, reference = cf.loop_margins(rounded), cf.loop_margins(exact)
    assert ours.gain_margin_low_db is None and ours.phase_crossover_low_rad_s is None
    assert [c.frequency_rad_s for c in ours.phase_crossovers] == \
        [c.frequency_rad_s for c in reference.phase_crossovers]
    # the crossovers of the two loops differ by the poles' 1e-12 rad/s shift only: 1e-9 is ample
    assert ours.phase_margin_deg == pytest.approx(reference.phase_margin_deg, rel=1e-9)


def test_a_real_negative_static_gain_is_still_a_phase_crossover_at_zero():
    # L(0) = -0.5, no pole near 0: a phase crossover at w = 0 with GM 20 log10(2) = 6.0206 dB
    m = cf.loop_margins(-0.5 / (s + 1))
    assert m.phase_crossovers[0].frequency_rad_s == 0.0
    assert m.phase_crossovers[0].gain_margin_db == pytest.approx(20 * math.log10(2), rel=1e-12)


# python-control's control/tests/margin_test.py::test_stability_margins_discrete (v0.10.2):
# a continuous TF sampled at dt (zero-order hold) and the stability_margins it publishes,
# (gm [ratio], pm [deg], sm, wpc [rad/s], wgc [rad/s], wms [rad/s]), to its own rtol.
DISCRETE = [
    ([2], [1, 3, 2, 0], 1e-2,
     [2.955761, 32.398492, 0.429535, 1.403725, 0.749367, 0.923898], 1e-5),
    ([2], [1, 3, 3, 1], .1, [3.4927, 65.4212, 0.5763, 1.6283, 0.76625, 1.2019], 1e-4),
    ([1.1 * 4 * np.pi**2], [1, 2 * 0.2 * 2 * np.pi, 4 * np.pi**2], .05,
     [2.3842, 18.161, 0.26953, 11.712, 8.7478, 9.1504], 1e-4),
    ([5e4], [1., 101., 10101., 10100., 10000.], 1e-3,
     [18.8766, 26.3564, 0.406841, 9.76358, 2.32933, 2.55986], 1e-5),
]


@pytest.mark.parametrize(("num", "den", "dt", "published", "rtol"), DISCRETE)
def test_discrete_systems_give_python_controls_margins(num, den, dt, published, rtol):
    # Before: a TypeError. Evaluated at z = exp(j w dt) up to pi/dt; the published values
    # carry 5-7 digits, python-control checks itself against them to rtol, and so do we.
    m = cf.loop_margins(control.tf(num, den).sample(dt))
    ours = [10 ** (m.gain_margin_db / 20), m.phase_margin_deg,
            10 ** (-m.sensitivity_peak_db / 20), m.phase_crossover_rad_s, m.crossover_rad_s,
            m.sensitivity_peak_rad_s]
    np.testing.assert_allclose(ours, published, rtol=rtol)
    assert m.closed_loop_stable is True
    assert m.omega_range_rad_s[1] == pytest.approx(math.pi / dt, rel=1e-8)


def test_discrete_phase_crossover_is_python_controls():
    # margin_test.py::test_phase_crossover_frequencies, its discrete case: L real at 1.6235
    # rad/s (and at 0, where L(1) = +1.889 is not a phase crossover of the negative axis).
    # python-control's polynomial roots are the independent reference: both to machine
    # precision, 1e-9 relative.
    system = control.tf(np.array([3, 11, 3]) * 1e-4, [1., -2.7145, 2.4562, -0.7408], .1)
    omega, gain = control.phase_crossover_frequencies(system)
    m = cf.loop_margins(system)
    assert len(m.phase_crossovers) == 1
    assert m.phase_crossovers[0].frequency_rad_s == pytest.approx(omega[0], rel=1e-9)
    assert m.gain_margin_db == pytest.approx(-20 * math.log10(-gain[0]), rel=1e-9)


@pytest.mark.parametrize(("gain", "stable"), [(1.0, True), (2.5, False)])
def test_discrete_closed_loop_stability_from_the_unit_circle(gain, stable):
    # L = K / (z - 0.5): the closed-loop pole is z = 0.5 - K, inside the unit circle for
    # K = 1 (z = -0.5), outside for K = 2.5 (z = -2)
    m = cf.loop_margins(control.tf([gain], [1.0, -0.5], 0.01))
    assert m.closed_loop_stable is stable
    assert (m.sensitivity_peak_db is not None) is stable


def test_discrete_range_past_nyquist_is_refused_naming_it():
    with pytest.raises(ValueError, match=r"omega_range: .* Nyquist frequency pi/dt = 314\.159"):
        cf.loop_margins(control.tf([1.0], [1.0, -0.5], 0.01), omega_range=(0.1, 1000.0))


def test_no_peak_when_the_largest_value_is_at_a_range_end():
    # L = 3(10+s)/(2+s) (python-control's margin_test system, sm published as inf: |1 + L|
    # has no stationary point): |S| = |2+s| / |32+4s| rises monotonically to 1/4 as omega
    # grows. Before: "Ms -12.04 dB at 10,000 rad/s", the range end. Now no peak, no disk margin.
    loop = 3 * (10 + s) / (2 + s)
    m = cf.loop_margins(loop)
    assert m.closed_loop_stable is True
    assert m.sensitivity_peak_db is None and m.sensitivity_peak_rad_s is None
    assert m.disk_margin_alpha is None and m.disk_margin_gain_db is None
    # T = 3(10+s)/(32+4s) falls monotonically from 30/32 to 3/4: no resonance peak
    t = cf.closed_loop_figures(control.feedback(loop, 1))
    assert t.peak_db is None and t.peak_rad_s is None
    # T = wn^2/(s^2 + 2 zeta wn s + wn^2), zeta = 0.2: an interior peak, 1/(2 zeta sqrt(1 -
    # zeta^2)) at wn sqrt(1 - 2 zeta^2), refined to ~1e-9 (rel 1e-7 is ample)
    resonant = cf.closed_loop_figures(control.tf([100.0], [1.0, 4.0, 100.0]))
    assert resonant.peak_db == pytest.approx(-20 * math.log10(0.4 * math.sqrt(0.96)), rel=1e-7)
    assert resonant.peak_rad_s == pytest.approx(10 * math.sqrt(0.92), rel=1e-7)


def test_a_discrete_loops_peak_at_nyquist_is_a_peak():
    # L = 1/(z - 0.5): |S| = |z - 0.5| / |z + 0.5| is largest at z = -1, the Nyquist frequency,
    # where the periodic frequency axis of a sampled loop turns: Ms = 3 (9.54 dB) there. The
    # grid stops 1e-9 short of pi/dt, which moves |S| by O(1e-18): rel 1e-12.
    m = cf.loop_margins(control.tf([1.0], [1.0, -0.5], 0.01))
    assert m.sensitivity_peak_db == pytest.approx(20 * math.log10(3.0), rel=1e-12)
    assert m.sensitivity_peak_rad_s == pytest.approx(math.pi / 0.01, rel=1e-8)
