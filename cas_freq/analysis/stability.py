r"""Closed-loop stability of one or many variants, from the Padé model (numpy only).

The position closed loop contains the current closed loop, so its poles decide both. A pole
whose real part is within a relative 1e-9 of zero is called marginal: the loop neither grows nor
decays there, and no frequency-domain figure of it is trustworthy.

Verdicts (all variants at once). The poles of the Padé model of order n of loops 0..k closed
are the roots of :math:`E_k`, the recurrence of :mod:`cas_freq.model.structure` in polynomial
arithmetic (:func:`loop_polynomials`) with the Padé approximant
:math:`e^{-x} \approx D(-x)/D(x)`. For the report's drive:

.. math::
    Q_c(s) = s\,D(s\tau_c)\,(Z_e P_m + K_e K_m) + n_{ci}(s)\,D(-s\tau_c)\,P_m

    Q(s) = s (T_f s + 1)\,D(s\tau_p)\,s\,Q_c(s)
           + K_m\,n_{cp}(s)\,D(-s\tau_p)\,n_{ci}(s)\,D(-s\tau_c)

:math:`Q_c` decides the current loop alone, :math:`Q` the whole actuator (either derivative
placement: the feedback path is :math:`C_p` in both). The verdict is read from the Routh array
of the scaled polynomial (no root finding), with a running bound on each entry's rounding error
(from the coefficients' own, :func:`loop_polynomial_bounds`). Where the array is ambiguous (a
first-column entry not clear of zero by :data:`~cas_freq.analysis.routh.ROUTH_SAFETY` times its
bound, or a root near s = 0: :func:`~cas_freq.analysis.routh.verdicts`) the poles are computed
and judged by :func:`pole_verdict`.

Poles (:func:`closed_loop_poles`): the eigenvalues of the closed-loop state matrix that
:func:`loop_system` assembles from the declared structure: the plant states (i, omega, theta)
of :func:`cas_freq.model.parts.plant_matrices`, each controller in its minimal form, the
filters and the Padé cascades of :func:`cas_freq.model.delay.pade_realization`. Eigenvalues of
the block matrix are preferred to polynomial roots: the polynomial mixes poles from ~10 rad/s
to ~1e5 rad/s, so its coefficients span tens of decades, while the block matrix holds the
physical coefficients themselves and LAPACK balances it. The current loop alone
(:func:`current_loop_poles`) drops the modes the current does not see.

Exact common factors are cancelled before realising, so no spurious pole appears: ``Ki = 0``
in a controller drops its integrator, ``Kd = 0`` drops the derivative filter (even with
``Tf`` set), and with ``mu_v = 0`` the current loop's integrator pole cancels the zero of Y at
s = 0 (the frictionless shaft drifts at constant speed with i = 0, a mode unobservable from i):
the current-loop verdict then uses ``C_i Y = J (K_p s + K_i) / D``. The whole loop observes
that mode through theta and keeps every state.
"""

import dataclasses

import numpy as np

from cas_freq.analysis.routh import verdicts
from cas_freq.model import parts
from cas_freq.model.delay import DEFAULT_PADE_ORDER, pade_realization
from cas_freq.model.structure import SIGNALS, build
from cas_freq.model.table import Polynomials, table, walk

#: |Re p| <= MARGINAL_TOLERANCE * max(1, |p|) counts as on the imaginary axis.
MARGINAL_TOLERANCE = 1e-9


def loop_polynomials(p, order=DEFAULT_PADE_ORDER):
    """Characteristic polynomials of loops 0..k closed, for every k, of each run.

    The recurrence :math:`E_k = b_k f_k E_{k-1} + c_k` of :mod:`cas_freq.model.structure` in
    polynomial arithmetic, with each delay its Padé approximant :math:`D(-s\tau)/D(s\tau)`
    and each controller in its minimal form. An inner loop's polynomial (k below the top) is
    divided by its factors s: those are modes its loops do not see (the shaft's position,
    unless a hinge stiffness acts on it) or exact cancellations (the frictionless shaft's zero
    of Y at 0 against the current integrator), never closed-loop poles of those loops.

    Parameters
    ----------
    p : cas_freq.parameters.LoopParameters
        The runs.
    order : int
        Padé order of every delay.

    Returns
    -------
    dict of str to numpy.ndarray
        Loop name (innermost first) -> stack of coefficients (highest power first; leading
        zeros where a delay or Tf is 0): that loop closed with every loop inside it.
    """
    return {name: e for name, (e, _) in _loop_recurrence(p, order, magnitudes=False).items()}


def loop_polynomial_bounds(p, order=DEFAULT_PADE_ORDER):
    """:func:`loop_polynomials` with, beside each stack, the same recurrence in the absolute
    values of every coefficient: each coefficient of that magnitude polynomial bounds the sum
    of the absolute values of the terms its coefficient was summed from, so a coefficient's
    rounding error is at most a few unit roundoffs per operation times it (Higham, *Accuracy
    and Stability of Numerical Algorithms*, 2nd ed., section 5.1 and problem 3.7).

    Returns
    -------
    dict of str to (numpy.ndarray, numpy.ndarray)
        Loop name -> (coefficients, magnitudes), both deflated alike.
    """
    return _loop_recurrence(p, order, magnitudes=True)


def _loop_recurrence(p, order, magnitudes):
    n = p.n_runs
    rows = table(build(p), minimal=True)
    results = []
    for transform in (None, np.abs) if magnitudes else (None,):
        algebra = Polynomials(n, order, transform)
        results.append({name: np.column_stack(e)
                        for name, e in walk(rows, algebra).characteristic.items()})
    names = rows.names
    paired = {}
    for k, name in enumerate(names):
        e = results[0][name]
        m = results[1][name] if magnitudes else None
        if k < len(names) - 1:
            e, m = _without_roots_at_zero(e, m)
        paired[name] = (e, m)
    return paired


def characteristic_polynomials(p, order=DEFAULT_PADE_ORDER):
    """(Q_c, Q): current-loop and whole-loop characteristic polynomials of each run
    (the first and last of :func:`loop_polynomials`).

    Parameters
    ----------
    p : cas_freq.parameters.LoopParameters
        The runs.
    order : int
        Padé order of every delay.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        Stacks of coefficients (highest power first); leading zeros where a delay or Tf is 0.
    """
    polynomials = list(loop_polynomials(p, order).values())
    return polynomials[0], polynomials[-1]


def _without_roots_at_zero(polynomials, magnitudes=None):
    """The polynomials with every factor s divided out (trailing zero coefficients), and
    ``magnitudes`` (if given) shifted alike."""
    out = polynomials.copy()
    bounds = None if magnitudes is None else magnitudes.copy()
    for _ in range(polynomials.shape[1] - 1):
        rows = (out[:, -1] == 0) & np.any(out != 0, axis=1)
        if not rows.any():
            break
        out = _deflated(out, rows)
        if bounds is not None:
            bounds = _deflated(bounds, rows)
    return out, bounds


def _deflated(polynomials, rows):
    """The polynomials with one factor s divided out in ``rows`` (their last coefficient 0)."""
    out = polynomials.copy()
    out[rows, 1:] = polynomials[rows, :-1]
    out[rows, 0] = 0.0
    return out


def loop_verdicts(p, order=DEFAULT_PADE_ORDER):
    """Verdicts of every loop closed with the loops inside it, for every run of ``p``.

    Parameters
    ----------
    p : cas_freq.parameters.LoopParameters
        The runs.
    order : int
        Padé order of every delay.

    Returns
    -------
    dict of str to numpy.ndarray
        Loop name (innermost first) -> ``"stable"``, ``"marginal"`` or ``"unstable"`` per run
        (object arrays); the last is the whole actuator's.
    """
    bounded = loop_polynomial_bounds(p, order)
    polynomials = {name: e for name, (e, _) in bounded.items()}
    names = list(polynomials)

    def fallback(name):
        if name == names[-1]:
            return lambda rows: [pole_verdict(poles) for poles in
                                 closed_loop_poles_of_runs(p.take(rows), order)]
        if name == names[0]:
            return lambda rows: [pole_verdict(current_loop_poles(p.run(r), order)) for r in rows]
        return lambda rows: [pole_verdict(poles) for poles in
                             _roots_of_rows(polynomials[name][rows])]

    return {name: verdicts(polynomial, fallback(name), bounded[name][1])
            for name, polynomial in polynomials.items()}


def stability_verdicts(p, order=DEFAULT_PADE_ORDER):
    """(whole-loop verdicts, current-loop verdicts) of every run of ``p`` (Padé order n).

    Parameters
    ----------
    p : cas_freq.parameters.LoopParameters
        The runs.
    order : int
        Padé order of every delay.

    Returns
    -------
    (numpy.ndarray, numpy.ndarray)
        ``"stable"``, ``"marginal"`` or ``"unstable"`` per run (object arrays).
    """
    every = list(loop_verdicts(p, order).values())
    return every[-1], every[0]


@dataclasses.dataclass(frozen=True)
class Stability:
    """Closed-loop stability verdict.

    Attributes
    ----------
    verdict : str
        ``"stable"``, ``"marginal"`` or ``"unstable"``.
    pade_order : int
        Padé order of the delays in the model whose poles were computed.
    current_loop_verdict : str
        The same verdict for the current loop T_i alone.
    poles : tuple of (float, float)
        Closed-loop poles of T as (real, imaginary) [rad/s], sorted by real part, largest first.
    """

    verdict: str
    pade_order: int
    current_loop_verdict: str
    poles: tuple

    @property
    def stable(self):
        """True only for a strictly stable closed loop."""
        return self.verdict == "stable"


def pole_verdict(poles):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` for continuous-time poles [rad/s]."""
    poles = np.asarray(poles, dtype=complex)
    if poles.size == 0:
        return "stable"
    tolerance = MARGINAL_TOLERANCE * np.maximum(1.0, np.abs(poles))
    if np.any(poles.real > tolerance):
        return "unstable"
    if np.any(np.abs(poles.real) <= tolerance):
        return "marginal"
    return "stable"


def closed_loop_stability(params, pade_order=DEFAULT_PADE_ORDER):
    """Stability of the current loop and of the whole actuator of one variant.

    The verdicts are those of :func:`stability_verdicts` (the same for every variant of a
    batch); the poles are listed too.

    Parameters
    ----------
    params : cas_freq.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order of the delays.

    Returns
    -------
    Stability
    """
    params = parts.one_variant(params)
    verdict, current = stability_verdicts(params, pade_order)
    poles = closed_loop_poles(params, pade_order)
    return Stability(
        verdict=str(verdict[0]),
        pade_order=pade_order,
        current_loop_verdict=str(current[0]),
        poles=tuple((float(p.real), float(p.imag)) for p in poles),
    )


def _scalars(p):
    """The one run of ``p`` with every parameter a Python float."""
    return {name: getattr(p, name)[0].item() for name in (
        "R", "L", "Km", "Ke", "J", "mu_v", "ci_Kp", "ci_Ki", "tau_c", "cp_Kp", "cp_Ki",
        "cp_Kd", "Tf", "tau_p", "ratio", "K_g", "c_g", "K_h", "J_L", "b_L", "eta")}


def closed_loop_poles(params, pade_order):
    """Poles [rad/s] of T = theta/theta_cmd with Padé delays, sorted by real part, largest first.

    The eigenvalues of the closed-loop state matrix of :func:`loop_system`.

    Parameters
    ----------
    params : cas_freq.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order n >= 1 of every delay.

    Returns
    -------
    numpy.ndarray
        Complex poles [rad/s]; 2n + 6 of them for the report's drive unless a controller
        term is zero.
    """
    return _sorted(np.linalg.eigvals(loop_system(params, pade_order)[0]))


def loop_system(params, pade_order, loops=None):
    """The actuator with its loops closed as a state-space system, from the declared structure.

    Inside out: the plant of :func:`cas_freq.model.parts.plant_matrices` (input V, outputs the
    signals of :data:`cas_freq.model.structure.SIGNALS`); each loop puts its forward path
    (controller in its minimal form, path filters, Padé delay) in front and closes through its
    sensor on the signal it measures. The result has the outermost loop's command as input and
    the four signals as outputs.

    Parameters
    ----------
    params : cas_freq.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order n >= 1 of every delay.
    loops : int, optional
        Close only this many loops, from the inside (default all).

    Returns
    -------
    tuple of numpy.ndarray
        (A, B, C, D); outputs in the order of :data:`cas_freq.model.structure.SIGNALS`.
    """
    return _assemble(parts.one_variant(params), pade_order, loops)


def _assemble(p, pade_order, loops=None, n=None):
    """:func:`loop_system` of one run (``n`` None: 2-D matrices) or of the ``n`` runs of
    ``p`` at once (stacks (n, ., .); every run must realise to the same state count, as
    :func:`_realization_shapes` groups them). The stacks hold, run by run, the same numbers
    as the one-run matrices: every product here has an inner dimension of 1 (one rounding)."""
    structure = build(p)
    a, b = parts.plant_matrices(p)
    states = a.shape[-1]
    if n is None:
        a, b, lead = a[0], b[0, :, :1], ()
        ratio = np.asarray(p.ratio, dtype=float).reshape(-1)[:1]
    else:
        b, lead = b[:, :, :1], (n,)
        ratio = np.broadcast_to(np.asarray(p.ratio, dtype=float), (n,))
    rows = np.zeros((*lead, 4, states))
    rows[..., 0, 0] = rows[..., 1, 1] = rows[..., 2, 2] = 1.0
    values, inverse = np.unique(ratio, return_inverse=True)
    output = np.stack([parts.fin_output(states, float(r)) for r in values])[inverse]
    rows[..., 3, :] = output[0] if n is None else output
    system = (a, b, rows, np.zeros((4, 1)))
    chosen = structure.loops[:loops]
    for k, loop in enumerate(chosen):
        forward = loop_forward(loop, pade_order, reference=k == len(chosen) - 1, n=n)
        system = _feedback(series(forward, system), SIGNAL_ROWS[loop.feedback],
                           loop_sensor(loop, n))
    return system


def closed_loop_poles_of_runs(p, pade_order):
    """:func:`closed_loop_poles` of every run of ``p`` (unsorted), the state matrices built
    and their eigenvalues found a group of runs at a time (runs whose blocks realise to the
    same state count): the same matrices, so the same eigenvalues, as run by run, without
    its cost in Python (about 3 ms a run for the cascade; a few microseconds here).

    Parameters
    ----------
    p : cas_freq.parameters.LoopParameters
        The runs.
    pade_order : int
        Padé order n >= 1 of every delay.

    Returns
    -------
    list of numpy.ndarray
        Complex poles [rad/s] of each run.
    """
    n = p.n_runs
    structure = build(p)
    if structure.loops[-1].reference is not None:  # the command's own path: run by run
        return [closed_loop_poles(p.run(r), pade_order) for r in range(n)]
    shapes = _realization_shapes(p, structure, n)
    _, group = np.unique(shapes, axis=0, return_inverse=True)
    out = [None] * n
    for g in range(int(group.max()) + 1 if n else 0):
        rows = np.flatnonzero(group.reshape(-1) == g)
        a = _assemble(p.take(rows), pade_order, n=rows.size)[0]
        for r, poles in zip(rows, np.linalg.eigvals(a), strict=True):
            out[r] = poles
    return out


def _realization_shapes(p, structure, n):
    """Per run, what sets its state count: a compliant gear, each realised denominator's
    leading zeros (a controller without its integrator, a filter of zero time constant) and
    each delay being zero; (n, k) integers."""
    columns = [np.broadcast_to(np.asarray(p.K_g) > 0, (n,))]
    for loop in structure.loops:
        columns += realised_orders(loop, n)
        columns.append(np.broadcast_to(np.asarray(loop.delay, dtype=float) == 0,
                                       (n,)).reshape(-1))
    return np.column_stack(columns).astype(int)


def realised_orders(loop, n):
    """Per run, the leading zeros of each denominator a loop's blocks realise (its controller
    in its minimal form, its path and sensor filters): what sets their state counts."""
    controller = loop.controller
    denominators = [controller.minimal()[1] if controller.minimal else
                    parts.stacked(controller.denominator, n)]
    denominators += [parts.stacked(block.denominator, n) for block in (*loop.path, *loop.sensor)]
    return [np.argmax(d != 0, axis=1) for d in denominators]


def _roots_of_rows(polynomials):
    """``np.roots`` of each row (leading zeros allowed), the companion matrices of rows with
    the same leading and trailing zeros stacked for one eigenvalue call (the matrices
    ``np.roots`` builds, so the same roots); rows that are equal (an inner loop that a sweep
    of an outer loop's gains leaves alone) are solved once."""
    distinct, inverse = np.unique(polynomials, axis=0, return_inverse=True)
    roots = _distinct_roots(distinct)
    return [roots[i] for i in inverse.reshape(-1)]


def _distinct_roots(polynomials):
    """:func:`_roots_of_rows` of rows without repeats."""
    nonzero = polynomials != 0
    width = polynomials.shape[1]
    first = np.argmax(nonzero, axis=1)
    last = width - 1 - np.argmax(nonzero[:, ::-1], axis=1)
    out = [None] * polynomials.shape[0]
    keys = np.column_stack([first, last])
    for key in np.unique(keys, axis=0):
        rows = np.flatnonzero(np.all(keys == key, axis=1))
        start, stop = int(key[0]), int(key[1])
        kept = polynomials[rows, start:stop + 1]
        size = kept.shape[1]
        if size > 1:
            companion = np.zeros((rows.size, size - 1, size - 1))
            companion[:, 1:, :-1] = np.eye(size - 2)
            companion[:, 0, :] = -kept[:, 1:] / kept[:, :1]
            roots = np.linalg.eigvals(companion)
        else:
            roots = np.zeros((rows.size, 0), dtype=complex)
        zeros = np.zeros((rows.size, width - 1 - stop), dtype=roots.dtype)
        for r, value in zip(rows, np.hstack((roots, zeros)), strict=True):
            out[r] = value
    return out


#: Output row of each measured signal in :func:`loop_system`.
SIGNAL_ROWS = {name: row for row, name in enumerate(SIGNALS)}


def loop_forward(loop, pade_order, reference=False, n=None):
    """A loop's forward path (controller, path filters, Padé delay) in state space with two
    input columns: the error, and the command (the same column unless ``reference`` and the
    controller's command path differs: the derivative on the measurement). Realised in its
    minimal form (exact common factors cancelled). One run (2-D matrices), or stacks over
    ``n`` runs that realise alike (no command path of its own)."""
    controller = loop.controller
    if reference and loop.reference is not None:
        if n is not None:
            raise ValueError("a command path of its own is realised run by run")
        numerators, denominator = _cancel_zero_roots(
            [parts.stacked(controller.numerator, 1)[0], parts.stacked(loop.reference, 1)[0]],
            parts.stacked(controller.denominator, 1)[0])
        first = _realize(numerators[0], denominator)
        command = _realize(numerators[1], denominator)
        first = (first[0], np.hstack([first[1], command[1]]), first[2],
                 np.hstack([first[3], command[3]]))
    else:
        numerator, denominator = (controller.minimal() if controller.minimal else
                                  (parts.stacked(controller.numerator, n or 1),
                                   parts.stacked(controller.denominator, n or 1)))
        if n is None:
            numerator, denominator = numerator[0], denominator[0]
        first = _realize(numerator, denominator)
        first = (first[0], _concatenate([first[1]] * 2, -1), first[2],
                 _concatenate([first[3]] * 2, -1))
    return series(first, _delay_free(loop, pade_order, n))


def _delay_free(loop, pade_order, n=None):
    """The path filters and the Padé delay of a loop, in series."""
    rest = (np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.ones((1, 1)))
    for block in loop.path:
        rest = series(rest, _realize_block(block, n))
    return series(rest, _pade(loop.delay, pade_order, n))


def _pade(delay, pade_order, n=None):
    """:func:`~cas_freq.model.delay.pade_realization` of a loop's delay: of one run, or a
    stack over ``n`` runs whose delays are all zero or all positive (2-D where they share it)."""
    taus = np.asarray(delay, dtype=float).reshape(-1)
    values, inverse = np.unique(taus, return_inverse=True)
    if n is None or values.size == 1:
        return pade_realization(float(values[0] if n is not None else taus[0]), pade_order)
    each = [pade_realization(float(tau), pade_order) for tau in values]
    return tuple(np.stack([m[i] for m in each])[np.broadcast_to(inverse, (n,))]
                 for i in range(4))


def loop_sensor(loop, n=None):
    """A loop's sensor filters in state space, None for a plain measurement."""
    sensor = None
    for block in loop.sensor:
        sensor = _realize_block(block, n) if sensor is None else series(
            sensor, _realize_block(block, n))
    return sensor


def _cancel_zero_roots(numerators, denominator):
    """Divide out every factor s common to all numerators and the denominator."""
    numerators = [np.trim_zeros(np.asarray(n, dtype=float), "f") for n in numerators]
    denominator = np.trim_zeros(np.asarray(denominator, dtype=float), "f")
    while denominator.size > 1 and denominator[-1] == 0 and all(
            n.size > 1 and n[-1] == 0 for n in numerators):
        numerators = [n[:-1] for n in numerators]
        denominator = denominator[:-1]
    return numerators, denominator


def _realize_block(block, n=None):
    numerator = parts.stacked(block.numerator, n or 1)
    denominator = parts.stacked(block.denominator, n or 1)
    if n is None:
        return _realize(numerator[0], denominator[0])
    return _realize(numerator, denominator)


def _trim_leading(coefficients):
    """The coefficients (..., width) without the leading columns that are zero in every row."""
    nonzero = np.any(coefficients.reshape(-1, coefficients.shape[-1]) != 0, axis=0)
    return coefficients[..., int(np.argmax(nonzero)) if nonzero.any() else coefficients.shape[-1]:]


def _realize(numerator, denominator):
    """(A, B, C, D) of a proper rational function (coefficients, highest power first) in
    observable companion form, normalised by the leading denominator coefficient. Rows of
    stacks (runs, width) give stacks (runs, ., .); their denominators must share a degree."""
    denominator = _trim_leading(np.asarray(denominator, dtype=float))
    numerator = _trim_leading(np.asarray(numerator, dtype=float))
    order = denominator.shape[-1] - 1
    lead = np.broadcast_shapes(numerator.shape[:-1], denominator.shape[:-1])
    if numerator.shape[-1] > order + 1:  # leading zeros of some rows only
        numerator = numerator[..., -(order + 1):]
    numerator = np.concatenate([np.zeros((*numerator.shape[:-1], order + 1 - numerator.shape[-1])),
                                numerator], axis=-1) / denominator[..., :1]
    denominator = denominator / denominator[..., :1]
    d = numerator[..., 0]
    a = np.zeros((*lead, order, order))
    if order:
        a[..., :, 0] = -denominator[..., 1:]
        a[..., :-1, 1:] = np.eye(order - 1)
    b = (numerator[..., 1:] - d[..., None] * denominator[..., 1:])[..., None]
    c = np.zeros((*lead, 1, order))
    if order:
        c[..., 0, 0] = 1.0
    return a, b, c, d[..., None, None]


def _concatenate(arrays, axis):
    """np.concatenate of matrices and stacks of matrices (leading axes broadcast)."""
    lead = np.broadcast_shapes(*(m.shape[:-2] for m in arrays))
    return np.concatenate([np.broadcast_to(m, (*lead, *m.shape[-2:])) for m in arrays],
                          axis=axis)


def _feedback(system, row, sensor=None):
    """Negative feedback of output ``row`` (through ``sensor``, if any) to the first input;
    the second input (the command) stays, every output kept. The fed-back output has no
    direct term, as every measured signal here. Matrices or stacks of them."""
    a, b, c, d = system
    b_error, b_command = b[..., :, :1], b[..., :, 1:]
    d_error, d_command = d[..., :, :1], d[..., :, 1:]
    measured = c[..., row:row + 1, :]
    if sensor is None:
        return a - b_error @ measured, b_command, c - d_error @ measured, d_command
    a_s, b_s, c_s, d_s = sensor
    m, q = a.shape[-1], a_s.shape[-1]
    lead = np.broadcast_shapes(*(x.shape[:-2] for x in (*system, *sensor)))
    a_new = np.zeros((*lead, m + q, m + q))
    a_new[..., :m, :m] = a - b_error @ d_s @ measured
    a_new[..., :m, m:] = -b_error @ c_s
    a_new[..., m:, :m] = b_s @ measured
    a_new[..., m:, m:] = a_s
    c_new = _concatenate([c - d_error @ d_s @ measured, -d_error @ c_s], -1)
    b_new = _concatenate([b_command, np.zeros((q, 1))], -2)
    return a_new, b_new, c_new, d_command


def current_loop_poles(params, pade_order):
    """Poles [rad/s] of T_i = i/i_cmd with a Padé current delay (exact cancellations removed).

    Parameters
    ----------
    params : cas_freq.parameters.LoopParameters or cas_freq.config.ActuatorConfig
        One variant.
    pade_order : int
        Padé order n >= 1 of the current-loop delay.

    Returns
    -------
    numpy.ndarray
        Complex poles [rad/s], sorted by real part, largest first.
    """
    params = parts.one_variant(params)
    v = _scalars(params)
    delay = pade_realization(v["tau_c"], pade_order)
    rigid_free = v["K_g"] == 0 and v["K_h"] == 0  # the shaft's position is not seen from i
    if rigid_free and v["mu_v"] == 0 and v["b_L"] == 0 and v["ci_Ki"] > 0:
        # C_i Y = (Kp s + Ki) J_eff / D: with mu_eff = 0, J_eff omega' = Km i, so i = (J_eff/Km)
        # s omega and the plant (i, omega) read out as Kp i + (J_eff Ki/Km) omega has exactly
        # this transfer.
        j_eff = v["J"] + v["J_L"] / (v["eta"] * v["ratio"] ** 2)
        output = np.array([[v["ci_Kp"], j_eff * v["ci_Ki"] / v["Km"]]])
        forward = series(delay, _plant(params, output, states=2))
    else:
        a, b, c, d = loop_forward(build(params).loops[0], pade_order)
        forward = series((a, b[:, :1], c, d[:, :1]),
                         (*parts.current_plant_matrices(params), np.zeros((1, 1))))
    return _sorted(np.linalg.eigvals(_close_loop(forward, 0, 0)[0]))


def _sorted(poles):
    return poles[np.argsort(-poles.real, kind="stable")]


def _plant(params, output, states=3):
    """The plant of :func:`cas_freq.model.parts.plant_matrices`, input V [V], states
    (i, omega[, theta]), outputs ``output @ x``."""
    a, b = parts.plant_matrices(params)
    return (a[0, :states, :states], b[0, :states, :1], np.asarray(output, dtype=float),
            np.zeros((output.shape[0], 1)))


def series(first, second):
    """``first`` then ``second`` (single input; ``first`` single output); matrices or stacks
    of them (leading axes broadcast)."""
    a1, b1, c1, d1 = first
    a2, b2, c2, d2 = second
    m1, m2 = a1.shape[-1], a2.shape[-1]
    lead = np.broadcast_shapes(*(m.shape[:-2] for m in (*first, *second)))
    a = np.zeros((*lead, m1 + m2, m1 + m2))
    a[..., :m1, :m1] = a1
    a[..., m1:, :m1] = b2 @ c1
    a[..., m1:, m1:] = a2
    return a, _concatenate([b1, b2 @ d1], -2), _concatenate([d2 @ c1, c2], -1), d2 @ d1


def _close_loop(system, feedback_row, output_row):
    """Unity negative feedback u = r - y[feedback_row]; returns (A, B, C, D) for y[output_row].

    The fed-back output must be strictly proper (zero feedthrough), as every loop here is.
    """
    a, b, c, d = system
    if np.any(d[feedback_row] != 0):
        raise AssertionError("feedback through a direct term")  # pragma: no cover
    a_closed = a - b @ c[feedback_row:feedback_row + 1]
    return a_closed, b, c[output_row:output_row + 1], d[output_row:output_row + 1]
