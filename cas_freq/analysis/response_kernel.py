r"""Every loop and T of a batch on a frequency grid in one compiled pass (numba).

:func:`grid_responses` is :func:`cas_freq.model.loops.responses` on the imaginary axis for the
large grids of :func:`~cas_freq.analysis.analyze.batch_analyze`: the walk of
:func:`cas_freq.model.table.walk` over the same loop table (:func:`cas_freq.model.table.table`,
whatever loops the structure declares), read as data, evaluated point by point instead of as
numpy temporaries of (runs x frequencies). The table comes in as coefficient stacks of one rank
and dtype whatever the architecture (a loop per row of each stack), so one compilation serves
every architecture:

- each stage's polynomials, padded with leading zeros to one width per role (the padding adds
  exact zeros), are summed in real arithmetic at :math:`j\omega` (:func:`_at`);
- each complex division is one real division (:func:`_divide`; the values stay far from
  overflow);
- the delays come in as their responses on the grid from :meth:`DelayModel.response`, so exact
  and Padé delays take the same path.

It agrees with the numpy reference to ~1e-14 relative (rounding order only);
``tests/test_response_kernel.py`` compares them. The kernel runs without the GIL, so
:func:`~cas_freq.analysis.analyze.batch_analyze`'s threads overlap on it.
"""

import numpy as np

from cas_freq.core.jit import cached_jit
from cas_freq.model import parts
from cas_freq.model.loops import LoopResponses
from cas_freq.model.structure import build
from cas_freq.model.table import Values, shaped, table


@cached_jit(inline="always")
def _divide(a, b):
    """a / b with one real division."""
    scale = 1.0 / (b.real * b.real + b.imag * b.imag)
    return complex((a.real * b.real + a.imag * b.imag) * scale,
                   (a.imag * b.real - a.real * b.imag) * scale)


@cached_jit(inline="always")
def _evaluate(c, w, w2, real, imaginary, out):
    """out[j] = the polynomial c (highest power first) at s = j w[j] (w2 = -w^2): the even
    powers give the real part, the odd ones the imaginary part, each by Horner's rule in w2
    (one pass over the grid per coefficient; ``real``, ``imaginary``: work arrays)."""
    size = c.size
    m = w.size
    real[:] = 0.0
    imaginary[:] = 0.0
    for index in range((size + 1) % 2, size, 2):
        coefficient = c[index]
        for j in range(m):
            real[j] = real[j] * w2[j] + coefficient
    for index in range(size % 2, size - 1, 2):
        coefficient = c[index]
        for j in range(m):
            imaginary[j] = imaginary[j] * w2[j] + coefficient
    for j in range(m):
        out[j] = complex(real[j], imaginary[j] * w[j])


@cached_jit(inline="always")
def _polynomial(coefficients, values, shared, k, i, w, w2, real, imaginary, out):
    """Polynomial k of run i on the grid: its precomputed values where every run shares it
    (``shared[k]``), else evaluated into ``out``."""
    if shared[k]:
        return values[k, 0]
    _evaluate(coefficients[k, _row(coefficients, i)], w, w2, real, imaginary, out)
    return out


@cached_jit(inline="always")
def _row(array, i):
    """Row i of a per-run stack (axis 1), or its only row where every run shares it."""
    return i if array.shape[1] > 1 else 0


@cached_jit(nogil=True)
def _responses(w, plant, output, a, b, g, f, reference, values, shared, has_reference,
               delays, fill, loops, aat, t):
    """Fill ``loops`` (k, run, frequency), ``aat`` (the same with every other loop closed; no
    runs where not asked) and ``t`` (no runs where not asked). Stacks (loop, run or 1, width)
    as built by :func:`grid_responses`, ``values`` their precomputed values where every run
    shares polynomial k (``shared``: a flag per polynomial; :func:`_shared_values`);
    ``fill[k]``: how many runs of loop k to write (1 where every run shares its cascade
    response). Each run is evaluated a stage at a time over the
    whole grid (loops over the grid that the compiler vectorises)."""
    count = a.shape[0]
    m = w.size
    with_t = t.shape[0] > 0
    with_aat = aat.shape[1] > 0
    w2 = -w * w
    e = np.empty(m, dtype=np.complex128)
    gain = np.empty(m, dtype=np.complex128)
    sensed = np.empty(m, dtype=np.complex128)
    command = np.empty(m, dtype=np.complex128)
    work = np.empty((5, m), dtype=np.complex128)
    real = np.empty(m)
    imaginary = np.empty(m)
    v_plant, v_output, v_a, v_b, v_g, v_f, v_reference = values
    s_plant, s_output, s_a, s_b, s_g, s_f, s_reference = shared
    inner = np.empty((count, m), dtype=np.complex128)
    terms = np.empty((count, m), dtype=np.complex128)
    betas = np.empty((count, m), dtype=np.complex128)
    for i in range(loops.shape[1]):
        e[:] = _polynomial(plant, v_plant, s_plant, 0, i, w, w2, real, imaginary, work[0])
        for j in range(m):
            gain[j] = 1.0
            sensed[j] = 1.0
            command[j] = 0.0
        for k in range(count):
            d = delays[k, _row(delays, i)]
            bk = _polynomial(b, v_b, s_b, k, i, w, w2, real, imaginary, work[1])
            fk = _polynomial(f, v_f, s_f, k, i, w, w2, real, imaginary, work[2])
            if with_t:
                if has_reference[k]:
                    value = _polynomial(reference, v_reference, s_reference, k, i, w, w2,
                                        real, imaginary, work[3])
                    for j in range(m):
                        command[j] = command[j] * bk[j] + gain[j] * value[j] * d[j]
                else:
                    for j in range(m):
                        command[j] = command[j] * bk[j]
            value = _polynomial(a, v_a, s_a, k, i, w, w2, real, imaginary, work[3])
            for j in range(m):
                gain[j] = gain[j] * value[j] * d[j]
            value = _polynomial(g, v_g, s_g, k, i, w, w2, real, imaginary, work[4])
            write = i < fill[k]
            for j in range(m):
                c = gain[j] * value[j] * sensed[j]
                beta = bk[j] * fk[j]
                if write:
                    loops[k, i, j] = _divide(c, beta * e[j])
                inner[k, j] = e[j]
                terms[k, j] = c
                betas[k, j] = beta
                e[j] = beta * e[j] + c
                sensed[j] = sensed[j] * fk[j]
        if with_t:
            value = _polynomial(output, v_output, s_output, 0, i, w, w2, real, imaginary, work[3])
            for j in range(m):
                t[i, j] = _divide(command[j] * sensed[j] * value[j], e[j])
        if with_aat:
            for j in range(m):
                upper = complex(0.0, 0.0)
                above = complex(1.0, 0.0)
                for k in range(count - 1, -1, -1):
                    upper += terms[k, j] * above
                    above = above * betas[k, j]
                    aat[k, i, j] = _divide(upper, above * inner[k, j])


def _shared_values(stack, shared, omega):
    """A stack's values on the grid, (loops, 1, m), of the polynomials every run shares
    (``shared``, a flag per loop; the others' rows are left unset and each run evaluates its
    own), by the kernel's own arithmetic, so a run's figures do not depend on the runs beside
    it (whether a coefficient varies within a chunk does)."""
    out = np.empty((stack.shape[0], 1, omega.size), dtype=complex)
    _evaluate_all(stack, shared, omega, out)
    return out


@cached_jit(nogil=True)
def _evaluate_all(stack, shared, w, out):
    """out[k, 0] = polynomial k of the stack on the grid (:func:`_evaluate`) where
    ``shared[k]`` (its first row: every row is the same)."""
    w2 = -w * w
    real = np.empty(w.size)
    imaginary = np.empty(w.size)
    for k in range(stack.shape[0]):
        if shared[k]:
            _evaluate(stack[k, 0], w, w2, real, imaginary, out[k, 0])


def _shared(value):
    return np.ndim(value) == 0 or np.size(value) == 1


def _scalar(value):
    return float(np.asarray(value, dtype=float).reshape(-1)[0])


def _rows(coefficients, n, size):
    """A polynomial as a float array (rows, size), padded with leading zeros: one row if no
    coefficient varies between runs, else n."""
    coefficients = (0.0,) * (size - len(coefficients)) + tuple(coefficients)
    if all(_shared(c) for c in coefficients):
        return np.array([[_scalar(c) for c in coefficients]])
    return parts.stacked([c if _shared(c) else np.asarray(c, dtype=float).reshape(-1)
                          for c in coefficients], n)


def _stack(polynomials, n):
    """Polynomials of every loop as one (loops, rows, width) array (rows 1 where all share)."""
    size = max(len(polynomial) for polynomial in polynomials)
    rows = [_rows(polynomial, n, size) for polynomial in polynomials]
    height = max(r.shape[0] for r in rows)
    return np.ascontiguousarray(np.stack([np.broadcast_to(r, (height, size)) for r in rows]))


def _delays(delay, omega, taus, n):
    """The delays' responses on the grid, (loops, 1 or n, m)."""
    values = [np.atleast_2d(delay.response(1j * omega, tau)) for tau in taus]
    height = max(v.shape[0] for v in values)
    return np.ascontiguousarray(
        np.stack([np.broadcast_to(v, (height, omega.size)) for v in values]), dtype=complex)


def grid_responses(p, omega, n, delay, closed=True, feedforward=False, loop_at_a_time=False):
    """Every loop, T (if ``closed``) and the loop-at-a-time responses (if asked) of ``n`` runs
    on the grid ``omega``.

    Parameters
    ----------
    p : types.SimpleNamespace
        The runs' response parameters, each a scalar or a column (n, 1)
        (:class:`~cas_freq.model.loops.Selector` with ``column=True``).
    omega : numpy.ndarray
        Frequencies [rad/s], shape (m,).
    n : int
        Number of runs.
    delay : cas_freq.model.delay.DelayModel
        Exact or Padé delays.
    closed : bool
        Also compute T.
    feedforward : bool
        Let the feed-forward act on the command in T.
    loop_at_a_time : bool
        Also compute every loop with all the others closed.

    Returns
    -------
    cas_freq.model.loops.LoopResponses
        Responses of shape (n, m); a loop that every run shares with all its inner loops
        (typically the current loop) of shape (m,), as :func:`~cas_freq.model.loops.responses`
        broadcasts it.
    """
    omega = np.ascontiguousarray(omega, dtype=float)
    rows = table(build(p), feedforward)
    steps = rows.rows
    count, m = len(steps), omega.size
    references = [s.reference if s.reference is not None else (0.0,) for s in steps]
    roles = ([rows.denominator], [rows.seen], [s.a for s in steps], [s.b for s in steps],
             [s.g for s in steps], [s.f for s in steps], references)
    stacks = tuple(_stack(role, n) for role in roles)
    has_reference = np.array([s.reference is not None for s in steps])
    delays = _delays(delay, omega, [s.tau for s in steps], n)
    # a loop whose rows (and those inside it) are the same in every run is computed once
    fill = np.full(count, n)
    shared = stacks[0].shape[1] == 1
    for k in range(count):
        shared = shared and all(all(_shared(c) for c in polynomial) for polynomial in
                                (steps[k].a, steps[k].b, steps[k].g, steps[k].f))
        shared = shared and _shared(steps[k].tau)
        if shared:
            fill[k] = 1
    loops = np.empty((count, n, m), dtype=complex)
    aat = np.empty((count, n if loop_at_a_time else 0, m), dtype=complex)
    t = np.empty((n if closed else 0, m), dtype=complex)
    shared = tuple(np.array([all(_shared(c) for c in polynomial) for polynomial in role])
                   for role in roles)
    values = tuple(_shared_values(stack, flags, omega)
                   for stack, flags in zip(stacks, shared, strict=True))
    _responses(omega, *stacks, values, shared, has_reference, delays, fill, loops, aat, t)
    names = rows.names
    cascade = {name: loops[k, 0] if fill[k] == 1 else loops[k] for k, name in enumerate(names)}
    return LoopResponses(
        cascade, shaped(t, rows, Values(1j * omega)) if closed else None,
        {name: aat[k] for k, name in enumerate(names)} if loop_at_a_time else None)
