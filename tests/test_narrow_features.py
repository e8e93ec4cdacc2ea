"""Crossings made by notches and peaks far narrower than the grid spacing: every |L| = 1 and
every -180° crossing is found, down to features 1e-5 of their frequency in width.

Such a feature moves ln |L| or the phase at the grid samples beside it only by about its width
over the distance to them (first order): the engine brackets those corners of the complex ln L
and subdivides until the feature is resolved (cas_freq.analysis.probes). The reference is
python-control's polynomial method (stability_margins with returnall, the roots of
|num|^2 - |den|^2 and of Im(num conj(den))): an independent second method.
"""

import math

import control
import numpy as np
import pytest

import cas_freq as cf
from cas_freq.analysis.frequency import frequency_grid

s = control.tf("s")
WIDTHS = [1e-3, 1e-4, 1e-5]


def _between_grid_points(w):
    """The geometric middle of the grid interval (200 per decade) holding w [rad/s]: the worst
    place for a feature, as far from both samples as it can be."""
    omega = frequency_grid(1e-2, 1e6)
    k = np.searchsorted(omega, w)
    return math.sqrt(omega[k - 1] * omega[k])


def _reference(loop):
    gm, pm, _, wpc, wgc, _ = control.stability_margins(loop, returnall=True)
    return np.sort(np.asarray(wgc)), np.sort(np.asarray(wpc)[np.asarray(wpc) > 0])


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("place", [909.84, 3000.0])
def test_every_crossing_of_a_notch_under_0_db(width, place):
    # Before: widths 1e-4 and 1e-5 were missed (only the crossover near 9,800 rad/s listed).
    # L = 1e4 / (s (s/5e4 + 1)) times a notch of pole damping `width` and zero damping
    # width/100 at w0: |L| ~ 11 there dips to 0.11 over a band ~2 width w0 wide, two crossings
    # between two grid samples 1.15 % apart.
    w0 = _between_grid_points(place)
    notch = (s**2 + 2 * width / 100 * w0 * s + w0**2) / (s**2 + 2 * width * w0 * s + w0**2)
    loop = 1e4 / (s * (s / 5e4 + 1)) * notch
    wgc, _ = _reference(loop)
    assert wgc.size == 3  # the notch's two and the crossover
    m = cf.loop_margins(loop, omega_range=(1e-2, 1e6))
    # both refine to ~1e-12; python-control's roots of a degree-10 polynomial whose two roots
    # are 2e-5 apart hold ~1e-10 relative: 1e-8 is ample
    np.testing.assert_allclose([c.frequency_rad_s for c in m.gain_crossovers], wgc, rtol=1e-8)


@pytest.mark.parametrize("width", WIDTHS)
def test_every_phase_crossover_of_a_narrow_dip_to_minus_180(width):
    # A lightly damped pole pair at w0 with a zero pair 3 widths above it: the phase dips by
    # nearly 180° between them and crosses -180° twice, over ~4 widths of w0; |L| peaks at ~3
    # times its neighbours' level there. Before: missed at width 1e-5.
    w0 = _between_grid_points(3000.0)
    wz = w0 * (1 + 3 * width)
    pair = (w0 / wz) ** 2 * (s**2 + 2 * width * wz * s + wz**2) / (
        s**2 + 2 * width * w0 * s + w0**2)
    loop = 30 / (s * (s / 50 + 1)) * pair
    _, wpc = _reference(loop)
    assert wpc.size == 2
    m = cf.loop_margins(loop, omega_range=(1e-2, 1e6))
    np.testing.assert_allclose([c.frequency_rad_s for c in m.phase_crossovers], wpc, rtol=1e-8)
