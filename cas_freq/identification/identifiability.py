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
    from cas_freq.units import registry

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
        Exponent of each free key (0 for the others).
    text : str
        ``"Km/J"``.
    value : float
        Its value at the estimate [``unit``].
    unit : str
        Its SI unit.
    half_width : float
        ~95 % half-width of its logarithm (a ratio e^±h).
    verdict : str
    """

    exponents: tuple
    text: str
    value: float
    unit: str
    half_width: float
    verdict: str


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
    from cas_freq.identification.free_keys import labels

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
           "monomial", "verdict"]
