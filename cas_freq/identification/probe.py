r"""Whether an interval is what moves the output: each one checked by simulating its ends.

An interval from the Fisher information is a linearisation: it claims that moving a key (or a
combination :math:`e \cdot x` of the fit coordinates) by its half-width h, the others
following it the way the data least mind (the direction :math:`d = C e / e^T C e`, C the
covariance), changes the weighted output by :math:`\Delta\chi^2 = h^2 / e^T C e = q^2`
(q the interval's quantile), the residual being the yardstick. A Jacobian taken by finite
differences can be fooled: a key whose effect is quantised (a delay rounded to whole sample
periods) has a huge difference quotient across a step and none elsewhere; keys that enter only
as a sum have columns that differ by the simulator's round-off alone. So each end of each
interval is simulated (:func:`probe`), :math:`\Delta\chi^2 = \|w(x \pm h d) - w(x)\|^2 / s^2`
of the weighted model w:

- it reaches :data:`SHORTFALL` of :math:`q^2`: the side stands;
- it does not: the side is widened, by doublings of h refined in eighths of an octave, to the
  first that reaches :math:`q^2` (no interval narrower than what moves the output);
- no move within a factor 100 (:data:`~cas_freq.identification.identifiability.UNBOUNDED`) or
  the search bound moves the output that much: that side is unbounded, and a key (or
  combination) unbounded on both sides is **not identifiable**: changing it does not change the
  simulation.

An interval the Fisher information already leaves unbounded is simulated at the factor 100
both ways, to tell "not determined" (the output moves, a little) from "not identifiable".
"""

import dataclasses
import math

import numpy as np

from cas_freq.identification.identifiability import UNBOUNDED

#: A side stands when its end moves the output by at least this fraction of what the interval
#: claims (q^2 in chi^2: a quarter is half the amplitude).
SHORTFALL = 0.25

#: Most doublings of a side's half-width searched for a move: the search goes on to the limit
#: (a factor 100), and 2^60 covers it from any half-width above round-off.
DOUBLINGS = 60

#: Steps per doubling of the refinement of a widened side (2^(1/8) = 1.09 apart).
REFINE = 8

#: The further scaling of a sum's other keys that linearises their correction [ln].
HELD_STEP = 1e-4

#: The verdict of what no change within the search moves.
NOT_IDENTIFIABLE = "not identifiable"


@dataclasses.dataclass(frozen=True)
class Probe:
    """What moving one key or combination to its interval's ends does to the output.

    Attributes
    ----------
    predicted : float
        The chi^2 change the interval claims at its ends, q^2 [-].
    moved : tuple of float
        (low end, high end): the chi^2 change simulated there [-].
    factor : tuple of float
        (low, high): how much each side was widened to move the output by q^2 (1: it stands;
        inf: nothing within the search does).
    """

    predicted: float
    moved: tuple
    factor: tuple

    @property
    def widened(self):
        """Whether a side had to be widened (or is unbounded)."""
        return any(f != 1.0 for f in self.factor)

    @property
    def identifiable(self):
        """False where no change within the search moves the output, either way."""
        return not all(math.isinf(f) for f in self.factor)


def probe(change, x, covariance, directions, half_widths, limits, bounds, q):
    """Simulate both ends of each interval; widen a side that does not move the output.

    Parameters
    ----------
    change : callable
        ``change(rows)``: the chi^2 change [-] of the weighted output from the estimate's, for
        each row of coordinates (one simulator batch).
    x : numpy.ndarray
        (p,) coordinates of the estimate.
    covariance : numpy.ndarray
        (p, p) covariance of the coordinates.
    directions : numpy.ndarray
        (m, p) the vectors e of the combinations e.x probed (a key: a unit vector).
    half_widths : numpy.ndarray
        (m,) each one's half-width h in coordinate units (inf or beyond ``limits``: unbounded).
    limits : numpy.ndarray
        (m,) the largest half-width searched [coordinate units].
    bounds : tuple of numpy.ndarray
        (lower, upper) of the coordinates: the probes are kept within them.
    q : float
        The intervals' quantile.

    Returns
    -------
    list of Probe
    """
    directions = np.atleast_2d(np.asarray(directions, dtype=float))
    lower, upper = bounds
    predicted = q * q
    # the covariance without the directions the data leave unbounded: a bounded interval's
    # direction is taken in it, so that its round-off component along an unbounded direction
    # (of a huge variance) does not send the probe along that direction
    w, vectors = np.linalg.eigh(0.5 * (covariance + covariance.T))
    keep = q * np.sqrt(np.maximum(w, 0.0)) <= UNBOUNDED
    bounded_part = (vectors[:, keep] * w[keep]) @ vectors[:, keep].T
    steps = []
    for e, h, limit in zip(directions, half_widths, limits, strict=True):
        bounded = math.isfinite(h) and h <= limit
        spread = float(e @ bounded_part @ e)
        if not (bounded and spread > 0):
            bounded_part_used, spread = covariance, float(e @ covariance @ e)
        else:
            bounded_part_used = bounded_part
        d = bounded_part_used @ e / spread if spread > 0 else e / max(float(e @ e), 1e-300)
        steps.append((d, h if bounded else limit, bounded, limit))

    def rows(points):
        return np.clip(np.array([x + t * d for d, t in points]), lower, upper)

    first = [(d, sign * h) for d, h, _, _ in steps for sign in (-1.0, 1.0)]
    moved = np.asarray(change(rows(first)), dtype=float).reshape(len(steps), 2)
    factor = np.ones((len(steps), 2))
    search = []
    for i, (d, h, bounded, limit) in enumerate(steps):
        for side, sign in enumerate((-1.0, 1.0)):
            if not bounded:
                factor[i, side] = 1.0 if moved[i, side] >= predicted else math.inf
            elif moved[i, side] < SHORTFALL * predicted:
                scales = [2.0 ** k for k in range(1, DOUBLINGS + 1) if 2.0 ** (k - 1) * h < limit]
                factor[i, side] = math.inf
                search += [(i, side, s, (d, sign * min(s * h, limit))) for s in scales]
    if search:
        found = np.asarray(change(rows([point for *_, point in search])), dtype=float)
        for (i, side, scale, _), value in zip(search, found, strict=True):
            if value >= predicted and scale < factor[i, side]:
                factor[i, side] = scale
        # the last doubling refined in eighths of an octave (2^(1/8): within 9 %)
        finer = [(i, side, f * 2.0 ** (n / REFINE - 1.0),
                  (steps[i][0], sign * f * 2.0 ** (n / REFINE - 1.0) * steps[i][1]))
                 for i, side, f, sign in ((i, side, factor[i, side], (-1.0, 1.0)[side])
                                          for i in range(len(steps)) for side in (0, 1))
                 if 1.0 < f < math.inf for n in range(1, REFINE)]
        if finer:
            found = np.asarray(change(rows([point for *_, point in finer])), dtype=float)
            for (i, side, scale, _), value in zip(finer, found, strict=True):
                if value >= predicted and scale < factor[i, side]:
                    factor[i, side] = scale
    return [Probe(predicted=predicted, moved=(float(m[0]), float(m[1])),
                  factor=(float(f[0]), float(f[1]))) for m, f in zip(moved, factor, strict=True)]


def limit_of(free, coordinate):
    """The largest half-width searched for a key [coordinate units]: a factor 100 of a log key,
    100 times its magnitude (or scale) otherwise."""
    return UNBOUNDED if free.log else UNBOUNDED * max(abs(coordinate), 1.0)


def along_sum(x, coefficients, j, half_width):
    r"""Points (rows of coordinates) that change key j of a sum, the sum held.

    Keys that enter the output only as :math:`S = \sum_k c_k v_k` (every one a log key) can
    trade one for another along a curve a straight probe leaves. Key j's coordinate is moved
    by :math:`\pm 2^k h` (k = 0, 1, ... up to a factor 100, clipped where another key would
    reach 0), the other keys of the sum scaled together to keep S. Each point comes with a
    companion, the others scaled by a further :data:`HELD_STEP`: the coefficients are
    estimates, and with data of the simulator's resolution their error alone would move S,
    so :func:`sum_factors` corrects the others' scale by the linearised step the two give.

    Parameters
    ----------
    x : numpy.ndarray
        (p,) coordinates of the estimate.
    coefficients : sequence of float
        (p,) the sum's coefficient of each key (0 outside it).
    j : int
        The key moved.
    half_width : float
        Its half-width [ln]; inf or beyond a factor 100: the ladder starts at a factor 100.

    Returns
    -------
    list of (side, scale, row, companion)
        side 0 (down) or 1 (up), the scale of ``half_width``, the coordinates, and the
        coordinates with the others scaled by ``exp(HELD_STEP)``.
    """
    c = np.asarray(coefficients, dtype=float)
    values = np.exp(np.asarray(x, dtype=float)) * (c != 0)
    total = float(c @ values)
    rest = total - c[j] * values[j]
    others = (c != 0) & (np.arange(len(c)) != j)
    h = half_width if math.isfinite(half_width) and half_width <= UNBOUNDED else UNBOUNDED
    points = []
    for side, sign in enumerate((-1.0, 1.0)):
        edge = math.log(total / (c[j] * values[j])) if sign > 0 else math.inf
        top = min(UNBOUNDED, edge * (1.0 - 1e-3))  # up: short of the others reaching 0
        for k in range(DOUBLINGS + 1):
            t = min((2.0 ** k) * h, top)
            row = np.array(x, dtype=float)
            row[j] += sign * t
            left = total - c[j] * math.exp(row[j])
            row[others] += math.log(left / rest)
            companion = row.copy()
            companion[others] += HELD_STEP
            points.append((side, 2.0 ** k if t < top else top / h, row, companion))
            if t >= top:
                break
    return points


def sum_factors(moves, points, predicted):
    """((low, high), held): the widening of a key moved along a sum (:func:`along_sum`), the
    smallest scale whose point moves the output by ``predicted`` (chi^2), 1 at least, inf where
    none does; and the points (corrected coordinates) that did not move it.

    ``moves(rows)`` gives the (n_rows, n) weighted output changes from the estimate's (over
    s, so that their sum of squares is the chi^2 change). A point's move is taken after the
    others' scale is corrected by the least-squares step its companion gives: the part of the
    move that scaling the others could undo is no move of the key.
    """
    rows = [row for _, _, row, _ in points] + [companion for *_, companion in points]
    found = np.asarray(moves(np.array(rows)), dtype=float)
    at, companions = found[:len(points)], found[len(points):]
    factor = [math.inf, math.inf]
    held = []
    for (side, scale, row, companion), u, v in zip(points, at, companions, strict=True):
        g = v - u  # the output's change per HELD_STEP of the others' scale
        if not np.all(np.isfinite(g)):  # a point the config refuses: no correction
            g = np.zeros_like(u)
        gg = float(g @ g)
        step = -float(u @ g) / gg if gg > 0 else 0.0
        value = float(u @ u) - (float(u @ g) ** 2 / gg if gg > 0 else 0.0)
        if value >= predicted:
            factor[side] = min(factor[side], max(scale, 1.0))
        else:
            held.append(row + step * (companion - row))
    return tuple(factor), held


def held_coefficient(x, coefficients, j, held):
    r"""Key j's coefficient in a sum, measured: the farthest of the points ``held`` (rows of
    coordinates along which the output did not move, :func:`sum_factors`) kept the sum, so
    :math:`c_j \Delta v_j = -\sum_{k \ne j} c_k \Delta v_k` there. None without such a
    point."""
    if not held:
        return None
    far = max(held, key=lambda row: abs(row[j] - x[j]))
    c = np.asarray(coefficients, dtype=float)
    change = np.exp(far) - np.exp(np.asarray(x, dtype=float))
    others = (c != 0) & (np.arange(len(c)) != j)
    if change[j] == 0:
        return None
    return float(-(c[others] @ change[others]) / change[j])


__all__ = ["DOUBLINGS", "NOT_IDENTIFIABLE", "Probe", "SHORTFALL", "along_sum", "held_coefficient",
           "limit_of", "probe", "sum_factors"]
