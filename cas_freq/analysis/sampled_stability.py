r"""Stability of sampled loops from their discrete-time poles (docs/model.md, "Sampled
controllers").

The loops of the declared structure are assembled in discrete-time state space by the one
assembly of the continuous closed loop (:func:`cas_freq.model.state_space.closings`, sampled):
the plant's hold-equivalent at the innermost rate with the current loop's delay exact, analog
measurement filters in that plant, each controller and digital filter discretised by the
generalised bilinear transform, the delays between controllers as delay lines, and a slower
loop seeing the loops inside it lifted to its rate.

A loop is stable when every pole of its closed loop (with the loops inside it) lies inside the
unit circle, marginal within :data:`cas_freq.analysis.stability.MARGINAL_TOLERANCE` of it.
"""

import numpy as np

from cas_freq.analysis.stability import MARGINAL_TOLERANCE
from cas_freq.core.threads import one_blas_thread
from cas_freq.model.sampled import groups
from cas_freq.model.state_space import closings, run_groups, z_to_s
from cas_freq.model.structure import build


def loop_poles(p):
    """The discrete-time poles of every loop closed with the loops inside it, per run.

    Parameters
    ----------
    p : cas_freq.core.parameters.LoopParameters
        The runs, with ``sample_rates``.

    Returns
    -------
    dict of str to list of numpy.ndarray
        Loop name (innermost first) -> each run's poles (complex, in the z-plane of the loop's
        own rate); an inner loop's without those at z = 1 (:func:`_unseen`).
    """
    out = {name: [None] * p.n_runs for name in build(p).names}
    for name, rows, poles, inner in _poles_by_group(p):
        for r, value in zip(rows, poles, strict=True):
            out[name][r] = value[~_unseen(value)] if inner else value
    return out


def loop_verdicts(p):
    """``"stable"``, ``"marginal"`` or ``"unstable"`` of every loop (closed with the loops
    inside it) of every run, as :func:`cas_freq.analysis.stability.loop_verdicts`."""
    out = {name: np.empty(p.n_runs, dtype=object) for name in build(p).names}
    for name, rows, poles, inner in _poles_by_group(p):
        radius = np.abs(poles)
        if inner:
            radius = np.where(_unseen(poles), 0.0, radius)
        out[name][rows] = np.where(
            np.any(radius > 1.0 + MARGINAL_TOLERANCE, axis=-1), "unstable",
            np.where(np.any(radius >= 1.0 - MARGINAL_TOLERANCE, axis=-1), "marginal", "stable"))
    return out


def _poles_by_group(p):
    """(loop name, runs, their poles (runs, states), whether an inner loop) for each group of
    runs that realise alike (one eigenvalue call per group and loop)."""
    top = build(p).names[-1]
    for rows in run_groups(p, sampled=True):
        for name, closing in closings(p.take(rows), n=rows.size, sampled=True,
                                      command=False).items():
            with one_blas_thread():
                yield name, rows, np.linalg.eigvals(closing.closed[0]), name != top


def _unseen(poles):
    """An inner loop's poles at z = 1: modes its loops do not see (the shaft's position) or
    exact cancellations, as the continuous inner loops' factors s
    (:func:`cas_freq.analysis.stability.loop_polynomials`); not counted in its verdict."""
    return np.abs(poles - 1.0) <= MARGINAL_TOLERANCE


def closed_loop_poles(p):
    """The whole loop's discrete-time poles of one run mapped to the s-plane,
    :math:`s = \\ln z / T` [rad/s] (T the outermost loop's period; those at z = 0 left out),
    sorted by real part, largest first: the continuous-time poles whose sampled motion they
    are."""
    names = build(p).names
    s = z_to_s(loop_poles(p)[names[-1]][0], groups(names, p.sample_rates)[-1].period)
    return s[np.argsort(-s.real, kind="stable")]
