"""The ``simulate`` command's data: an output step, its figures and its second-order fit."""

import dataclasses
import io
import math

import numpy as np

from cas_freq.core.fileio import json_ready
from cas_freq.core.output import ANGLE, OutputUnit, output_json, output_unit
from cas_freq.core.parameters import LoopParameters, loop_structure
from cas_freq.model import DEFAULT_PADE_ORDER, ActuatorLoops
from cas_freq.simulation.commands import Step
from cas_freq.simulation.second_order import fit_second_order
from cas_freq.simulation.simulator import BUDGET_ENV, BudgetError, loop_time_step, simulate_batch
from cas_freq.simulation.sinedwell import (
    bound_meets,
    dwell_frequencies,
    limit_onset_amplitude,
    sine_dwell,
)
from cas_freq.simulation.step_figures import diverged, simulation_step_figures

#: Columns of the time-series CSV, with their units (the same for every config; ``fit`` also
#: reads the former ``command_fin``).
CSV_COLUMNS = (
    ("t", "s"), ("command_output", "deg"), ("delta", "deg"), ("theta", "rad"), ("omega", "rad/s"),
    ("i", "A"), ("V", "V"), ("current_limited", "0/1"), ("voltage_limited", "0/1"),
)


@dataclasses.dataclass(frozen=True, eq=False)
class StepRun:
    """A simulated output step of one variant, with its figures and second-order fit.

    ``linear_stability`` is the verdict of the linear closed loop (Padé-model poles, or the
    discrete-time poles of sampled loops, as ``analyze`` gives it): when it is not
    ``"stable"`` the step's figures describe a loop that only the limits keep bounded, if
    anything.
    """

    config: str
    config_path: str
    variant: str
    overrides: tuple
    result: object
    step: object
    fit: object
    linear_stability: str = "stable"
    output: str = "output"
    #: How the output is measured and shown (:mod:`cas_freq.core.output`).
    output_unit: OutputUnit = ANGLE


def linear_verdict(params):
    """Stability verdict of the linear closed loop, as ``analyze`` reports it: from the Padé
    model's poles, or for sampled loops from the discrete-time poles."""
    from cas_freq.analysis.analyze import every_loop_verdict

    p = params if isinstance(params, LoopParameters) else LoopParameters.from_config(params)
    return str(list(every_loop_verdict(p, DEFAULT_PADE_ORDER).values())[-1][0])


def _identity(loaded):
    """config, config_path, variant, overrides and the output's label (``output_name``, else
    "output") of a loaded variant, as every run holds them."""
    return {
        "config": loaded.params.name,
        "config_path": loaded.source,
        "variant": loaded.variant,
        "overrides": tuple(f"{key}={value}" for key, value in loaded.overrides),
        "output": loaded.params.output_label,
        "output_unit": output_unit(loaded.params),
    }


def step_run(loaded, amplitude_rad):
    """Simulate a fin step of ``amplitude_rad`` [rad] on one loaded variant and analyse it."""
    return step_runs([loaded], amplitude_rad)[0]


def _batch_key(params, p=None):
    """Variants with equal keys can share a batch and get exactly their solo results: the same
    controller rates, time step and loop structure (a batch has one structure). ``p``: the
    variant's :class:`~cas_freq.core.parameters.LoopParameters`, if built already."""
    rates = params.simulation.rates_hz
    p = LoopParameters.from_config(params) if p is None else p
    periods = [1.0 / rate for rate in rates if rate]
    return rates, loop_time_step(p, periods), loop_structure(params)


def step_runs(variants, amplitude_rad, progress=None):
    """:func:`step_run` of several variants, simulated in as few batches as possible.

    Variants with the same controller sampling and default time step run in one batch; each
    run is cut at its own settling horizon (:class:`~cas_freq.simulation.BatchResult`), so
    every result is the one :func:`step_run` gives alone.

    Returns
    -------
    list of StepRun
        In the order of ``variants``.
    """
    return step_batch([(loaded, amplitude_rad) for loaded in variants], progress=progress)


def step_batch(items, verdicts=None, progress=None, parameters=None):
    """Step runs of (variant, step size [rad]) pairs, batched as :func:`step_runs` does.

    Parameters
    ----------
    items : sequence of (LoadedVariant, float)
        Variants and step sizes at the fin [rad].
    verdicts : dict, optional
        ``id(loaded) -> linear stability verdict`` already known (e.g. from the variant's
        :class:`~cas_freq.analysis.Analysis`); the others are computed once per variant.
    progress : callable, optional
        ``progress(steps_done, steps_planned)`` of each batch (:func:`simulate_batch`).
    parameters : dict, optional
        ``id(loaded) -> LoopParameters`` already built (the API's actuator keeps its own);
        the others are built once per variant.

    Returns
    -------
    list of StepRun
        In the order of ``items``.
    """
    groups, verdicts, tables = {}, dict(verdicts or {}), dict(parameters or {})
    for index, (loaded, _) in enumerate(items):
        if id(loaded) not in tables:  # once per variant, however many step sizes
            tables[id(loaded)] = LoopParameters.from_config(loaded.params)
        groups.setdefault(_batch_key(loaded.params, tables[id(loaded)]), []).append(index)
        if id(loaded) not in verdicts:
            verdicts[id(loaded)] = linear_verdict(loaded.params)
    runs = [None] * len(items)
    for ((current_rate_hz, position_rate_hz), dt, _), members in groups.items():
        variants = [items[index][0] for index in members]
        batch = simulate_batch(
            tables[id(variants[0])] if len(variants) == 1 else [v.params for v in variants],
            [Step(items[index][1]) for index in members], dt=dt,
            current_rate_hz=current_rate_hz, position_rate_hz=position_rate_hz,
            progress=progress,
        )
        for position, index in enumerate(members):
            (loaded, amplitude_rad), result = items[index], batch.run(position)
            runs[index] = StepRun(
                **_identity(loaded),
                result=result,
                step=simulation_step_figures(result, amplitude_rad),
                fit=fit_second_order(result.t, result.delta, amplitude_rad),
                linear_stability=verdicts[id(loaded)],
            )
    return runs


def limit_activity(t, active):
    """When a limit acted: total time, first and last time [s] (None without activity).

    Parameters
    ----------
    t : numpy.ndarray
        Sample times [s], evenly spaced.
    active : numpy.ndarray of bool
        The limit's flag at each sample.

    Returns
    -------
    dict
        ``active_s`` (samples flagged x sample spacing), ``first_s``, ``last_s``.
    """
    active = np.asarray(active, dtype=bool)
    if not active.any():
        return {"active_s": 0.0, "first_s": None, "last_s": None}
    spacing = float(t[1] - t[0]) if t.size > 1 else 0.0
    flagged = t[active]
    return {"active_s": float(active.sum() * spacing), "first_s": float(flagged[0]),
            "last_s": float(flagged[-1])}


def diverged_at(run):
    """The first time [s] at which a :class:`StepRun`'s output diverged
    (:func:`~cas_freq.simulation.step_figures.diverged`), or None."""
    return diverged(run.result.t, run.result.delta, run.step.amplitude_deg * np.pi / 180)


def step_run_dict(run):
    """JSON-ready dict of a :class:`StepRun` (non-finite numbers become None)."""
    result = run.result
    return json_ready(output_json({
        "config": run.config,
        "config_path": run.config_path,
        "variant": run.variant,
        "overrides": list(run.overrides),
        "step": dataclasses.asdict(run.step),
        "fit": dataclasses.asdict(run.fit),
        "linear_closed_loop": run.linear_stability,
        "limits": {
            "current": limit_activity(result.t, result.current_limited),
            "voltage": limit_activity(result.t, result.voltage_limited),
        },
        "simulation": {
            "controllers": controllers_text(result),
            "dt_s": result.dt_s,
            "t_end_s": result.t_end_s,
            "extended": result.extended,
            "settled": result.settled,
            "diverged_at_s": diverged_at(run),
        },
    }, run.output_unit))


def controllers_text(result):
    """How a run's controllers ran, in words: ``continuous`` or ``sampled (...)``."""
    rates = [(name, getattr(result, f"{name}_rate_hz"))
             for name in ("current", "velocity", "position")]
    sampled = [f"{name} loop {rate:g} Hz" for name, rate in rates if rate is not None]
    if not sampled:
        return "continuous"
    method = {"backward": "backward difference", "tustin": "Tustin"}[result.sampling_method]
    return f"sampled ({', '.join(sampled)}, zero-order hold, {method})"


def step_csv_name(path, run, count):
    """CSV path for ``run``: ``path`` itself, or ``stem.<variant>.csv`` for several variants."""
    from pathlib import Path

    path = Path(path)
    return path if count == 1 else path.with_name(f"{path.stem}.{run.variant}{path.suffix}")


def step_run_csv(run):
    """The run's time series as CSV text (header names carry units; the output's in deg, or
    in mm at a linear output)."""
    r, unit = run.result, run.output_unit
    columns = np.column_stack([
        r.t, r.command * unit.scale, r.delta * unit.scale, r.theta, r.omega, r.i, r.V,
        r.current_limited.astype(int), r.voltage_limited.astype(int),
    ])
    out = io.StringIO()
    out.write(",".join(f"{name} [{unit.shown if shown == 'deg' else shown}]"
                       for name, shown in CSV_COLUMNS) + "\n")
    np.savetxt(out, columns, delimiter=",", fmt="%.9g")
    return out.getvalue()


@dataclasses.dataclass(frozen=True, eq=False)
class CommandRun:
    """A simulated user command (a CSV table) of one variant: how well the output followed it."""

    config: str
    config_path: str
    variant: str
    overrides: tuple
    source: str
    result: object
    linear_stability: str
    output: str = "output"
    #: How the output is measured and shown (:mod:`cas_freq.core.output`).
    output_unit: OutputUnit = ANGLE


def command_run(loaded, command, progress=None):
    """Simulate a :class:`~cas_freq.simulation.commands.Table` command on one variant.

    The horizon is the table's last time plus the simulator's default settling time, extended
    (as for a step) until the fin has settled on the table's last value.
    """
    current_rate_hz, position_rate_hz = loaded.params.simulation.rates_hz
    result = simulate_batch(
        [loaded.params], command, current_rate_hz=current_rate_hz,
        position_rate_hz=position_rate_hz, progress=progress,
    ).run(0)
    return CommandRun(
        **_identity(loaded), source=command.source, result=result,
        linear_stability=linear_verdict(loaded.params),
    )


def command_run_dict(run):
    """JSON-ready dict of a :class:`CommandRun`: tracking error, peaks, limit activity."""
    r = run.result
    error = np.degrees(r.delta - r.command)
    return json_ready({
        "config": run.config,
        "config_path": run.config_path,
        "variant": run.variant,
        "overrides": list(run.overrides),
        "command": {"source": run.source, "end_s": r.t_end_s},
        "linear_closed_loop": run.linear_stability,
        "tracking": {
            "max_abs_error_deg": float(np.max(np.abs(error))),
            "rms_error_deg": float(np.sqrt(np.mean(error**2))),
            "final_error_deg": float(error[-1]),
        },
        "max_current_a": float(np.max(np.abs(r.i))),
        "max_voltage_v": float(np.max(np.abs(r.V))),
        "limits": {
            "current": limit_activity(r.t, r.current_limited),
            "voltage": limit_activity(r.t, r.voltage_limited),
        },
        "simulation": {"controllers": controllers_text(r), "dt_s": r.dt_s, "t_end_s": r.t_end_s,
                       "extended": r.extended, "settled": r.settled},
    })


#: Fixed sine-dwell frequencies of the many-actuator studies (``sweep --sinedwell``, Monte Carlo)
#: [rad/s]: 30 log-spaced points over 100..5000 rad/s, around the closed-loop bandwidths of the
#: shipped variants (about 300 to 1400 rad/s). One variant's sine-dwell follows its own
#: bandwidth instead (:func:`cas_freq.simulation.sinedwell.dwell_frequencies`).
DEFAULT_SINEDWELL_FREQUENCIES_RAD_S = tuple(np.geomspace(100.0, 5000.0, 30))


@dataclasses.dataclass(frozen=True, eq=False)
class SineDwellRun:
    """The ``sinedwell`` command's data for one variant.

    Attributes
    ----------
    config, config_path, variant, overrides, output
        Which actuator; ``output`` is what text calls its output (``output_name``, else
        "output").
    feedforward : bool
        Whether the velocity/acceleration feed-forward acted on the sine commands.
    controllers : str
        ``"continuous"`` or a description of the sampled controllers.
    result : cas_freq.simulation.sinedwell.SineDwellResult or None
        First-harmonic response per amplitude and frequency; None when it was not computed
        (``not_computed`` says why).
    linear_response : numpy.ndarray or None
        Exact-delay linear delta/delta_cmd at the same frequencies (with the same feed-forward
        setting), complex, shape (n_f,); None with ``result``.
    linear_bandwidth_rad_s : float or None
        docs/model.md's closed-loop bandwidth of T (no feed-forward), from ``analyze``.
    steps : tuple of StepRun
        A nonlinear fin step of each amplitude, with its figures and second-order fit.
    limit_onset_rad : float or None
        Smallest amplitude [rad] at which a limit acts somewhere in the frequency grid.
    bandwidth_requirement_rad_s : float or None
        The config's required closed-loop bandwidth (:func:`bandwidth_requirement`), which
        every estimate is shown against.
    reference : cas_freq.config.schema.Reference or None
        The config's ``reference:`` section (measured figures shown beside the model's), if
        it declares one.
    frequencies_rad_s : tuple of float
        The sine-dwell grid asked for [rad/s].
    not_computed : str or None
        Why the sine-dwell was not computed (:func:`unstable_reason`, "the linear closed loop
        is unstable ..."; or "the sine-dwell grid ... needs ...; set ..."), or None when it was.
    """

    config: str
    config_path: str
    variant: str
    overrides: tuple
    feedforward: bool
    controllers: str
    result: object
    linear_response: np.ndarray
    linear_bandwidth_rad_s: float | None
    steps: tuple
    limit_onset_rad: float | None
    bandwidth_requirement_rad_s: float | None = None
    reference: object = None
    output: str = "output"
    #: How the output is measured and shown (:mod:`cas_freq.core.output`).
    output_unit: OutputUnit = ANGLE
    frequencies_rad_s: tuple = ()
    not_computed: str | None = None


def bandwidth_requirement(params):
    """Lower bound [rad/s] of the config's required closed-loop bandwidth, or None."""
    bounds = [r.min for r in params.requirements
              if r.metric == "closed_loop.bandwidth_rad_s" and r.min is not None]
    return max(bounds) if bounds else None


def dwell_parameters(params, feedforward):
    """Simulator parameters of one variant, without the feed-forward unless ``feedforward``."""
    loop = LoopParameters.from_config(params)
    return loop if feedforward else loop.without_feedforward()


def over_budget_reason(error, frequencies_rad_s, option="--frequencies"):
    """Why a sine-dwell beyond the simulation budget was not computed, and what changes it.

    Parameters
    ----------
    error : cas_freq.simulation.simulator.BudgetError
    frequencies_rad_s : sequence of float
        The grid [rad/s].
    option : str
        Where the grid is set (named in the text).
    """
    w = sorted(frequencies_rad_s)
    return (f"the sine-dwell grid {w[0]:.4g}..{w[-1]:.4g} rad/s needs a {error.horizon_s:.3g} s "
            "horizon (set by its lowest frequency), beyond the simulation budget; set "
            f"{BUDGET_ENV}={math.ceil(error.factor_needed)} or raise the lowest of {option}")


def unstable_reason(verdict):
    """Why the default sine-dwell of a loop whose linear closed loop is ``verdict`` (not
    "stable") is not computed: a diverging run has no first harmonic to measure."""
    return (f"the linear closed loop is {verdict} (Padé poles): its runs diverge or only the "
            "limits bound them, so they have no first harmonic and no sine-dwell bandwidth "
            "exists (give --frequencies to dwell anyway)")


def sinedwell_run(loaded, amplitudes_rad, frequencies_rad_s=None, *, feedforward=False,
                  progress=None, analysis=None, over_budget="raise"):
    """Sine-dwell the nonlinear loop of one variant, with the cross-checks beside it.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
        The variant.
    amplitudes_rad : sequence of float
        Command amplitudes at the fin [rad].
    frequencies_rad_s : sequence of float, optional
        Dwell frequencies [rad/s]; default the variant's grid
        (:func:`~cas_freq.simulation.sinedwell.dwell_frequencies`, around its linear ω_BW).
        By default a variant whose linear closed loop is not stable is not dwelt (``result``
        None, ``not_computed`` says why, :func:`unstable_reason`); its steps are still
        simulated. Given frequencies are dwelt whatever the loop.
    feedforward : bool
        Let the feed-forward act on the sines (default False: docs/model.md's T, whose bandwidth is
        the requirement's, has no feed-forward).
    progress : callable, optional
        ``progress(steps_done, steps_planned)`` of the sine-dwell batch.
    analysis : cas_freq.analysis.Analysis, optional
        The variant's exact-delay analysis, if already computed: its stability verdict and
        linear bandwidth are used instead of being computed again.
    over_budget : {"raise", "skip"}
        A sine-dwell beyond the simulation budget raises
        :class:`~cas_freq.simulation.simulator.BudgetError` (before any simulation), or is
        skipped: the run then has ``result`` None and ``not_computed`` the reason (the steps
        are still simulated).

    Returns
    -------
    SineDwellRun
    """
    from cas_freq.analysis.closed_loop import closed_loop_summary
    from cas_freq.analysis.frequency import DEFAULT_RANGE_RAD_S, frequency_grid

    if over_budget not in ("raise", "skip"):
        raise ValueError(f"over_budget: 'raise' or 'skip', got {over_budget!r}")
    params = loaded.params
    not_computed = None
    if frequencies_rad_s is None:
        if analysis is None:
            from cas_freq.analysis import analyze

            analysis = analyze(loaded)
        if analysis.stability.verdict != "stable":
            not_computed, frequencies_rad_s = unstable_reason(analysis.stability.verdict), ()
        else:
            frequencies_rad_s = dwell_frequencies(analysis)
    current_rate_hz, position_rate_hz = params.simulation.rates_hz
    rates = {"current_rate_hz": current_rate_hz, "position_rate_hz": position_rate_hz}
    result = None
    try:  # the budget is checked before the batch starts
        if not_computed is None:
            result = sine_dwell(
                dwell_parameters(params, feedforward), amplitudes_rad, frequencies_rad_s,
                progress=progress, **rates,
            )
    except BudgetError as error:
        if over_budget == "raise":
            raise
        not_computed = over_budget_reason(error, frequencies_rad_s)
    amplitudes = (np.asarray(result.amplitudes_rad) if result is not None
                  else np.atleast_1d(np.asarray(amplitudes_rad, dtype=float)))
    known = {} if analysis is None else {id(loaded): analysis.stability.verdict}
    steps = step_batch([(loaded, float(amplitude)) for amplitude in amplitudes], known)
    loops = ActuatorLoops(params)
    linear = None if result is None else loops.closed_loop(
        1j * np.asarray(result.frequencies_rad_s), feedforward=feedforward)
    linear_bandwidth = None  # an unstable loop has no frequency response to measure
    if analysis is not None and analysis.delay_model == "exact":
        if analysis.closed_loop is not None:
            linear_bandwidth = analysis.closed_loop.bandwidth_rad_s
    elif steps[0].linear_stability == "stable":
        grid = frequency_grid(*DEFAULT_RANGE_RAD_S, total_delay=loops.total_delay)
        linear_bandwidth = closed_loop_summary(loops.closed_loop, grid).bandwidth_rad_s
    return SineDwellRun(
        **_identity(loaded), feedforward=feedforward,
        controllers=controllers_text(steps[0].result),
        result=result, linear_response=linear, linear_bandwidth_rad_s=linear_bandwidth,
        steps=tuple(steps),
        limit_onset_rad=None if result is None else limit_onset_amplitude(result),
        bandwidth_requirement_rad_s=bandwidth_requirement(params), reference=params.reference,
        frequencies_rad_s=tuple(float(w) for w in sorted(frequencies_rad_s)),
        not_computed=not_computed,
    )


def _db(values):
    return 20.0 * np.log10(np.abs(values))


def _reference_fit(reference):
    """The ``report_bench`` entry of a config's ``reference:`` fit (its source, step [deg],
    bandwidth [rad/s], wn [rad/s], zeta), or None without a reference fit with a bandwidth."""
    fit = None if reference is None else reference.fit
    if fit is None or fit.bandwidth_rad_s is None:
        return None
    step = reference.step_amplitude
    return {"source": reference.source or None,
            "step_deg": None if step is None else float(np.degrees(step)),
            "bandwidth_rad_s": fit.bandwidth_rad_s, "wn_rad_s": fit.wn, "zeta": fit.zeta}


def _bound_dict(bound):
    """JSON of a bandwidth known only as a bound: ``{"relation": ">", "edge_rad_s": 5000}``."""
    return None if bound is None else {"relation": bound[0], "edge_rad_s": bound[1]}


def _meets(value, bound, required):
    """Whether a bandwidth (or its bound) meets ``>= required``: True, False, or None when a
    bound cannot decide it (:func:`~cas_freq.simulation.sinedwell.bound_meets`)."""
    if value is not None and math.isfinite(value):
        return value >= required
    return None if bound is None else bound_meets(bound, minimum=required)


def _not_computed_dict(run):
    """:func:`sinedwell_run_dict` of a run whose sine-dwell was not computed (unstable loop, or
    beyond the simulation budget): the steps and their fits, null sine-dwell figures and why."""
    required = run.bandwidth_requirement_rad_s
    amplitudes, three_ways = [], []
    for step in run.steps:
        amplitudes.append({
            "amplitude_deg": step.step.amplitude_deg, "bandwidth_rad_s": None,
            "bandwidth_bound": None, "magnitude_db": [], "phase_deg": [],
            "current_limited": [], "voltage_limited": [], "limit_hit": None,
            "step": dataclasses.asdict(step.step), "fit": dataclasses.asdict(step.fit),
            "diverged_at_s": diverged_at(step),
        })
        row = {"amplitude_deg": step.step.amplitude_deg,
               "linear_rad_s": run.linear_bandwidth_rad_s, "sinedwell_rad_s": None,
               "step_fit_rad_s": step.fit.bandwidth_closed_form_rad_s, "sinedwell_bound": None}
        if required is not None:
            row["meets_requirement"] = {
                "linear_rad_s": _meets(row["linear_rad_s"], None, required),
                "sinedwell_rad_s": None,
                "step_fit_rad_s": _meets(row["step_fit_rad_s"], None, required),
            }
        three_ways.append(row)
    bench = _reference_fit(run.reference)
    return json_ready({
        "config": run.config, "config_path": run.config_path, "variant": run.variant,
        "overrides": list(run.overrides), "feedforward": run.feedforward,
        "linear_closed_loop": run.steps[0].linear_stability,
        "not_computed": {"sinedwell": run.not_computed},
        "frequencies_rad_s": [],
        "linear": {"bandwidth_rad_s": run.linear_bandwidth_rad_s, "magnitude_db": [],
                   "phase_deg": []},
        "amplitudes": amplitudes, "limit_onset_amplitude_deg": None,
        "bandwidth_three_ways": three_ways, "bandwidth_requirement_rad_s": required,
        **({} if bench is None else {"report_bench": bench}),
        "simulation": {"controllers": run.controllers},
    })


def sinedwell_run_dict(run):
    """JSON-ready dict of a :class:`SineDwellRun` (non-finite numbers become None).

    ``amplitudes`` has one entry per amplitude (sine-dwell response and bandwidth, and the
    nonlinear step of the same size with its second-order fit); ``bandwidth_three_ways`` puts
    the linear, sine-dwell and step-fit bandwidths side by side; ``report_bench``, only where
    the config's ``reference:`` declares a fit with a bandwidth, is that reference fit.

    A sine-dwell bandwidth outside the grid is ``bandwidth_rad_s: null`` with
    ``bandwidth_bound: {"relation": ">", "edge_rad_s": w_max}`` (still above −3.01 dB at the
    grid's top) or ``{"relation": "<", "edge_rad_s": w_min}`` (already below at its bottom);
    ``bandwidth_bound`` is null when the grid holds the crossing (or nothing is known). With a
    bandwidth requirement, ``meets_requirement`` is true / false where the value or the bound
    decides it and null where a bound cannot ("not decided").

    A sine-dwell that was not computed (``run.result`` None) gives the same keys with empty
    responses and null sine-dwell bandwidths, ``not_computed: {"sinedwell": reason}``, and
    each step's ``diverged_at_s`` (:func:`_not_computed_dict`).
    """
    r = run.result
    if r is None:
        return _not_computed_dict(run)
    amplitudes = []
    three_ways = []
    required = run.bandwidth_requirement_rad_s
    bounds = r.bandwidth_bounds
    for index, amplitude in enumerate(r.amplitudes_rad):
        step = run.steps[index]
        amplitude_deg = float(np.degrees(amplitude))
        amplitudes.append({
            "amplitude_deg": amplitude_deg,
            "bandwidth_rad_s": r.bandwidth_rad_s[index],
            "bandwidth_bound": _bound_dict(bounds[index]),
            "magnitude_db": r.magnitude_db[index].tolist(),
            "phase_deg": r.phase_deg[index].tolist(),
            "current_limited": r.current_limited[index].tolist(),
            "voltage_limited": r.voltage_limited[index].tolist(),
            "limit_hit": bool(r.limit_hit[index].any()),
            "step": dataclasses.asdict(step.step),
            "fit": dataclasses.asdict(step.fit),
        })
        three_ways.append({
            "amplitude_deg": amplitude_deg,
            "linear_rad_s": run.linear_bandwidth_rad_s,
            "sinedwell_rad_s": r.bandwidth_rad_s[index],
            "step_fit_rad_s": step.fit.bandwidth_closed_form_rad_s,
            "sinedwell_bound": _bound_dict(bounds[index]),
        })
        if required is not None:
            row = three_ways[-1]
            row["meets_requirement"] = {
                "linear_rad_s": _meets(row["linear_rad_s"], None, required),
                "sinedwell_rad_s": _meets(row["sinedwell_rad_s"], bounds[index], required),
                "step_fit_rad_s": _meets(row["step_fit_rad_s"], None, required),
            }
    onset = run.limit_onset_rad
    bench = _reference_fit(run.reference)
    return json_ready({
        "config": run.config,
        "config_path": run.config_path,
        "variant": run.variant,
        "overrides": list(run.overrides),
        "feedforward": run.feedforward,
        "linear_closed_loop": run.steps[0].linear_stability,
        "frequencies_rad_s": np.asarray(r.frequencies_rad_s).tolist(),
        "linear": {
            "bandwidth_rad_s": run.linear_bandwidth_rad_s,
            "magnitude_db": _db(run.linear_response).tolist(),
            "phase_deg": np.degrees(np.unwrap(np.angle(run.linear_response))).tolist(),
        },
        "amplitudes": amplitudes,
        "limit_onset_amplitude_deg": None if onset is None else float(np.degrees(onset)),
        "bandwidth_three_ways": three_ways,
        "bandwidth_requirement_rad_s": required,
        **({} if bench is None else {"report_bench": bench}),
        "simulation": {
            "controllers": run.controllers,
            "dt_s": r.dt_s,
            "t_end_s": r.t_end_s,
            "settle_s": np.asarray(r.settle_s).tolist(),
            "periods_measured": np.asarray(r.periods_measured).tolist(),
        },
    })
