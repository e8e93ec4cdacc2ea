r"""Closed-loop figures of T(s) = delta/delta_cmd (MODEL.md, "Definitions of the figures").

- bandwidth :math:`\omega_{BW}`: the lowest frequency where :math:`|T(j\omega)|` falls
  :math:`20 \log_{10} \sqrt 2 = 3.0103` dB below :math:`|T(0)|`;
- resonance peak: :math:`\max_\omega |T(j\omega)| / |T(0)|` [dB] and where it occurs;
- the lowest frequency where the (continuous) phase of T reaches -90°.
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.frequency import refine_maximum, refine_roots
from cas_freq.formulas import HALF_POWER


@dataclasses.dataclass(frozen=True)
class ClosedLoopFigures:
    """Bandwidth and shape of the closed loop; None where the figure does not exist in range.

    Attributes
    ----------
    dc_gain_db : float
        |T(0)| [dB], taken 1000 times below the grid's lowest frequency.
    bandwidth_rad_s : float or None
        -3 dB bandwidth [rad/s]; None if |T| stays above the line up to the top of the range.
    peak_db : float
        Largest |T|/|T(0)| [dB]; 0 dB (or a hair above) when there is no resonance.
    peak_rad_s : float or None
        Where the peak is [rad/s]; None when |T| has no interior maximum (no resonance).
    phase_90_rad_s : float or None
        Lowest frequency where the phase of T reaches -90° [rad/s].
    """

    dc_gain_db: float
    bandwidth_rad_s: float | None
    peak_db: float
    peak_rad_s: float | None
    phase_90_rad_s: float | None


def _first(roots):
    return float(roots[0]) if len(roots) else None


def closed_loop_figures(closed_loop, omega):
    """Figures of a closed-loop frequency response.

    Parameters
    ----------
    closed_loop : callable
        ``closed_loop(s) -> complex``, vectorised over ``s`` [rad/s].
    omega : numpy.ndarray
        Analysis grid [rad/s].

    Returns
    -------
    ClosedLoopFigures
    """
    dc = abs(complex(closed_loop(1j * omega[0] * 1e-3)))
    response = closed_loop(1j * omega)
    magnitude = np.abs(response) / dc

    # Bandwidth: first downward crossing of the half-power line.
    below = np.nonzero(magnitude < HALF_POWER)[0]
    bandwidth = None
    if len(below) and below[0] > 0:
        k = below[0]
        bandwidth = _first(
            refine_roots(
                lambda w: abs(closed_loop(1j * w)) / dc - HALF_POWER,
                omega[k - 1 : k + 1],
                magnitude[k - 1 : k + 1] - HALF_POWER,
            )
        )

    peak_w, peak, interior = refine_maximum(
        lambda w: abs(closed_loop(1j * w)) / dc, omega, magnitude
    )

    # Phase: unwrap along the grid from its value near DC, then refine the first -90° crossing.
    phase = np.unwrap(np.angle(response))
    shifted = phase + math.pi / 2
    crossing = np.nonzero((shifted[:-1] > 0) & (shifted[1:] <= 0))[0]
    phase_90 = None
    if len(crossing):
        k = crossing[0]
        anchor = phase[k]

        def phase_error(w):
            value = closed_loop(1j * w)
            return anchor + np.angle(value * np.exp(-1j * anchor)) + math.pi / 2

        phase_90 = _first(refine_roots(phase_error, omega[k : k + 2], shifted[k : k + 2]))

    return ClosedLoopFigures(
        dc_gain_db=20.0 * math.log10(dc),
        bandwidth_rad_s=bandwidth,
        peak_db=20.0 * math.log10(peak),
        peak_rad_s=peak_w if interior else None,
        phase_90_rad_s=phase_90,
    )
