"""The load envelope: every figure and requirement verdict of a variant against hinge stiffness.

An engineer sizing an actuator asks how much bandwidth and margin is left at the hinge moment
of the worst flight condition, and at what hinge stiffness a requirement fails. This module
sweeps ``load.hinge_stiffness`` (at the output, N*m/rad; > 0 opposes the motion, < 0 aids it) over
a grid for one variant, with the batch engine of ``cas-freq sweep`` (linear figures, and the
nonlinear step and its second-order fit where a requirement needs them), checks each
requirement at every point as ``cas-freq verify`` does (a figure of a loop that is not stable
never passes), and finds, on each side of the variant's own stiffness, where each requirement
is lost:

- where the figure crosses its bound between two grid points, by bisection of the verdict
  (:data:`BISECTIONS` steps, all requirements at once; the figures need not be continuous in
  the stiffness: the bandwidth jumps where a low-frequency dip of T crosses -3 dB);
- where the loss is the closed loop going unstable, at the stability boundary found by
  bisection of the Padé model's verdict (:func:`cas_freq.analysis.drivetrain.stable_hinge_range`).
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.drivetrain import stable_hinge_range
from cas_freq.core.parameters import LoopParameters
from cas_freq.core.summary import Summary
from cas_freq.simulation.simulator import RecordingBuffers
from cas_freq.studies.shown import run_figures_not_shown, shown_run_figure
from cas_freq.studies.sweep import evaluate_figures

KEY = "load.hinge_stiffness"
#: Bisection steps refining a loss between two grid points (a 5 N*m/rad step to 0.005).
BISECTIONS = 10


@dataclasses.dataclass(frozen=True)
class Loss:
    """Where a requirement is lost on one side of the variant's own hinge stiffness.

    Attributes
    ----------
    at : float
        Hinge stiffness [N*m/rad] of the loss (interpolated, or the stability boundary).
    between : (float, float)
        The grid points it lies between [N*m/rad].
    how : str
        ``"bound"`` (the figure crosses the requirement's bound) or ``"unstable"`` (the closed
        loop goes unstable first).
    bracket : (float, float)
        The last (passing, failing) hinge stiffness of the bisection [N*m/rad].
    """

    at: float
    between: tuple
    how: str
    bracket: tuple = ()


@dataclasses.dataclass(frozen=True)
class RequirementEnvelope:
    """One requirement over the envelope.

    Attributes
    ----------
    id, metric, severity : str
    min, max : float or None
        The requirement's bounds in the figure's unit.
    evaluated : bool
        False when the envelope does not compute its figure (``reason`` says why).
    passed : numpy.ndarray of bool or None
        Per grid point.
    at_nominal : bool or None
        The verdict at the variant's own hinge stiffness (evaluated there exactly).
    lost_below, lost_above : Loss or None
        The nearest loss on the aiding (lower) and opposing (higher) side of the variant's own
        stiffness; None where the requirement holds up to the end of the grid (or fails at
        the nominal).
    reason : str
    """

    id: str
    metric: str
    severity: str
    min: float | None
    max: float | None
    evaluated: bool
    passed: np.ndarray | None = None
    at_nominal: bool | None = None
    lost_below: Loss | None = None
    lost_above: Loss | None = None
    reason: str = ""


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class LoadEnvelope(Summary):
    """Figures and verdicts of one variant against hinge stiffness.

    Attributes
    ----------
    variant : str
    nominal_n_m_rad : float
        The variant's own hinge stiffness [N*m/rad], always one of the grid points.
    hinge_stiffness : numpy.ndarray
        Grid [N*m/rad], ascending.
    figures : dict of str to numpy.ndarray
        Every figure of ``cas-freq sweep`` per grid point (NaN where it does not exist).
    stability : numpy.ndarray of str
    stable_range : (float or None, float or None)
        Hinge stiffness between which the closed loop is stable [N*m/rad].
    step_deg : float or None
        Output step of the step figures [deg].
    requirements : tuple of RequirementEnvelope
    """

    variant: str
    nominal_n_m_rad: float
    hinge_stiffness: np.ndarray
    figures: dict
    stability: np.ndarray
    stable_range: tuple
    step_deg: float | None
    requirements: tuple

    def _summary(self):
        k = self.hinge_stiffness
        low, high = self.stable_range
        rows = [("nominal load spring K_h", self.nominal_n_m_rad, "N·m/rad"),
                ("stable from", low, "N·m/rad"), ("stable to", high, "N·m/rad")]
        for requirement in self.requirements:
            if not requirement.evaluated:
                text = f"not evaluated: {requirement.reason}"
            else:
                held = "holds" if requirement.at_nominal else "fails"
                lost = [f"lost {side} at {loss.at:.4g} N·m/rad ({loss.how})"
                        for side, loss in (("below", requirement.lost_below),
                                           ("above", requirement.lost_above)) if loss]
                text = "; ".join([f"{held} at the nominal", *lost])
            rows.append((f"{requirement.id} ({requirement.metric})", text, ""))
        return (f"{self.variant}: {k.size} load springs K_h {k.min():.4g} .. {k.max():.4g} "
                "N·m/rad", rows)


def load_envelope(loaded, hinge_stiffness, step_rad=None, progress=None, stable_range=None):
    """The load envelope of one variant.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
        The variant (its other load and drivetrain keys stay as they are).
    hinge_stiffness : array_like
        Grid [N*m/rad at the output]; the variant's own value is added to it.
    step_rad : float, optional
        Output step [rad] for the step and fit figures; default the first step requirement's, or
        no step if no requirement needs one.
    progress : callable, optional
        ``progress(done, total)``.
    stable_range : (float or None, float or None), optional
        The variant's stable hinge-stiffness range when already known (``analyze``'s
        drivetrain figures of a loaded variant); computed otherwise.

    Returns
    -------
    LoadEnvelope
    """
    params = loaded.params
    nominal = float(params.load.hinge_stiffness)
    grid = np.unique(np.append(np.asarray(hinge_stiffness, dtype=float), nominal))
    stepped = [r for r in params.requirements if r.kind == "step"]
    if step_rad is None and stepped:
        step_rad = stepped[0].step
    fit = any(r.metric.startswith("fit.") for r in stepped)
    figures, stability = evaluate_figures(params, {KEY: grid}, step_rad=step_rad, fit=fit,
                                          progress=progress)
    if stable_range is None:
        stable_range = stable_hinge_range(LoopParameters.from_config(params))
    stable = stability.astype(str) == "stable"
    index = int(np.flatnonzero(grid == nominal)[0])
    results = tuple(
        _requirement(r, grid, figures, stable, index, stable_range, step_rad)
        for r in params.requirements
    )
    results = _refined(params, results, step_rad, fit)
    return LoadEnvelope(
        variant=loaded.variant, nominal_n_m_rad=nominal, hinge_stiffness=grid,
        figures=figures, stability=stability, stable_range=stable_range,
        step_deg=None if step_rad is None else math.degrees(step_rad), requirements=results,
    )


def _requirement(requirement, grid, figures, stable, index, stable_range, step_rad):
    """:class:`RequirementEnvelope` of one requirement (see the module docstring)."""
    base = dict(id=requirement.id, metric=requirement.metric, severity=requirement.severity,
                min=requirement.min, max=requirement.max)
    values = figures.get(requirement.metric)
    reason = ""
    if requirement.kind == "step" and (step_rad is None or not math.isclose(
            requirement.step, step_rad, rel_tol=1e-9)):
        reason = f"needs a {math.degrees(requirement.step):g} deg step; the envelope runs " + (
            "none" if step_rad is None else f"{math.degrees(step_rad):g} deg")
    elif values is None:
        reason = "figure not computed by the envelope (sine-dwell and profile figures are not)"
    if reason:
        return RequirementEnvelope(**base, evaluated=False, reason=reason)
    passed = np.array([bool(ok) and requirement.passes(None if math.isnan(v) else float(v))
                       for v, ok in zip(values, stable, strict=True)])
    below = above = None
    if passed[index]:
        below = _loss(requirement, grid, values, stable, passed, index, -1, stable_range[0])
        above = _loss(requirement, grid, values, stable, passed, index, +1, stable_range[1])
    return RequirementEnvelope(**base, evaluated=True, passed=passed,
                               at_nominal=bool(passed[index]), lost_below=below,
                               lost_above=above)


def _loss(requirement, grid, values, stable, passed, index, direction, stability_bound):
    """The first loss walking from ``index`` in ``direction`` (see :class:`Loss`)."""
    k = index
    while 0 <= k + direction < grid.size and passed[k + direction]:
        k += direction
    j = k + direction
    if not 0 <= j < grid.size:
        return None
    between = tuple(sorted((float(grid[k]), float(grid[j]))))
    if not stable[j] and stability_bound is not None and between[0] <= stability_bound <= \
            between[1]:
        return Loss(float(stability_bound), between, "unstable")
    # refined by _refined: (passing end, failing end) of the bracket
    return Loss(0.5 * (between[0] + between[1]), between,
                "unstable" if not stable[j] else "bound", (float(grid[k]), float(grid[j])))


def _refined(params, results, step_rad, fit):
    """The results with every "bound" loss bisected (all at once, one batch per step)."""
    tasks = [(n, side) for n, r in enumerate(results) if r.evaluated
             for side in ("lost_below", "lost_above")
             if getattr(r, side) is not None and getattr(r, side).how == "bound"]
    if not tasks:
        return results
    requirements = {r.id: r for r in params.requirements}
    brackets = [list(getattr(results[n], side).bracket) for n, side in tasks]
    stepped = any(requirements[results[n].id].kind == "step" for n, _ in tasks)
    fitted = fit and any(results[n].metric.startswith("fit.") for n, _ in tasks)
    buffers = RecordingBuffers()  # the bisection's small batches record into the same memory
    for _ in range(BISECTIONS):
        middles = np.array([0.5 * (good + bad) for good, bad in brackets])
        figures, stability = evaluate_figures(params, {KEY: middles},
                                              step_rad=step_rad if stepped else None,
                                              fit=fitted, buffers=buffers)
        for t, (n, _) in enumerate(tasks):
            requirement = requirements[results[n].id]
            value = figures.get(requirement.metric, np.full(len(tasks), np.nan))[t]
            ok = str(stability[t]) == "stable" and requirement.passes(
                None if math.isnan(value) else float(value))
            brackets[t][0 if ok else 1] = float(middles[t])
    results = list(results)
    for (n, side), (good, bad) in zip(tasks, brackets, strict=True):
        loss = dataclasses.replace(getattr(results[n], side), at=0.5 * (good + bad),
                                   bracket=(good, bad))
        results[n] = dataclasses.replace(results[n], **{side: loss})
    return tuple(results)


#: Figures left out of :func:`envelope_dict`: the second-order fit's wn and zeta alone. Under a
#: stiff opposing hinge the step creeps in on the integral term, the fit is overdamped and only
#: its dominant pole (about wn/(2 zeta), hence the closed-form bandwidth, which is kept) is
#: determined: wn and zeta then run to 1e9 rad/s and 1e7 together, to values set by the last
#: bits of the arithmetic. Each variant's own fit (the report's step section) has them, with
#: their confidence intervals.
_UNIDENTIFIABLE = ("fit.wn_rad_s", "fit.zeta")

#: The fit's parameters kept in :func:`envelope_dict` (beside its RMS residual, the minimum of
#: the sum of squares, which is determined however flat the minimum is).
FIT_PARAMETERS = ("fit.td_s", "fit.bandwidth_closed_form_rad_s")

#: Damping ratio above which a fit is degenerate: its fast pole (4 zeta^2 times the slow one)
#: is far beyond the data, and only the slow pole wn/(2 zeta) is fitted. The shipped
#: envelopes' fits are either below 2 or above 3e6. There the closed-form bandwidth (that
#: slow pole) still moved by 1.1e-4 under another BLAS kernel (loaded, 15 N*m/rad): the
#: optimiser stops anywhere along the flat valley of (wn, zeta), so it is not stored either.
DEGENERATE_ZETA = 1e3


def not_shown(envelope):
    """Why each grid point's :data:`~cas_freq.studies.shown.RUN_FIGURES` are not shown (None
    where they are): :func:`~cas_freq.studies.shown.run_figures_not_shown`, the sweep's rule."""
    return run_figures_not_shown(envelope.figures, envelope.stability)


def fit_not_shown(envelope):
    """Why each grid point's :data:`FIT_PARAMETERS` are not shown (besides
    :func:`not_shown`): None where they are.

    Returns
    -------
    list of str or None
        Per grid point: a degenerate fit (:data:`DEGENERATE_ZETA`).
    """
    zeta = envelope.figures.get("fit.zeta", np.full(envelope.hinge_stiffness.size, np.nan))
    return [f"degenerate fit: overdamped beyond zeta {DEGENERATE_ZETA:g}, only its slow pole "
            "is fitted and not to the written precision" if z > DEGENERATE_ZETA else None
            for z in zeta]


def shown_figure(envelope, key):
    """The figure ``key`` per grid point [its unit], NaN where it does not exist or is not
    shown (:func:`not_shown` for the run figures, :func:`fit_not_shown` for the
    :data:`FIT_PARAMETERS`).

    Returns
    -------
    numpy.ndarray
    """
    values = shown_run_figure(
        envelope.figures.get(key, np.full(envelope.hinge_stiffness.size, np.nan)), key,
        not_shown(envelope))
    if key in FIT_PARAMETERS:
        values[[reason is not None for reason in fit_not_shown(envelope)]] = np.nan
    return values


def envelope_dict(envelope):
    """JSON-ready dict of a :class:`LoadEnvelope` (floats as they are; NaN and the figures
    :func:`shown_figure` does not show -> None, with the reasons per grid point in
    ``run_figures_not_shown`` and ``fit_parameters_not_shown``)."""
    def loss(item):
        return None if item is None else {"at_n_m_rad": item.at,
                                           "between_n_m_rad": list(item.between),
                                           "how": item.how}

    def clean(values):
        return [None if not math.isfinite(v) else float(v) for v in values]

    return {
        "variant": envelope.variant,
        "nominal_hinge_stiffness_n_m_rad": envelope.nominal_n_m_rad,
        "hinge_stiffness_n_m_rad": clean(envelope.hinge_stiffness),
        "stable_range_n_m_rad": list(envelope.stable_range),
        "step_deg": envelope.step_deg,
        "stability": [str(v) for v in envelope.stability],
        # why the closed loop's, the step's and the fit's figures of a point are null (or the
        # step's and the fit's alone, where the step diverged), and why the fit's parameters are
        "run_figures_not_shown": not_shown(envelope),
        "fit_parameters_not_shown": fit_not_shown(envelope),
        "figures": {name: clean(shown_figure(envelope, name)) for name in envelope.figures
                    if not name.startswith("_") and name not in _UNIDENTIFIABLE},
        "requirements": [
            {"id": r.id, "metric": r.metric, "severity": r.severity, "min": r.min,
             "max": r.max, "evaluated": r.evaluated,
             "reason": r.reason or None,
             "passed": None if r.passed is None else [bool(v) for v in r.passed],
             "at_nominal": r.at_nominal, "lost_below": loss(r.lost_below),
             "lost_above": loss(r.lost_above)}
            for r in envelope.requirements
        ],
    }
