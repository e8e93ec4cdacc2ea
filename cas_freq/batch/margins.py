r"""Margins, sensitivity peaks and closed-loop figures of many variants at once.

The definitions are those of :mod:`cas_freq.analysis.margins` and
:mod:`cas_freq.analysis.closed_loop` (MODEL.md); this module finds the same figures for a
batch: crossings by sign changes on the common grid, all refined together
(:mod:`cas_freq.batch.roots`). Figures that do not exist are NaN.

Phase crossovers: with exact delays a loop has dozens in range. Only the headline figures are
kept (smallest upper gain margin, lower margin closest to 0 dB), so only the crossings whose
grid-interpolated gain margin is within :data:`CANDIDATE_DB` of the best one of its kind are
refined; the interpolation error on a 200-per-decade grid is far below that.
"""

import math

import numpy as np

from cas_freq.batch.roots import refine_maxima, refine_roots
from cas_freq.formulas import HALF_POWER

#: Phase crossings refined: those within this of the best grid estimate of their kind [dB].
CANDIDATE_DB = 1.0

#: Figures of one loop, in the order and with the names of ``to_dict(analysis)``.
LOOP_FIGURES = (
    "crossover_rad_s", "phase_margin_deg", "delay_margin_s", "gain_margin_db",
    "phase_crossover_rad_s", "gain_margin_low_db", "phase_crossover_low_rad_s",
    "sensitivity_peak_db", "sensitivity_peak_rad_s", "disk_margin_alpha",
    "disk_margin_gain_db", "disk_margin_phase_deg", "gain_crossover_count",
)

#: Raw values :func:`loop_figures` adds for the grid split (not figures).
EXTRA = ("_sensitivity_max", "_disk_distance_max", "_maximum_at_top")

#: Closed-loop figures, as in ``to_dict(analysis)["closed_loop"]``.
CLOSED_LOOP_FIGURES = ("dc_gain_db", "bandwidth_rad_s", "peak_db", "peak_rad_s", "phase_90_rad_s")


def _brackets(values):
    """(run, k) of every sign change between grid points k and k + 1 (0 counts as negative:
    an exact zero on the grid is a measure-zero event)."""
    positive = values > 0
    return np.nonzero(positive[:, :-1] != positive[:, 1:])


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


def continuous_phase_at(response, omega, rows, columns):
    """Continuous phase [rad] of ``response[rows, columns]``, unwrapped from the first grid
    point on the branch set by the low-frequency asymptote.

    Row-wise :func:`cas_freq.analysis.frequency.continuous_phase`, evaluated only where asked:
    rows whose turned response (``response * exp(-1j target)``) does not jump before the
    column need one angle; the others are unwrapped like ``numpy.unwrap``.
    """
    slope = np.log(np.abs(response[:, 1]) / np.abs(response[:, 0])) / math.log(omega[1] / omega[0])
    target = -np.round(-slope) * math.pi / 2
    out = np.empty(rows.size)
    if rows.size == 0:
        return out
    width = int(columns.max()) + 1
    needed = np.unique(rows)
    turned = response[needed, :width] * np.exp(-1j * target[needed])[:, None]
    first_jump = np.full(response.shape[0], width)
    first_jump[needed] = _first_true(phase_jumps(turned)) if width > 1 else width
    simple = columns <= first_jump[rows]
    value = response[rows, columns] * np.exp(-1j * target[rows])
    out[simple] = np.angle(value[simple]) + target[rows[simple]]
    for row in np.unique(rows[~simple]):
        unwrapped = np.unwrap(np.angle(response[row, :width] * np.exp(-1j * target[row])))
        mine = (rows == row) & ~simple
        out[mine] = unwrapped[columns[mine]] + target[row]
    return out


def _sine(value):
    size = np.abs(value)
    return np.divide(value.imag, size, out=np.zeros(size.shape), where=size > 0)


def _phase_candidates(n, response, squared):
    """(run, k) of the phase crossings worth refining (see :data:`CANDIDATE_DB`)."""
    runs, k = _brackets(response.imag)
    real_lo, real_hi = response.real[runs, k], response.real[runs, k + 1]
    keep = (real_lo < 0) | (real_hi < 0)
    runs, k = runs[keep], k[keep]
    im_lo, im_hi = response.imag[runs, k], response.imag[runs, k + 1]
    share = im_lo / (im_lo - im_hi)
    low, high = np.sqrt(squared[runs, k]), np.sqrt(squared[runs, k + 1])
    estimate = -20.0 * np.log10(low + share * (high - low))
    upper = estimate >= -CANDIDATE_DB
    lower = estimate < CANDIDATE_DB
    best_upper, _ = _group_min(n, runs[upper], estimate[upper], estimate[upper])
    best_lower, _ = _group_min(n, runs[lower], -estimate[lower], estimate[lower])
    candidate = (upper & (estimate <= np.maximum(best_upper[runs], 0.0) + CANDIDATE_DB)) | (
        lower & (estimate >= np.minimum(-best_lower[runs], 0.0) - CANDIDATE_DB)
    )
    return runs[candidate], k[candidate]


def loop_figures(evaluate, omega, response, ms_valid):
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

    Returns
    -------
    dict of str to numpy.ndarray
        :data:`LOOP_FIGURES`, each shape (n,).
    """
    n = response.shape[0]
    log_w = np.log(omega)
    re, im = response.real, response.imag
    squared = re * re + im * im
    out = {}

    # Gain crossovers (|L| = 1, all) and phase crossovers (Im L = 0 with Re L < 0, the
    # candidates), refined together.
    g_runs, g_k = _brackets(squared - 1.0)
    p_runs, p_k = _phase_candidates(n, response, squared)
    runs, k = np.concatenate([g_runs, p_runs]), np.concatenate([g_k, p_k])
    gain = np.arange(runs.size) < g_runs.size
    grid_lo, grid_hi = response[runs, k], response[runs, k + 1]
    f_lo = np.where(gain, np.abs(grid_lo) - 1.0, _sine(grid_lo))
    f_hi = np.where(gain, np.abs(grid_hi) - 1.0, _sine(grid_hi))

    def crossing(x, j):
        value = evaluate(runs[j], np.exp(x))
        return np.where(gain[j], np.abs(value) - 1.0, _sine(value))

    w_all = refine_roots(crossing, log_w[k], log_w[k + 1], f_lo, f_hi)
    value_all = evaluate(runs, w_all)

    w, value, g = w_all[gain], value_all[gain], runs[gain]
    above = np.minimum(np.searchsorted(omega, w), omega.size - 1)
    anchor = continuous_phase_at(response, omega, g, above)
    angle = anchor + np.angle(value / response[g, above])
    pm = np.degrees(math.pi + angle)
    dm = np.radians(pm) / w
    out["phase_margin_deg"], out["crossover_rad_s"] = _group_min(n, g, pm, w)
    out["delay_margin_s"], _ = _group_min(n, g, dm, dm)
    out["gain_crossover_count"] = np.bincount(g, minlength=n).astype(float)

    w, value, r = w_all[~gain], value_all[~gain], runs[~gain]
    negative = value.real < 0
    r, w, value = r[negative], w[negative], value[negative]
    gm = -20.0 * np.log10(np.abs(value))
    up = gm >= 0
    out["gain_margin_db"], out["phase_crossover_rad_s"] = _group_min(n, r[up], gm[up], w[up])
    low_key, out["phase_crossover_low_rad_s"] = _group_min(n, r[~up], -gm[~up], w[~up])
    out["gain_margin_low_db"] = -low_key

    # Sensitivity peak and disk margin, refined together.
    every = np.arange(n)
    plus = (re + 1.0) ** 2 + im * im  # |1 + L|^2
    (s_w, s_value, _), (d_w, distance, _) = _maxima(
        evaluate, omega,
        [(every, -plus, lambda v, i: 1.0 / np.abs(1.0 + v), response),
         (every, ((re - 1.0) ** 2 + im * im) / plus, lambda v, i: _disk_distance(v),
          response)],
    )
    # for the grid split of cas_freq.batch.analyze: the raw maxima and whether they are at
    # the grid's top end
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
    return {name: out[name] for name in (*LOOP_FIGURES, *EXTRA)}


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


def closed_loop_figures(evaluate, omega, response, valid):
    """Closed-loop figures of a batch (:mod:`cas_freq.analysis.closed_loop`), NaN where not
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
    out["peak_db"][runs] = 20.0 * np.log10(peak)
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
    lowest frequency, as :mod:`cas_freq.analysis.closed_loop` does), its grid index k, the
    phase at k, and phase + 90 deg at k and k + 1.

    Until the wrapped angle first jumps (:func:`phase_jumps`) it is the unwrapped phase, and
    it is above -90 deg exactly where ``Re T > 0`` or ``Im T >= 0``: no angle is computed
    except at the crossing. Rows with a jump before their crossing are unwrapped in full.
    """
    n, m = response.shape
    above = (response.real > 0) | (response.imag >= 0)
    crossing = _first_true(above[:, :-1] & ~above[:, 1:])
    jump = _first_true(phase_jumps(response))
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
