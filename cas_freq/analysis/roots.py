"""Vectorised refinement of many bracketed roots and maxima at once.

Each task is a set of brackets ``[lo, hi]`` in log frequency, one per (run, crossing); all are
refined together, every iteration evaluating the function once at one point per bracket:

- roots: the Anderson-Bjorck variant of regula falsi (superlinear, always bracketed), to
  :data:`LOG_TOLERANCE` in log frequency;
- maxima: successive parabolic interpolation (golden-section fallback) on
  ``[w_(k-1), w_(k+1)]`` around the largest grid value.

Roots are located to 1e-12 relative in frequency; maxima to ~1e-9 in frequency (a maximum's
frequency is only defined to about the square root of machine epsilon) and ~1e-15 in value.
"""

import math

import numpy as np

#: Refined roots are accurate to this in log frequency (relative in frequency).
LOG_TOLERANCE = 1e-12
#: Maxima are located to this in log frequency: the value at a maximum is then exact to
#: ~1e-18 relative, and the frequency of a maximum is only defined to ~sqrt(machine epsilon).
MAXIMUM_TOLERANCE = 1e-9
#: Iteration cap of the root refinement (Anderson-Bjorck needs about 6 to 10).
MAX_ROOT_ITERATIONS = 100
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def refine_roots(func, lo, hi, f_lo=None, f_hi=None):
    """Roots of ``func`` in the brackets ``[lo, hi]`` (log frequency), all at once.

    Parameters
    ----------
    func : callable
        ``func(x, which) -> float array``: the function of brackets ``which`` (int array) at
        log frequencies ``x`` (same shape), one point per bracket.
    lo, hi : numpy.ndarray
        Bracket ends [log(rad/s)], shape (k,).
    f_lo, f_hi : numpy.ndarray, optional
        ``func`` at the ends (evaluated if not given).

    Returns
    -------
    numpy.ndarray
        Roots [rad/s], shape (k,). Where the ends do not differ in sign when evaluated again
        (a root on a grid point to within rounding), the end with the smaller |f| is returned.
    """
    a, b = np.array(lo, dtype=float), np.array(hi, dtype=float)
    if a.size == 0:
        return np.exp(a)
    every = np.arange(a.size)
    fa = func(a, every) if f_lo is None else np.array(f_lo, dtype=float)
    fb = func(b, every) if f_hi is None else np.array(f_hi, dtype=float)
    best = np.where(np.abs(fa) <= np.abs(fb), a, b)
    active = fa * fb < 0
    for _ in range(MAX_ROOT_ITERATIONS):
        active &= np.abs(b - a) > LOG_TOLERANCE * np.maximum(1.0, np.abs(a))
        if not active.any():
            break
        k = np.flatnonzero(active)
        ak, bk, fak, fbk = a[k], b[k], fa[k], fb[k]
        with np.errstate(divide="ignore", invalid="ignore"):
            secant = (ak * fbk - bk * fak) / (fbk - fak)
        # converged when the secant step from the newest point (a superlinear method's error
        # estimate) is below the tolerance
        done = np.abs(secant - bk) <= LOG_TOLERANCE * np.maximum(1.0, np.abs(bk))
        if done.any():
            best[k[done]] = bk[done]
            active[k[done]] = False
            keep = ~done
            k, ak, bk, fak, fbk, secant = k[keep], ak[keep], bk[keep], fak[keep], fbk[keep], \
                secant[keep]
            if k.size == 0:
                break
        low, high = np.minimum(ak, bk), np.maximum(ak, bk)
        c = np.where((secant > low) & (secant < high), secant, 0.5 * (ak + bk))
        fc = func(c, k)
        # Anderson-Bjorck: b is always the newest point, a the end kept. When the root lies
        # between b and c the old b becomes the kept end; otherwise the kept end's value is
        # scaled down so that the next secant step moves past it.
        switch = fc * fbk < 0
        with np.errstate(divide="ignore", invalid="ignore"):
            m = 1.0 - fc / fbk
        m = np.where(m > 0, m, 0.5)
        a[k] = np.where(switch, bk, ak)
        fa[k] = np.where(switch, fbk, fak * m)
        b[k], fb[k] = c, fc
        best[k] = c
        active[k[fc == 0]] = False
    return np.exp(best)


def refine_maxima(func, lo, hi, f_lo=None, f_mid=None, f_hi=None, mid=None):
    """Maximum of ``func`` on each interval ``[lo, hi]`` (log frequency).

    Successive parabolic interpolation through a bracketing triple (lo, mid, hi with the
    middle value highest), falling back to a golden-section step whenever the parabola's
    vertex is not strictly inside the bracket; stops when the vertex is within
    :data:`MAXIMUM_TOLERANCE` of the best point.

    ``func(x, which)`` as for :func:`refine_roots`. ``mid``: the starting middle point
    (default (lo + hi) / 2), whose value must be >= those at lo and hi; ``f_lo``, ``f_mid``,
    ``f_hi``: the values at lo, mid and hi if known (the grid values around a grid maximum).

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Frequencies [rad/s] and values at the maxima, shape (k,).
    """
    a, c = np.array(lo, dtype=float), np.array(hi, dtype=float)
    if a.size == 0:
        return np.exp(a), np.zeros(0)
    every = np.arange(a.size)
    b = 0.5 * (a + c) if mid is None else np.array(mid, dtype=float)
    fa = func(a, every) if f_lo is None else np.array(f_lo, dtype=float)
    fb = func(b, every) if f_mid is None else np.array(f_mid, dtype=float)
    fc = func(c, every) if f_hi is None else np.array(f_hi, dtype=float)
    tolerance = MAXIMUM_TOLERANCE * np.maximum(1.0, np.abs(b))
    active = np.ones(a.size, dtype=bool)
    for _ in range(MAX_ROOT_ITERATIONS):
        active &= (c - a) > 2 * tolerance
        if not active.any():
            break
        k = np.flatnonzero(active)
        ak, bk, ck, fak, fbk, fck = a[k], b[k], c[k], fa[k], fb[k], fc[k]
        p = (bk - ak) ** 2 * (fbk - fck) - (bk - ck) ** 2 * (fbk - fak)
        q = (bk - ak) * (fbk - fck) - (bk - ck) * (fbk - fak)
        with np.errstate(divide="ignore", invalid="ignore"):
            x = bk - 0.5 * p / q
        # converged when the parabola's vertex is within the tolerance of the best point
        done = np.isfinite(x) & (np.abs(x - bk) <= tolerance[k])
        if done.any():
            active[k[done]] = False
            keep = ~done
            k, ak, bk, ck, fak, fbk, fck, x = (v[keep] for v in (k, ak, bk, ck, fak, fbk, fck, x))
            if k.size == 0:
                break
        right = (ck - bk) > (bk - ak)
        golden = np.where(right, bk + (1 - _GOLDEN) * (ck - bk), bk - (1 - _GOLDEN) * (bk - ak))
        gap = tolerance[k]
        ok = np.isfinite(x) & (x > ak + gap) & (x < ck - gap)
        x = np.where(ok, x, golden)
        fx = func(x, k)
        higher = fx > fbk
        left_of_b = x < bk
        # new triple: if f(x) > f(b), x is the new middle; else x becomes an end
        na = np.where(higher, np.where(left_of_b, ak, bk), np.where(left_of_b, x, ak))
        nc = np.where(higher, np.where(left_of_b, bk, ck), np.where(left_of_b, ck, x))
        nfa = np.where(higher, np.where(left_of_b, fak, fbk), np.where(left_of_b, fx, fak))
        nfc = np.where(higher, np.where(left_of_b, fbk, fck), np.where(left_of_b, fck, fx))
        a[k], c[k], fa[k], fc[k] = na, nc, nfa, nfc
        b[k] = np.where(higher, x, bk)
        fb[k] = np.where(higher, fx, fbk)
    return np.exp(b), fb
