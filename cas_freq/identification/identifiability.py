r"""What the data determine: verdicts on keys and on combinations of keys.

From the Fisher information :math:`F = J_w^T J_w` of the fit coordinates (logarithms of
positive keys, :mod:`~cas_freq.identification.free_keys`) and the residual variance
:math:`s^2`, the covariance is :math:`C = s^2 F^{-1}` (eigenvalues of F below
:data:`RANK_TOLERANCE` of the largest count as that tolerance: the direction is not determined
at all). A coordinate's interval half-width is :math:`h = q\sqrt{C_{jj}}` (q the ~95 % t
quantile); for a log key it is a ratio, :math:`e^{\pm h}`. The verdict of a key or a
combination, by its half-width:

- **well determined**: :math:`h \le \ln 1.1` (within about ±10 %);
- **poorly determined**: up to :math:`\ln 2`;
- **not determined**: beyond a factor 2 either way.

A key can be poorly determined on its own while a combination of it with others is well
determined: position data fix the motor's torque-to-inertia ratio Km/J, not Km and J apart.
Combinations are products of the log keys with small integer exponents (-2..2): a basis of
them, the best determined and simplest first, each independent of those before; a direction
the data leave unbounded (scaling Km, J and mu_v together, with Ke fixed, changes no signal at
all) is given as F's eigenvector (exponents rounded). With
``conditional`` half-widths (the others known) beside the marginal ones, a reader sees which
key would be determined if the others were measured.
"""

import dataclasses
import itertools
import math

import numpy as np

from cas_freq.core.units import registry
from cas_freq.identification.free_keys import labels

#: Half-widths (of a coordinate) that separate the verdicts.
WELL = math.log(1.1)
NOT = math.log(2.0)

#: Eigenvalues of F below this fraction of the largest are taken as this fraction.
RANK_TOLERANCE = 1e-14

#: Most log keys searched for simple combinations (5**8 candidates).
MAX_SEARCH_KEYS = 8


def verdict(half_width):
    """``"well determined"``, ``"poorly determined"`` or ``"not determined"``."""
    if half_width <= WELL:
        return "well determined"
    if half_width <= NOT:
        return "poorly determined"
    return "not determined"


def monomial(exponents, names):
    """``"Km/J"``, ``"Km·J·mu_v"``, ``"Km^2/J"`` of exponents over names."""
    def power(name, e):
        e = abs(e)
        text = f"{e:g}"
        return name if e == 1 else f"{name}^{text}"

    up = [power(n, e) for n, e in zip(names, exponents, strict=True) if e > 0]
    down = [power(n, e) for n, e in zip(names, exponents, strict=True) if e < 0]
    top = "·".join(up) or "1"
    if not down:
        return top
    bottom = down[0] if len(down) == 1 else f"({'·'.join(down)})"
    return f"{top}/{bottom}"


def _unit(exponents, units):
    """The SI unit of a product of powers of units, as pint writes it compactly."""
    quantity = registry().Quantity(1.0)
    for e, unit in zip(exponents, units, strict=True):
        if e:
            quantity = quantity * registry().Quantity(1.0, unit) ** float(e)
    unit = quantity.to_base_units().units
    return "" if unit == registry().dimensionless else f"{unit:~P}"


@dataclasses.dataclass(frozen=True)
class Combination:
    """A product of powers of keys and how well the data determine it.

    Attributes
    ----------
    exponents : tuple of float
        Exponent of each free key (0 for the others); of a sum S, the local exponents
        d ln S / d ln v_k = c_k v_k / S.
    text : str
        ``"Km/J"``, or ``"J + 0.0025·inertia"`` for a sum.
    value : float
        Its value at the estimate [``unit``].
    unit : str
        Its SI unit.
    half_width : float
        ~95 % half-width of its logarithm (a ratio e^±h).
    verdict : str
    coefficients : tuple of float or None
        A sum S = sum of c_k v_k, of keys that enter the output only together: each key's
        coefficient c_k [unit of the first key / unit of the key] (0 for the others, 1 for the
        first); None for a product.
    """

    exponents: tuple
    text: str
    value: float
    unit: str
    half_width: float
    verdict: str
    coefficients: tuple | None = None


@dataclasses.dataclass(frozen=True)
class KeyVerdict:
    """One key: marginal and conditional (the others known) half-widths and the verdict.

    Half-widths are of the coordinate: relative (ln) for a log key, in scales otherwise.
    """

    key: str
    label: str
    half_width: float
    conditional_half_width: float
    verdict: str


@dataclasses.dataclass(frozen=True, eq=False)
class Identifiability:
    """Verdicts of one set of data.

    Attributes
    ----------
    covariance : numpy.ndarray
        :math:`s^2 F^{-1}` of the coordinates.
    keys : list of KeyVerdict
    determined : list of Combination
        The simplest well-determined products of the log keys.
    undetermined : list of Combination
        The directions not determined (F's eigenvectors, exponents rounded to 0.5 where close).
    condition : float
        Largest over smallest eigenvalue of F (inf for a singular F).
    """

    covariance: np.ndarray
    keys: list
    determined: list
    undetermined: list
    condition: float


def relative_half_width(half_width, free, coordinate):
    """Half-width of a linear key relative to its magnitude (or its scale near 0)."""
    if free.log:
        return half_width
    return half_width / max(abs(coordinate), 1.0)


def identifiability(fisher, free, x, s2, q):
    """The :class:`Identifiability` of Fisher information ``fisher`` at coordinates ``x``.

    Parameters
    ----------
    fisher : numpy.ndarray
        (p, p) :math:`J_w^T J_w`.
    free : list of FreeKey
    x : numpy.ndarray
        Coordinates of the estimate.
    s2 : float
        Residual variance of the weighted residuals (about 1).
    q : float
        Interval quantile.
    """
    names = labels(free)
    w, vectors = np.linalg.eigh(0.5 * (fisher + fisher.T))
    top = max(float(w[-1]), 1e-300)
    floored = np.maximum(w, RANK_TOLERANCE * top)
    covariance = s2 * (vectors / floored) @ vectors.T
    keys = []
    for j, f in enumerate(free):
        h = relative_half_width(q * math.sqrt(covariance[j, j]), f, x[j])
        information = max(fisher[j, j], RANK_TOLERANCE * top)
        alone = relative_half_width(q * math.sqrt(s2 / information), f, x[j])
        keys.append(KeyVerdict(f.key, names[j], h, alone, verdict(h)))
    logs = [j for j, f in enumerate(free) if f.log]
    values = np.array([f.value(c) for f, c in zip(free, x, strict=True)])
    determined, undetermined = [], []
    if logs:
        def width(exponents):
            """Half-width of e.x for exponents over the log keys, summed over F's eigenvectors
            (no cancellation of the large variance of a direction e is orthogonal to)."""
            rows = np.zeros(np.shape(exponents)[:-1] + (len(free),))
            rows[..., logs] = exponents
            return q * np.sqrt(s2 * np.sum((rows @ vectors) ** 2 / floored, axis=-1))

        determined, undetermined = _combinations(covariance[np.ix_(logs, logs)], logs, free,
                                                 names, values, width)
        sums = _sums(fisher, covariance, logs, free, names, values, width)
        for group, combination in sums:
            # the sum replaces the products of its keys alone (the directions F's
            # eigenvectors give where nothing is determined are kept)
            def alone(c, group=group):
                return c.half_width <= UNBOUNDED and all(
                    j in group for j, e in enumerate(c.exponents) if e)

            determined = [c for c in determined if not alone(c)]
            undetermined = [c for c in undetermined if not alone(c)]
            (determined if combination.verdict == "well determined" else undetermined).insert(
                0, combination)
    condition = float(w[-1] / w[0]) if w[0] > 0 else math.inf
    return Identifiability(covariance=covariance, keys=keys, determined=determined,
                           undetermined=undetermined, condition=condition)


def _combination(exponents, logs, free, names, values, half_width):
    """The Combination of exponents over the log keys ``logs``."""
    full = [0.0] * len(free)
    for j, e in zip(logs, exponents, strict=True):
        full[j] = float(e)
    chosen = [j for j in logs if full[j]]
    value = math.prod(values[j] ** full[j] for j in chosen)
    if len(chosen) == 1 and full[chosen[0]] == 1:  # one key: its own unit, as the config has it
        unit = free[chosen[0]].unit
    else:
        unit = _unit([full[j] for j in chosen], [free[j].unit for j in chosen])
    return Combination(
        exponents=tuple(full), text=monomial([full[j] for j in chosen], [names[j] for j in chosen]),
        value=value, unit=unit,
        half_width=half_width, verdict=verdict(half_width))


#: A log half-width beyond this (a factor 100 either way) is "unbounded": the data say nothing
#: useful of such a direction, given as F's eigenvector rather than as a simple product, and of
#: a key with such an interval (no interval is printed).
UNBOUNDED = math.log(100.0)


#: Keys whose estimates correlate beyond this (in absolute value), linked in a chain, are a
#: group whose sum may be what the data determine.
SUM_CORRELATION = 0.99


def _groups(covariance, logs):
    """Groups (sorted index lists, two keys or more) of log keys linked by a correlation
    beyond :data:`SUM_CORRELATION`."""
    error = np.sqrt(np.diag(covariance))
    linked = {j: {j} for j in logs}
    for a, b in itertools.combinations(logs, 2):
        if abs(covariance[a, b]) >= SUM_CORRELATION * error[a] * error[b]:
            merged = linked[a] | linked[b]
            for j in merged:
                linked[j] = merged
    unique = {tuple(sorted(group)) for group in linked.values() if len(group) > 1}
    return sorted(unique)


def _sums(fisher, covariance, logs, free, names, values, width):
    r"""(group, Combination) of each group of correlated keys that enter the output as a sum.

    Where the output depends on the keys of a group only through :math:`S = \sum_k c_k v_k`
    (a rotor's and a reflected load's inertia: :math:`J + J_L/(\eta N^2)`), the Jacobian
    columns in the keys' own units are proportional, :math:`\partial r/\partial v_k = c_k
    \partial r/\partial S`: the coefficients are the best-determined direction of the
    information in those units, :math:`D^{-1} F D^{-1}` (D the values), scaled to 1 on the
    first key. A group is a sum when every coefficient is positive and the sum is better
    determined than each of its keys (a ratio, Km/J, has a negative one and stays a product).
    """
    found = []
    for group in _groups(covariance, logs):
        scale = values[list(group)]
        block = fisher[np.ix_(group, group)] / np.outer(scale, scale)
        _, vectors = np.linalg.eigh(0.5 * (block + block.T))
        c = vectors[:, -1] / vectors[0, -1]
        if not np.all(c > 0):
            continue
        total = float(c @ scale)
        local = np.zeros(len(logs))
        for k, j in enumerate(group):
            local[logs.index(j)] = c[k] * scale[k] / total
        h = float(width(local))
        keys_alone = min(float(width(np.eye(len(logs))[logs.index(j)])) for j in group)
        if not (h < keys_alone and h <= UNBOUNDED):
            continue
        coefficients = np.zeros(len(free))
        coefficients[list(group)] = c
        found.append((group, sum_combination(coefficients, free, names, values, h)))
    return found


def sum_combination(coefficients, free, names, values, half_width):
    """The Combination of the sum of ``values`` with ``coefficients`` (0 outside the sum, 1 on
    its first key), its log half-width ``half_width``."""
    c = np.asarray(coefficients, dtype=float)
    group = [int(j) for j in np.flatnonzero(c)]
    total = float(c @ np.where(c != 0, values, 0.0))
    first = free[group[0]]
    terms = [names[group[0]]]
    for j in group[1:]:
        unit = _unit([1.0, -1.0], [first.unit, free[j].unit])
        factor = f"{c[j]:.4g}" + (f" {unit}" if unit else "")
        terms.append(f"{factor}·{names[j]}")
    exponents = tuple(float(c[j] * values[j] / total) if c[j] else 0.0
                      for j in range(len(free)))
    return Combination(exponents=exponents, text=" + ".join(terms), value=total,
                       unit=first.unit, half_width=half_width, verdict=verdict(half_width),
                       coefficients=tuple(float(v) for v in c))


def _candidates(n):
    """Exponent vectors over n keys: entries -2..2, not all 0, first non-zero > 0, not all
    even."""
    grid = np.array(list(itertools.product(range(-2, 3), repeat=n)), dtype=float)
    grid = grid[np.any(grid != 0, axis=1)]
    first = grid[np.arange(grid.shape[0]), np.argmax(grid != 0, axis=1)]
    grid = grid[first > 0]
    return grid[~np.all(grid % 2 == 0, axis=1)]


def _combinations(covariance, logs, free, names, values, width):
    """(determined, not well determined) products of the log keys.

    A basis of the log keys' space: the simplest products, best determined first, each
    independent of those before, for every direction whose half-width is bounded; F's
    eigenvectors (exponents rounded to 0.5 where close) for the unbounded ones.
    """
    w, vectors = np.linalg.eigh(covariance)
    unbounded = [k for k in range(len(w)) if width(vectors[:, k]) > UNBOUNDED]
    wanted = len(logs) - len(unbounded)
    picked = []
    if wanted and len(logs) <= MAX_SEARCH_KEYS:
        grid = _candidates(len(logs))
        widths = width(grid)
        keep = widths <= UNBOUNDED
        grid, widths = grid[keep], widths[keep]
        rank = np.select([widths <= WELL, widths <= NOT], [0, 1], 2)
        order = np.lexsort((widths, np.abs(grid).sum(axis=1), np.count_nonzero(grid, axis=1),
                            rank))
        for index in order:
            trial = np.array([*(grid[i] for i, _ in picked), grid[index]])
            if np.linalg.matrix_rank(trial, tol=1e-9) == len(trial):
                picked.append((index, float(widths[index])))
                if len(picked) == wanted:
                    break
        picked = [(grid[i], h) for i, h in picked]
    for k in unbounded:
        v = vectors[:, k] / np.max(np.abs(vectors[:, k]))
        v = v * np.sign(v[np.argmax(np.abs(v) > 1e-9)])
        halves = np.round(2 * v) / 2
        v = np.where(np.abs(v - halves) < 0.1, halves, np.round(v, 2))
        picked.append((v, float(width(v))))
    found = [_combination(e, logs, free, names, values, h) for e, h in picked]
    return ([c for c in found if c.verdict == "well determined"],
            [c for c in found if c.verdict != "well determined"])


__all__ = ["Combination", "Identifiability", "KeyVerdict", "NOT", "WELL", "identifiability",
           "monomial", "sum_combination", "verdict"]
