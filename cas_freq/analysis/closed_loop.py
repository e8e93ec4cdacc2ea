r"""Closed-loop figures of T(s) = delta/delta_cmd, for many loops at once (docs/model.md).

- bandwidth :math:`\omega_{BW}`: the lowest frequency where :math:`|T(j\omega)|` falls
  :math:`20 \log_{10} \sqrt 2 = 3.0103` dB below :math:`|T(0)|`;
- resonance peak: :math:`\max_\omega |T(j\omega)| / |T(0)|` [dB] and where it occurs, at an
  interior maximum of |T| only (none when |T| is largest at an end of the range: that value
  is no peak but a bound, e.g. |T(0)| itself);
- the lowest frequency where the (continuous) phase of T reaches -90°.

Crossings are bracketed on the grid and refined together (:mod:`cas_freq.analysis.roots`).
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.margins import _first_true, _maxima, phase_jumps
from cas_freq.analysis.roots import refine_roots
from cas_freq.analysis.scan_kernel import first_fall_below_90 as kernel
from cas_freq.core.formulas import HALF_POWER
from cas_freq.core.jit import compiled_for

#: Closed-loop figures, as in the JSON of ``analyze``.
CLOSED_LOOP_FIGURES = ("dc_gain_db", "bandwidth_rad_s", "peak_db", "peak_rad_s", "phase_90_rad_s")


@dataclasses.dataclass(frozen=True)
class ClosedLoopFigures:
    """Bandwidth and shape of the closed loop; None where the figure does not exist in range.

    Attributes
    ----------
    dc_gain_db : float
        |T(0)| [dB], taken 1000 times below the grid's lowest frequency.
    bandwidth_rad_s : float or None
        -3 dB bandwidth [rad/s]; None if |T| stays above the line up to the top of the range.
    peak_db : float or None
        Largest |T|/|T(0)| at an interior maximum of |T| [dB]; None when there is none (no
        resonance: |T| is largest at an end of the range).
    peak_rad_s : float or None
        Where the peak is [rad/s]; None with ``peak_db``.
    phase_90_rad_s : float or None
        Lowest frequency where the phase of T reaches -90° [rad/s].
    """

    dc_gain_db: float
    bandwidth_rad_s: float | None
    peak_db: float | None
    peak_rad_s: float | None
    phase_90_rad_s: float | None


def closed_loop_figures(evaluate, omega, response, valid):
    """Closed-loop figures of a batch (module notes), NaN where not
    ``valid`` (closed loop not stable).

    Parameters
    ----------
    evaluate : callable
        ``evaluate(runs, omega) -> complex`` T of runs ``runs`` at ``omega`` [rad/s].
    omega : numpy.ndarray
        Grid [rad/s], shape (m,).
    response : numpy.ndarray
        T on the grid, shape (n, m).
    valid : numpy.ndarray of bool
        Runs whose closed loop is stable.

    Returns
    -------
    dict of str to numpy.ndarray
        :data:`CLOSED_LOOP_FIGURES`, each shape (n,).
    """
    n = response.shape[0]
    out = {name: np.full(n, np.nan) for name in CLOSED_LOOP_FIGURES}
    runs = np.flatnonzero(valid)
    if runs.size == 0:
        out["_peak"] = np.full(n, np.nan)
        out["_maximum_at_top"] = np.zeros(n, dtype=bool)
        return out
    if runs.size < n:
        response = response[runs]
    log_w = np.log(omega)
    dc = np.abs(evaluate(runs, np.full(runs.size, omega[0] * 1e-3)))
    magnitude = np.abs(response) / dc[:, None]
    out["dc_gain_db"][runs] = 20.0 * np.log10(dc)

    below = magnitude < HALF_POWER
    k = np.argmax(below, axis=1)
    has = below[np.arange(runs.size), k] & (k > 0)
    idx = np.flatnonzero(has)
    r, kk, d = runs[idx], k[idx], dc[idx]
    bandwidth = refine_roots(
        lambda x, j: np.abs(evaluate(r[j], np.exp(x))) / d[j] - HALF_POWER,
        log_w[kk - 1], log_w[kk],
        magnitude[idx, kk - 1] - HALF_POWER, magnitude[idx, kk] - HALF_POWER,
    )
    out["bandwidth_rad_s"][r] = bandwidth

    ((peak_w, peak, interior),) = _maxima(
        evaluate, omega, [(runs, magnitude, lambda v, i: np.abs(v) / dc[i], response)]
    )
    out["peak_db"][runs] = np.where(interior, 20.0 * np.log10(peak), np.nan)
    out["_peak"] = np.full(n, np.nan)
    out["_peak"][runs] = peak
    out["_maximum_at_top"] = np.zeros(n, dtype=bool)
    out["_maximum_at_top"][runs] = peak_w == omega[-1]
    out["peak_rad_s"][runs] = np.where(interior, peak_w, np.nan)

    idx, kk, anchor, shifted_lo, shifted_hi = _first_phase_90(response)
    r = runs[idx]

    def phase_error(x, j):
        value = evaluate(r[j], np.exp(x))
        return anchor[j] + np.angle(value * np.exp(-1j * anchor[j])) + math.pi / 2

    out["phase_90_rad_s"][r] = refine_roots(
        phase_error, log_w[kk], log_w[kk + 1], shifted_lo, shifted_hi
    )
    return out


def _first_phase_90(response):
    """Rows with a first downward crossing of -90 deg by the grid phase (unwrapped from the
    lowest frequency, from the lowest frequency), its grid index k, the
    phase at k, and phase + 90 deg at k and k + 1.

    Until the wrapped angle first jumps (:func:`phase_jumps`) it is the unwrapped phase, and
    it is above -90 deg exactly where ``Re T > 0`` or ``Im T >= 0``: no angle is computed
    except at the crossing. Rows with a jump before their crossing are unwrapped in full.
    """
    n, m = response.shape
    crossing, jump = first_fall_below_90(response)
    simple = (crossing < m - 1) & (jump > crossing)
    hard = np.flatnonzero(jump <= crossing)
    rows = np.flatnonzero(simple)
    k = crossing[rows]
    phase_k = np.angle(response[rows, k])
    phase_next = np.angle(response[rows, k + 1])
    found = [(rows, k, phase_k, phase_k + math.pi / 2, phase_next + math.pi / 2)]
    if hard.size:
        phase = np.unwrap(np.angle(response[hard]), axis=1)
        shifted = phase + math.pi / 2
        cross = (shifted[:, :-1] > 0) & (shifted[:, 1:] <= 0)
        first = np.argmax(cross, axis=1)
        hit = np.flatnonzero(cross[np.arange(hard.size), first])
        kk = first[hit]
        found.append((hard[hit], kk, phase[hit, kk], shifted[hit, kk], shifted[hit, kk + 1]))
    parts = [np.concatenate([f[i] for f in found]) for i in range(5)]
    order = np.argsort(parts[0], kind="stable")
    return tuple(part[order] for part in parts)


def first_fall_below_90(response):
    """Per row (n, m): the first k where the phase falls below -90 deg between k and k + 1
    while unwrapped from the first point (the point leaves ``Re > 0 or Im >= 0``), m - 1 if
    it never does; and the first phase jump (:func:`phase_jumps`), m - 1 if none. A jump
    after the crossing is reported as m - 1 on the compiled path, which stops at the crossing
    (:mod:`cas_freq.analysis.scan_kernel`, on large arrays: :func:`cas_freq.core.jit.compiled_for`);
    :func:`_first_phase_90` only asks whether the jump comes after the crossing.
    """
    if compiled_for(response.size):
        crossing = np.empty(response.shape[0], dtype=np.int64)
        jump = np.empty(response.shape[0], dtype=np.int64)
        kernel(response, crossing, jump)
        return crossing, jump
    above = (response.real > 0) | (response.imag >= 0)
    return _first_true(above[:, :-1] & ~above[:, 1:]), _first_true(phase_jumps(response))


def figures_of_run(figures, run=0):
    """The :class:`ClosedLoopFigures` of one run of :func:`closed_loop_figures` (None if the
    run's closed loop is not stable)."""
    if not np.isfinite(figures["dc_gain_db"][run]):
        return None
    values = {name: figures[name][run] for name in CLOSED_LOOP_FIGURES}
    return ClosedLoopFigures(**{name: (None if not np.isfinite(v) else float(v))
                                for name, v in values.items()})


def closed_loop_summary(closed_loop, omega):
    """Figures of one closed loop given as a function of s.

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
    response = np.asarray(closed_loop(1j * omega), dtype=complex)[None, :]
    figures = closed_loop_figures(lambda runs, w: closed_loop(1j * w), omega, response,
                                  np.array([True]))
    return figures_of_run(figures)
