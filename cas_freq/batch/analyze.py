"""Every headline figure of ``analyze`` for many variants at once, in bounded memory.

:func:`batch_analyze` works through the runs in chunks (:data:`DEFAULT_CHUNK`): for each chunk
it evaluates L_i, L_p and T on one common grid (that of
:func:`cas_freq.analysis.frequency.frequency_grid`, densified for the chunk's largest total
delay), finds every crossing by sign changes and refines them all together. The figures and
their names are those of ``to_dict(analyze(...))`` (dotted: ``position_loop.phase_margin_deg``,
``closed_loop.bandwidth_rad_s``); a figure that does not exist is NaN.

Peak memory grows with the chunk, not with the number of runs: 112 MiB (tracemalloc peak,
results included) for 100,000 runs at the default chunk of 256 (``benchmarks/run.py``).
"""

import concurrent.futures
import dataclasses
import os

import numpy as np

from cas_freq.analysis.frequency import (
    DEFAULT_POINTS_PER_DECADE,
    DEFAULT_RANGE_RAD_S,
    frequency_grid,
)
from cas_freq.batch.margins import (
    CLOSED_LOOP_FIGURES,
    LOOP_FIGURES,
    closed_loop_figures,
    loop_figures,
)
from cas_freq.batch.responses import Selector, current_loop, responses
from cas_freq.batch.stability import batch_stability
from cas_freq.model.delay import DEFAULT_PADE_ORDER

#: Runs per chunk: the grid responses take about 26 kB per run and response (1,601 points).
DEFAULT_CHUNK = 256

#: Every figure name of a batch analysis, in output order (``stable`` is 1.0 or 0.0).
FIGURES = (
    "stable",
    *(f"current_loop.{name}" for name in LOOP_FIGURES),
    *(f"position_loop.{name}" for name in LOOP_FIGURES),
    *(f"closed_loop.{name}" for name in CLOSED_LOOP_FIGURES),
)


@dataclasses.dataclass(frozen=True, eq=False)
class BatchAnalysis:
    """Figures of n variants.

    Attributes
    ----------
    figures : dict of str to numpy.ndarray
        :data:`FIGURES` -> float array (n,), NaN where a figure does not exist (or is not
        reported because the loop is not stable, as in ``analyze``).
    stability : numpy.ndarray of str
        ``"stable"``, ``"marginal"`` or ``"unstable"`` per run (Padé model of ``pade_order``).
    current_loop_stability : numpy.ndarray of str
        The same for the current loop alone.
    pade_order : int
        Padé order of the stability verdicts.
    """

    figures: dict
    stability: np.ndarray
    current_loop_stability: np.ndarray
    pade_order: int

    def __len__(self):
        return self.stability.shape[0]


def _figures_on(p, omega, verdict, current_verdict, columns=None):
    """Figures of the runs ``p`` on grid ``omega`` (only its first ``columns`` points if
    given), with the raw values :func:`_needs_full_grid` checks."""
    selector = Selector(p)
    grid = responses(selector(column=True), 1j * omega)
    stable = verdict == "stable"
    current_stable = current_verdict == "stable"
    n = p.n_runs
    low = omega[:columns]
    m = low.size

    def evaluator(kind):
        def evaluate(runs, w):
            if kind == "current_loop":
                return current_loop(selector(runs), 1j * w)
            values = responses(selector(runs), 1j * w, closed=kind == "closed_loop")
            return getattr(values, kind)
        return evaluate

    figures = {"stable": stable.astype(float)}
    current = grid.current_loop
    if current.ndim == 1:  # every run has the same current loop: its figures once
        values = loop_figures(evaluator("current_loop"), low, current[None, :m],
                              current_stable[:1])
        values = {key: np.broadcast_to(value, (n,)) for key, value in values.items()}
    else:
        values = loop_figures(evaluator("current_loop"), low, current[:, :m], current_stable)
    figures.update({f"current_loop.{key}": value for key, value in values.items()})
    position = np.broadcast_to(grid.position_loop, (n, omega.size))
    values = loop_figures(evaluator("position_loop"), low, position[:, :m], stable)
    figures.update({f"position_loop.{key}": value for key, value in values.items()})
    closed_grid = np.broadcast_to(grid.closed_loop, (n, omega.size))
    values = closed_loop_figures(evaluator("closed_loop"), low, closed_grid[:, :m], stable)
    figures.update({f"closed_loop.{key}": value for key, value in values.items()})
    tops = {
        "current_loop": np.broadcast_to(np.abs(current[..., m - 1 :]), (n, omega.size - m + 1)),
        "position_loop": np.abs(position[:, m - 1 :]),
        "closed_loop": np.abs(closed_grid[:, m - 1 :]),
    }
    return figures, tops


def _needs_full_grid(figures, tops, stable):
    """Runs whose figures might lie above the split (so the low grid alone cannot be trusted).

    ``tops``: |L_i|, |L_p| and |T| on the log-grid points from the split's last point up. On
    a 200-per-decade log grid the magnitude varies by far less than 2x between points (the
    delay ripple of |T_i| has ~9 points per period at 1e6 rad/s), so twice the sampled
    maximum bounds the magnitude anywhere above: a crossing or peak up there is ruled out when
    that bound cannot produce it.
    """
    need = np.zeros(stable.shape, dtype=bool)
    for loop in ("current_loop", "position_loop"):
        bound = 2.0 * np.max(tops[loop], axis=1)
        gm = figures[f"{loop}.gain_margin_db"]
        with np.errstate(divide="ignore", invalid="ignore"):
            smallest_gm_above = -20.0 * np.log10(bound)
            sensitivity_above = 1.0 / (1.0 - bound)
            disk_above = (1.0 + bound) / (2.0 * (1.0 - bound))
        need |= bound >= 0.5  # |L| up there might reach 1 (bound >= 1 with margin)
        need |= ~np.isfinite(gm) | ~(smallest_gm_above > gm)
        need |= ~(sensitivity_above < figures[f"{loop}._sensitivity_max"])
        need |= ~(disk_above < figures[f"{loop}._disk_distance_max"])
        need |= figures[f"{loop}._maximum_at_top"]
    bound = 2.0 * np.max(tops["closed_loop"], axis=1)
    dc = 10.0 ** (figures["closed_loop.dc_gain_db"] / 20.0)
    closed_need = (
        ~np.isfinite(figures["closed_loop.bandwidth_rad_s"])
        | ~np.isfinite(figures["closed_loop.phase_90_rad_s"])
        | ~(bound / dc < figures["closed_loop._peak"])
        | figures["closed_loop._maximum_at_top"]
    )
    return need | (stable & closed_need)


def _split_index(full, coarse):
    """Number of leading points the densified grid shares with the plain log grid."""
    size = min(full.size, coarse.size)
    differ = np.flatnonzero(full[:size] != coarse[:size])
    return int(differ[0]) if differ.size else size


def _chunk_figures(p, frequency_range, points_per_decade, pade_order):
    """Figures of one chunk.

    The grid of the single path is a log grid, densified with linear steps above the
    frequency where the delays turn the phase faster than the log spacing (~74,000 rad/s for
    the shipped config). The chunk is first analysed on the plain log grid, of which the points
    below that frequency are exactly the single path's; only runs for which something could
    lie above (:func:`_needs_full_grid`) are analysed again on the full grid. The figures are
    the same either way; the split saves the ~40 % of points that only matter in rare cases.
    """
    total_delay = float(np.max(p.tau_c + p.tau_p))
    full = frequency_grid(*frequency_range, points_per_decade, total_delay)
    verdict, current_verdict = batch_stability(p, pade_order)
    coarse = frequency_grid(*frequency_range, points_per_decade, 0.0)
    split = _split_index(full, coarse)
    if split >= coarse.size - 1 or split < 3:
        figures, _ = _figures_on(p, full, verdict, current_verdict)
        return figures, verdict, current_verdict
    figures, tops = _figures_on(p, coarse, verdict, current_verdict, columns=split)
    need = _needs_full_grid(figures, tops, verdict == "stable")
    if need.any():
        rows = np.flatnonzero(need)
        again, _ = _figures_on(p.take(rows), full, verdict[rows], current_verdict[rows])
        for name, value in again.items():
            figures[name] = np.array(figures[name], copy=True)
            figures[name][rows] = value
    return figures, verdict, current_verdict


def batch_analyze(
    params,
    frequency_range=DEFAULT_RANGE_RAD_S,
    points_per_decade=DEFAULT_POINTS_PER_DECADE,
    pade_order=DEFAULT_PADE_ORDER,
    chunk_size=DEFAULT_CHUNK,
    progress=None,
    workers=None,
):
    """Analyse every run of a batch (exact delays; stability from Padé-model poles).

    Parameters
    ----------
    params : cas_freq.simulation.LoopParameters
        The variants (n runs).
    frequency_range : (float, float)
        Analysed range [rad/s].
    points_per_decade : int
        Grid density before refinement [1/decade].
    pade_order : int
        Padé order of the stability verdict (``analyze`` uses 6).
    chunk_size : int
        Runs evaluated together (bounds the memory).
    progress : callable, optional
        ``progress(done, total)`` after each chunk.
    workers : int, optional
        Threads evaluating chunks side by side (default: the CPU count). The figures do not
        depend on it: each chunk is computed alone and put in its place.

    Returns
    -------
    BatchAnalysis
    """
    n = params.n_runs
    figures = {name: np.empty(n) for name in FIGURES}
    verdict = np.empty(n, dtype=object)
    current = np.empty(n, dtype=object)
    starts = range(0, n, chunk_size)

    def work(start):
        chunk = params.take(slice(start, min(start + chunk_size, n)))
        return _chunk_figures(chunk, frequency_range, points_per_decade, pade_order)

    # numpy releases the GIL inside its array loops, so chunks overlap on several cores
    with concurrent.futures.ThreadPoolExecutor(max_workers=_workers(workers, len(starts))) as pool:
        for start, (values, v, c) in zip(starts, pool.map(work, starts), strict=True):
            stop = min(start + chunk_size, n)
            for name in FIGURES:
                figures[name][start:stop] = values[name]
            verdict[start:stop], current[start:stop] = v, c
            if progress:
                progress(stop, n)
    return BatchAnalysis(figures, verdict, current, pade_order)


def _workers(requested, chunks):
    count = (os.cpu_count() or 1) if requested is None else requested
    if not (isinstance(count, int) and count >= 1):
        raise ValueError(f"workers: need an integer >= 1, got {requested!r}")
    return max(1, min(count, chunks))


def analysis_figures(analysis_dict):
    """The :data:`FIGURES` of a single-variant ``to_dict(analyze(...))``, NaN for None.

    For comparing the batch with the single-variant path.
    """
    out = {"stable": 1.0 if analysis_dict["stable"] else 0.0}
    for loop in ("current_loop", "position_loop"):
        data = analysis_dict[loop]
        for name in LOOP_FIGURES:
            if name == "gain_crossover_count":
                value = len(data["gain_crossovers"])
            else:
                value = data[name]
            out[f"{loop}.{name}"] = np.nan if value is None else float(value)
    for name in CLOSED_LOOP_FIGURES:
        value = analysis_dict["closed_loop"][name]
        out[f"closed_loop.{name}"] = np.nan if value is None else float(value)
    return out
