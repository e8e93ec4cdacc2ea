r"""Stability margins of loops from their frequency responses, for many loops at once.

Definitions (docs/model.md):

- gain crossover: :math:`|L(j\omega_c)| = 1`; phase margin
  :math:`PM = 180° + \angle L(j\omega_c)` in (-180°, 180°]: the *continuous* phase
  (unwrapped from the low-frequency asymptote, -90° per integrator) locates the crossover on
  the phase curve, and the margin is taken modulo 360° (a loop whose phase starts on another
  branch, e.g. with a negative DC gain, has the same margins); delay margin: the smallest
  positive delay that puts L through -1 at :math:`\omega_c`,
  :math:`(PM[\mathrm{rad}] + 2\pi k) / \omega_c` with k = 0 for PM >= 0 and 1 below;
- phase crossover: :math:`L(j\omega_{180})` real and negative; gain margin
  :math:`GM = -20 \log_{10} |L(j\omega_{180})|` [dB]. Positive GM is an upper margin (gain may
  rise by that much), negative is a lower one (gain may fall by that much, as in the type-2
  position loop whose phase starts at -180°);
- sensitivity peak :math:`M_s = \max_\omega |1/(1+L)|`;
- symmetric (skew 0) disk margin :math:`\alpha = 1 / \max_\omega |S - 1/2|`, with gain margin
  :math:`(2+\alpha)/(2-\alpha)` and phase margin :math:`2 \arctan(\alpha/2)` (Seiler, Packard
  and Gahinet, "An introduction to disk margins", IEEE Control Systems 40(5), 2020).

Method. Every loop of the batch is sampled on one common grid; crossings are bracketed by sign
changes between samples and all refined together (:mod:`cas_freq.analysis.roots`). A crossing
pair cannot hide between two samples: *probes* are added where the response may have a
feature narrower than the grid, and the brackets are split at them:

- every local maximum of |L| on the grid below 0 dB and every local minimum above 0 dB is
  refined to the true extremum, which becomes a probe (a narrow peak that pokes above 0 dB, or
  a notch that dips below, between two samples; however low the samples beside it are, since a
  peak 30 times narrower than the grid spacing shows only its far flanks);
- every sample where the complex ln L = ln |L| + j phase has a corner (second differences
  above :data:`~cas_freq.analysis.probes.LOG_SHARP`) marks a feature narrower than the grid:
  a notch or peak of width W bends ln L at its flank samples by about W / distance, first
  order in W (ln |L| alone bends to second order: a notch 1e-5 wide shows in the phase). Its
  grid intervals are subdivided while the corners do not fade as a resolved curve's do;
- every other sample where ln |L| has a corner marks a feature the grid does not resolve whose
  extremum is not the sample's: typically a notch next to a peak (a lightly damped zero pair
  beside a pole pair, as a compliant gear puts into L_i), whose samples show the peak's flank
  while the notch dips below 0 dB between them. The two grid intervals beside it are
  subdivided, and again beside every sharp corner of the finer samples, until none is left;
  every sample taken is a probe;
- the caller may add probes of its own, e.g. where the inner loop L_i passes close to -1, so
  that T_i and hence L_p have a resonance narrower than the grid.

The probes are found in :mod:`cas_freq.analysis.probes`.

Between consecutive samples the magnitude and phase of a resonance are monotone, so every
crossing is bracketed. Phase crossovers: with exact delays a loop has dozens in range. Unless
all are asked for, only those whose interpolated gain margin is within :data:`CANDIDATE_DB` of
the best one of their kind are refined (the headline figures are the same).
"""

import dataclasses
import math

import numpy as np

import cas_freq.analysis.scan_kernel as scan_kernel
from cas_freq.analysis.probes import (
    Probes,
    extremum_probes,
    near_minus_one_probes,
)
from cas_freq.analysis.roots import refine_maxima, refine_roots
from cas_freq.core.jit import compiled_for

#: Phase crossings refined: those within this of the best grid estimate of their kind [dB].
CANDIDATE_DB = 1.0

#: Figures of one loop, in the order and with the names of the JSON of ``analyze``.
LOOP_FIGURES = (
    "crossover_rad_s", "phase_margin_deg", "delay_margin_s", "delay_margin_crossover_rad_s",
    "gain_margin_db",
    "phase_crossover_rad_s", "gain_margin_low_db", "phase_crossover_low_rad_s",
    "sensitivity_peak_db", "sensitivity_peak_rad_s", "disk_margin_alpha",
    "disk_margin_gain_db", "disk_margin_phase_deg", "gain_crossover_count",
)

#: Raw values :func:`loop_figures` adds for the grid split of the analysis (not figures).
EXTRA = ("_sensitivity_max", "_disk_distance_max", "_maximum_at_top")


@dataclasses.dataclass(frozen=True)
class GainCrossover:
    """One frequency where |L| = 1: its phase margin in (-180, 180] [deg], delay margin (> 0,
    0 at PM = 0) [s] and the continuous phase of L there [deg] (which locates it on the phase
    curve: ``phase_deg - phase_margin_deg`` is the -180° + k 360° line it is measured from)."""

    frequency_rad_s: float
    phase_margin_deg: float
    delay_margin_s: float
    phase_deg: float


@dataclasses.dataclass(frozen=True)
class PhaseCrossover:
    """One frequency where L is real and negative."""

    frequency_rad_s: float
    gain_margin_db: float


@dataclasses.dataclass(frozen=True)
class LoopMargins:
    """Every margin of one loop. A figure that does not exist (no crossover) is None.

    ``crossover_rad_s``/``phase_margin_deg`` are those of the gain crossover nearest the
    critical point, with the smallest absolute phase margin (as python-control's
    ``stability_margins``);
    ``delay_margin_s`` is the smallest over all gain crossovers, at
    ``delay_margin_crossover_rad_s`` (not necessarily the same crossover).
    ``gain_margin_db`` is the smallest upper gain margin (> 0 dB) and ``gain_margin_low_db`` the
    lower margin closest to 0 dB (< 0 dB), each with its phase crossover frequency.
    """

    crossover_rad_s: float | None
    phase_margin_deg: float | None
    delay_margin_s: float | None
    delay_margin_crossover_rad_s: float | None
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
    #: The same figures with every other loop closed (MIL-F-9490D's break-point margins), None
    #: where not computed; the outermost loop's are its own.
    loop_at_a_time: "LoopMargins | None" = None


def _group_min(n, runs, keys, payload):
    """Per run, the payload of the entry with the smallest key (NaN where a run has none)."""
    out_key = np.full(n, np.nan)
    out_payload = np.full(n, np.nan)
    if runs.size == 0:
        return out_key, out_payload
    order = np.lexsort((keys, runs))
    runs_sorted = runs[order]
    first = np.ones(runs_sorted.size, dtype=bool)
    first[1:] = runs_sorted[1:] != runs_sorted[:-1]
    chosen = order[first]
    out_key[runs[chosen]] = keys[chosen]
    out_payload[runs[chosen]] = payload[chosen]
    return out_key, out_payload


def phase_jumps(u):
    """Where ``numpy.unwrap`` of ``angle(u)`` along each row would add a turn: between grid
    points k and k + 1 when the wrapped angles differ by more than pi.

    Found without computing angles: the wrapped angle jumps by more than pi exactly when the
    point moves between the upper and lower half-planes the long way round, i.e. when the
    sign of ``Im(conj(u_k) u_(k+1))`` is that of the move (positive from upper to lower).

    Returns
    -------
    numpy.ndarray of bool
        Shape (n, m - 1).
    """
    re, im = u.real, u.imag
    upper = im >= 0
    cross = re[:, :-1] * im[:, 1:] - im[:, :-1] * re[:, 1:]
    down = upper[:, :-1] & ~upper[:, 1:]
    up = ~upper[:, :-1] & upper[:, 1:]
    return (down & (cross > 0)) | (up & (cross < 0))


def _first_true(mask):
    """(index of the first True per row, or the row length if none)."""
    has = mask.any(axis=1)
    return np.where(has, np.argmax(mask, axis=1), mask.shape[1])


def quarter_turn(values, quarters):
    """``values * 1j ** quarters`` for whole numbers of quarter turns (float array
    broadcasting against ``values``; NaN gives NaN), exactly: a quarter turn swaps the parts
    and negates one, so nothing is rounded and no CPU's complex multiply (with or without
    FMA) can move a point across an axis."""
    values = np.asarray(values, dtype=complex)
    q = np.broadcast_to(np.mod(quarters, 4.0), values.shape)
    re, im = values.real, values.imag
    turns = [q == 0.0, q == 1.0, q == 2.0, q == 3.0]
    out = np.empty(values.shape, dtype=complex)
    out.real = np.select(turns, [re, -im, -re, im], np.nan)
    out.imag = np.select(turns, [im, re, -im, -re], np.nan)
    return out


def first_turned_jumps(response, rows, quarters, width):
    """For each of ``rows``, the first k < width - 1 where ``response[row, :width]`` turned by
    ``quarters`` (:func:`quarter_turn`, one per row) jumps (:func:`phase_jumps`) between k and
    k + 1, else width - 1.

    Compiled (:mod:`cas_freq.analysis.scan_kernel`, stopping at each row's first jump) on
    large arrays (:func:`cas_freq.core.jit.compiled_for`); this numpy form is its reference.
    """
    quarters = np.asarray(quarters, dtype=float)
    if compiled_for(rows.size * width):
        out = np.empty(rows.size, dtype=np.int64)
        scan_kernel.first_turned_jumps(response, rows.astype(np.int64), quarters, width, out)
        return out
    return _first_true(phase_jumps(quarter_turn(response[rows, :width], quarters[:, None])))


def continuous_phase_at(response, omega, rows, columns):
    """Continuous phase [rad] of ``response[rows, columns]``, unwrapped from the first grid
    point on the branch set by the low-frequency asymptote (-90° per integrator).

    Rows whose turned response (``response * exp(-1j target)``, an exact
    :func:`quarter_turn`) does not jump before the column need one angle; the others are
    unwrapped like ``numpy.unwrap``.
    """
    slope = np.log(np.abs(response[:, 1]) / np.abs(response[:, 0])) / math.log(omega[1] / omega[0])
    quarters = np.round(-slope)  # exp(-1j target) = 1j ** quarters
    target = -quarters * math.pi / 2
    out = np.empty(rows.size)
    if rows.size == 0:
        return out
    width = int(columns.max()) + 1
    needed = np.unique(rows)
    first_jump = np.full(response.shape[0], width)
    if width > 1:
        first_jump[needed] = first_turned_jumps(response, needed, quarters[needed], width)
    simple = columns <= first_jump[rows]
    value = quarter_turn(response[rows, columns], quarters[rows])
    out[simple] = np.angle(value[simple]) + target[rows[simple]]
    hard = ~simple
    if hard.any():  # every such row unwrapped at once (row by row: the same numbers)
        unique, which = np.unique(rows[hard], return_inverse=True)
        turned = quarter_turn(response[unique, :width], quarters[unique][:, None])
        unwrapped = np.unwrap(np.angle(turned), axis=1)
        out[hard] = unwrapped[which.reshape(-1), columns[hard]] + target[rows[hard]]
    return out


def _sine(value):
    size = np.abs(value)
    return np.divide(value.imag, size, out=np.zeros(size.shape), where=size > 0)


def _gain_sign(value):
    return np.abs(value) > 1.0


def _phase_sign(value):
    return value.imag > 0


@dataclasses.dataclass(frozen=True, eq=False)
class _Samples:
    """The grid response plus the probes of each run, evaluated."""

    log_w: np.ndarray           # grid [log(rad/s)], (m,)
    response: np.ndarray        # (n, m)
    probes: Probes
    values: np.ndarray          # L at the probes
    interval: np.ndarray        # grid interval k of each probe (log_w[k] < x < log_w[k + 1])


def _samples(evaluate, log_w, response, probes):
    inside = (probes.log_w > log_w[0]) & (probes.log_w < log_w[-1])
    probes = Probes(probes.runs[inside], probes.log_w[inside])
    values = evaluate(probes.runs, np.exp(probes.log_w)) if probes.runs.size else \
        np.zeros(0, dtype=complex)
    interval = np.searchsorted(log_w, probes.log_w, side="right") - 1
    return _Samples(log_w, response, probes, values, interval)


def _brackets(samples, sign, positive=None):
    """Every sign change of ``sign(L)`` between consecutive samples of a run.

    Returns
    -------
    tuple
        (runs, grid interval k, x_lo, x_hi, L at x_lo, L at x_hi, whether the bracket lies in
        an interval split by probes).
    """
    response, log_w = samples.response, samples.log_w
    if positive is None:
        positive = sign(response)
    runs, k = np.nonzero(positive[:, :-1] != positive[:, 1:])
    probes = samples.probes
    if probes.runs.size == 0:
        return (runs, k, log_w[k], log_w[k + 1], response[runs, k], response[runs, k + 1],
                np.zeros(runs.size, dtype=bool))
    m = log_w.size
    split = np.unique(probes.runs * m + samples.interval)
    kept = ~np.isin(runs * m + k, split)
    runs, k = runs[kept], k[kept]
    # the split intervals: their two grid ends and the probes inside, sorted by frequency
    s_runs, s_k = split // m, split % m
    seq_runs = np.concatenate([s_runs, s_runs, probes.runs])
    seq_k = np.concatenate([s_k, s_k, samples.interval])
    seq_x = np.concatenate([log_w[s_k], log_w[s_k + 1], probes.log_w])
    seq_v = np.concatenate([response[s_runs, s_k], response[s_runs, s_k + 1], samples.values])
    order = np.lexsort((seq_x, seq_k, seq_runs))
    seq_runs, seq_k, seq_x, seq_v = seq_runs[order], seq_k[order], seq_x[order], seq_v[order]
    same = (seq_runs[1:] == seq_runs[:-1]) & (seq_k[1:] == seq_k[:-1])
    positive = sign(seq_v)
    change = np.flatnonzero(same & (positive[1:] != positive[:-1]) & (seq_x[1:] > seq_x[:-1]))
    return (
        np.concatenate([runs, seq_runs[change]]),
        np.concatenate([k, seq_k[change]]),
        np.concatenate([log_w[k], seq_x[change]]),
        np.concatenate([log_w[k + 1], seq_x[change + 1]]),
        np.concatenate([response[runs, k], seq_v[change]]),
        np.concatenate([response[runs, k + 1], seq_v[change + 1]]),
        np.concatenate([np.zeros(runs.size, dtype=bool), np.ones(change.size, dtype=bool)]),
    )


def magnitudes(response):
    """|L|^2, |1 + L|^2 and the disk-margin ratio |1 - L|^2 / |1 + L|^2 on the grid (n, m);
    compiled in one pass on large arrays (:mod:`cas_freq.analysis.scan_kernel`, the same
    operations), this numpy form its reference."""
    if compiled_for(response.size):
        squared, plus, disk = (np.empty(response.shape) for _ in range(3))
        scan_kernel.magnitudes(response, squared, plus, disk)
        return squared, plus, disk
    re, im = response.real, response.imag
    plus = (re + 1.0) ** 2 + im * im
    with np.errstate(divide="ignore", invalid="ignore"):
        return re * re + im * im, plus, ((re - 1.0) ** 2 + im * im) / plus


def _phase_candidates(n, brackets):
    """Which phase brackets are worth refining (see :data:`CANDIDATE_DB`)."""
    runs, _, _, _, v_lo, v_hi, _ = brackets
    keep = (v_lo.real < 0) | (v_hi.real < 0)
    im_lo, im_hi = v_lo.imag, v_hi.imag
    with np.errstate(divide="ignore", invalid="ignore"):
        share = im_lo / (im_lo - im_hi)
    low, high = np.abs(v_lo), np.abs(v_hi)
    with np.errstate(divide="ignore"):
        estimate = -20.0 * np.log10(low + share * (high - low))
    upper = keep & (estimate >= -CANDIDATE_DB)
    lower = keep & (estimate < CANDIDATE_DB)
    best_upper, _ = _group_min(n, runs[upper], estimate[upper], estimate[upper])
    best_lower, _ = _group_min(n, runs[lower], -estimate[lower], estimate[lower])
    return (upper & (estimate <= np.maximum(best_upper[runs], 0.0) + CANDIDATE_DB)) | (
        lower & (estimate >= np.minimum(-best_lower[runs], 0.0) - CANDIDATE_DB)
    )


def _phases_through(evaluate, samples, runs, k, x_end, phase_start):
    """Continuous phase [rad] at ``x_end`` of crossings inside split grid intervals, by
    unwrapping along a path from the interval's lower grid sample (run ``runs``, interval
    ``k``, continuous phase ``phase_start`` there) through 16 equal steps and every probe in
    between; all crossings in one evaluation."""
    log_w, probes = samples.log_w, samples.probes
    m = log_w.size
    # the probes of each crossing's interval below it
    key = probes.runs * m + samples.interval
    order = np.argsort(key, kind="stable")
    key, probe_x = key[order], probes.log_w[order]
    wanted = runs * m + k
    first = np.searchsorted(key, wanted, side="left")
    count = np.searchsorted(key, wanted, side="right") - first
    owner = np.repeat(np.arange(runs.size), count)
    position = np.arange(owner.size) - np.repeat(np.cumsum(count) - count, count)
    x = probe_x[np.repeat(first, count) + position]
    x_start = log_w[k]
    below = x < x_end[owner]
    steps = np.linspace(0.0, 1.0, 17)
    owner = np.concatenate([np.repeat(np.arange(runs.size), steps.size), owner[below]])
    x = np.concatenate([(x_start[:, None] + steps * (x_end - x_start)[:, None]).ravel(),
                        x[below]])
    order = np.lexsort((x, owner))
    owner, x = owner[order], x[order]
    values = evaluate(runs[owner], np.exp(x))
    start = np.ones(owner.size, dtype=bool)
    start[1:] = owner[1:] != owner[:-1]
    values[start] = samples.response[runs, k]  # the grid sample itself, as on the grid
    same = ~start[1:]
    turn = np.angle(values[1:][same] / values[:-1][same])
    return phase_start + np.bincount(owner[1:][same], weights=turn, minlength=runs.size)


def phase_and_delay_margins(phase, omega):
    """Phase margin [rad] in (-pi, pi] and delay margin [s] of gain crossovers.

    Parameters
    ----------
    phase : numpy.ndarray
        Phase of L at the crossovers [rad], on any branch (the continuous phase).
    omega : numpy.ndarray
        Crossover frequencies [rad/s].

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        PM = pi + phase modulo 2 pi, in (-pi, pi]; the delay margin, the smallest delay
        tau >= 0 that turns L(j omega) onto -1: PM / omega for PM >= 0, else
        (PM + 2 pi) / omega (a negative PM is a turn of 2 pi - |PM| away the way a delay turns).
    """
    pm = math.pi - np.mod(-phase, 2.0 * math.pi)  # pi + phase, in (-pi, pi]
    return pm, np.where(pm >= 0.0, pm, pm + 2.0 * math.pi) / omega


def loop_figures(evaluate, omega, response, ms_valid, probes=None, crossings=False,
                 inner=False):
    """Margins of a batch of loops.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(runs, omega) -> complex`` loop response of runs ``runs`` (int array) at
        frequencies ``omega`` [rad/s] (same shape).
    omega : numpy.ndarray
        Grid [rad/s], shape (m,).
    response : numpy.ndarray
        Loop response on the grid, shape (n, m).
    ms_valid : numpy.ndarray of bool
        Where the sensitivity peak and disk margin are meaningful (stable closed loop);
        NaN elsewhere.
    probes : Probes, optional
        Extra samples (e.g. :func:`near_minus_one_probes`), besides the extremum probes that
        are always added.
    crossings : bool
        Also return every gain crossover and every phase crossover (all refined).
    inner : bool
        The loop is an inner loop: also return ``"_inner_probes"``, the
        :func:`near_minus_one_probes` for the loops that contain it.

    Returns
    -------
    dict of str to numpy.ndarray
        :data:`LOOP_FIGURES` (and :data:`EXTRA`), each shape (n,); with ``crossings`` also
        ``"_gain_crossings"`` (runs, frequency, PM [deg], delay margin [s], continuous phase
        [deg]) and
        ``"_phase_crossings"`` (runs, frequency, GM [dB]), sorted by run and frequency, and
        ``"_interior_maxima"``: whether the maxima of |S| and of the disk distance are inside
        the grid, and whether each is at its top end (bool (n,) each; at an end they are
        bounds, not peaks, but at a sampled loop's Nyquist frequency).
    """
    n = response.shape[0]
    log_w = np.log(omega)
    im = response.imag
    out = {}
    squared, plus, disk = magnitudes(response)
    probes = extremum_probes(evaluate, omega, response, squared) + (probes or Probes.none())
    samples = _samples(evaluate, log_w, response, probes)

    # Gain crossovers (|L| = 1, all) and phase crossovers (Im L = 0 with Re L < 0), refined
    # together.
    gain_b = _brackets(samples, _gain_sign, squared > 1.0)
    phase_b = _brackets(samples, _phase_sign, im > 0)
    if not crossings:
        chosen = _phase_candidates(n, phase_b)
        phase_b = tuple(part[chosen] for part in phase_b)
    else:
        keep = (phase_b[4].real < 0) | (phase_b[5].real < 0)
        phase_b = tuple(part[keep] for part in phase_b)
    size_g = gain_b[0].size
    runs, k, x_lo, x_hi, v_lo, v_hi, split = (
        np.concatenate([g, p]) for g, p in zip(gain_b, phase_b, strict=True))
    gain = np.arange(runs.size) < size_g
    f_lo = np.where(gain, np.abs(v_lo) - 1.0, _sine(v_lo))
    f_hi = np.where(gain, np.abs(v_hi) - 1.0, _sine(v_hi))

    def crossing(x, j):
        value = evaluate(runs[j], np.exp(x))
        return np.where(gain[j], np.abs(value) - 1.0, _sine(value))

    w_all = refine_roots(crossing, x_lo, x_hi, f_lo, f_hi)
    value_all = evaluate(runs, w_all)

    w, value, g, gk, gsplit = w_all[gain], value_all[gain], runs[gain], k[gain], split[gain]
    above = np.minimum(np.searchsorted(omega, w), omega.size - 1)
    anchor = continuous_phase_at(response, omega, g, above)
    angle = anchor + np.angle(value / response[g, above])
    if gsplit.any():
        below = continuous_phase_at(response, omega, g[gsplit], gk[gsplit])
        angle[gsplit] = _phases_through(evaluate, samples, g[gsplit], gk[gsplit],
                                        np.log(w[gsplit]), below)
    pm_rad, dm = phase_and_delay_margins(angle, w)
    pm = np.degrees(pm_rad)
    # the headline: the crossover nearest the critical point, i.e. with the smallest |PM| (a
    # crossover at PM -177° has L near +1, the farthest from -1); of equal ones, the lower PM
    _, nearest = _group_min(n, g, np.abs(pm) + 1e-9 * np.sign(pm), np.arange(g.size))
    found = np.isfinite(nearest)
    chosen = nearest[found].astype(int)
    out["phase_margin_deg"], out["crossover_rad_s"] = np.full(n, np.nan), np.full(n, np.nan)
    out["phase_margin_deg"][found], out["crossover_rad_s"][found] = pm[chosen], w[chosen]
    out["delay_margin_s"], out["delay_margin_crossover_rad_s"] = _group_min(n, g, dm, w)
    out["gain_crossover_count"] = np.bincount(g, minlength=n).astype(float)
    if crossings:
        order = np.lexsort((w, g))
        out["_gain_crossings"] = (g[order], w[order], pm[order], dm[order],
                                  np.degrees(angle[order]))

    w, value, r = w_all[~gain], value_all[~gain], runs[~gain]
    negative = value.real < 0
    r, w, value = r[negative], w[negative], value[negative]
    gm = -20.0 * np.log10(np.abs(value))
    up = gm >= 0
    out["gain_margin_db"], out["phase_crossover_rad_s"] = _group_min(n, r[up], gm[up], w[up])
    low_key, out["phase_crossover_low_rad_s"] = _group_min(n, r[~up], -gm[~up], w[~up])
    out["gain_margin_low_db"] = -low_key
    if crossings:
        order = np.lexsort((w, r))
        out["_phase_crossings"] = (r[order], w[order], gm[order])

    # Sensitivity peak and disk margin, refined together.
    every = np.arange(n)
    if inner:
        out["_inner_probes"] = near_minus_one_probes(omega, response, distance2=plus)
    (s_w, s_value, s_inside), (d_w, distance, d_inside) = _maxima(
        evaluate, omega,
        [(every, -plus, lambda v, i: 1.0 / np.abs(1.0 + v), response),
         (every, disk, lambda v, i: _disk_distance(v), response)],
    )
    # for the grid split of the analysis: the raw maxima and whether they are at the top end
    out["_sensitivity_max"], out["_disk_distance_max"] = s_value, distance
    out["_maximum_at_top"] = (s_w == omega[-1]) | (d_w == omega[-1])
    alpha = 1.0 / distance
    with np.errstate(divide="ignore", invalid="ignore"):
        disk_gain = np.where(alpha < 2.0, 20.0 * np.log10((2.0 + alpha) / (2.0 - alpha)), np.nan)
    nan = np.where(ms_valid, 1.0, np.nan)
    out["sensitivity_peak_db"] = 20.0 * np.log10(s_value) * nan
    out["sensitivity_peak_rad_s"] = s_w * nan
    out["disk_margin_alpha"] = alpha * nan
    out["disk_margin_gain_db"] = disk_gain * nan
    out["disk_margin_phase_deg"] = np.degrees(2.0 * np.arctan(alpha / 2.0)) * nan
    names = (*LOOP_FIGURES, *EXTRA)
    if crossings:
        # a maximum at the top end of a sampled loop's grid (its Nyquist frequency, the end of
        # its periodic frequency axis) is the caller's to accept
        out["_interior_maxima"] = (s_inside, d_inside, s_w == omega[-1], d_w == omega[-1])
        names = (*names, "_gain_crossings", "_phase_crossings", "_interior_maxima")
    if inner:
        names = (*names, "_inner_probes")
    return {name: out[name] for name in names}


def _disk_distance(value):
    return np.abs(1.0 - value) / (2.0 * np.abs(1.0 + value))


def _maxima(evaluate, omega, tasks):
    """Largest value of each task's function on the grid, refined to a local maximum, all
    tasks together.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(runs, omega) -> complex`` response.
    omega : numpy.ndarray
        Grid [rad/s].
    tasks : list of (runs, key, transform, grid)
        ``runs`` (int array); ``key`` (len(runs), m), increasing with the function on the
        grid (its argmax is the function's); ``transform(response, i) -> float`` the function
        of the response at rows ``i`` of the task; ``grid`` the response on the grid, rows as
        ``runs``.

    Returns
    -------
    list of (frequency [rad/s], value, interior)
        Per task; a maximum on an end of the grid stays there (interior False).
    """
    log_w = np.log(omega)
    results, pieces = [], []
    for number, (runs, key, transform, grid) in enumerate(tasks):
        rows = np.arange(runs.size)
        k = np.argmax(key, axis=1)
        best = transform(grid[rows, k], rows)
        interior = (k > 0) & (k < omega.size - 1)
        results.append([omega[k].astype(float), best.astype(float), interior])
        inner = np.flatnonzero(interior)
        kk = k[inner]
        triple = [transform(grid[inner, kk + shift], inner) for shift in (-1, 0, 1)]
        pieces.append((np.full(inner.size, number), inner, runs[inner], kk, triple))
    task = np.concatenate([piece[0] for piece in pieces])
    row = np.concatenate([piece[1] for piece in pieces])
    run = np.concatenate([piece[2] for piece in pieces])
    k = np.concatenate([piece[3] for piece in pieces])
    f = [np.concatenate([piece[4][i] for piece in pieces]) for i in range(3)]

    def func(x, j):
        value = evaluate(run[j], np.exp(x))
        out = np.empty(j.size)
        for number, (_, _, transform, _) in enumerate(tasks):
            mine = task[j] == number
            out[mine] = transform(value[mine], row[j][mine])
        return out

    # the grid point k is the middle of the starting triple (the grid is not uniform in log
    # where it is densified, so the triple's middle is not the interval's centre)
    w, v = refine_maxima(func, log_w[k - 1], log_w[k + 1], f[0], f[1], f[2], log_w[k])
    for number, result in enumerate(results):
        mine = task == number
        rows = row[mine]
        better = v[mine] >= result[1][rows]
        result[0][rows] = np.where(better, w[mine], result[0][rows])
        result[1][rows] = np.where(better, v[mine], result[1][rows])
    return [tuple(result) for result in results]


def _none(value):
    return None if not np.isfinite(value) else float(value)


def margins_of_run(figures, run=0):
    """The :class:`LoopMargins` of one run from :func:`loop_figures` (with ``crossings``)."""
    g_runs, g_w, g_pm, g_dm, g_phase = figures["_gain_crossings"]
    p_runs, p_w, p_gm = figures["_phase_crossings"]
    mine, theirs = g_runs == run, p_runs == run
    values = {name: _none(figures[name][run]) for name in LOOP_FIGURES
              if name != "gain_crossover_count"}
    return LoopMargins(
        **values,
        gain_crossovers=tuple(
            GainCrossover(float(w), float(pm), float(dm), float(phase)) for w, pm, dm, phase in
            zip(g_w[mine], g_pm[mine], g_dm[mine], g_phase[mine], strict=True)),
        phase_crossovers=tuple(PhaseCrossover(float(w), float(gm)) for w, gm in
                               zip(p_w[theirs], p_gm[theirs], strict=True)),
    )


def loop_margins(loop, omega, stable=True):
    """All margins of one loop given as a function of s.

    Parameters
    ----------
    loop : callable
        ``loop(s) -> complex`` frequency response, vectorised over ``s`` [rad/s]; broken where
        the margins are wanted.
    omega : numpy.ndarray
        Analysis grid [rad/s] (see :func:`~cas_freq.analysis.frequency.frequency_grid`). Only
        crossings inside it are found.
    stable : bool
        Whether the closed loop is stable (otherwise Ms and the disk margin are None).

    Returns
    -------
    LoopMargins
    """
    response = np.asarray(loop(1j * omega), dtype=complex)[None, :]
    figures = loop_figures(lambda runs, w: loop(1j * w), omega, response,
                           np.array([stable]), crossings=True)
    return margins_of_run(figures)
