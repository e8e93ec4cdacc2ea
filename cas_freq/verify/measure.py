"""Measure the figures a list of requirements refers to, for one variant.

Each figure is computed exactly as the command that prints it computes it, so a verdict can be
reproduced by hand: ``analyze`` (exact delays, default range) for loop and closed-loop figures,
``simulate --step`` for ``step.*`` and ``fit.*``, ``sinedwell`` (feed-forward off) for
``sinedwell.bandwidth_rad_s``, ``simulate --profile`` (the config's feed-forward) for
``profile.*``. Runs shared by several requirements (the same step size, the same amplitude and
grid, the same move) are done once.
"""

import math

from cas_freq.core.figures import FIGURES
from cas_freq.core.fileio import json_ready
from cas_freq.core.output import LENGTH, output_unit
from cas_freq.model.sampled import time_varying_views
from cas_freq.simulation.commands import condition_profile
from cas_freq.simulation.simulator import BudgetError
from cas_freq.simulation.sinedwell import dwell_frequencies, sine_dwell
from cas_freq.studies.profile_run import profile_condition_text, profile_runs
from cas_freq.studies.run import dwell_parameters, over_budget_reason, step_batch


def figure(result, metric):
    """The figure named ``metric`` (its dotted key in the command's JSON, e.g.
    ``closed_loop.bandwidth_rad_s``) of a typed result (:class:`~cas_freq.analysis.Analysis`,
    :class:`~cas_freq.studies.run.StepRun`): the same names, read as attributes. None where
    the figure does not exist. A linear output's quantity (``profile.tracking_error_max_mm``)
    is its rotary twin's attribute in mm (:mod:`cas_freq.core.output`); one in its own unit
    (``stiffness.min_N_per_m``) is read as it is."""
    record = FIGURES.get(metric)
    if record is not None and record.output == "length" and record.unit == "mm":
        value = figure(result, record.twin)
        if value is None:
            return None
        return LENGTH.value(value) if FIGURES[record.twin].unit == "deg" else value * LENGTH.scale
    value = result
    for part in metric.split("."):
        value = getattr(value, part, None)
        if value is None:
            return None
    value = float(value)
    return value if math.isfinite(value) else None


def measure(variants, requirements, known=None):
    """Figures of every variant for each requirement.

    Parameters
    ----------
    variants : sequence of cas_freq.config.LoadedVariant
        The variants (their steps of one size run in one batch).
    requirements : sequence of cas_freq.config.requirement.Requirement
        What to measure.
    known : sequence of dict, optional
        Per variant, results already computed by the same code (so not computed again):
        ``"analyze"``, the variant's :class:`~cas_freq.analysis.Analysis`, and ``"steps"``,
        its :class:`~cas_freq.studies.run.StepRun` steps; a step of the right size (to 1e-9)
        is used instead of a new run.

    Returns
    -------
    list of (dict, dict, bool, dict)
        Per variant, ``values``: requirement id -> figure (float, or None when it does not
        exist, e.g. no crossover in range), ``context``: requirement id -> a short text of
        what was run, whether the closed loop is stable (if not, no figure may pass), and
        ``bounds``: requirement id -> ``(relation, edge)`` for a sine-dwell bandwidth outside
        its grid (:func:`~cas_freq.simulation.sinedwell.bandwidth_bound`; value None).
    """
    from cas_freq.analysis import analyze

    known = known or [{} for _ in variants]
    analyses = [item.get("analyze") or analyze(loaded)
                for loaded, item in zip(variants, known, strict=True)]
    stable = [index for index, analysis in enumerate(analyses) if analysis.stable]
    verdicts = {id(variants[index]): analyses[index].stability.verdict for index in stable}
    steps = {}
    for size in sorted({r.step for r in requirements if r.kind == "step"}):
        steps[size] = {index: _known_step(known[index], size) for index in stable}
        missing = [index for index, run in steps[size].items() if run is None]
        runs = step_batch([(variants[index], size) for index in missing], verdicts) \
            if missing else []
        steps[size].update(zip(missing, runs, strict=True))
    moves = {}
    for condition in dict.fromkeys(r.profile for r in requirements if r.kind == "profile"):
        runs = profile_runs([variants[index] for index in stable],
                            condition_profile(condition), verdicts) if stable else []
        moves[condition] = dict(zip(stable, runs, strict=True))
    out = []
    for index, loaded in enumerate(variants):
        values, context, bounds = {}, {}, {}
        dwells = {}
        for requirement in requirements:
            key = requirement.id
            if index not in stable:
                values[key], context[key] = _unstable_figure(analyses[index], requirement)
            elif requirement.kind == "analyze":
                values[key] = figure(analyses[index], requirement.metric)
                context[key] = _linear_condition(analyses[index], requirement.metric)
            elif requirement.kind == "step":
                run = steps[requirement.step][index]
                values[key] = figure(run, requirement.metric)
                context[key] = f"nonlinear step of {run.output_unit.show(run.step.amplitude_deg)}"
            elif requirement.kind == "profile":
                run = moves[requirement.profile][index]
                values[key] = figure(run, requirement.metric)
                context[key] = (f"profile move of "
                                f"{profile_condition_text(run.move, run.output_unit)}, "
                                "feed-forward as configured")
            else:
                condition = (requirement.amplitude, requirement.frequencies)
                if condition not in dwells:
                    dwells[condition] = _sinedwell_bandwidth(loaded, analyses[index],
                                                             *condition)
                values[key], bounds[key], context[key] = dwells[condition]
        out.append((json_ready(values), context, index in stable, bounds))
    return out


#: Prefixes of the figures of the loops' open-loop responses (margins and crossovers).
_LOOP_PREFIXES = ("position_loop.", "current_loop.")

def _linear_condition(analysis, metric):
    """How a linear figure was measured: exact delays, and with sampled controllers at the
    sampling instants (a loop-at-a-time view inside a slower loop is not defined)."""
    if not analysis.sampling:
        return "linear, exact delays"
    words = "linear, sampled controllers, exact delays"
    loop = metric.split(".")[0]
    if (".loop_at_a_time." in metric and figure(analysis, metric) is None
            and loop in time_varying_views(analysis.sampling["rates_hz"])):
        words += (f"; not defined: with the slower loops closed the {loop.replace('_', ' ')}"
                  " is periodically time-varying")
    return words


def _unstable_figure(analysis, requirement):
    """(value, condition) of a requirement on a variant whose closed loop is not stable.

    The open-loop margins of either loop exist whatever the closed loop does, so they are
    measured and shown (a negative phase margin is the plainest statement of instability), but
    no requirement passes on an unstable actuator, not even one of the current loop alone
    (:func:`measure` says which variants are stable). Closed-loop, step and sine-dwell
    figures of an unstable loop do not exist (None).
    """
    stability = analysis.stability
    if requirement.kind == "analyze" and requirement.metric.startswith(_LOOP_PREFIXES):
        return (figure(analysis, requirement.metric),
                f"{_linear_condition(analysis, requirement.metric)}; the closed loop is "
                f"unstable (current loop alone: {stability.current_loop_verdict})")
    return None, f"not assessed: the closed loop is {stability.verdict}"


def _known_step(item, size):
    """The :class:`StepRun` of a step of ``size`` [rad] among ``item["steps"]``, or None."""
    for run in item.get("steps", ()):
        if math.isclose(math.radians(run.step.amplitude_deg), size, rel_tol=1e-9):
            return run
    return None


def _sinedwell_bandwidth(loaded, analysis, amplitude, frequencies):
    """Sine-dwell bandwidth at one amplitude (as ``cas-freq sinedwell``, feed-forward off, on
    the requirement's grid or the variant's default one).

    Returns
    -------
    (float or None, (str, float) or None, str)
        The bandwidth [rad/s], the bound the grid gives when it holds no crossing, and the text
        of what was run (with why nothing was, when the sine-dwell exceeds the budget).
    """
    grid = frequencies or dwell_frequencies(analysis)
    shown = output_unit(loaded.params).show(math.degrees(amplitude))
    text = (f"sine-dwell at {shown}, {len(grid)} frequencies "
            f"{min(grid):.4g}..{max(grid):.4g} rad/s"
            + ("" if frequencies else " (the variant's default grid)"))
    current_rate_hz, position_rate_hz = loaded.params.simulation.rates_hz
    try:
        result = sine_dwell(
            dwell_parameters(loaded.params, feedforward=False), [amplitude], grid,
            current_rate_hz=current_rate_hz, position_rate_hz=position_rate_hz,
        )
    except BudgetError as error:
        reason = over_budget_reason(error, grid, "the requirement's frequencies")
        return None, None, f"{text}: not computed: {reason}"
    return result.bandwidth_rad_s[0], result.bandwidth_bounds[0], text
