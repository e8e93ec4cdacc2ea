"""Every figure and requirement verdict of many candidate tunings at once.

The candidates, each in every scenario (:mod:`~cas_freq.tuning.scenarios`), go through
:func:`cas_freq.studies.sweep.evaluate_figures`, the same code as ``verify`` and
``montecarlo``: first the batch analysis of all, then the nonlinear step of the step
requirements (and its second-order fit where a requirement needs it) and the sine-dwell of the
first sine-dwell requirement of the candidates the linear requirements leave feasible. A
requirement passes in a scenario as ``verify`` decides it (an unstable loop fails every
requirement), with its bound moved inwards by ``margin`` of its magnitude.
"""

import dataclasses
import math

import numpy as np

from cas_freq.core.parameters import base_values
from cas_freq.studies.montecarlo import dwell_condition
from cas_freq.studies.steps import FIT_FIGURES, STEP_FIGURES
from cas_freq.studies.sweep import evaluate_figures
from cas_freq.tuning.options import OBJECTIVES

#: The figures of the trade-off (Pareto front): figure, +1 maximised / -1 minimised.
TRADE_OFF = (("closed_loop.bandwidth_rad_s", 1.0), ("position_loop.phase_margin_deg", 1.0),
             ("step.overshoot_pct", -1.0))

#: The violation of a requirement whose figure is missing or whose loop is unstable.
MISSING_VIOLATION = 10.0


@dataclasses.dataclass(frozen=True)
class Constraint:
    """A requirement as the tune holds it: its bounds moved inwards by the margin."""

    requirement: object
    low: float | None
    high: float | None

    @property
    def id(self):
        return self.requirement.id

    @property
    def metric(self):
        return self.requirement.metric

    def passes(self, values):
        """Bool array: within the tightened bounds (NaN fails)."""
        values = np.asarray(values, dtype=float)
        ok = np.isfinite(values)
        with np.errstate(invalid="ignore"):
            if self.low is not None:
                ok &= values >= self.low
            if self.high is not None:
                ok &= values <= self.high
        return ok

    def shortfall(self, values):
        """How far outside the tightened bounds, relative to the bound's magnitude (0 inside,
        :data:`MISSING_VIOLATION` for NaN)."""
        values = np.asarray(values, dtype=float)
        out = np.zeros(values.shape)
        if self.low is not None:
            out = np.maximum(out, (self.low - values) / max(abs(self.low), 1e-12))
        if self.high is not None:
            out = np.maximum(out, (values - self.high) / max(abs(self.high), 1e-12))
        return np.where(np.isfinite(values), out, MISSING_VIOLATION)


def constraints(requirements, margin=0.0, advisory=False):
    """(Constraints, requirements not held) of the config's requirements.

    Required requirements are held (and advisory ones with ``advisory``); profile
    requirements are not (a tune does not simulate moves: ``verify`` checks them after).
    """
    held, skipped = [], []
    for r in requirements:
        if r.severity != "required" and not advisory:
            continue
        if r.kind == "profile":
            skipped.append((r, "profile moves are not simulated by tune; verify checks them"))
            continue
        low = None if r.min is None else r.min + margin * abs(r.min)
        high = None if r.max is None else r.max - margin * abs(r.max)
        held.append(Constraint(r, low, high))
    steps = {r.requirement.step for r in held if r.requirement.kind == "step"}
    dwells = {(r.requirement.amplitude, r.requirement.frequencies) for r in held
              if r.requirement.kind == "sinedwell"}
    if len(steps) > 1 or len(dwells) > 1:
        first_step = next(iter(sorted(steps))) if steps else None
        kept = []
        for c in held:
            r = c.requirement
            if r.kind == "step" and r.step != first_step:
                skipped.append((r, "only one step size per tune (the first); verify checks it"))
            elif r.kind == "sinedwell" and (r.amplitude, r.frequencies) != next(iter(dwells)):
                skipped.append((r, "only one sine-dwell condition per tune; verify checks it"))
            else:
                kept.append(c)
        held = kept
    return held, skipped


@dataclasses.dataclass(frozen=True, eq=False)
class Evaluation:
    """Candidates' results.

    Attributes
    ----------
    values : dict of str to numpy.ndarray
        Free key -> (n,) values [SI].
    objective : numpy.ndarray
        (n,) the objective's figure in the nominal scenario (NaN where undefined).
    passed : numpy.ndarray
        (n, n_constraints) share of counted scenarios passing each constraint.
    yield_all : numpy.ndarray
        (n,) share of counted scenarios passing every constraint.
    feasible : numpy.ndarray of bool
        (n,) the nominal scenario passes and ``yield_all`` reaches the target.
    violation : numpy.ndarray
        (n, n_constraints) shortfall of each constraint at the target quantile of the counted
        scenarios (0 where it holds; NaN for a step or sine-dwell requirement of a candidate
        the linear requirements screened out, whose step was not simulated).
    nominal : dict of str to numpy.ndarray
        Figure -> (n,) values in the nominal scenario (the trade-off figures and every
        constraint's).
    stable : numpy.ndarray of bool
        (n,) the closed loop of the nominal scenario is stable (else every constraint fails
        there, not assessed, whatever its figure).
    """

    values: dict
    objective: np.ndarray
    passed: np.ndarray
    yield_all: np.ndarray
    feasible: np.ndarray
    violation: np.ndarray
    nominal: dict
    stable: np.ndarray


def _quantile_shortfall(constraint, values, counted, target):
    """Shortfall of the k-th best counted scenario, k = ceil(target * count): 0 exactly when at
    least the target share of them passes (the others may fail)."""
    shortfall = np.sort(constraint.shortfall(values[:, counted]), axis=1)
    k = max(1, math.ceil(target * shortfall.shape[1] - 1e-9))
    return shortfall[:, k - 1]


def _screened_figures(params, changes, n, m, scenario_set, held, step, fit, sinedwell,
                      scheduler, screen=True, simulate=True):
    """Figures of every row: the linear ones of all, the simulated ones (step, fit,
    sine-dwell) only of the candidates the linear requirements leave feasible.

    A candidate whose linear figures already fail (in the nominal scenario, or at the target
    yield) cannot be feasible whatever its step does, so its simulated figures stay NaN (its
    shortfall NaN: not known, not counted when candidates are ranked). The figures of the
    others are those of one batch with the simulation, as ``verify`` computes them. With
    ``simulate`` False (a structure the simulator does not run yet) no candidate is simulated:
    the simulated figures are NaN.
    """
    figures, stability = evaluate_figures(params, changes, scheduler=scheduler)
    linear = [c for c in held if c.requirement.kind not in ("step", "sinedwell")]
    stable = (stability.astype(str) == "stable").reshape(n, m)
    ok = stable.copy()
    for c in linear:
        ok &= c.passes(figures[c.metric].reshape(n, m))
    counted = scenario_set.counted
    keep = ok[:, 0] & (ok[:, counted].mean(axis=1) >= scenario_set.target - 1e-12)
    if not screen:
        keep = np.ones(n, dtype=bool)
    if not simulate:
        keep = np.zeros(n, dtype=bool)
    rows = np.repeat(keep, m)
    simulated = {key: values[rows] for key, values in changes.items()}
    if keep.any():
        more, _ = evaluate_figures(params, simulated, step_rad=step, fit=fit,
                                   sinedwell=sinedwell, scheduler=scheduler)
        for name, values in more.items():
            if name not in figures:
                figures[name] = np.full(n * m, np.nan)
                figures[name][rows] = values
    else:
        for name in STEP_FIGURES + (FIT_FIGURES if fit else ()) + (
                ("sinedwell.bandwidth_rad_s",) if sinedwell else ()):
            figures[name] = np.full(n * m, np.nan)
    return figures, stability, keep


def evaluate(params, keys, unit, scenario_set, held, objective, scheduler=None, screen=True,
             simulate=True):
    """Evaluate candidates given as unit-box points ``unit`` (n, k); ``screen``: simulate only
    the candidates the linear requirements leave feasible (else every one); ``simulate``
    False: none (the step and sine-dwell figures NaN)."""
    unit = np.atleast_2d(unit)
    n = unit.shape[0]
    values = {k.key: k.value(unit[:, j]) for j, k in enumerate(keys)}
    changes = scenario_set.changes(values, base_values(params))
    step = next((c.requirement.step for c in held if c.requirement.kind == "step"), None)
    if step is None:
        step = math.radians(10.0)
    fit = any(c.metric.startswith("fit.") for c in held)
    dwell = next((c.requirement for c in held if c.requirement.kind == "sinedwell"), None)
    sinedwell = None
    if dwell is not None:
        sinedwell = dwell_condition(dwell)
    m = scenario_set.count
    figures, stability, simulated = _screened_figures(params, changes, n, m, scenario_set,
                                                      held, step, fit, sinedwell, scheduler,
                                                      screen, simulate)
    stable = (stability.astype(str) == "stable").reshape(n, m)
    counted, target = scenario_set.counted, scenario_set.target
    passed, violation, every = [], [], np.ones((n, m), dtype=bool)
    nominal = {}
    for c in held:
        figure = figures[c.metric].reshape(n, m)
        ok = stable & c.passes(figure)
        every &= ok
        passed.append(ok[:, counted].mean(axis=1))
        shortfall = _quantile_shortfall(c, np.where(stable, figure, np.nan), counted, target)
        if c.requirement.kind in ("step", "sinedwell"):  # NaN: not simulated (screened out)
            shortfall = np.where(simulated, shortfall, np.nan)
        violation.append(shortfall)
        nominal[c.metric] = figure[:, 0]
    for name, _ in TRADE_OFF:
        nominal[name] = np.where(stable[:, 0], figures[name].reshape(n, m)[:, 0], np.nan)
    name, _ = OBJECTIVES[objective]
    score = np.where(stable[:, 0], figures[name].reshape(n, m)[:, 0], np.nan)
    yield_all = every[:, counted].mean(axis=1)
    feasible = every[:, 0] & (yield_all >= target - 1e-12)
    shape = (n, len(held))
    return Evaluation(
        values=values, objective=score,
        passed=np.column_stack(passed) if held else np.zeros(shape),
        yield_all=yield_all, feasible=feasible,
        violation=np.column_stack(violation) if held else np.zeros(shape), nominal=nominal,
        stable=stable[:, 0])


def joined(evaluations, rows=slice(None)):
    """One Evaluation of several, candidates in order (``rows`` of them)."""
    fields = {}
    for field in dataclasses.fields(Evaluation):
        items = [getattr(e, field.name) for e in evaluations]
        if isinstance(items[0], dict):
            fields[field.name] = {key: np.concatenate([item[key] for item in items])[rows]
                                  for key in items[0]}
        else:
            fields[field.name] = np.concatenate(items)[rows]
    return Evaluation(**fields)


__all__ = ["Constraint", "Evaluation", "OBJECTIVES", "TRADE_OFF", "constraints", "evaluate",
           "joined"]
