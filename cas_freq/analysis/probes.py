"""Where a loop's crossings may hide between two grid samples: the *probes* added to the grid.

Used by :mod:`cas_freq.analysis.margins` (its module docstring gives the method): the refined
local extrema of |L| (:func:`extremum_probes`), the subdivided intervals beside a corner of
ln |L| (:func:`subdivision_probes`), and where an inner loop passes close to -1
(:func:`near_minus_one_probes`).
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.roots import refine_maxima
from cas_freq.analysis.scan_kernel import log_corners, long_chords
from cas_freq.core.jit import compiled_for

#: A local extremum whose second difference of ln |L|^2 over three grid samples exceeds this is
#: not resolved by the grid (a smooth function sampled 50 times per feature width stays far
#: below; an unresolved resonance gives ln 9 or more) and is refined.
SHARP = 0.05

#: The same for the complex ln L = ln |L| + j phase, in size: a pole or zero pair of width W
#: (W/omega of its frequency) between two samples a distance D from them bends ln L by about
#: W/D at the flank samples, first order in W, in the phase (a notch: a zero pair under a
#: pole pair) or in ln |L| (a peak beside a notch). W = 1e-5 between samples 1.15 % apart
#: (200 per decade) gives ~2e-3, where it may still cross 0 dB or -180° between them. A
#: smooth loop (a delay's included, on the grid that follows it) bends by less than 1e-5 but
#: beside resolved resonances, which are then subdivided once or twice.
LOG_SHARP = 1e-3

#: Subdivisions of an unresolved feature's grid intervals, each into four: down to 4^-20 of
#: the grid spacing (about 1e-14 relative at 200 points per decade), below rounding.
MAX_SUBDIVISIONS = 20


@dataclasses.dataclass(frozen=True, eq=False)


class Probes:
    """Extra sample frequencies per run: ``runs`` (int) and ``log_w`` [log(rad/s)], same shape."""

    runs: np.ndarray
    log_w: np.ndarray

    @classmethod
    def none(cls):
        return cls(np.zeros(0, dtype=int), np.zeros(0))

    def __add__(self, other):
        return Probes(np.concatenate([self.runs, other.runs]),
                      np.concatenate([self.log_w, other.log_w]))

    def below(self, log_w):
        """The probes at or below ``log_w`` [log(rad/s)] (a sampled loop's figures stop at its
        Nyquist frequency)."""
        kept = self.log_w <= log_w
        return self if kept.all() else Probes(self.runs[kept], self.log_w[kept])


def extremum_probes(evaluate, omega, response, squared=None):
    """Probes at the local extrema of |L| that may cross 0 dB between two samples.

    A local maximum of |L| on the grid below 0 dB (or a minimum above it) is refined when it
    may reach 0 dB between samples:

    - when it is not resolved by the grid: a peak narrower than the spacing shows as a sharp
      corner in log |L| (its two flank samples differ from the top one by a factor of about 3
      or more), so a second difference of log |L|^2 above :data:`SHARP` marks it, whatever
      the height of the samples;
    - when it is resolved: the parabola through the three samples of log |L|^2 predicts the
      extremum; one predicted within 6 dB of 0 dB is refined.

    Smooth ripples (e.g. of a delay, sampled many times per period) are neither, and are left.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(runs, omega) -> complex`` loop response.
    omega : numpy.ndarray
        Grid [rad/s], shape (m,).
    response : numpy.ndarray
        Loop response on the grid, shape (n, m).
    squared : numpy.ndarray, optional
        |response|^2, if already computed.

    Returns
    -------
    Probes
    """
    if omega.size < 3:
        return Probes.none()
    if squared is None:
        squared = response.real ** 2 + response.imag ** 2
    rising = squared[:, 1:] > squared[:, :-1]
    all_runs, all_k = np.nonzero(rising[:, :-1] != rising[:, 1:])  # every local extremum
    all_k = all_k + 1
    top = rising[all_runs, all_k - 1]  # rising before: a maximum
    level = squared[all_runs, all_k]
    log_w = np.log(omega)
    # a corner that is not a maximum under 0 dB or a minimum over it (those are refined
    # below) is resolved by subdivision
    inner = squared[:, 2:-2]
    before, after = rising[:, 1:-2], rising[:, 2:-1]
    maximum, minimum = before & ~after, ~before & after
    refined = (maximum & (inner < 1.0)) | (minimum & (inner > 1.0))
    with np.errstate(divide="ignore"):
        log_squared = np.log(squared)
    if compiled_for(response.size):  # the same in one pass (analysis/scan_kernel.py)
        log_corner = np.empty((response.shape[0], omega.size - 4), dtype=bool)
        log_size = np.empty(log_corner.shape)
        log_corners(log_w, response, log_squared, LOG_SHARP, log_corner, log_size)
    else:
        log_corner, log_size = _log_corners(log_w, response, log_squared)
    corners = (_corners(log_w, squared, log_squared) & ~refined) | log_corner
    runs, k = np.nonzero(corners)
    # a corner of |L| alone is followed by its own test, not by the ratio of ln L's (inf)
    parent = np.where(log_corner[runs, k], log_size[runs, k], np.inf)
    found = subdivision_probes(evaluate, log_w, squared, runs, k + 2, response, parent)
    for sign in (1.0, -1.0):
        chosen = (top & (level < 1.0)) if sign > 0 else (~top & (level > 1.0))
        runs, k = all_runs[chosen], all_k[chosen]
        if runs.size == 0:
            continue
        with np.errstate(divide="ignore", invalid="ignore"):
            y = np.log(np.stack([squared[runs, k - 1], squared[runs, k], squared[runs, k + 1]]))
            x = np.stack([log_w[k - 1], log_w[k], log_w[k + 1]])
            sharp = -sign * (y[0] - 2.0 * y[1] + y[2]) > SHARP
            reach = sign * _parabola_vertex(x, y) > -math.log(4.0)
        keep = (sharp | reach) & np.isfinite(y).all(axis=0)
        runs, k = runs[keep], k[keep]
        if runs.size == 0:
            continue
        x, _ = _refine_log_maxima(
            lambda x, j, runs=runs, sign=sign: sign * np.abs(evaluate(runs[j], np.exp(x))),
            log_w[k - 1], log_w[k + 1], log_w[k],
            sign * np.sqrt(squared[runs, k - 1]), sign * np.sqrt(squared[runs, k]),
            sign * np.sqrt(squared[runs, k + 1]),
        )
        found = found + Probes(runs, x)
    return found


def _corners(log_w, squared, log_squared=None):
    """Where ln |L|^2 has a corner at a grid sample (k = 2 .. m - 3, shape (n, m - 4)): its
    second difference exceeds :data:`SHARP` in size and differs by more than that from the
    mean of its neighbours' (a resolved resonance curves smoothly: the second differences
    beside its top are alike; a feature narrower than the spacing bends the samples next to
    it only, e.g. 0.05, -0.09, 0.04 beside a notch-and-peak pair).

    The second differences are taken on the grid as it is, ((y2 - y1)/h2 - (y1 - y0)/h1)
    (h1 + h2)/2, which is y0 - 2 y1 + y2 where it is uniform and, unlike it, zero for a
    straight line where it is not (the log grid merged into a linear one for the delays).
    """
    h = np.diff(log_w)
    with np.errstate(divide="ignore", invalid="ignore"):
        log_squared = np.log(squared) if log_squared is None else log_squared
        slope = np.diff(log_squared, axis=1) / h
        second = np.diff(slope, axis=1) * (0.5 * (h[:-1] + h[1:]))
        bend = second[:, 1:-1] - 0.5 * (second[:, :-2] + second[:, 2:])
    return (np.abs(second[:, 1:-1]) > SHARP) & (np.abs(bend) > SHARP)


def _log_corners(log_w, response, log_squared):
    """Where the complex ln L has a corner at a grid sample (k = 2 .. m - 3, shape
    (n, m - 4)), as :func:`_corners` for ln |L|^2 but with :data:`LOG_SHARP`: a notch or a
    peak narrower than the spacing, which bends ln L at its flank samples to first order in its
    width. The steps of ln L are those of ``log_squared`` (ln |L|^2) halved and the angles of
    consecutive ratios, so no unwrapping is needed. Also returns the size of each second difference
    (what the subdivision compares its own with, :func:`subdivision_probes`).

    On a grid that is not uniform (the log grid merged with a delay's linear one) the second
    divided differences D_k = f[x_k, x_k+1, x_k+2] are used: for a cubic they are linear in
    the nodes' mean, so the bend (D_k less its neighbours' interpolated at its nodes' mean) is
    zero for any cubic on any grid, and a delay's fast but smooth phase makes none. Both are
    scaled as second differences, by (x_k+2 - x_k)^2 / 2."""
    h = np.diff(log_w)
    span = log_w[2:] - log_w[:-2]
    centre = (log_w[:-2] + log_w[1:-1] + log_w[2:]) / 3.0
    before, after = centre[1:-1] - centre[:-2], centre[2:] - centre[1:-1]
    weight = after / (before + after)
    scale = 0.5 * span[1:-1] ** 2
    re, im = response.real, response.imag
    with np.errstate(divide="ignore", invalid="ignore"):
        # the steps of ln L: ln |ratio| (from |L|^2) and the ratio's angle, in real arithmetic
        parts = (0.5 * np.diff(log_squared, axis=1), _angle_steps(re, im, log_squared))
        size2 = bend2 = 0.0
        for number, step in enumerate(parts):
            change = step[:, 1:] - step[:, :-1] * (h[1:] / h[:-1])  # (slope change) h_k+1
            if number:  # the phase's, modulo a turn (4 in the units of _angle_steps)
                change = 2.0 - np.mod(2.0 - change, 4.0)
            divided = change / (h[1:] * span)
            middle = divided[:, 1:-1]
            between = divided[:, :-2] * weight + divided[:, 2:] * (1.0 - weight)
            size2 = size2 + (middle * scale) ** 2
            bend2 = bend2 + ((middle - between) * scale) ** 2
    size, bend = np.sqrt(size2), np.sqrt(bend2)
    return (size > LOG_SHARP) & (bend > LOG_SHARP), size


def _angle_steps(re, im, log_squared):
    """The angle steps between consecutive samples, as a cheap monotone stand-in for the angle
    a (which costs an arctan per sample, most of this scan): sin a for |a| <= pi/2, else
    sign(a) (2 - |sin a|), in (-2, 2]. It is a to within 8 % for the steps a grid takes on a
    smooth loop (< pi/8, with a delay's densified grid) and smooth in a, so a corner of the
    phase is one of these steps, scaled by cos a."""
    cross = re[:, :-1] * im[:, 1:] - im[:, :-1] * re[:, 1:]
    dot = re[:, :-1] * re[:, 1:] + im[:, :-1] * im[:, 1:]
    sine = cross * np.exp(-0.5 * (log_squared[:, :-1] + log_squared[:, 1:]))
    return np.where(dot >= 0.0, sine, np.sign(cross) * (2.0 - np.abs(sine)))


def _wrapped(log_change):
    """A change of ln L with its phase part taken modulo a turn, in (-pi, pi]: a phase step
    near half a turn reads +pi at one sample and -pi at the next, which is no corner."""
    return log_change.real + 1j * (math.pi - np.mod(math.pi - log_change.imag, 2.0 * math.pi))


def _sharp(squared, values=None, parent=None):
    """Where the second difference of ln |L|^2 over consecutive samples exceeds :data:`SHARP`
    in size, or (given the complex ``values``) that of ln L exceeds :data:`LOG_SHARP` and a
    quarter of ``parent`` (per row: that of the coarser samples it was cut from), at the inner
    samples of each row (shape (n, m - 2)); False where not finite (the subdivisions' samples
    are uniform in log frequency). Also returns the sizes of ln L's second differences (None
    without ``values``).

    The quarter tells an unresolved feature from a resolved one: cutting the spacing by 4
    makes the second differences of a resolved curve 16 times smaller, while those beside a
    feature narrower than the spacing stay or grow (the samples come nearer to it)."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        ratio = squared[:, :-2] * squared[:, 2:] / (squared[:, 1:-1] * squared[:, 1:-1])
        bound = math.exp(SHARP)
        sharp = np.isfinite(ratio) & ((ratio > bound) | (ratio * bound < 1.0))
        if values is None:
            return sharp, None
        size = np.abs(_wrapped(np.log(values[:, 2:] / values[:, 1:-1])
                               - np.log(values[:, 1:-1] / values[:, :-2])))
    size = np.where(np.isfinite(size), size, 0.0)
    return sharp | ((size > LOG_SHARP) & (size > 0.25 * parent[:, None])), size


def subdivision_probes(evaluate, log_w, squared, runs, k, response=None, parent=None):
    """Probes that resolve the features at the sharp corners (``runs``, ``k``) of |L|^2 (and,
    given ``response``, of the phase of L).

    The two grid intervals beside each corner are cut into four; beside every sharp corner
    among the new samples (second differences over the five samples of an interval, see
    :func:`_sharp`, of ln |L|^2 and of the phase) the quarters are cut again, and so on, at
    most :data:`MAX_SUBDIVISIONS` times. A feature of width W stops showing corners once the
    spacing is below about W/5, so its extrema, its 0 dB and its -180° crossings are then
    bracketed by the samples.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(runs, omega) -> complex`` loop response.
    log_w : numpy.ndarray
        Grid [log(rad/s)], shape (m,).
    squared : numpy.ndarray
        |L|^2 on the grid, shape (n, m).
    runs, k : numpy.ndarray of int
        The sharp grid samples (0 < k < m - 1).
    response : numpy.ndarray, optional
        L on the grid, shape (n, m): the corners of ln L are followed as well, while they do
        not fade as a resolved curve's do (:func:`_sharp`).
    parent : numpy.ndarray, optional
        With ``response``: per corner, the size of ln L's second difference there (inf: a
        corner of |L|^2 alone).

    Returns
    -------
    Probes
        Every sample taken.
    """
    m = log_w.size
    both = np.concatenate([runs * m + k - 1, runs * m + k])
    interval, which = np.unique(both, return_inverse=True)
    if response is not None:
        parents = np.full(interval.size, -np.inf)
        np.maximum.at(parents, which.reshape(-1), np.concatenate([parent, parent]))
    runs, j = interval // m, interval % m
    lo, hi = log_w[j], log_w[j + 1]
    s_lo, s_hi = squared[runs, j], squared[runs, j + 1]
    if response is not None:
        v_lo, v_hi = response[runs, j], response[runs, j + 1]
    quarters = np.array([0.25, 0.5, 0.75])
    taken = []
    for _ in range(MAX_SUBDIVISIONS):
        if runs.size == 0:
            break
        x = lo[:, None] + (hi - lo)[:, None] * quarters
        value = evaluate(np.repeat(runs, 3), np.exp(x.ravel())).reshape(x.shape)
        taken.append(Probes(np.repeat(runs, 3), x.ravel()))
        xs = np.column_stack([lo, x, hi])
        ss = np.column_stack([s_lo, value.real ** 2 + value.imag ** 2, s_hi])
        vs = None if response is None else np.column_stack([v_lo, value, v_hi])
        sharp, size = _sharp(ss, vs, None if vs is None else parents)  # the 3 inner samples
        cut = np.zeros((runs.size, 4), dtype=bool)  # the quarters beside a sharp sample
        cut[:, :-1] |= sharp
        cut[:, 1:] |= sharp
        row, i = np.nonzero(cut)
        runs, lo, hi = runs[row], xs[row, i], xs[row, i + 1]
        s_lo, s_hi = ss[row, i], ss[row, i + 1]
        if vs is not None:
            v_lo, v_hi = vs[row, i], vs[row, i + 1]
            # each quarter's parent: the larger second difference at its two ends (inner ones)
            ends = np.full((size.shape[0], 5), -np.inf)
            ends[:, 1:4] = size
            parents = np.maximum(ends[row, i], ends[row, i + 1])
    return sum(taken, Probes.none())


def _parabola_vertex(x, y):
    """Extreme value of the parabola through three points per column (x, y of shape (3, k));
    the middle value where the points are collinear."""
    x0, x2 = x[0] - x[1], x[2] - x[1]  # centred on the middle point: no cancellation
    y0, y1, y2 = y
    d01, d12 = (y1 - y0) / -x0, (y2 - y1) / x2
    a = (d12 - d01) / (x2 - x0)
    b = d01 - a * x0  # slope at the middle point
    return np.where(a != 0, y1 - b * b / (4.0 * a), y1)


def _long_chords(inner, distance2):
    """(rows, k) of the grid intervals whose chord is longer than sqrt(3) times the distance
    of its nearer end to -1 (``distance2``: |1 + L|^2), in row-major order; compiled on large
    arrays (:mod:`cas_freq.analysis.scan_kernel`), this numpy form its reference."""
    if compiled_for(inner.size):
        empty = np.empty(0, dtype=np.int64)
        count = long_chords(inner, distance2, empty, empty)
        rows, k = np.empty(count, dtype=np.int64), np.empty(count, dtype=np.int64)
        long_chords(inner, distance2, rows, k)
        return rows, k
    chord = inner[:, 1:] - inner[:, :-1]
    length2 = chord.real ** 2 + chord.imag ** 2
    return np.nonzero(length2 > 3.0 * np.minimum(distance2[:, :-1], distance2[:, 1:]))


def near_minus_one_probes(omega, inner, runs=None, distance2=None):
    """Probes where an inner loop L_i passes close to -1 between two grid samples.

    There |1 + L_i| has a sharp minimum, so T_i = L_i/(1 + L_i) and every loop containing it
    have a resonance that the grid may step over. Over one grid interval L_i is nearly a
    straight segment (its own poles and the delay turn it slowly); the point of the segment
    closest to -1 at distance d, with L_i moving at speed v per unit log frequency, gives a
    resonance centred there with half-width about d / v. Probes are placed at the centre and
    at 0.5, 1, 2 and 4 half-widths on each side.

    Parameters
    ----------
    omega : numpy.ndarray
        Grid [rad/s], shape (m,).
    inner : numpy.ndarray
        L_i on the grid, shape (n, m) (or (1, m) shared by every run).
    runs : numpy.ndarray, optional
        Run numbers of the rows of ``inner`` (default 0..n-1).
    distance2 : numpy.ndarray, optional
        |1 + L_i|^2 on the grid, if already computed.

    Returns
    -------
    Probes
    """
    log_w = np.log(omega)
    # A segment passing -1 at d < e/2 with both ends at >= e from it is longer than
    # 2 sqrt(e^2 - d^2) > sqrt(3) e: only such intervals are examined.
    if distance2 is None:
        plus = inner + 1.0
        distance2 = plus.real ** 2 + plus.imag ** 2
    ends2 = distance2
    rows, k = _long_chords(inner, ends2)
    if rows.size == 0:
        return Probes.none()
    a = inner[rows, k]
    chord = inner[rows, k + 1] - a
    length2 = chord.real ** 2 + chord.imag ** 2
    to_point = -1.0 - a
    t = (chord.real * to_point.real + chord.imag * to_point.imag) / length2
    inside = (t > 0.0) & (t < 1.0)
    distance = np.abs(a + np.where(inside, t, 0.0) * chord + 1.0)
    ends = np.sqrt(np.minimum(ends2[rows, k], ends2[rows, k + 1]))
    sharp = inside & (distance < 0.5 * ends)
    rows, k, t, distance, length2 = rows[sharp], k[sharp], t[sharp], distance[sharp], \
        length2[sharp]
    if rows.size == 0:
        return Probes.none()
    step = log_w[k + 1] - log_w[k]
    centre = log_w[k] + t * step
    width = distance * step / np.sqrt(length2)
    offsets = np.array([-4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0])
    x = centre[:, None] + offsets[None, :] * width[:, None]
    x = np.clip(x, log_w[k][:, None], log_w[k + 1][:, None])
    owner = rows if runs is None else np.asarray(runs)[rows]
    return Probes(np.repeat(owner, offsets.size), x.ravel())


def _refine_log_maxima(func, lo, hi, mid, f_lo, f_mid, f_hi):
    """:func:`refine_maxima` returning log frequencies."""
    w, value = refine_maxima(func, lo, hi, f_lo, f_mid, f_hi, mid)
    return np.log(w), value
