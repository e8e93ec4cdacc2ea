"""The ``sweep`` command's data: every figure of ``analyze`` (and of ``simulate``) over a grid.

A grid is the Cartesian product of one or more dotted keys, each given as ``start:stop:count``
(``count`` values evenly spaced from start to stop, both included) or as a list ``a,b,c``;
values are numbers in the key's SI unit or strings with a unit (``0.05ms:0.2ms:4``).
"""

import dataclasses
import io
import math

import numpy as np

from cas_freq.analysis import FIGURES, batch_analyze
from cas_freq.analysis.disturbance import batch_disturbance_figures, position_encoder_counts
from cas_freq.analysis.frequency import (
    DEFAULT_POINTS_PER_DECADE,
    DEFAULT_RANGE_RAD_S,
    frequency_grid,
)
from cas_freq.config.wording import OutputWords
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import json_ready
from cas_freq.core.parameter_keys import MAX_POINTS
from cas_freq.core.parameters import unit_of, variant_parameters
from cas_freq.model.structure import total_delay
from cas_freq.simulation.sinedwell import sine_dwell_bandwidths
from cas_freq.studies.distributed import (
    CHUNK_SAMPLES,
    RETRIES,
    chunk_slices,
    client_for,
    cluster_lost,
    distributed_module,
)
from cas_freq.studies.shown import run_figures_not_shown, shown_run_figure
from cas_freq.studies.steps import DEFAULT_STEP_CHUNK, batch_steps


def grid(axes):
    """Cartesian product of axes: dict key -> values → dict key -> flat arrays (first key
    slowest)."""
    keys = list(axes)
    total = math.prod(len(axes[k]) for k in keys)
    if total > MAX_POINTS:
        raise ConfigError(f"sweep: {total} grid points, more than the {MAX_POINTS} accepted")
    mesh = np.meshgrid(*(axes[k] for k in keys), indexing="ij")
    return {key: values.ravel() for key, values in zip(keys, mesh, strict=True)}


def evaluate_figures(params, changes, *, step_rad=None, fit=True, sinedwell=None,
                     disturbance=False, progress=None, scheduler=None, buffers=None):
    """Every figure of each sample: the batch analysis, the step's if ``step_rad``, and the
    sine-dwell bandwidth if ``sinedwell``.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        Base config.
    changes : dict of str to numpy.ndarray
        Dotted key -> values [SI] per sample.
    step_rad : float, optional
        Output step [rad] to simulate for each sample.
    fit : bool
        Fit the second-order model to each step.
    sinedwell : (float, sequence of float), optional
        (amplitude [rad], frequencies [rad/s]) of a sine-dwell of each sample, as
        ``cas-freq sinedwell`` runs it (feed-forward off): adds ``sinedwell.bandwidth_rad_s``
        (NaN without a crossing in the grid).
    disturbance : bool
        Also the dynamic stiffness, the control effort and the encoder noise's current of
        each sample (``stiffness.*``, ``effort.*``, ``noise.current_rms_A``:
        :func:`~cas_freq.analysis.disturbance.batch_disturbance_figures`, NaN where a sample
        is not stable).
    progress : callable, optional
        ``progress(done, total)`` in whole samples (ints): the work done so far, each stage
        (analysis, steps, sine dwell) weighted by its rough cost, in samples' worth.
    scheduler : str, optional
        Evaluate the samples in chunks on a dask.distributed cluster: ``local:N`` or a
        scheduler address (:mod:`cas_freq.studies.distributed`; the same numbers as locally).
    buffers : cas_freq.simulation.simulator.RecordingBuffers, optional
        Memory the steps record into, kept by the caller between calls (local runs only; see
        :func:`~cas_freq.studies.steps.batch_steps`).

    Returns
    -------
    (dict of str to numpy.ndarray, numpy.ndarray of str)
        Figures (:data:`cas_freq.analysis.FIGURES`, then ``step.*``/``fit.*``,
        ``sinedwell.*``) and the stability verdict per sample.
    """
    if scheduler is not None:
        return evaluate_figures_distributed(params, changes, scheduler, progress=progress,
                                            step_rad=step_rad, fit=fit, sinedwell=sinedwell,
                                            disturbance=disturbance)
    loop = variant_parameters(params, changes)
    n = loop.n_runs
    # share of the progress bar per stage, by their rough cost
    stages = [("analysis", 0.1), ("step", 1.0 if step_rad is not None else 0.0),
              ("sinedwell", 2.0 if sinedwell is not None else 0.0)]
    total = sum(weight for _, weight in stages)
    offsets = dict(zip([name for name, _ in stages],
                       np.cumsum([0.0] + [w for _, w in stages[:-1]]) / total, strict=True))
    weights = {name: weight / total for name, weight in stages}

    def stage_progress(stage):
        def report(done, planned):
            if progress:
                # whole samples' worth of work (1e-6: the shares' rounding at the very end)
                share = offsets[stage] + weights[stage] * done / planned
                progress(min(n, int(share * n + 1e-6)), n)
        return report

    analysis = batch_analyze(loop, progress=stage_progress("analysis"),
                             loop_at_a_time=wants_loop_at_a_time(params))
    figures = dict(analysis.figures)
    if disturbance:
        omega = frequency_grid(*DEFAULT_RANGE_RAD_S, DEFAULT_POINTS_PER_DECADE, total_delay(loop))
        figures.update(batch_disturbance_figures(
            loop, omega, position_encoder_counts(params), OutputWords.of(params).linear,
            analysis.stability.astype(str) == "stable"))
    if step_rad is not None:
        figures.update(batch_steps(loop, step_rad, fit=fit, rates_hz=params.simulation.rates_hz,
                                   progress=stage_progress("step"), buffers=buffers))
    if sinedwell is not None:
        amplitude, frequencies = sinedwell
        current_rate_hz, position_rate_hz = params.simulation.rates_hz
        bandwidth, _, _ = sine_dwell_bandwidths(
            loop.without_feedforward(), amplitude, frequencies,
            current_rate_hz=current_rate_hz, position_rate_hz=position_rate_hz,
            progress=stage_progress("sinedwell"),
        )
        figures["sinedwell.bandwidth_rad_s"] = bandwidth
    return figures, analysis.stability


def wants_loop_at_a_time(params):
    """Whether a study of ``params`` computes the loop-at-a-time figures: where a requirement
    of the config bounds one (they cost as many margin searches again per inner loop)."""
    return any(".loop_at_a_time." in requirement.metric
               for requirement in getattr(params, "requirements", ()) or ())


@dataclasses.dataclass(frozen=True, eq=False)
class Sweep:
    """Figures over a grid.

    Attributes
    ----------
    config, config_path, variant : str
        Which config.
    overrides : tuple of str
        Fixed ``--set`` overrides applied to the base.
    axes : dict of str to numpy.ndarray
        Swept key -> its values [SI].
    points : dict of str to numpy.ndarray
        Swept key -> value at each grid point (flattened, first key slowest).
    figures : dict of str to numpy.ndarray
        Figure -> value at each grid point (NaN where it does not exist).
    stability : numpy.ndarray of str
        Verdict per point.
    step_deg : float or None
        Simulated output step [deg].
    sinedwell_deg : float or None
        Sine-dwell amplitude [deg].
    """

    config: str
    config_path: str
    variant: str
    overrides: tuple
    axes: dict
    points: dict
    figures: dict
    stability: np.ndarray
    step_deg: float | None
    sinedwell_deg: float | None = None
    units: dict = dataclasses.field(default_factory=dict)

    def unit(self, key):
        """SI unit of swept ``key`` in the swept config's architecture."""
        return self.units.get(key) or unit_of(key)


def run_sweep(loaded, axes, *, step_rad=None, fit=True, sinedwell=None, progress=None,
              scheduler=None):
    """Sweep a loaded variant over ``axes`` (dict key -> values [SI]); returns :class:`Sweep`.

    ``sinedwell``: (amplitude [rad], frequencies [rad/s]) and ``scheduler`` (a dask cluster)
    as for :func:`evaluate_figures`.
    """
    points = grid(axes)
    figures, stability = evaluate_figures(loaded.params, points, step_rad=step_rad, fit=fit,
                                          sinedwell=sinedwell, progress=progress,
                                          scheduler=scheduler)
    return Sweep(
        config=loaded.params.name, config_path=loaded.source, variant=loaded.variant,
        overrides=tuple(f"{k}={v}" for k, v in loaded.overrides), axes=dict(axes),
        points=points, figures=figures, stability=stability,
        step_deg=None if step_rad is None else math.degrees(step_rad),
        sinedwell_deg=None if sinedwell is None else math.degrees(sinedwell[0]),
        units={key: unit_of(key, loaded.params) for key in axes},
    )


def figure_names(figures):
    """Figure names in output order."""
    return [name for name in FIGURES if name in figures] + [
        name for name in figures if name not in FIGURES
    ]


def not_shown(sweep):
    """Why each grid point's closed-loop, step and fit figures are not shown (None where they
    are): :func:`~cas_freq.studies.shown.run_figures_not_shown`, the load envelope's rule."""
    return run_figures_not_shown(sweep.figures, sweep.stability)


def shown_figures(sweep):
    """Every figure per grid point as the sweep shows it (text, JSON, CSV, plot): NaN where it
    does not exist or is not shown (:func:`not_shown`)."""
    reasons = not_shown(sweep)
    return {name: shown_run_figure(values, name, reasons) for name, values in sweep.figures.items()}


def sweep_dict(sweep):
    """JSON-ready dict: one record per grid point (swept keys, stability, every figure; null
    where it does not exist or is not shown, ``run_figures_not_shown`` then says why)."""
    names = figure_names(sweep.figures)
    figures, reasons = shown_figures(sweep), not_shown(sweep)
    records = []
    for index in range(len(sweep.stability)):
        record = {key: float(values[index]) for key, values in sweep.points.items()}
        record["stability"] = str(sweep.stability[index])
        record["run_figures_not_shown"] = reasons[index]
        for name in names:
            value = float(figures[name][index])
            record[name] = bool(value) if name in _FLAGS and math.isfinite(value) else value
        records.append(record)
    return json_ready({
        "config": sweep.config,
        "config_path": sweep.config_path,
        "variant": sweep.variant,
        "overrides": list(sweep.overrides),
        "swept": {key: {"unit": sweep.unit(key), "values": values.tolist()}
                  for key, values in sweep.axes.items()},
        "step_deg": sweep.step_deg,
        "sinedwell_deg": sweep.sinedwell_deg,
        "count": len(records),
        "points": records,
    })


_FLAGS = {"stable", "step.current_limited", "step.voltage_limited"}


def sweep_csv(sweep):
    """CSV text: swept keys, stability, then every figure (empty where it does not exist or is
    not shown), then why the run figures are not shown (empty where they are)."""
    names = figure_names(sweep.figures)
    figures, reasons = shown_figures(sweep), not_shown(sweep)
    keys = list(sweep.points)
    out = io.StringIO()
    out.write(",".join([*(f"{k} [{sweep.unit(k)}]" for k in keys), "stability", *names,
                        "run_figures_not_shown"]) + "\n")
    for index in range(len(sweep.stability)):
        cells = [f"{sweep.points[k][index]:.10g}" for k in keys]
        cells.append(str(sweep.stability[index]))
        for name in names:
            value = figures[name][index]
            cells.append(f"{value:.10g}" if math.isfinite(value) else "")
        cells.append(reasons[index] or "")
        out.write(",".join(cells) + "\n")
    return out.getvalue()


def _evaluate_chunk(params, changes, options):
    """Figures and verdicts of one chunk (runs on a worker)."""
    return evaluate_figures(params, changes, **options)


def evaluate_figures_distributed(params, changes, scheduler, *, progress=None,
                                 chunk_samples=CHUNK_SAMPLES, **options):
    """:func:`cas_freq.studies.sweep.evaluate_figures` with its samples cut into chunks and
    evaluated on a dask cluster.

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        Base config (sent to the cluster once).
    changes : dict of str to numpy.ndarray
        Dotted key -> values [SI] per sample.
    scheduler : str
        ``local:N`` or a scheduler address (:func:`parse_scheduler`).
    progress : callable, optional
        ``progress(done, total)`` in samples, as chunks complete.
    chunk_samples : int
        Samples per chunk: a multiple of the step batch
        (:data:`cas_freq.studies.steps.DEFAULT_STEP_CHUNK`), so that results do not depend on it.
    **options
        ``step_rad``, ``fit``, ``sinedwell`` as for ``evaluate_figures``.

    Returns
    -------
    (dict of str to numpy.ndarray, numpy.ndarray of str)
        As ``evaluate_figures``, in sample order.
    """
    if chunk_samples <= 0 or chunk_samples % DEFAULT_STEP_CHUNK:
        raise ValueError(f"chunk_samples must be a positive multiple of {DEFAULT_STEP_CHUNK}, "
                         f"got {chunk_samples}")
    distributed = distributed_module()
    n = len(next(iter(changes.values()))) if changes else 0
    slices = chunk_slices(n, chunk_samples)
    with client_for(scheduler) as client:
        # hash=False: a key of its own each call. With the default content hash, a second
        # study of the same config in one session (tune's batches) reuses the first's key,
        # which the first's release then drops from the workers ("lost dependencies").
        shared = client.scatter(params, broadcast=True, hash=False)
        futures = [
            client.submit(_evaluate_chunk, shared, {k: v[part] for k, v in changes.items()},
                          options, retries=RETRIES, pure=False)
            for part in slices
        ]
        index = {future.key: position for position, future in enumerate(futures)}
        results = [None] * len(futures)
        done = 0
        for future in distributed.as_completed(futures):
            position = index[future.key]
            try:
                results[position] = future.result()  # a chunk's error after its retries
            except (distributed.client.FutureCancelledError, distributed.KilledWorker) as exc:
                raise cluster_lost(scheduler, exc, done, n) from None
            done += slices[position].stop - slices[position].start
            if progress:
                progress(done, n)
    return _joined(results)


def _joined(results):
    """One (figures, stability) from the chunks' results, in order."""
    names = list(results[0][0])
    figures = {name: np.concatenate([figures[name] for figures, _ in results])
               for name in names}
    stability = np.concatenate([stability for _, stability in results])
    return figures, stability
