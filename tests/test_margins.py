"""Margins and closed-loop figures against analytic loops worked out here."""

import math

import numpy as np
import pytest

from cas_freq.analysis.closed_loop import closed_loop_summary
from cas_freq.analysis.frequency import frequency_grid
from cas_freq.analysis.margins import loop_margins
from cas_freq.core.formulas import second_order_bandwidth

# Crossings are refined (Anderson-Bjorck regula falsi) to 1e-12 in log frequency; figures
# computed from them are accurate to ~1e-9 relative. 1e-7 leaves room for the conversion to
# degrees and dB.
RTOL = 1e-7


def integrator_with_delay(gain, tau):
    return lambda s: gain * np.exp(-s * tau) / s


def test_integrator_with_delay():
    # L = K e^(-s tau)/s: |L| = K/omega, so omega_c = K; phase = -90° - omega tau, so
    # PM = 90° - K tau [rad->deg] and the delay margin is PM/omega_c = (pi/2 - K tau)/K.
    # Phase crossovers where -pi/2 - omega tau = -pi - 2 pi k: omega_k = (pi/2 + 2 pi k)/tau,
    # with GM_k = 20 log10(omega_k / K).
    gain, tau = 100.0, 1e-3
    omega = frequency_grid(1.0, 1e5, total_delay=tau)
    margins = loop_margins(integrator_with_delay(gain, tau), omega)
    assert margins.crossover_rad_s == pytest.approx(gain, rel=RTOL)
    assert margins.phase_margin_deg == pytest.approx(90 - math.degrees(gain * tau), rel=RTOL)
    assert margins.delay_margin_s == pytest.approx((math.pi / 2 - gain * tau) / gain, rel=RTOL)
    expected = [(math.pi / 2 + 2 * math.pi * k) / tau for k in range(20)]
    expected = [w for w in expected if w <= 1e5]
    found = [c.frequency_rad_s for c in margins.phase_crossovers]
    np.testing.assert_allclose(found, expected, rtol=RTOL)
    assert margins.phase_crossover_rad_s == pytest.approx(expected[0], rel=RTOL)
    assert margins.gain_margin_db == pytest.approx(20 * math.log10(expected[0] / gain), rel=RTOL)
    assert margins.gain_margin_low_db is None


def test_integrator_disk_margin_is_unbounded_gain_and_90_degrees():
    # L = K/s: S - 1/2 = (s - K)/(2(s + K)) has magnitude 1/2 at every frequency, so
    # alpha = 2: the disk allows any gain increase (gain margin unbounded -> None) and
    # 2 atan(1) = 90° of phase (Seiler et al. 2020, skew 0).
    margins = loop_margins(lambda s: 50.0 / s, frequency_grid(1e-2, 1e4))
    assert margins.disk_margin_alpha == pytest.approx(2.0, rel=1e-9)
    assert margins.disk_margin_gain_db is None
    assert margins.disk_margin_phase_deg == pytest.approx(90.0, rel=1e-7)
    assert margins.phase_crossovers == ()


@pytest.mark.parametrize("zeta", [0.2, 0.54, 0.7])
def test_standard_second_order_loop(zeta):
    # L = wn^2/(s (s + 2 zeta wn)) closes to T = wn^2/(s^2 + 2 zeta wn s + wn^2). Textbook
    # results (e.g. Ogata, Modern Control Engineering, §7-6):
    #   omega_c = wn sqrt(sqrt(1 + 4 zeta^4) - 2 zeta^2),  PM = atan(2 zeta wn / omega_c),
    #   bandwidth = the report's closed form, -90° of T at exactly wn,
    #   resonance 1/(2 zeta sqrt(1 - zeta^2)) at wn sqrt(1 - 2 zeta^2) for zeta < 1/sqrt(2).
    wn = 462.0
    loop = lambda s: wn**2 / (s * (s + 2 * zeta * wn))  # noqa: E731
    closed = lambda s: wn**2 / (s**2 + 2 * zeta * wn * s + wn**2)  # noqa: E731
    omega = frequency_grid(1e-1, 1e5)
    margins = loop_margins(loop, omega)
    wc = wn * math.sqrt(math.sqrt(1 + 4 * zeta**4) - 2 * zeta**2)
    assert margins.crossover_rad_s == pytest.approx(wc, rel=RTOL)
    assert margins.phase_margin_deg == pytest.approx(
        math.degrees(math.atan2(2 * zeta * wn, wc)), rel=RTOL
    )
    assert margins.gain_margin_db is None  # phase never reaches -180°
    figures = closed_loop_summary(closed, omega)
    assert figures.bandwidth_rad_s == pytest.approx(second_order_bandwidth(wn, zeta), rel=RTOL)
    assert figures.phase_90_rad_s == pytest.approx(wn, rel=RTOL)
    assert figures.dc_gain_db == pytest.approx(0.0, abs=1e-9)
    if zeta < 1 / math.sqrt(2):
        peak = 1 / (2 * zeta * math.sqrt(1 - zeta**2))
        assert figures.peak_db == pytest.approx(20 * math.log10(peak), rel=1e-7)
        assert figures.peak_rad_s == pytest.approx(wn * math.sqrt(1 - 2 * zeta**2), rel=1e-5)


def test_no_resonance_has_no_peak():
    # First-order T = 1/(tau s + 1): monotone, -3 dB at 1/tau, phase never reaches -90°. Its
    # largest |T| is at the range's low end: a bound, not a peak (before: "peak 0 dB at —").
    figures = closed_loop_summary(lambda s: 1 / (1e-3 * s + 1), frequency_grid(1e-1, 1e5))
    assert figures.peak_rad_s is None
    assert figures.peak_db is None
    assert figures.bandwidth_rad_s == pytest.approx(1e3, rel=RTOL)
    assert figures.phase_90_rad_s is None


def test_bandwidth_outside_range_is_none():
    figures = closed_loop_summary(lambda s: 1 / (1e-3 * s + 1), frequency_grid(1e-1, 1e2))
    assert figures.bandwidth_rad_s is None


def test_type_two_loop_has_lower_gain_margin():
    # L = K (s + z)^2 / (s^2 (s + p)) with p < z: the phase -180° + 2 atan(w/z) - atan(w/p)
    # starts at -180°, dips below it and comes back up where 2 atan(w/z) = atan(w/p), i.e.
    # (taking tangents) w^2 = z (z - 2p). With K large |L| > 1 there: a lower gain margin,
    # -20 log10 |L| < 0 dB, and no upper one (the phase ends at -90°).
    gain, z, p = 20.0, 10.0, 2.0
    loop = lambda s: gain * (s + z) ** 2 / (s**2 * (s + p))  # noqa: E731
    margins = loop_margins(loop, frequency_grid(1e-3, 1e4))
    w180 = math.sqrt(z * (z - 2 * p))
    magnitude = gain * (w180**2 + z**2) / (w180**2 * math.hypot(w180, p))
    assert margins.phase_crossover_low_rad_s == pytest.approx(w180, rel=RTOL)
    assert margins.gain_margin_low_db == pytest.approx(-20 * math.log10(magnitude), rel=RTOL)
    assert margins.gain_margin_db is None


def test_several_gain_crossovers_are_all_reported():
    # A loop whose magnitude crosses 1 three times: L = K (s/a + 1)^2 / (s (s/b + 1)^3) ... use
    # a simple construction with a known magnitude: |L| = 2 at DC-ish band, dips below 1 and
    # rises again; here L = 2 (s^2 + 1)/(s^2 + 0.1 s + 1) * 1/(1e-3 s + 1)^2 has a notch at 1
    # rad/s (|L| -> 0) and rolls off above 1 krad/s: crossings at two notch flanks + roll-off.
    loop = lambda s: 2 * (s**2 + 1) / (s**2 + 0.1 * s + 1) / (1e-3 * s + 1) ** 2  # noqa: E731
    margins = loop_margins(loop, frequency_grid(1e-3, 1e6))
    assert len(margins.gain_crossovers) == 3
    for crossover in margins.gain_crossovers:
        assert abs(loop(1j * crossover.frequency_rad_s)) == pytest.approx(1.0, rel=1e-9)
    # On the notch's flanks L is near 1 with its phase at -60° and +60°: PM 120° and -120°,
    # both far from -1; the roll-off crossover (PM 90°) is the nearest, the headline.
    pms = [c.phase_margin_deg for c in margins.gain_crossovers]
    np.testing.assert_allclose(pms, [119.89, -120.12, 90.006], atol=0.01)
    assert margins.phase_margin_deg == pms[2] and margins.crossover_rad_s > 999
    assert margins.delay_margin_s == min(c.delay_margin_s for c in margins.gain_crossovers)


def test_grid_resolves_delay_phase():
    tau = 0.46e-3
    omega = frequency_grid(1e-2, 1e6, total_delay=tau)
    assert np.all(np.diff(omega) > 0)
    assert np.max(np.diff(omega)) <= math.pi / (8 * tau) * 1.0001
    with pytest.raises(ValueError, match="0 < w_min < w_max"):
        frequency_grid(10.0, 1.0)


# --- Phase margins in (-180°, 180°] whatever branch the phase starts on (issue 24) ---


def test_aiding_plant_margin_is_on_the_branch_of_the_crossover(engine):
    # An aiding spring makes the plant 1/(s^2 - 1): at s = j w its denominator -w^2 - 1 is
    # negative real for every w, so L = K (1 + s Td)(1 + s/z) / ((s^2 - 1)(1 + s/p)) starts at
    # -K (phase ±180°) and a little lag (1/p > Td + 1/z) puts its first samples at +179.5°.
    # Its phase at the crossover is 180° + atan(w Td) + atan(w/z) - atan(w/p) (mod 360°), so
    # PM = atan(w Td) + atan(w/z) - atan(w/p), in (-180°, 180°]; the old engine said 423°.
    # w_c from |L| = 1, with u = w^2: K^2 (1 + u Td^2)(1 + u/z^2) = (1 + u)^2 (1 + u/p^2).
    gain, td, p, z = 40.0, 1.0, 0.1, 2.0
    loop = lambda s: gain * (1 + s * td) * (1 + s / z) / ((s * s - 1) * (1 + s / p))  # noqa: E731
    # the closed loop is stable (its characteristic polynomial's roots), so the margin matters
    numerator = gain * np.polymul([td, 1.0], [1 / z, 1.0])
    denominator = np.polymul([1.0, 0.0, -1.0], [1 / p, 1.0])
    assert np.roots(np.polyadd(denominator, numerator)).real.max() < 0
    left = gain**2 * np.polymul([td**2, 1.0], [1 / z**2, 1.0])
    right = np.polymul(np.polymul([1.0, 1.0], [1.0, 1.0]), [1 / p**2, 1.0])
    u = np.roots(np.polysub(right, left))
    (wc,) = np.sqrt(u[(abs(u.imag) < 1e-12) & (u.real > 0)].real)
    pm = math.degrees(math.atan(wc * td) + math.atan(wc / z) - math.atan(wc / p))
    omega = frequency_grid(1e-3, 1e4)
    assert np.angle(loop(1j * omega[0]), deg=True) > 179  # the first sample: the +180° side
    margins = loop_margins(loop, omega)
    assert margins.crossover_rad_s == pytest.approx(wc, rel=RTOL)
    assert margins.phase_margin_deg == pytest.approx(pm, rel=RTOL)
    assert margins.delay_margin_s == pytest.approx(math.radians(pm) / wc, rel=RTOL)
    # the continuous phase still locates it: +179.5° at the start, turned up to 180° + PM
    assert margins.gain_crossovers[0].phase_deg == pytest.approx(180 + pm, rel=RTOL)


def _pade_polynomials(tau, order):
    """Numerator and denominator (highest power first) of the [order/order] Padé approximant
    of exp(-s tau): coefficient of (s tau)^k is (2n - k)! n! / ((2n)! k! (n - k)!), with
    (-1)^k in the numerator (e.g. Golub and Van Loan, Matrix Computations, §11.3)."""
    n = order
    c = [math.factorial(2 * n - k) * math.factorial(n)
         / (math.factorial(2 * n) * math.factorial(k) * math.factorial(n - k)) * tau**k
         for k in range(n + 1)]
    return np.array([(-1) ** k * c[k] for k in range(n, -1, -1)]), np.array(c[::-1])


def test_loop_on_another_branch_example21(engine):
    # python-control's "example21" x 1000 (control/tests/margin_test.py, test_zmore_margin):
    # open-loop unstable (a pole at +0.0005), negative DC gain (0.002 * 0.02*0.05*5*10 /
    # (-0.0005 * 0.0001 * 0.01 * 0.2 * 1 * 100^2) < 0): the phase starts on the -180° side.
    # python-control gives PM 22.5215° at 0.0630 rad/s. Here, a second method: the crossover
    # by bisection on |L| = 1 on a fine grid, PM = 180° + angle(L) wrapped into (-180°, 180°],
    # and the delay margin PM [rad] / w_c = 6.24 s, confirmed independently by the closed loop
    # with a Padé-8 delay: stable at 6.0 s, unstable at 6.5 s (the old engine said 382.52° and
    # 106 s).
    num = 1000 * 0.002 * np.poly([-0.02, -0.05, -5.0, -10.0])
    den = np.poly([0.0005, -0.0001, -0.01, -0.2, -1.0, -100.0, -100.0])
    loop = lambda s: np.polyval(num, s) / np.polyval(den, s)  # noqa: E731
    margins = loop_margins(loop, frequency_grid(1e-5, 1e4))
    assert len(margins.gain_crossovers) == 1
    w = np.geomspace(1e-5, 1e4, 900_001)
    above = np.abs(loop(1j * w)) > 1.0
    (k,) = np.flatnonzero(above[1:] != above[:-1])
    lo, hi = w[k], w[k + 1]
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        lo, hi = (mid, hi) if (abs(loop(1j * mid)) > 1.0) == above[k] else (lo, mid)
    wc = math.sqrt(lo * hi)
    pm = 180.0 - (-np.angle(loop(1j * wc), deg=True)) % 360.0  # 180° + angle, wrapped
    assert pm == pytest.approx(22.5215, abs=1e-3)  # python-control's value
    assert margins.crossover_rad_s == pytest.approx(wc, rel=1e-9)
    assert margins.phase_margin_deg == pytest.approx(pm, rel=1e-7)
    delay = math.radians(pm) / wc
    assert margins.delay_margin_s == pytest.approx(delay, rel=1e-7)
    assert delay == pytest.approx(6.24, abs=0.01)

    def stable_with_delay(tau):
        pade_num, pade_den = _pade_polynomials(tau, 8)
        characteristic = np.polyadd(np.polymul(den, pade_den), np.polymul(num, pade_num))
        return np.roots(characteristic).real.max() < 0

    assert stable_with_delay(0.0) and stable_with_delay(6.0)
    assert not stable_with_delay(6.5)


def test_delay_margin_of_a_negative_phase_margin_is_the_delay_to_the_next_turn():
    # L = K e^(-s tau)/s with K tau = 2 rad (> pi/2): PM = 90° - 114.6° = -24.6° at w_c = K.
    # A further delay t turns L(j K) by -K t; it reaches -180° - 360° (the next pass through
    # -1) at K t = 2 pi + PM [rad], the smallest positive delay there: (2 pi + PM)/K.
    gain, tau = 100.0, 0.02
    margins = loop_margins(integrator_with_delay(gain, tau), frequency_grid(1.0, 1e5,
                                                                            total_delay=tau))
    pm = 90.0 - math.degrees(gain * tau)
    assert margins.phase_margin_deg == pytest.approx(pm, rel=RTOL)
    assert margins.delay_margin_s == pytest.approx((2 * math.pi + math.radians(pm)) / gain,
                                                   rel=RTOL)
