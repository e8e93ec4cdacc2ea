r"""Stability margins of a loop from its frequency response (exact delays allowed).

Definitions (MODEL.md):

- gain crossover: :math:`|L(j\omega_c)| = 1`; phase margin
  :math:`PM = 180° + \angle L(j\omega_c)` with the *continuous* phase (unwrapped from the
  low-frequency asymptote, -90° per integrator), so a crossover past a whole turn of delay
  phase shows PM < -180° instead of a reassuring wrapped value; delay margin
  :math:`PM[\mathrm{rad}] / \omega_c` (negative when PM is);
- phase crossover: :math:`L(j\omega_{180})` real and negative; gain margin
  :math:`GM = -20 \log_{10} |L(j\omega_{180})|` [dB]. Positive GM is an upper margin (gain may
  rise by that much), negative is a lower one (gain may fall by that much, as in the type-2
  position loop whose phase starts at -180°);
- sensitivity peak :math:`M_s = \max_\omega |1/(1+L)|`;
- symmetric (skew 0) disk margin :math:`\alpha = 1 / \max_\omega |S - 1/2|`, with gain margin
  :math:`(2+\alpha)/(2-\alpha)` and phase margin :math:`2 \arctan(\alpha/2)` (Seiler, Packard
  and Gahinet, "An introduction to disk margins", IEEE Control Systems 40(5), 2020).
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.frequency import continuous_phase, refine_maximum, refine_roots


@dataclasses.dataclass(frozen=True)
class GainCrossover:
    """One frequency where |L| = 1."""

    frequency_rad_s: float
    phase_margin_deg: float
    delay_margin_s: float


@dataclasses.dataclass(frozen=True)
class PhaseCrossover:
    """One frequency where L is real and negative."""

    frequency_rad_s: float
    gain_margin_db: float


@dataclasses.dataclass(frozen=True)
class LoopMargins:
    """Every margin of one loop. A figure that does not exist (no crossover) is None.

    ``crossover_rad_s``/``phase_margin_deg`` are those of the gain crossover with the smallest
    phase margin; ``delay_margin_s`` is the smallest over all gain crossovers.
    ``gain_margin_db`` is the smallest upper gain margin (> 0 dB) and ``gain_margin_low_db`` the
    lower margin closest to 0 dB (< 0 dB), each with its phase crossover frequency.
    """

    crossover_rad_s: float | None
    phase_margin_deg: float | None
    delay_margin_s: float | None
    gain_margin_db: float | None
    phase_crossover_rad_s: float | None
    gain_margin_low_db: float | None
    phase_crossover_low_rad_s: float | None
    sensitivity_peak_db: float | None
    sensitivity_peak_rad_s: float | None
    disk_margin_alpha: float | None
    disk_margin_gain_db: float | None
    disk_margin_phase_deg: float | None
    gain_crossovers: tuple[GainCrossover, ...]
    phase_crossovers: tuple[PhaseCrossover, ...]


def _gain_crossovers(loop, omega, response):
    def magnitude_minus_one(w):
        return abs(loop(1j * w)) - 1.0

    phase = continuous_phase(response, omega)
    found = []
    for w in refine_roots(magnitude_minus_one, omega, np.abs(response) - 1.0):
        k = min(int(np.searchsorted(omega, w)), len(omega) - 1)  # nearest grid point above
        value = loop(1j * w)
        # continuous phase at w: the grid's phase plus the small step from the grid point
        angle = phase[k] + np.angle(value / response[k])
        pm = math.degrees(math.pi + angle)
        found.append(GainCrossover(float(w), pm, math.radians(pm) / w))
    return tuple(found)


def _phase_crossovers(loop, omega, response):
    def sine_of_phase(w):  # sin(angle L); 0 where L = 0 (no phase there, and not negative)
        value = loop(1j * w)
        return value.imag / abs(value) if value != 0 else 0.0

    found = []
    magnitude = np.abs(response)
    sines = np.divide(response.imag, magnitude, out=np.zeros(len(magnitude)), where=magnitude > 0)
    for w in refine_roots(sine_of_phase, omega, sines):
        value = loop(1j * w)
        if value.real < 0:
            found.append(PhaseCrossover(float(w), -20.0 * math.log10(abs(value))))
    return tuple(found)


def _disk_margin(alpha):
    """(gain margin [dB] or None when unbounded, phase margin [deg]) of a skew-0 disk."""
    phase = math.degrees(2.0 * math.atan(alpha / 2.0))
    if alpha >= 2.0:
        return None, phase
    return 20.0 * math.log10((2.0 + alpha) / (2.0 - alpha)), phase


def without_closed_loop_figures(margins):
    """The same margins with the sensitivity peak and disk margin removed (set to None).

    Both describe robustness of a stable nominal closed loop; for an unstable one they are
    numbers without meaning.
    """
    return dataclasses.replace(
        margins,
        sensitivity_peak_db=None,
        sensitivity_peak_rad_s=None,
        disk_margin_alpha=None,
        disk_margin_gain_db=None,
        disk_margin_phase_deg=None,
    )


def loop_margins(loop, omega):
    """All margins of a loop transfer function.

    Parameters
    ----------
    loop : callable
        ``loop(s) -> complex`` frequency response, vectorised over ``s`` [rad/s]; broken where
        the margins are wanted.
    omega : numpy.ndarray
        Analysis grid [rad/s] (see :func:`~cas_freq.analysis.frequency.frequency_grid`). Only
        crossings inside it are found.

    Returns
    -------
    LoopMargins
    """
    response = loop(1j * omega)
    gains = _gain_crossovers(loop, omega, response)
    phases = _phase_crossovers(loop, omega, response)

    worst_pm = min(gains, key=lambda c: c.phase_margin_deg, default=None)
    upper = [c for c in phases if c.gain_margin_db >= 0]
    lower = [c for c in phases if c.gain_margin_db < 0]
    gm = min(upper, key=lambda c: c.gain_margin_db, default=None)
    gm_low = max(lower, key=lambda c: c.gain_margin_db, default=None)

    def sensitivity(w):
        return 1.0 / abs(1.0 + loop(1j * w))

    def disk_distance(w):  # |S - 1/2| = |1 - L| / (2 |1 + L|)
        value = loop(1j * w)
        return abs(1.0 - value) / (2.0 * abs(1.0 + value))

    ms_w, ms, _ = refine_maximum(sensitivity, omega, 1.0 / np.abs(1.0 + response))
    _, dd, _ = refine_maximum(
        disk_distance, omega, np.abs(1.0 - response) / (2.0 * np.abs(1.0 + response))
    )
    alpha = 1.0 / dd
    disk_gain, disk_phase = _disk_margin(alpha)
    return LoopMargins(
        crossover_rad_s=worst_pm.frequency_rad_s if worst_pm else None,
        phase_margin_deg=worst_pm.phase_margin_deg if worst_pm else None,
        delay_margin_s=min((c.delay_margin_s for c in gains), default=None),
        gain_margin_db=gm.gain_margin_db if gm else None,
        phase_crossover_rad_s=gm.frequency_rad_s if gm else None,
        gain_margin_low_db=gm_low.gain_margin_db if gm_low else None,
        phase_crossover_low_rad_s=gm_low.frequency_rad_s if gm_low else None,
        sensitivity_peak_db=20.0 * math.log10(ms),
        sensitivity_peak_rad_s=ms_w,
        disk_margin_alpha=alpha,
        disk_margin_gain_db=disk_gain,
        disk_margin_phase_deg=disk_phase,
        gain_crossovers=gains,
        phase_crossovers=phases,
    )
