"""Every frequency-domain figure of one variant or of many at once (one engine).

:func:`batch_analyze` works through the variants in chunks (:data:`DEFAULT_CHUNK`): for each
chunk it evaluates L_i, L_p and T (:mod:`cas_freq.model.loops`) on one common grid
(:func:`cas_freq.analysis.frequency.frequency_grid`, densified for the chunk's largest total
delay), finds every crossing (:mod:`cas_freq.analysis.margins`,
:mod:`cas_freq.analysis.closed_loop`) and refines them all together. :func:`analyze` is the
same engine on a batch of one, which also lists every crossing, the closed-loop poles and, on
request, the same figures at Padé orders 1..n beside the exact ones; it returns the typed
:class:`Analysis`, and :meth:`Analysis.to_dict` the JSON of ``cas-freq analyze``.

Peak memory grows with the chunk, not with the number of variants: about 112 MiB for 100,000
variants at the default chunk of 256 (``benchmarks/run.py``).
"""

import dataclasses
import os

import numpy as np

import cas_freq.analysis.response_kernel as response_kernel
import cas_freq.analysis.sampled_stability as sampled_stability
from cas_freq.analysis.closed_loop import (
    CLOSED_LOOP_FIGURES,
    ClosedLoopFigures,
    closed_loop_figures,
    figures_of_run,
)
from cas_freq.analysis.disturbance import disturbance_figures, position_encoder_counts
from cas_freq.analysis.drivetrain import derived_load_notes, drivetrain, drivetrain_notes
from cas_freq.analysis.frequency import (
    DEFAULT_POINTS_PER_DECADE,
    DEFAULT_RANGE_RAD_S,
    frequency_grid,
)
from cas_freq.analysis.limit_cycles import limit_cycles
from cas_freq.analysis.limit_cycles import to_json as limit_cycles_json
from cas_freq.analysis.margins import (
    LOOP_FIGURES,
    LoopMargins,
    loop_figures,
    margins_of_run,
)
from cas_freq.analysis.probes import Probes
from cas_freq.analysis.rate_envelope import rate_envelope, sine_frequencies
from cas_freq.analysis.sampling_text import sampling_notes, sampling_section
from cas_freq.analysis.stability import (
    Stability,
    closed_loop_poles,
    loop_verdicts,
)
from cas_freq.config.wording import OutputWords
from cas_freq.core.fileio import json_ready
from cas_freq.core.jit import compiled_for, use_compiled
from cas_freq.core.output import output_json, output_unit
from cas_freq.core.parameters import LoopParameters
from cas_freq.core.summary import Summary
from cas_freq.core.threads import result_of, worker_threads
from cas_freq.model.delay import DEFAULT_PADE_ORDER, EXACT, DelayModel
from cas_freq.model.loops import PreparedResponses, Selector, responses
from cas_freq.model.sampled import PreparedSampled, is_sampled, nyquist_frequencies
from cas_freq.model.sampled import grid_responses as sampled_grid_responses
from cas_freq.model.structure import build, total_delay

#: Variants per chunk: the grid responses take about 26 kB per variant and response.
DEFAULT_CHUNK = 256

#: The view of each loop with every other loop closed (MIL-F-9490D's break-point margins).
AT_A_TIME = "loop_at_a_time"


def figure_names(loops=("current_loop", "position_loop"), loop_at_a_time=True):
    """Every figure name of a batch analysis of drives with these loops (innermost first), in
    output order (``stable`` is 1.0 or 0.0): each loop's figures, then (``loop_at_a_time``)
    the same with every other loop closed (``<loop>.loop_at_a_time.<figure>``), then the
    closed loop's."""
    views = loops if loop_at_a_time else ()
    return (
        "stable",
        *(f"{loop}.{name}" for loop in loops for name in LOOP_FIGURES),
        *(f"{loop}.{AT_A_TIME}.{name}" for loop in views for name in LOOP_FIGURES),
        *(f"closed_loop.{name}" for name in CLOSED_LOOP_FIGURES),
    )


#: Every figure name of a batch analysis of the report's drive (PID-on-PI).
FIGURES = figure_names()


@dataclasses.dataclass(frozen=True, eq=False)
class BatchAnalysis:
    """Figures of n variants.

    Attributes
    ----------
    figures : dict of str to numpy.ndarray
        :func:`figure_names` of the drive's loops -> float array (n,), NaN where a figure
        does not exist (or is not reported because the loop is not stable, as in
        :func:`analyze`).
    stability : numpy.ndarray of str
        ``"stable"``, ``"marginal"`` or ``"unstable"`` per variant (Padé model of
        ``pade_order``).
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


def _figures_on(p, omega, verdicts, columns=None, delay=EXACT, crossings=False,
                compiled=None, at_a_time=True):
    """Figures of the runs ``p`` on grid ``omega`` (only its first ``columns`` points if
    given), with the raw values :func:`_needs_full_grid` checks.

    ``verdicts``: each loop's verdict closed with the loops inside it
    (:func:`~cas_freq.analysis.stability.loop_verdicts`). Each loop's figures are taken where
    that verdict is stable; those with every other loop closed where the whole loop is stable.
    Where a loop passes close to −1 between samples, the loops around it have a narrow
    resonance there: they are probed at those frequencies.
    """
    selector = Selector(p)
    names = tuple(verdicts)
    top = names[-1]
    grid = _grid_responses(selector(column=True), omega, p.n_runs, delay, compiled, at_a_time)
    whole = verdicts[top] == "stable"
    n = p.n_runs
    low = omega[:columns]
    m = low.size
    # a sampled loop's figures stop below its Nyquist frequency
    limit = ({name: int(np.searchsorted(low, w, side="left")) for name, w in
              nyquist_frequencies(p).items()} if is_sampled(p) else dict.fromkeys(names, m))
    limit["closed_loop"] = limit[top]

    prepared = PreparedSampled(selector) if is_sampled(p) else PreparedResponses(selector())

    def evaluator(kind, view=None):
        def evaluate(runs, w):
            if kind == names[0] and view is None:
                return prepared.current_loop(runs, 1j * w, delay)
            values = prepared.responses(runs, 1j * w, closed=kind == "closed_loop",
                                        delay=delay, loop_at_a_time=view is not None,
                                        through=kind if kind in names else None)
            if kind == "closed_loop":
                return values.closed_loop
            return (values.loops if view is None else values.loop_at_a_time)[kind]
        return evaluate

    figures = {"stable": whole.astype(float)}
    tops = {}
    probes = None
    for k, name in enumerate(names):
        response = grid.loops[name]
        inner = k < len(names) - 1
        own = limit[name]
        probes = probes if probes is None else probes.below(np.log(low[own - 1]))
        values, found = _loop_figures_of(evaluator(name), low[:own], response[..., :own], n,
                                         verdicts[name] == "stable", probes, crossings, inner)
        figures.update({f"{name}.{key}": value for key, value in values.items()})
        tops[name] = np.broadcast_to(np.abs(response[..., m - 1:]), (n, omega.size - m + 1))
        if at_a_time and inner:
            aat = np.broadcast_to(grid.loop_at_a_time[name], (n, omega.size))
            if np.isnan(aat[:, :1]).all():  # inside a slower sampled loop: not defined
                values = {key: _undefined(value, n) for key, value in values.items()}
            else:
                values, _ = _loop_figures_of(evaluator(name, AT_A_TIME), low[:own],
                                             aat[:, :own], n, whole, probes, crossings, False)
            tops[f"{name}.{AT_A_TIME}"] = np.abs(aat[:, m - 1:])
        if at_a_time:  # (the outermost loop's two views are one)
            figures.update({f"{name}.{AT_A_TIME}.{key}": value for key, value in values.items()})
        probes = found if probes is None else probes + found
    closed_grid = np.broadcast_to(grid.closed_loop, (n, omega.size))
    own = limit["closed_loop"]
    values = closed_loop_figures(evaluator("closed_loop"), low[:own], closed_grid[:, :own],
                                 whole)
    figures.update({f"closed_loop.{key}": value for key, value in values.items()})
    tops["closed_loop"] = np.abs(closed_grid[:, m - 1:])
    return figures, tops


def _undefined(value, n):
    """A figure of a view that is not defined: NaN, no crossings, no maximum at the top."""
    if isinstance(value, tuple):  # the crossings' (runs, frequencies, ...) arrays
        return tuple(np.zeros(0, dtype=np.asarray(v).dtype) for v in value)
    if np.asarray(value).dtype == bool:
        return np.zeros(n, dtype=bool)
    return np.full(n, np.nan)


def _loop_figures_of(evaluate, low, response, n, stable, probes, crossings, inner):
    """:func:`~cas_freq.analysis.margins.loop_figures` of one loop of every run, and the probes
    it found (where ``inner``); a response every run shares (shape (m,)) is analysed once."""
    if response.ndim == 1:
        values = loop_figures(evaluate, np.asarray(low), response[None, :], stable[:1],
                              crossings=crossings, inner=inner)
        found = values.pop("_inner_probes", Probes.none())
        if found.runs.size:  # the same probes for every run
            count = found.runs.size
            found = Probes(np.repeat(np.arange(n), count), np.tile(found.log_w, n))
        values = {key: value if key.startswith("_") and isinstance(value, tuple) else
                  np.broadcast_to(value, (n,)) for key, value in values.items()}
        return values, found
    values = loop_figures(evaluate, low, response, stable, probes=probes, crossings=crossings,
                          inner=inner)
    return values, values.pop("_inner_probes", Probes.none())


def _grid_responses(p, omega, n, delay, compiled=None, at_a_time=True):
    """Every loop (both views) and T on the grid: compiled
    (:mod:`cas_freq.analysis.response_kernel`) where ``compiled`` (default: where
    :func:`cas_freq.core.jit.compiled_for` says so), else numpy
    (:func:`cas_freq.model.loops.responses`, the reference). The two agree to ~1e-14 relative,
    not to the last bit: a batch chooses once for all its chunks, so a run's figures do not
    depend on the chunk it falls in."""
    if is_sampled(p):
        return sampled_grid_responses(p, omega, loop_at_a_time=at_a_time)
    if compiled_for(n * omega.size) if compiled is None else compiled:
        return response_kernel.grid_responses(p, omega, n, delay, loop_at_a_time=at_a_time)
    return responses(p, 1j * omega, delay=delay, loop_at_a_time=at_a_time)


def _needs_full_grid(figures, tops, stable):
    """Runs whose figures might lie above the split (so the low grid alone cannot be trusted).

    ``tops``: |L| of every loop (both views) and |T| on the log-grid points from the split's
    last point up. On
    a 200-per-decade log grid the magnitude varies by far less than 2x between points (the
    delay ripple of |T_i| has ~9 points per period at 1e6 rad/s), so twice the sampled
    maximum bounds the magnitude anywhere above: a crossing or peak up there is ruled out when
    that bound cannot produce it.
    """
    need = np.zeros(stable.shape, dtype=bool)
    for loop in (name for name in tops if name != "closed_loop"):
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


def _chunk_figures(p, frequency_range, points_per_decade, pade_order, delay=EXACT,
                   crossings=False, verdicts=None, compiled=None, at_a_time=True):
    """Figures of one chunk.

    The grid of the single path is a log grid, densified with linear steps above the
    frequency where the delays turn the phase faster than the log spacing (~74,000 rad/s for
    the shipped config). The chunk is first analysed on the plain log grid, of which the points
    below that frequency are exactly the single path's; only runs for which something could
    lie above (:func:`_needs_full_grid`) are analysed again on the full grid. The figures are
    the same either way; the split saves the ~40 % of points that only matter in rare cases.
    With ``crossings`` (every crossing listed) the full grid is used. Returns the figures and
    every loop's verdicts.
    """
    full = frequency_grid(*frequency_range, points_per_decade, total_delay(p))
    if verdicts is None:
        verdicts = every_loop_verdict(p, pade_order)
    coarse = frequency_grid(*frequency_range, points_per_decade, 0.0)
    split = _split_index(full, coarse)
    if crossings or split >= coarse.size - 1 or split < 3 or is_sampled(p):
        figures, _ = _figures_on(p, full, verdicts, delay=delay, crossings=crossings,
                                 compiled=compiled, at_a_time=at_a_time)
        return figures, verdicts
    figures, tops = _figures_on(p, coarse, verdicts, columns=split, delay=delay,
                                compiled=compiled, at_a_time=at_a_time)
    need = _needs_full_grid(figures, tops, verdicts[list(verdicts)[-1]] == "stable")
    if need.any():
        rows = np.flatnonzero(need)
        again, _ = _figures_on(p.take(rows), full,
                               {name: verdict[rows] for name, verdict in verdicts.items()},
                               delay=delay, compiled=compiled, at_a_time=at_a_time)
        for name, value in again.items():
            figures[name] = np.array(figures[name], copy=True)
            figures[name][rows] = value
    return figures, verdicts


def every_loop_verdict(p, pade_order=DEFAULT_PADE_ORDER):
    """Each loop's verdict closed with the loops inside it, per run: from the Padé model's
    poles (:func:`~cas_freq.analysis.stability.loop_verdicts`), or for sampled loops from the
    discrete-time poles (:func:`~cas_freq.analysis.sampled_stability.loop_verdicts`)."""
    if is_sampled(p):
        return sampled_stability.loop_verdicts(p)
    return loop_verdicts(p, pade_order)


def batch_analyze(
    params,
    frequency_range=DEFAULT_RANGE_RAD_S,
    points_per_decade=DEFAULT_POINTS_PER_DECADE,
    pade_order=DEFAULT_PADE_ORDER,
    chunk_size=DEFAULT_CHUNK,
    progress=None,
    workers=None,
    delay=EXACT,
    loop_at_a_time=True,
):
    """Analyse every variant of a batch (stability from Padé-model poles).

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters
        The variants (n runs).
    frequency_range : (float, float)
        Analysed range [rad/s].
    points_per_decade : int
        Grid density before refinement [1/decade].
    pade_order : int
        Padé order of the stability verdict (6 by default).
    chunk_size : int
        Runs evaluated together (bounds the memory).
    progress : callable, optional
        ``progress(done, total)`` after each chunk.
    workers : int, optional
        Threads evaluating chunks side by side (default: the CPU count; on the shared 2-core
        machine two threads beat one at every load measured, one or two other busy processes
        included). The figures do not depend on it: each chunk is computed alone and put in
        its place.
    delay : DelayModel
        Exact delays (default) or Padé of some order in every frequency response.
    loop_at_a_time : bool
        Also the inner loops' figures with every other loop closed (as many margin searches
        again for each inner loop whose response differs between runs: off where no figure of
        them is wanted).

    Returns
    -------
    BatchAnalysis
    """
    n = params.n_runs
    names = figure_names(build(params).names, loop_at_a_time)
    compiled = use_compiled()  # every chunk alike, whatever its size
    figures = {name: np.empty(n) for name in names}
    verdicts = {}
    starts = range(0, n, chunk_size)

    def work(start):
        chunk = params.take(slice(start, min(start + chunk_size, n)))
        return _chunk_figures(chunk, frequency_range, points_per_decade, pade_order, delay,
                              compiled=compiled, at_a_time=loop_at_a_time)

    # numpy releases the GIL inside its array loops, so chunks overlap on several cores
    with worker_threads(_workers(workers, len(starts))) as pool:  # Ctrl-C: not waited for
        futures = [pool.submit(work, start) for start in starts]  # pool.map, its waits sliced
        for start, future in zip(starts, futures, strict=True):
            values, chunk_verdicts = result_of(future)
            stop = min(start + chunk_size, n)
            for name in names:
                figures[name][start:stop] = values[name]
            for name, verdict in chunk_verdicts.items():
                verdicts.setdefault(name, np.empty(n, dtype=object))[start:stop] = verdict
            if progress:
                progress(stop, n)
    every = list(verdicts.values())
    return BatchAnalysis(figures, every[-1], every[0], pade_order)


def _workers(requested, chunks):
    count = (os.cpu_count() or 1) if requested is None else requested
    if not (isinstance(count, int) and count >= 1):
        raise ValueError(f"workers: need an integer >= 1, got {requested!r}")
    return max(1, min(count, chunks))


@dataclasses.dataclass(frozen=True)
class PadeComparison:
    """Headline figures at one delay model (a row of the Padé-vs-exact table).

    ``closed_loop_max_error`` is max |T_pade - T_exact| over the analysis grid (0 for exact).
    """

    delay_model: str
    current_phase_margin_deg: float | None
    current_crossover_rad_s: float | None
    current_gain_margin_db: float | None
    position_phase_margin_deg: float | None
    position_crossover_rad_s: float | None
    position_gain_margin_db: float | None
    position_gain_margin_low_db: float | None
    bandwidth_rad_s: float | None
    peak_db: float
    phase_90_rad_s: float | None
    closed_loop_max_error: float


@dataclasses.dataclass(frozen=True, repr=False)
class Analysis(Summary):
    """Every figure of one variant under one delay model (definitions: docs/model.md).

    Closed-loop figures are None when the closed loop is not stable: a frequency response of
    an unstable loop has no steady state to measure. Its repr (and, in a notebook, its HTML
    table) shows the headline figures; :meth:`plot` draws the Bode of L_i, L_p and T.
    """

    config: str
    config_path: str
    variant: str
    overrides: tuple
    delay_model: str
    frequency_range_rad_s: tuple[float, float]
    stable: bool
    stability: Stability
    current_loop: LoopMargins
    position_loop: LoopMargins
    closed_loop: ClosedLoopFigures | None
    pade_vs_exact: tuple[PadeComparison, ...]
    notes: tuple[str, ...]
    #: ((section, figure, at the edge), ...): whether a maximum (sensitivity peak, disk margin,
    #: closed-loop peak) lies at an end of the analysed range, where it is not a peak;
    #: written into the JSON as ``<section>.<figure>_at_range_edge``.
    range_edges: tuple = ()
    #: The load and drivetrain figures (:mod:`cas_freq.analysis.drivetrain`); None unloaded.
    drivetrain: object = None
    #: The velocity loop's margins, for a drive with one (None otherwise).
    velocity_loop: LoopMargins | None = None
    #: With sampled controllers, the headline figures of the same loops run continuously
    #: (:func:`_continuous_figures`); None otherwise.
    continuous: dict | None = None
    #: With sampled controllers: {"method", "rates_hz": {loop: Hz}, "nyquist_rad_s": {...}}.
    sampling: dict | None = None
    #: Stiffness, effort and noise (:mod:`cas_freq.analysis.disturbance`): the
    #: dynamic stiffness, the control effort and the encoder noise's current.
    stiffness: object = None
    effort: object = None
    noise: object = None
    #: The predicted limit cycles (:class:`cas_freq.analysis.limit_cycles.LimitCycles`).
    limit_cycles: object = None
    #: The rate and torque envelope (:mod:`cas_freq.analysis.rate_envelope`); None when the
    #: analysis was not given its config.
    envelope: object = None
    #: The analysed variant (:class:`cas_freq.config.LoadedVariant`), which :meth:`plot`
    #: evaluates the loops of; not part of the JSON.
    loaded: object = dataclasses.field(default=None, compare=False)

    def to_dict(self):
        """JSON-ready dict, the JSON of ``cas-freq analyze`` (non-finite numbers become None)."""
        return to_dict(self)

    def _summary(self):
        closed = self.closed_loop
        rows = [("stability", self.stability.verdict, "")]
        loops = ("current_loop", "velocity_loop", "position_loop")
        for loop in (name for name in loops if getattr(self, name) is not None):
            margins = getattr(self, loop)
            rows += [(f"{loop}.{name}", getattr(margins, name))
                     for name in ("phase_margin_deg", "crossover_rad_s", "gain_margin_db")]
        rows += [("closed_loop.bandwidth_rad_s", closed and closed.bandwidth_rad_s),
                 ("closed_loop.peak_db", closed and closed.peak_db),
                 ("position_loop.delay_margin_s", self.position_loop.delay_margin_s),
                 ("position_loop.sensitivity_peak_db", self.position_loop.sensitivity_peak_db)]
        changed = f" with {', '.join(self.overrides)}" if self.overrides else ""
        return f"{self.config} / {self.variant}{changed} ({self.delay_model} delays)", rows


def _value(number):
    return None if not np.isfinite(number) else float(number)


def _margins(figures, loop):
    """A loop's :class:`LoopMargins` with its loop-at-a-time margins."""
    return dataclasses.replace(
        margins_of_run(_loop(figures, loop)),
        loop_at_a_time=margins_of_run(_loop(figures, f"{loop}.{AT_A_TIME}")))


def _loop(figures, prefix):
    return {key[len(prefix) + 1:]: value for key, value in figures.items()
            if key.startswith(prefix + ".")}


def pade_study(params, max_order, omega):
    """Headline figures with Padé delays of order 1..max_order, then with exact delays.

    Parameters
    ----------
    params : cas_freq.core.parameters.LoopParameters
        One variant.
    max_order : int
        Highest Padé order, >= 1.
    omega : numpy.ndarray
        Analysis grid [rad/s].

    Returns
    -------
    tuple of PadeComparison
        One row per order, the exact row last.
    """
    stable = {name: np.array(["stable"], dtype=object) for name in build(params).names}
    p = Selector(params)()
    reference = responses(p, 1j * omega).closed_loop
    rows = []
    for order in [*range(1, max_order + 1), None]:
        delay = DelayModel(order)
        figures, _ = _figures_on(params, omega, stable, delay=delay)
        current = _loop(figures, "current_loop")
        position = _loop(figures, "position_loop")
        closed = _loop(figures, "closed_loop")
        response = responses(p, 1j * omega, delay=delay).closed_loop
        rows.append(PadeComparison(
            delay_model=delay.label,
            current_phase_margin_deg=_value(current["phase_margin_deg"][0]),
            current_crossover_rad_s=_value(current["crossover_rad_s"][0]),
            current_gain_margin_db=_value(current["gain_margin_db"][0]),
            position_phase_margin_deg=_value(position["phase_margin_deg"][0]),
            position_crossover_rad_s=_value(position["crossover_rad_s"][0]),
            position_gain_margin_db=_value(position["gain_margin_db"][0]),
            position_gain_margin_low_db=_value(position["gain_margin_low_db"][0]),
            bandwidth_rad_s=_value(closed["bandwidth_rad_s"][0]),
            peak_db=_value(closed["peak_db"][0]),
            phase_90_rad_s=_value(closed["phase_90_rad_s"][0]),
            closed_loop_max_error=float(np.max(np.abs(response - reference))),
        ))
    return tuple(rows)


def analyze(
    loaded,
    delay=EXACT,
    frequency_range=DEFAULT_RANGE_RAD_S,
    points_per_decade=DEFAULT_POINTS_PER_DECADE,
    pade_orders=0,
    limit_cycle_check=False,
    hinge_range=True,
):
    """Analyse one loaded config variant (the engine of :func:`batch_analyze` on one variant).

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
        The variant to analyse.
    delay : DelayModel
        Delay representation for every frequency response (exact by default).
    frequency_range : (float, float)
        Analysed range [rad/s]; crossings outside it are not reported.
    points_per_decade : int
        Grid density before refinement [1/decade].
    pade_orders : int
        If > 0, also tabulate the headline figures at Padé orders 1..pade_orders and exact.
    limit_cycle_check : bool
        Check each predicted limit cycle by a nonlinear simulation started near it
        (:func:`cas_freq.analysis.limit_cycles.limit_cycles`; the prediction itself is always
        made).
    hinge_range : bool
        Scan a loaded variant's stable hinge-stiffness range
        (:func:`cas_freq.analysis.drivetrain.drivetrain`; no requirement refers to it).

    Returns
    -------
    Analysis
    """
    params = LoopParameters.from_config(loaded.params)
    omega = frequency_grid(*frequency_range, points_per_decade, total_delay(params))
    order = delay.order or DEFAULT_PADE_ORDER
    sampled = is_sampled(params)
    verdicts = every_loop_verdict(params, order)
    every = list(verdicts.values())
    poles = (sampled_stability.closed_loop_poles(params) if sampled
             else closed_loop_poles(params, order))
    stability = Stability(
        verdict=str(every[-1][0]), pade_order=order,
        current_loop_verdict=str(every[0][0]),
        poles=tuple((float(p.real), float(p.imag)) for p in poles),
    )
    figures, _ = _chunk_figures(params, frequency_range, points_per_decade, order, delay,
                                crossings=True, verdicts=verdicts)
    notes = []
    continuous = sampling = None
    if sampled:
        continuous = _continuous_figures(params, frequency_range, points_per_decade, order,
                                         delay)
        sampling = sampling_section(params)
        notes.extend(sampling_notes(params, continuous))
    elif delay.exact:
        notes.append(
            f"stability from the poles of the Padé model of order {stability.pade_order}; "
            "every frequency figure uses exact delays"
        )
    if not stability.stable:
        notes.append(
            f"closed loop is {stability.verdict}: closed-loop figures (bandwidth, peak) are not "
            "reported; the open-loop margins still say how far the loop is from stability"
        )
    if stability.current_loop_verdict != "stable":
        notes.append(f"the current loop alone is {stability.current_loop_verdict}")
    if not stability.stable:
        notes.append("sensitivity peak and disk margin are not reported for a loop that is "
                     "not stable")
    load = drivetrain(params, order, hinge_range) if params.loaded[0] else None
    if load is not None:
        unit = output_unit(loaded.params)
        notes.extend(drivetrain_notes(load, loaded.params.output_label,
                                      (unit.spring, unit.spring_unit)))
    notes.extend(derived_load_notes(loaded.params))
    stiff, push, noise = disturbance_figures(
        params, omega, position_encoder_counts(loaded.params),
        OutputWords.of(loaded.params), stability.stable, delay)
    rows = pade_study(params, pade_orders, omega) if pade_orders > 0 else ()
    closed_figures = figures_of_run(_loop(figures, "closed_loop"))
    envelope = rate_envelope(
        loaded.params, params,
        sine_frequencies(closed_figures.bandwidth_rad_s) if stability.stable else ())
    edges = _range_edges(figures, omega, stability.stable, sampled)
    for section, figure, at_edge in edges:
        if at_edge:
            notes.append(f"{_edge_words(section, figure)} at an end of the analysed range "
                         f"({omega[0]:.4g}..{omega[-1]:.4g} rad/s): not a peak; widen --range")
    return Analysis(
        config=loaded.params.name,
        config_path=loaded.source,
        variant=loaded.variant,
        overrides=tuple(f"{key}={value}" for key, value in loaded.overrides),
        delay_model=delay.label,
        frequency_range_rad_s=(float(omega[0]), float(omega[-1])),
        stable=stability.stable,
        stability=stability,
        current_loop=_margins(figures, "current_loop"),
        position_loop=_margins(figures, "position_loop"),
        velocity_loop=(_margins(figures, "velocity_loop") if "velocity_loop" in verdicts
                       else None),
        closed_loop=closed_figures,
        pade_vs_exact=rows,
        notes=tuple(notes),
        range_edges=edges,
        drivetrain=load,
        continuous=continuous,
        sampling=sampling,
        stiffness=stiff,
        effort=push,
        noise=noise,
        limit_cycles=limit_cycles(params, simulate=limit_cycle_check,
                                  linear=bool(getattr(loaded.params, "linear", False))),
        envelope=envelope,
        loaded=loaded,
    )


def _continuous_figures(params, frequency_range, points_per_decade, order, delay):
    """The headline figures of the same loops run continuously (the cost of sampling):
    {loop: {figure: value}, "closed_loop": {...}, "stability": verdict}."""
    params = dataclasses.replace(params, sample_rates=())
    verdicts = every_loop_verdict(params, order)
    figures, _ = _chunk_figures(params, frequency_range, points_per_decade, order, delay,
                                verdicts=verdicts)
    out = {"stability": str(list(verdicts.values())[-1][0])}
    for name in verdicts:
        out[name] = {key: _value(figures[f"{name}.{key}"][0]) for key in CONTINUOUS_FIGURES}
    out["closed_loop"] = {key: _value(figures[f"closed_loop.{key}"][0])
                          for key in ("bandwidth_rad_s", "peak_db")}
    return out


#: The loop figures shown beside a sampled loop's (``continuous`` in the JSON).
CONTINUOUS_FIGURES = ("phase_margin_deg", "crossover_rad_s", "gain_margin_db", "delay_margin_s")


def _edge_words(section, figure):
    """What a maximum at the range's edge is, in words."""
    if section == "closed_loop":
        return "closed-loop resonance peak"
    loop, _, view = section.partition(".")
    words = f"{loop.replace('_loop', '')}-loop sensitivity peak / disk margin"
    return words + (" (every other loop closed)" if view else "")


def _range_edges(figures, omega, stable, sampled=False):
    """(section, figure, bool) for each maximum the engine searched: True when it lies at the
    top end of the grid (``_maximum_at_top``) or, for the sensitivity peak, at the bottom end;
    None for a loop that is not stable (no peak is reported then). A section is a loop, a
    loop's ``loop_at_a_time`` view (``current_loop.loop_at_a_time``) or the closed loop."""
    edges = []
    sections = [key[:-len("._maximum_at_top")] for key in figures
                if key.endswith("._maximum_at_top") and key != "closed_loop._maximum_at_top"]
    for section in sections:
        # a sampled loop's grid ends at its Nyquist frequency, the top of its frequency axis
        at_top = bool(np.asarray(figures[f"{section}._maximum_at_top"])[0]) and not sampled
        peak_w = np.asarray(figures[f"{section}.sensitivity_peak_rad_s"])[0]
        at_bottom = bool(np.isfinite(peak_w) and peak_w == omega[0])
        edges.append((section, "sensitivity_peak", (at_top or at_bottom) if stable else None))
    closed_top = bool(np.asarray(figures["closed_loop._maximum_at_top"])[0]) and not sampled
    edges.append(("closed_loop", "peak", closed_top if stable else None))
    return tuple(edges)


def to_dict(analysis):
    """JSON-ready dict of an :class:`Analysis` (non-finite numbers become None)."""
    unit = output_unit(analysis.loaded.params) if analysis.loaded is not None else None
    data = dataclasses.asdict(dataclasses.replace(analysis, loaded=None, limit_cycles=None,
                                                  envelope=None))
    del data["loaded"]
    del data["limit_cycles"]
    if analysis.limit_cycles is not None:
        data.update(limit_cycles_json(analysis.limit_cycles))
    if analysis.envelope is None or unit is None:
        del data["envelope"]
    else:
        data["envelope"] = analysis.envelope.to_dict(unit)
    edges = data.pop("range_edges")
    for section in ("stiffness", "effort", "noise"):
        part = getattr(analysis, section)
        if part is None:
            del data[section]
        else:
            data[section] = part.to_json()
    if data["drivetrain"] is None:
        del data["drivetrain"]
    if data["velocity_loop"] is None:
        del data["velocity_loop"]
    if data["continuous"] is None:
        del data["continuous"]
        del data["sampling"]
    else:
        for name, rate in analysis.sampling["rates_hz"].items():
            margin = data[name]["delay_margin_s"]
            data[name]["delay_margin_samples"] = None if margin is None else margin * rate
    for loop in ("current_loop", "velocity_loop", "position_loop"):
        if loop in data and data[loop]["loop_at_a_time"] is not None:
            del data[loop]["loop_at_a_time"]["loop_at_a_time"]
    stability = data.pop("stability")
    data["stability"] = stability["verdict"]
    data["stability_pade_order"] = stability["pade_order"]
    data["current_loop"]["stability"] = stability["current_loop_verdict"]
    data["closed_loop_poles"] = [list(pole) for pole in stability["poles"]]
    if data["closed_loop"] is None:
        data["closed_loop"] = {
            field.name: None for field in dataclasses.fields(ClosedLoopFigures)
        }
    for section, figure, at_edge in edges:
        place = data
        for part in section.split("."):
            place = place[part]
        place[f"{figure}_at_range_edge"] = None if at_edge is None else bool(at_edge)
    return json_ready(data if unit is None else output_json(data, unit))
