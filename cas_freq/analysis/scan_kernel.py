"""Scans of a batch's grid responses that stop at the first event of each row (numba).

The numpy forms in :mod:`cas_freq.analysis.margins` and :mod:`cas_freq.analysis.closed_loop`
(the references, ``tests/test_scan_kernel.py``) test every grid point of every row and then
take the first; these kernels walk each row only up to its first event, with the same tests
(:func:`~cas_freq.analysis.margins.phase_jumps`: the sign of the cross product of
neighbouring points where the imaginary part changes sign). On the batches of
``benchmarks/run.py`` they replace two full passes over (256 x 1,601) arrays per loop.
"""

from cas_freq.jit import cached_jit


@cached_jit(inline="always")
def _jumps(previous, current):
    """True where the wrapped angle jumps by more than pi from ``previous`` to ``current``."""
    upper, next_upper = previous.imag >= 0, current.imag >= 0
    cross = previous.real * current.imag - previous.imag * current.real
    return (upper and not next_upper and cross > 0) or (not upper and next_upper and cross < 0)


@cached_jit(nogil=True)
def first_turned_jumps(response, rows, turn, width, out):
    """out[q]: the first k < width - 1 where ``response[rows[q]] * turn[q]`` jumps between
    k and k + 1, else width - 1."""
    for q in range(rows.size):
        i = rows[q]
        out[q] = width - 1
        previous = response[i, 0] * turn[q]
        for k in range(width - 1):
            current = response[i, k + 1] * turn[q]
            if _jumps(previous, current):
                out[q] = k
                break
            previous = current


@cached_jit(nogil=True)
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
