r"""Empirical frequency responses of sweep recordings and their comparison with the model.

The estimate is Welch's H1 (:func:`scipy.signal.csd`, :func:`scipy.signal.welch`):
:math:`H_1(\omega) = P_{xy}/P_{xx}` with x the input (the output command, or the current command)
and y the output, and the magnitude-squared coherence
:math:`\gamma^2 = |P_{xy}|^2/(P_{xx} P_{yy})` (:func:`scipy.signal.coherence`): Hann windows
of ``nperseg`` samples overlapping by half, by default as long as lets :data:`AVERAGES`
averages fit the recording. Only frequencies where the input has power are kept (its PSD at
least :data:`POWER_FLOOR` of its largest): a chirp's band, a stepped sine's dwell frequencies.
Noise on the output biases neither H1 nor its phase; it lowers the coherence, so comparisons
use the frequencies with :math:`\gamma^2 \ge` :data:`COHERENT`.

The model (:func:`model_responses`) is the package's own loops
(:class:`cas_freq.model.actuator_loops.ActuatorLoops`, exact delays): T (output angle / output
command, without the feed-forward, docs/model.md), :math:`T_i` (current / current command at
the current controller) and the current per output command,
:math:`i/\delta_{cmd} = N e^{-s\tau_p} T_i C_r/(1 + L_p)` (the position controller's output
:math:`C_r \theta_{cmd} - C_p \theta` delayed by :math:`\tau_p` is the current command).
"""

import dataclasses
import math

import numpy as np
from scipy import signal

from cas_freq.model.actuator_loops import ActuatorLoops
from cas_freq.simulation.sinedwell import crossing_bandwidth

#: Welch averages the default segment length aims at (50 % overlap: 2 n / nperseg - 1).
AVERAGES = 8
#: Input PSD, relative to its largest, below which a frequency is dropped.
POWER_FLOOR = 1e-3
#: Coherence from which a frequency counts in the comparisons.
COHERENT = 0.9
#: The half-power level [dB].
HALF_POWER_DB = -20.0 * math.log10(math.sqrt(2.0))


@dataclasses.dataclass(frozen=True, eq=False)
class Frf:
    """One empirical frequency response.

    Attributes
    ----------
    omega_rad_s : numpy.ndarray
        Frequencies kept [rad/s] (the input has power there), increasing.
    response : numpy.ndarray
        H1 estimate (complex) [output unit / input unit].
    coherence : numpy.ndarray
        Magnitude-squared coherence [-] (0..1).
    nperseg : int
        Samples per Welch segment.
    averages : int
        Segments averaged.
    """

    omega_rad_s: np.ndarray
    response: np.ndarray
    coherence: np.ndarray
    nperseg: int
    averages: int

    @property
    def coherent(self):
        """Mask of the frequencies with coherence >= :data:`COHERENT`."""
        return self.coherence >= COHERENT


def default_nperseg(n):
    """Segment length letting :data:`AVERAGES` half-overlapping Hann segments fit ``n``
    samples: 2 n / (AVERAGES + 1), at least 16."""
    length = max(16, int(2 * n // (AVERAGES + 1)))
    while length > 16 and 1 + (n - length) // (length - length // 2) < AVERAGES:
        length -= 1
    return length


def estimate(x, y, interval_s, nperseg=None):
    """H1 and coherence of output ``y`` against input ``x``, uniformly sampled.

    Parameters
    ----------
    x, y : numpy.ndarray
        Input and output samples.
    interval_s : float
        Sampling interval [s].
    nperseg : int, optional
        Samples per segment (default :func:`default_nperseg`).

    Returns
    -------
    Frf
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    nperseg = min(x.size, nperseg or default_nperseg(x.size))
    options = dict(fs=1.0 / interval_s, window="hann", nperseg=nperseg,
                   noverlap=nperseg // 2, detrend="constant")
    f, pxx = signal.welch(x, **options)
    _, pxy = signal.csd(x, y, **options)
    _, coherence = signal.coherence(x, y, **options)
    keep = (f > 0) & (pxx >= POWER_FLOOR * np.max(pxx[1:]))
    averages = 1 + (x.size - nperseg) // (nperseg - nperseg // 2)
    return Frf(2.0 * math.pi * f[keep], pxy[keep] / pxx[keep], np.clip(coherence[keep], 0, 1),
               nperseg, int(averages))


def model_responses(params, omega_rad_s):
    """The model's responses at ``omega_rad_s`` [rad/s] (exact delays).

    Parameters
    ----------
    params : ActuatorConfig or LoopParameters
        One variant.
    omega_rad_s : array_like
        Frequencies [rad/s].

    Returns
    -------
    dict of str to numpy.ndarray
        ``position``: T = delta/delta_cmd [-]; ``current``: i/delta_cmd [A/rad];
        ``current_loop``: T_i = i/i_cmd [-] (complex).
    """
    loops = ActuatorLoops(params)
    s = 1j * np.asarray(omega_rad_s, dtype=float)
    current_loop = loops.current_closed_loop(s)
    current = loops.current_response(s)
    return {"position": loops.closed_loop(s), "current": current, "current_loop": current_loop}


def db(values):
    """20 log10 |values| [dB]."""
    return 20.0 * np.log10(np.abs(values))


def unwrapped_deg(values, reference_deg=None):
    """Unwrapped phase [deg] of complex ``values``; shifted by whole turns so that its first
    value is within 180 deg of ``reference_deg`` if given."""
    phase = np.degrees(np.unwrap(np.angle(values)))
    if reference_deg is not None and phase.size:
        phase = phase - 360.0 * np.round((phase[0] - reference_deg) / 360.0)
    return phase


def compare(frf, model):
    """Data vs model where the coherence is >= :data:`COHERENT`.

    Parameters
    ----------
    frf : Frf
    model : numpy.ndarray
        The model's complex response at ``frf.omega_rad_s``.

    Returns
    -------
    dict
        ``coherent`` (count), ``rms_db`` and ``rms_deg`` (RMS of the magnitude difference [dB]
        and of the phase difference wrapped to ±180 [deg]; None without coherent
        frequencies), ``max_db`` and ``max_deg`` (largest absolute differences).
    """
    mask = frf.coherent
    count = int(np.count_nonzero(mask))
    if not count:
        return {"coherent": 0, "rms_db": None, "rms_deg": None, "max_db": None, "max_deg": None}
    ratio = frf.response[mask] / model[mask]
    magnitude, phase = db(ratio), np.degrees(np.angle(ratio))
    return {"coherent": count,
            "rms_db": float(np.sqrt(np.mean(magnitude**2))),
            "rms_deg": float(np.sqrt(np.mean(phase**2))),
            "max_db": float(np.max(np.abs(magnitude))),
            "max_deg": float(np.max(np.abs(phase)))}


def bandwidth(frf):
    """The empirical -3.01 dB bandwidth [rad/s] of a T estimate over its coherent frequencies
    (first downward crossing, interpolated in log w and dB), with why it is missing.

    Returns
    -------
    tuple of (float or None, str or None)
        The bandwidth, or None and ``"below -3 dB from the lowest frequency"`` /
        ``"not reached: above -3 dB up to <w> rad/s"`` / ``"no coherent frequencies"``.
    """
    mask = frf.coherent
    if not np.any(mask):
        return None, "no coherent frequencies"
    w, m = frf.omega_rad_s[mask], db(frf.response[mask])
    if m[0] < HALF_POWER_DB:
        return None, f"below -3 dB from the lowest coherent frequency, {w[0]:.4g} rad/s"
    value = crossing_bandwidth(w, m, HALF_POWER_DB)
    if value is None:
        return None, f"not reached: above -3 dB up to {w[-1]:.4g} rad/s"
    return value, None


def model_bandwidth(params, low_rad_s=1.0, high_rad_s=1e5, points=4000):
    """The model's -3.01 dB bandwidth of T [rad/s] on a fine log grid (None if not crossed)."""
    omega = np.geomspace(low_rad_s, high_rad_s, points)
    return crossing_bandwidth(omega, db(ActuatorLoops(params).closed_loop(1j * omega)),
                              HALF_POWER_DB)


def between(first, second):
    """RMS differences [dB], [deg] of ``second`` against ``first`` (two Frf of one signal) at
    ``first``'s coherent frequencies inside ``second``'s coherent band, ``second`` interpolated
    in log w (magnitude in dB, unwrapped phase); None where they share no frequencies."""
    a, b = first.coherent, second.coherent
    if not np.any(a) or np.count_nonzero(b) < 2:
        return {"shared": 0, "rms_db": None, "rms_deg": None}
    wb = np.log(second.omega_rad_s[b])
    wa = first.omega_rad_s[a]
    inside = (np.log(wa) >= wb[0]) & (np.log(wa) <= wb[-1])
    if not np.any(inside):
        return {"shared": 0, "rms_db": None, "rms_deg": None}
    x = np.log(wa[inside])
    magnitude = np.interp(x, wb, db(second.response[b])) - db(first.response[a][inside])
    phase_a = unwrapped_deg(first.response[a])[inside]
    phase_b = np.interp(x, wb, unwrapped_deg(second.response[b], phase_a[0]))
    phase = (phase_b - phase_a + 180.0) % 360.0 - 180.0
    return {"shared": int(x.size), "rms_db": float(np.sqrt(np.mean(magnitude**2))),
            "rms_deg": float(np.sqrt(np.mean(phase**2)))}


__all__ = ["AVERAGES", "COHERENT", "Frf", "POWER_FLOOR", "between", "bandwidth", "compare",
           "db", "default_nperseg", "estimate", "model_bandwidth", "model_responses",
           "unwrapped_deg"]
