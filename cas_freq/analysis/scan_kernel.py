"""Scans of a batch's grid responses, compiled (numba): first events, magnitudes, chords.

:func:`first_turned_jumps` and :func:`first_fall_below_90` stop at the first event of each
row; :func:`magnitudes` and :func:`long_chords` compute in one pass what numpy computes in
several, with the same operations in the same order (so the same numbers, to the bit).

The numpy forms in :mod:`cas_freq.analysis.margins`, :mod:`cas_freq.analysis.probes` and
:mod:`cas_freq.analysis.closed_loop` (the references, ``tests/test_scan_kernel.py``) test
every grid point of every row and then take the first; these kernels walk each row only up
to its first event, with the same tests (:func:`~cas_freq.analysis.margins.phase_jumps`: the
sign of the cross product of neighbouring points where the imaginary part changes sign). On
the batches of ``benchmarks/run.py`` they replace about ten full passes over (256 x 1,601)
arrays per loop.

Each kernel has one signature (:func:`~cas_freq.core.jit.cached_jit`'s ``arguments``): arrays of any
layout, so that a grid's row slice and the whole grid share one machine code.
"""

import math

import numpy as np
from numba import types

from cas_freq.core.jit import array_type, cached_jit

#: The argument types: a batch's grid responses (n, m), read; real and index arrays.
_GRID = array_type("complex128", 2)
_REAL, _REAL_OUT = array_type("float64", 2), array_type("float64", 2, written=True)
_INDEX, _INDEX_OUT = array_type("int64", 1), array_type("int64", 1, written=True)


@cached_jit(inline="always")
def _jumps(previous, current):
    """True where the wrapped angle jumps by more than pi from ``previous`` to ``current``."""
    upper, next_upper = previous.imag >= 0, current.imag >= 0
    cross = previous.real * current.imag - previous.imag * current.real
    return (upper and not next_upper and cross > 0) or (not upper and next_upper and cross < 0)


@cached_jit(inline="always")
def _quarter_turn(value, quarters):
    """``value * 1j ** quarters`` exactly, as :func:`~cas_freq.analysis.margins.quarter_turn`."""
    if quarters != quarters or abs(quarters) == math.inf:
        return complex(math.nan, math.nan)
    q = quarters % 4.0
    if q == 0.0:
        return value
    if q == 1.0:
        return complex(-value.imag, value.real)
    if q == 2.0:
        return complex(-value.real, -value.imag)
    return complex(value.imag, -value.real)


@cached_jit((_GRID, _INDEX, array_type("float64", 1), types.int64, _INDEX_OUT), nogil=True)
def first_turned_jumps(response, rows, quarters, width, out):
    """out[q]: the first k < width - 1 where ``response[rows[q]]`` turned by ``quarters[q]``
    quarter turns jumps between k and k + 1, else width - 1."""
    for q in range(rows.size):
        i = rows[q]
        out[q] = width - 1
        previous = _quarter_turn(response[i, 0], quarters[q])
        for k in range(width - 1):
            current = _quarter_turn(response[i, k + 1], quarters[q])
            if _jumps(previous, current):
                out[q] = k
                break
            previous = current


@cached_jit((_GRID, _INDEX_OUT, _INDEX_OUT), nogil=True)
def first_fall_below_90(response, crossing, jump):
    """Per row: ``crossing``, the first k where the point leaves the half-planes Re > 0 or
    Im >= 0 between k and k + 1 (m - 1 if never); ``jump``, the first phase jump at or
    before it, else m - 1 (later jumps are not looked for)."""
    n, m = response.shape
    for i in range(n):
        crossing[i] = m - 1
        jump[i] = m - 1
        previous = response[i, 0]
        above = previous.real > 0 or previous.imag >= 0
        for k in range(m - 1):
            current = response[i, k + 1]
            next_above = current.real > 0 or current.imag >= 0
            if jump[i] == m - 1 and _jumps(previous, current):
                jump[i] = k
            if above and not next_above:
                crossing[i] = k
                break
            previous, above = current, next_above


@cached_jit((_GRID, _REAL_OUT, _REAL_OUT, _REAL_OUT), nogil=True)
def magnitudes(response, squared, plus, disk):
    """|L|^2, |1 + L|^2 and |1 - L|^2 / |1 + L|^2 of every point, in one pass."""
    n, m = response.shape
    for i in range(n):
        for k in range(m):
            re, im = response[i, k].real, response[i, k].imag
            im2 = im * im
            squared[i, k] = re * re + im2
            shifted = re + 1.0
            plus[i, k] = shifted * shifted + im2
            shifted = re - 1.0
            disk[i, k] = (shifted * shifted + im2) / plus[i, k]


@cached_jit((_GRID, _REAL, _INDEX_OUT, _INDEX_OUT), nogil=True)
def long_chords(inner, distance2, rows, columns):
    """The intervals (row, k) where the chord from point k to k + 1 is longer than sqrt(3)
    times the nearer end's distance to -1, in row-major order; returns how many (the first
    that many entries of ``rows`` and ``columns``; call with empty arrays to count)."""
    n, m = inner.shape
    count = 0
    for i in range(n):
        for k in range(m - 1):
            chord = inner[i, k + 1] - inner[i, k]
            length2 = chord.real * chord.real + chord.imag * chord.imag
            # (min, unlike numpy.minimum, may drop a NaN; a NaN end makes the chord NaN)
            if length2 > 3.0 * min(distance2[i, k], distance2[i, k + 1]):
                if count < rows.size:
                    rows[count], columns[count] = i, k
                count += 1
    return count


@cached_jit(inline="always")
def _angle_step(re0, im0, re1, im1, log_squared0, log_squared1):
    """:func:`~cas_freq.analysis.probes._angle_steps` of one pair of samples."""
    cross = re0 * im1 - im0 * re1
    dot = re0 * re1 + im0 * im1
    sine = cross * math.exp(-0.5 * (log_squared0 + log_squared1))
    if dot >= 0.0:
        return sine
    sign = 1.0 if cross > 0.0 else (-1.0 if cross < 0.0 else 0.0)
    return sign * (2.0 - abs(sine))


@cached_jit((array_type("float64", 1), _GRID, _REAL, types.float64,
             array_type("bool_", 2, written=True), _REAL_OUT), nogil=True)
def log_corners(log_w, response, log_squared, sharp, corner, size):
    """:func:`~cas_freq.analysis.probes._log_corners` a row at a time: ``corner`` (its size
    and its bend above ``sharp``) and ``size`` (n, m - 4) at the samples k = 2 .. m - 3, the
    same arithmetic in the same order."""
    n, m = response.shape
    steps = np.empty((2, m - 1))  # per row: the steps of ln |L| and of the phase
    divided = np.empty((2, m - 2))  # and their divided second differences
    for i in range(n):
        for q in range(m - 1):
            steps[0, q] = 0.5 * (log_squared[i, q + 1] - log_squared[i, q])
            a, b = response[i, q], response[i, q + 1]
            steps[1, q] = _angle_step(a.real, a.imag, b.real, b.imag, log_squared[i, q],
                                      log_squared[i, q + 1])
        for q in range(m - 2):
            h0, h1 = log_w[q + 1] - log_w[q], log_w[q + 2] - log_w[q + 1]
            span = log_w[q + 2] - log_w[q]
            divided[0, q] = (steps[0, q + 1] - steps[0, q] * (h1 / h0)) / (h1 * span)
            change = 2.0 - np.mod(2.0 - (steps[1, q + 1] - steps[1, q] * (h1 / h0)), 4.0)
            divided[1, q] = change / (h1 * span)
        for j in range(m - 4):
            c0 = (log_w[j] + log_w[j + 1] + log_w[j + 2]) / 3.0
            c1 = (log_w[j + 1] + log_w[j + 2] + log_w[j + 3]) / 3.0
            c2 = (log_w[j + 2] + log_w[j + 3] + log_w[j + 4]) / 3.0
            before, after = c1 - c0, c2 - c1
            weight = after / (before + after)
            span = log_w[j + 3] - log_w[j + 1]
            scale = 0.5 * span ** 2
            size2 = 0.0
            bend2 = 0.0
            for number in range(2):
                middle = divided[number, j + 1]
                between = divided[number, j] * weight + divided[number, j + 2] * (1.0 - weight)
                size2 = size2 + (middle * scale) ** 2
                bend2 = bend2 + ((middle - between) * scale) ** 2
            size[i, j] = math.sqrt(size2)
            corner[i, j] = size[i, j] > sharp and math.sqrt(bend2) > sharp
