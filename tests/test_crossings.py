"""Crossings that lie between two grid points must not be missed.

A lightly damped resonance can lift |L| above 0 dB (or a notch drop it below) over a band
narrower than the grid spacing (about 1.2 % at 200 points per decade): both crossings then lie
between two grid points and no sign change shows on the grid. The engine probes every local
extremum of |L| near 0 dB and every place where the inner loop L_i passes close to -1
(cas_freq.analysis.margins); these tests build such loops and work out the crossings here.
"""

import math

import numpy as np
import pytest

from cas_freq.analysis import analyze, loop_margins
from cas_freq.analysis.frequency import frequency_grid
from cas_freq.config.loader import load_variant

# Crossings are refined to 1e-12 in log frequency; 1e-9 leaves room for the closed forms.
RTOL = 1e-9


def resonance_crossings(gain, zeta, w0):
    """Frequencies where |gain w0^2 / (s^2 + 2 zeta w0 s + w0^2)| = 1, by hand.

    With u = (w/w0)^2: (1 - u)^2 + 4 zeta^2 u = gain^2, a quadratic in u.
    """
    b = 2.0 - 4.0 * zeta**2
    c = 1.0 - gain**2
    root = math.sqrt(b * b - 4.0 * c)
    return sorted(w0 * math.sqrt(u) for u in ((b - root) / 2.0, (b + root) / 2.0) if u > 0)


def test_resonance_narrower_than_the_grid_spacing():
    # zeta = 2e-4: the half-power width 2 zeta w0 is 0.04 % of w0, 30 times narrower than the
    # grid spacing; the static gain 1/2500 puts the peak (1/(2 zeta) times higher) at +6 dB.
    # w0 is placed halfway between two grid points so that neither sits on the peak.
    omega = frequency_grid(1.0, 1e5)
    k = np.searchsorted(omega, 1234.0)
    w0 = math.sqrt(omega[k] * omega[k + 1])
    zeta, gain = 2e-4, 2.0 * 2e-4 * 2.0  # peak gain / (2 zeta) = 2 (+6.02 dB)
    loop = lambda s: gain * w0**2 / (s**2 + 2 * zeta * w0 * s + w0**2)  # noqa: E731
    grid = np.abs(loop(1j * omega))
    assert grid.max() < 1.0  # the grid alone sees no crossing
    margins = loop_margins(loop, omega)
    found = [c.frequency_rad_s for c in margins.gain_crossovers]
    np.testing.assert_allclose(found, resonance_crossings(gain, zeta, w0), rtol=RTOL)
    # phase of a second-order lag: -90° at w0 exactly, so PM = 180° + angle at each crossing
    for crossing in margins.gain_crossovers:
        expected = 180.0 + math.degrees(np.angle(loop(1j * crossing.frequency_rad_s)))
        assert crossing.phase_margin_deg == pytest.approx(expected, rel=1e-9)


def test_notch_narrower_than_the_grid_spacing():
    # L = 2 (s^2 + 2 zeta_z w0 s + w0^2)/(s^2 + 2 zeta_p w0 s + w0^2): +6 dB everywhere except
    # a notch of depth zeta_z/zeta_p = 1/20 (-26 dB + 6 dB = -20 dB) at w0, 0.1 % wide.
    omega = frequency_grid(1.0, 1e5)
    k = np.searchsorted(omega, 567.0)
    w0 = math.sqrt(omega[k] * omega[k + 1])
    zeta_z, zeta_p = 5e-5, 1e-3
    loop = lambda s: 2.0 * (s**2 + 2 * zeta_z * w0 * s + w0**2) / (  # noqa: E731
        s**2 + 2 * zeta_p * w0 * s + w0**2)
    assert np.abs(loop(1j * omega)).min() > 1.0  # the grid alone sees no crossing
    found = [c.frequency_rad_s for c in loop_margins(loop, omega).gain_crossovers]
    assert len(found) == 2
    # |L| = 1 at each: check the definition directly, and that they straddle the notch. The
    # notch's flank is steep, d ln|L| / d ln w ~ 1/zeta_p = 1e3, so the refinement's 1e-12 of
    # ln w (times |ln w| ~ 6.3) is up to ~6e-9 of |L|: 1e-8
    np.testing.assert_allclose(np.abs(loop(1j * np.array(found))), 1.0, rtol=1e-8)
    assert found[0] < w0 < found[1]
    assert found[1] / found[0] - 1 < 0.01  # both inside one grid interval


# The stable config of issue 10: |L_p| rises to +1.86 dB between 18,408 and 18,490 rad/s
# (a resonance of T_i, where L_i passes close to -1), between two grid points.
NARROW = """
name: narrow_peak
motor: {R: 0.07784818102447305 ohm, L: 0.022147164764477298 mH, Km: 0.09492955843481765 N*m/A,
        Ke: 0.05923126955948338, J: 33.898276035136995 g*cm^2, mu_v: 5.084288327751034e-06}
gear: {ratio: 12.869753263582648}
current_loop: {Kp: 0.3259322149942999, Ki: 0.0, v_max: 3.756339529082125 V,
               delay: 9.788172303654834e-05}
position_loop: {Kp: 10.951315400859645, Ki: 66.65495112270925, Kd: 0.08700003778419067,
                ff_v: 0.003115103335383351, ff_a: 0.0, i_max: 89.935817238277,
                delay: 1.055965873288901 ms, derivative_on: error}
"""


def test_narrow_inner_loop_resonance_of_the_issue(tmp_path):
    path = tmp_path / "narrow.yaml"
    path.write_text(NARROW)
    result = analyze(load_variant(path))
    found = [c.frequency_rad_s for c in result.position_loop.gain_crossovers]
    # Second method: a brute-force scan 100 times denser than the grid around the feature and
    # across the whole low range, locating sign changes of |L_p| - 1.
    from cas_freq.model import ActuatorLoops

    loops = ActuatorLoops(load_variant(path).params)
    dense = np.geomspace(1.0, 1e5, 2_000_000)
    above = np.abs(loops.position_loop(1j * dense)) > 1.0
    changes = dense[np.flatnonzero(above[1:] != above[:-1])]
    assert len(found) == len(changes) == 3
    np.testing.assert_allclose(found, changes, rtol=1e-5)  # the scan's spacing is 5.8e-6
    # the smallest delay margin is at one of the narrow crossings, not at 67.5 rad/s (their
    # phase margins, -138.9° and 143.3°, are farther from -1 than the 108° at 67.5 rad/s)
    assert result.position_loop.delay_margin_crossover_rad_s > 18_000
    assert result.position_loop.delay_margin_s < 2e-4


def _dense_crossings(loop, low, high, points=2_000_001):
    """Brute force: sign changes of |L| - 1 on a uniform grid of ``points`` in [low, high]."""
    w = np.linspace(low, high, points)
    above = np.abs(loop(1j * w)) > 1.0
    return w[np.flatnonzero(above[1:] != above[:-1])], w[1] - w[0]


def test_notch_beside_a_peak_inside_one_grid_interval(engine):
    # L = 3.4 wz/s (s^2 + 2 z wz s + wz^2)/(s^2 + 2 z wp s + wp^2), wp = wz (1 - 1e-4),
    # z = 1e-6: a pole pair just below a zero pair, both inside one grid interval (as a
    # lightly damped compliant gear puts into L_i). Away from them |L| = 3.4 wz/w; between
    # them the zeros pull |L| below 0 dB over 0.06 rad/s. The samples show only the pole's
    # flank: a sharp maximum above 0 dB, beside a minimum too shallow to be refined, so the
    # pair was missed. Second method: a brute-force scan of the interval (2e6 points, 5e-6
    # rad/s apart; the found crossings must agree to that spacing).
    omega = frequency_grid(1.0, 1e5)
    k = np.searchsorted(omega, 900.0)
    wz = math.sqrt(omega[k] * omega[k + 1])
    wp, zeta = wz * (1 - 1e-4), 1e-6
    loop = lambda s: 3.4 * wz / s * (s**2 + 2 * zeta * wz * s + wz**2) / (  # noqa: E731
        s**2 + 2 * zeta * wp * s + wp**2)
    expected, step = _dense_crossings(loop, omega[k], omega[k + 1])
    assert len(expected) == 2 and expected[1] - expected[0] < 0.1
    found = [c.frequency_rad_s for c in loop_margins(loop, omega).gain_crossovers]
    assert len(found) == 3  # the pair and the roll-off crossover at 3.4 wz
    np.testing.assert_allclose(found[:2], expected, atol=step)
    np.testing.assert_allclose(np.abs(loop(1j * np.array(found))), 1.0, rtol=1e-9)


# A made-up servo (the motor and gains of configs/dc_servo.yaml) with a light, lightly damped
# compliant load: its gear mode (resonance 900.90 rad/s, anti-resonance 900.00 rad/s, damping
# ratio ~1e-5) puts a notch beside a peak into L_i, between two grid points.
LIGHT_GEAR = """
name: light_gear
motor: {R: 2.5 ohm, L: 1.2 mH, Km: 0.05 N*m/A, Ke: 0.05 V*s/rad, J: 2e-5 kg*m^2,
        mu_v: 2e-6 N*m*s/rad}
gear: {ratio: 50, stiffness: 81 N*m/rad, damping: DAMPING N*m*s/rad}
load: {inertia: 1e-4 kg*m^2}
current_loop: {Kp: 3.6 V/A, Ki: 7500 V/(A*s), v_max: 24 V, delay: 0.05 ms}
position_loop: {Kp: 6 A/rad, Ki: 30 A/(rad*s), Kd: 0.08 A*s/rad, i_max: 5 A, delay: 0.2 ms}
"""


@pytest.mark.parametrize("damping", ["1e-6", "1e-8"])
def test_current_loop_notch_of_a_lightly_damped_gear(tmp_path, damping):
    # 1e-6 N*m*s/rad: two crossovers 0.03 rad/s apart near 900.9 rad/s, missed before; 1e-8:
    # found, but one at PM 184.06° (its phase is 4° past the -180° line: PM -175.94°).
    # Second method: a brute-force scan of L_i, uniform in 800..1000 rad/s (1e-4 rad/s apart).
    from cas_freq.model import ActuatorLoops

    path = tmp_path / "light_gear.yaml"
    path.write_text(LIGHT_GEAR.replace("DAMPING", damping))
    loaded = load_variant(path)
    result = analyze(loaded)
    loop = ActuatorLoops(loaded.params).current_loop
    expected, step = _dense_crossings(loop, 800.0, 1000.0)
    assert len(expected) == 2 and expected[1] - expected[0] < 0.04
    crossovers = [c for c in result.current_loop.gain_crossovers
                  if 800 < c.frequency_rad_s < 1000]
    np.testing.assert_allclose([c.frequency_rad_s for c in crossovers], expected, atol=step)
    for crossover in crossovers:
        angle = np.angle(loop(1j * crossover.frequency_rad_s), deg=True)
        assert -180 < crossover.phase_margin_deg <= 180
        assert crossover.phase_margin_deg == pytest.approx(
            180.0 - (-angle) % 360.0, abs=1e-6)  # 180° + angle, wrapped
