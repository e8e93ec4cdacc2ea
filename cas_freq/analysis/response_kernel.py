r"""L_i, L_p and T of a batch on a frequency grid in one compiled pass (numba).

:func:`grid_responses` is :func:`cas_freq.model.loops.responses` on the imaginary axis for
the large grids of :func:`~cas_freq.analysis.analyze.batch_analyze`: the same ratios of the
same polynomials (:mod:`cas_freq.model.parts`), evaluated point by point instead of as a dozen
numpy temporaries of (runs x frequencies). Where ``responses`` documents the ratios, this is
their scalar form:

- each polynomial, padded with leading zeros to a fixed degree (D to 4, n_theta to 2, n_out to
  1: the padding adds exact zeros), is summed in real arithmetic at :math:`j\omega`;
- each complex division is one real division (:func:`_divide`; the values stay far from
  overflow: about 1e60 at most for a compliant drivetrain at 1e7 rad/s);
- the delays come in as their responses on the grid from :meth:`DelayModel.response`, so exact
  and Padé delays take the same path.

It agrees with the numpy reference to ~1e-15 relative (rounding order only);
``tests/test_response_kernel.py`` compares them. The kernel runs without the GIL, so
:func:`~cas_freq.analysis.analyze.batch_analyze`'s threads overlap on it. On the 6-key batch
of ``benchmarks/run.py`` (256 runs x 1,601 frequencies) it takes ~3-5 ms against ~17-24 ms
for numpy.
"""

import numpy as np

from cas_freq.jit import cached_jit
from cas_freq.model import parts
from cas_freq.model.loops import LoopResponses


@cached_jit(inline="always")
def _divide(a, b):
    """a / b with one real division."""
    scale = 1.0 / (b.real * b.real + b.imag * b.imag)
    return complex((a.real * b.real + a.imag * b.imag) * scale,
                   (a.imag * b.real - a.real * b.imag) * scale)


@cached_jit(inline="always")
def _linear(c, w):
    """c[0] s + c[1] at s = j w."""
    return complex(c[1], c[0] * w)


@cached_jit(inline="always")
def _quadratic(c, w, w2):
    """c[0] s^2 + c[1] s + c[2] at s = j w (w2 = -w^2)."""
    return complex(c[0] * w2 + c[2], c[1] * w)


@cached_jit(inline="always")
def _quartic(c, w, w2):
    """c[0] s^4 + ... + c[4] at s = j w (w2 = -w^2)."""
    return complex((c[0] * w2 + c[2]) * w2 + c[4], (c[1] * w2 + c[3]) * w)


@cached_jit(inline="always")
def _row(array, i):
    """Row i of a per-run array, or its only row where every run shares it."""
    return i if array.shape[0] > 1 else 0


@cached_jit(nogil=True)
def _responses(w, ci, ze, d, n_theta, n_out, coupling, km, n_cp, filter_, reference_path,
               on_measurement, feedforward, delay_c, delay_p, factored, li, lp, t):
    """Fill li, lp and t (rows: runs; t may have no rows, li one row for a shared current
    loop). The arguments are those of :func:`grid_responses`, each with one row per run or
    one row for all."""
    with_ff = feedforward.shape[1] > 0
    for i in range(lp.shape[0]):
        c_ci, c_ze, c_d = ci[_row(ci, i)], ze[_row(ze, i)], d[_row(d, i)]
        c_theta, c_out = n_theta[_row(n_theta, i)], n_out[_row(n_out, i)]
        c_cp, c_f = n_cp[_row(n_cp, i)], filter_[_row(filter_, i)]
        c_ref, c_ff = reference_path[_row(reference_path, i)], feedforward[_row(feedforward, i)]
        r_c, r_p = _row(delay_c, i), _row(delay_p, i)
        k_e_m, k_m = coupling[_row(coupling, i)], km[_row(km, i)]
        measured = on_measurement[_row(on_measurement, i)]
        for j in range(w.size):
            wj = w[j]
            w2 = -wj * wj
            s = complex(0.0, wj)
            d_value = _quartic(c_d, wj, w2)
            theta = _quadratic(c_theta, wj, w2)
            drive = _linear(c_ci, wj) * delay_c[r_c, j]
            a = drive * d_value
            back = k_e_m * theta
            if not factored:
                back = back * s
            b = (_linear(c_ze, wj) * d_value + back) * s
            if i < li.shape[0]:
                li[i, j] = _divide(a, b)
            cp_value = _quadratic(c_cp, wj, w2)
            forward = (k_m * delay_p[r_p, j]) * drive
            filter_value = _linear(c_f, wj)
            denominator = (filter_value * (s * s if factored else s)) * (a + b)
            forward_out = forward * _linear(c_out, wj)
            numerator = cp_value * (forward * theta)
            lp[i, j] = _divide(numerator, denominator)
            if t.shape[0]:
                if measured:
                    reference = _linear(c_ref, wj) * filter_value * forward_out
                else:
                    reference = cp_value * forward_out
                if with_ff:
                    rate = (c_ff[0] * s + c_ff[1]) * s
                    reference = reference + rate * s * filter_value * forward_out
                t[i, j] = _divide(reference, denominator + numerator)


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


def _vector(value, dtype=float):
    """Per-run values (n,), or one value for all (1,)."""
    value = np.asarray(value, dtype=dtype).reshape(-1)
    return value if value.size > 1 else value[:1].copy()


def _delay_rows(delay, omega, tau):
    """The delays' responses on the grid: (1, m) if shared, else (n, m)."""
    return np.ascontiguousarray(np.atleast_2d(delay.response(1j * omega, tau)), dtype=complex)


def grid_responses(p, omega, n, delay, closed=True, feedforward=False):
    """L_i, L_p and T (if ``closed``) of ``n`` runs on the grid ``omega``.

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

    Returns
    -------
    cas_freq.model.loops.LoopResponses
        L_p and T of shape (n, m); L_i of shape (m,) where every run has the same current
        loop (as :func:`~cas_freq.model.loops.responses` broadcasts it), else (n, m).
    """
    omega = np.ascontiguousarray(omega, dtype=float)
    d, n_theta, n_out = parts.mechanics(p)
    factored = not np.any(d[-1])
    if factored:  # D/s, as the numpy reference
        d = d[:-1]
    ci, ze = _rows(parts.current_controller(p), n, 2), _rows(parts.electrical(p), n, 2)
    d, n_theta = _rows(d, n, 5), _rows(n_theta, n, 3)
    coupling, delay_c = _vector(parts.back_emf_coupling(p)), _delay_rows(delay, omega, p.tau_c)
    shared_current = all(a.shape[0] == 1 for a in (ci, ze, d, n_theta, coupling, delay_c))
    m = omega.size
    li = np.empty((1 if shared_current else n, m), dtype=complex)
    lp = np.empty((n, m), dtype=complex)
    t = np.empty((n if closed else 0, m), dtype=complex)
    _responses(
        omega, ci, ze, d, n_theta, _rows(n_out, n, 2), coupling, _vector(p.Km),
        _rows(parts.position_controller(p), n, 3), _rows(parts.position_filter(p), n, 2),
        _rows(parts.reference_path(p), n, 2), _vector(p.derivative_on_measurement, bool),
        _rows((p.ff_a, p.ff_v), n, 2) if feedforward else np.zeros((1, 0)),
        delay_c, _delay_rows(delay, omega, p.tau_p), bool(factored), li, lp, t,
    )
    return LoopResponses(li[0] if shared_current else li, lp, t if closed else None)
