r"""The worst case of each required figure over the box of the tolerances (``cas-freq
worstcase``, ``Actuator.worst_case``, ``verify`` with ``worst_case: true``; docs/model.md,
"Tolerances and the worst case").

The box is :math:`p_i \in [p_{i0} - \Delta_i, p_{i0} + \Delta_i]` of the tolerances
(:mod:`cas_freq.core.tolerances`). A requirement's figure is worst where its margin to its
bound (:meth:`~cas_freq.config.requirement.Requirement.margin`) is smallest; a point where the
loop is not stable, or where the figure does not exist, fails and is the worst there is.

How the worst is searched (every evaluation is a variant of the batch engine of ``sweep`` and
``montecarlo``, :func:`~cas_freq.studies.sweep.evaluate_figures`, so dask runs them where a
scheduler is given, with the same numbers):

1. the nominal point, **every corner** of the box (2^d), and ``samples`` points drawn uniformly
   in it (seeded);
2. a **local search** from each requirement's worst corner and worst sample: a compass search
   that tries a step up and down along every key (clipped to the box), moves to the best point
   that lowers the margin, else halves the step, until every step is below ``resolution`` of
   its key's width. Each round evaluates the candidates of every requirement at once.

The result is the **worst found**, with the point that reaches it and the search that found
it. For every loop's phase and gain margins and the bandwidth of continuous loops on the
motor encoder (PID-on-PI or cascade, with their filters and a rigid or compliant load), a
**guaranteed bound** over the whole box and a proof of stability over it come from interval
enclosures of the loops (:mod:`cas_freq.analysis.interval_bound`), with the gap to the worst
found; for the other figures and drives the output says "bound: none" (a worst inside the box that
no corner, sample or compass step reaches would be missed). Stability is also checked at
every point evaluated (a point that is not stable is reported, with where), and the
outermost loop's phase and gain margins are searched as the "stability" objective even
where no requirement names them.
"""

import dataclasses
import math
import time

import numpy as np

from cas_freq.analysis.disturbance import PREFIXES as DISTURBANCE
from cas_freq.analysis.interval_bound import MAX_CELLS, box_bounds, supported
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import json_ready
from cas_freq.core.parameters import LoopParameters, base_values, unit_of
from cas_freq.model.sampled import time_varying_views
from cas_freq.studies.montecarlo import dwell_condition, not_defined
from cas_freq.studies.sweep import evaluate_figures

#: Most toleranced keys: their corners are all evaluated (2^12 = 4096).
MAX_KEYS = 12
#: Uniform samples of the box evaluated before the local search (a default).
DEFAULT_SAMPLES = 256
#: The local search stops when every step is below this share of its key's width.
DEFAULT_RESOLUTION = 1e-3
#: First step of the local search, as a share of each key's width.
FIRST_STEP = 0.25
#: Most rounds of the local search (each halves a step or moves).
MAX_ROUNDS = 60
#: Starts of the local search per requirement: its worst corner and its worst sample.
STARTS = ("corner", "sample")
#: The figures of the "stability" objective: the outermost loop's margins (min bounds 0).
STABILITY_FIGURES = ("phase_margin_deg", "gain_margin_db")


@dataclasses.dataclass(frozen=True)
class Box:
    """The tolerance box: per key its nominal value and its ends [SI]."""

    keys: tuple
    nominal: np.ndarray
    low: np.ndarray
    high: np.ndarray

    @property
    def width(self):
        """high - low per key [SI]."""
        return self.high - self.low

    def corners(self):
        """Every corner (2^d, d) [SI], the first key changing slowest."""
        d = len(self.keys)
        signs = (np.arange(2**d)[:, None] >> np.arange(d)[::-1]) & 1
        return np.where(signs == 1, self.high, self.low)

    def relative(self, point):
        """Each key's offset from nominal as a share of its half-width (-1 .. 1)."""
        half = 0.5 * self.width
        return np.where(half > 0, (np.asarray(point) - self.nominal) / np.where(half > 0, half,
                                                                                1.0), 0.0)

    def at_corner(self, point, resolution=DEFAULT_RESOLUTION):
        """True when every key sits at an end of its range (within ``resolution``)."""
        return bool(np.all(np.abs(np.abs(self.relative(point)) - 1.0) <= 2 * resolution))


def tolerance_box(params, tolerances):
    """The :class:`Box` of ``tolerances`` around a validated config's values."""
    tolerances = list(tolerances)
    if not tolerances:
        raise ConfigError("worst case: no tolerances: give --tolerance KEY=TOL or a "
                          "'tolerances:' section in the config (e.g. motor.Km: 10%)")
    if len(tolerances) > MAX_KEYS:
        raise ConfigError(f"worst case: {len(tolerances)} toleranced keys; at most {MAX_KEYS} "
                          f"(every corner is evaluated: 2^{MAX_KEYS})")
    base = base_values(params)
    keys, nominal, half = [], [], []
    for tolerance in tolerances:
        value = base[tolerance.key]
        if value is None:
            raise ConfigError(f"{tolerance.key}: not set in the config (derived), so it has no "
                              "nominal value to tolerance")
        if tolerance.key in keys:
            raise ConfigError(f"tolerances: {tolerance.key} is given twice")
        keys.append(tolerance.key)
        nominal.append(float(value))
        half.append(float(tolerance.half_width(value)))
    nominal, half = np.array(nominal), np.array(half)
    return Box(tuple(keys), nominal, nominal - half, nominal + half)


@dataclasses.dataclass
class _Objective:
    """One figure searched: a requirement's, or the stability objective's."""

    id: str
    metric: str
    minimum: float | None
    maximum: float | None
    kind: str
    severity: str = "required"

    @property
    def needs(self):
        """What its points' evaluation needs: "analyze", "step", "sinedwell" or, for the
        stiffness, effort and noise figures, "disturbance"."""
        return "disturbance" if self.metric.startswith(DISTURBANCE) else self.kind

    def margins(self, figures, stable):
        """The margin of every point (-inf where not stable or missing: it fails)."""
        values = figures.get(self.metric)
        if values is None:
            return np.full(stable.size, -np.inf)
        values = np.asarray(values, dtype=float)
        margin = np.full(values.shape, np.inf)
        if self.minimum is not None:
            margin = np.minimum(margin, values - self.minimum)
        if self.maximum is not None:
            margin = np.minimum(margin, self.maximum - values)
        return np.where(np.isfinite(values) & stable, margin, -np.inf)


class _Evaluator:
    """Evaluates points of the box (the frequency figures, and the step's where asked),
    counting the evaluations."""

    def __init__(self, params, box, step_rad, fit, sinedwell, scheduler):
        self.params, self.box = params, box
        self.step_rad, self.fit, self.sinedwell = step_rad, fit, sinedwell
        self.scheduler = scheduler
        self.count = {"analyze": 0, "step": 0, "sinedwell": 0}
        #: Points evaluated that are not stable: how many, and the first (point, verdict).
        self.not_stable, self.first_not_stable = 0, None

    def __call__(self, points, kinds):
        """Figures and stability (bool) of ``points`` (n, d); ``kinds``: the set of what the
        objectives need ("analyze", "step", "sinedwell", "disturbance":
        :attr:`_Objective.needs`)."""
        changes = {key: points[:, j] for j, key in enumerate(self.box.keys)}
        step = self.step_rad if "step" in kinds else None
        dwell = self.sinedwell if "sinedwell" in kinds else None
        figures, stability = evaluate_figures(self.params, changes, step_rad=step,
                                              fit=self.fit and step is not None,
                                              sinedwell=dwell,
                                              disturbance="disturbance" in kinds,
                                              scheduler=self.scheduler)
        self.count["analyze"] += len(points)
        self.count["step"] += len(points) if step is not None else 0
        self.count["sinedwell"] += len(points) if dwell is not None else 0
        verdicts = np.asarray(stability).astype(str)
        stable = verdicts == "stable"
        if not stable.all():
            self.not_stable += int((~stable).sum())
            if self.first_not_stable is None:
                first = int(np.flatnonzero(~stable)[0])
                self.first_not_stable = (points[first].copy(), str(verdicts[first]))
        return figures, stable, verdicts


def _objectives(params, requirements):
    """The objectives searched and the requirements left out (with why)."""
    requirements = params.requirements if requirements is None else requirements
    stepped = [r for r in requirements if r.kind == "step"]
    step_rad = stepped[0].step if stepped else None
    dwelt = [r for r in requirements if r.kind == "sinedwell"]
    sinedwell = dwell_condition(dwelt[0]) if dwelt else None
    objectives, skipped = [], []
    time_varying = time_varying_views(LoopParameters.from_config(params).sample_rates)
    for r in requirements:
        if not_defined(r.metric, time_varying):
            skipped.append((r, not_defined(r.metric, time_varying)))
        elif r.kind == "profile":
            skipped.append((r, "a profile move is not evaluated over the box"))
        elif r.kind == "step" and not math.isclose(r.step, step_rad):
            skipped.append((r, f"needs a {math.degrees(r.step):g} deg step; the search runs "
                               f"the first step requirement's {math.degrees(step_rad):g} deg"))
        elif r.kind == "sinedwell" and dwell_condition(r) != sinedwell:
            skipped.append((r, "only the first sine-dwell condition is evaluated"))
        elif r.kind == "analyze" and r.metric.startswith("envelope."):
            skipped.append((r, "figure not computed by the batch engine"))
        else:
            objectives.append(_Objective(r.id, r.metric, r.min, r.max, r.kind, r.severity))
    for name in STABILITY_FIGURES:  # the outermost loop is the position loop
        objectives.append(_Objective(f"stability ({name.split('_')[0]} margin)",
                                     f"position_loop.{name}", 0.0, None, "analyze",
                                     "stability"))
    fit = any(o.metric.startswith("fit.") for o in objectives)
    return objectives, skipped, step_rad, fit, sinedwell


def _search(evaluate, box, objectives, starts, resolution, max_rounds):
    """Compass search from every (objective, start) pair at once: returns per pair
    (point, margin, rounds)."""
    width = np.where(box.width > 0, box.width, 1.0)
    pairs = [(index, np.array(point, dtype=float), margin)
             for index, point, margin, _ in starts]
    steps = [FIRST_STEP * box.width.copy() for _ in pairs]
    active = [margin > -np.inf and bool(np.any(box.width > 0)) for _, _, margin in pairs]
    rounds = 0
    d = len(box.keys)
    while any(active) and rounds < max_rounds:
        rounds += 1
        candidates, owners = [], []
        for number, ((_, point, _), step) in enumerate(zip(pairs, steps, strict=True)):
            if not active[number]:
                continue
            for j in range(d):
                if box.width[j] == 0:
                    continue
                for sign in (1.0, -1.0):
                    moved = point.copy()
                    moved[j] = np.clip(point[j] + sign * step[j], box.low[j], box.high[j])
                    if moved[j] != point[j]:
                        candidates.append(moved)
                        owners.append(number)
        if not candidates:
            break
        points, owners = np.array(candidates), np.array(owners)
        # the candidates of the frequency-domain figures apart from those that need a step
        # (or a sine dwell): a simulation only where a figure needs one
        objective_of = np.array([pairs[n][0] for n in owners])
        candidate_margin = np.empty(owners.size)
        for kind in sorted({objectives[index].needs for index in set(objective_of.tolist())}):
            rows = np.flatnonzero([objectives[index].needs == kind for index in objective_of])
            figures, stable, _ = evaluate(points[rows], {kind})
            for index in set(objective_of[rows].tolist()):  # each objective's margins once
                mine = objective_of[rows] == index
                candidate_margin[rows[mine]] = objectives[index].margins(figures, stable)[mine]
        for number in set(owners.tolist()):
            index, point, margin = pairs[number]
            mine = np.flatnonzero(owners == number)
            margins = candidate_margin[mine]
            best = int(np.argmin(margins))
            if margins[best] < margin - 1e-12 * max(1.0, abs(margin)):
                pairs[number] = (index, points[mine[best]], float(margins[best]))
                if margins[best] == -np.inf:
                    active[number] = False
            else:
                steps[number] = 0.5 * steps[number]
                if np.all(steps[number] <= resolution * width):
                    active[number] = False
    return pairs, rounds


def worst_case(loaded, tolerances=None, requirements=None, *, samples=DEFAULT_SAMPLES, seed=0,
               resolution=DEFAULT_RESOLUTION, scheduler=None, max_rounds=MAX_ROUNDS,
               bound_cells=MAX_CELLS):
    """The worst case of every requirement's figure over the tolerance box.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
        The variant (with its overrides).
    tolerances : sequence of Tolerance, optional
        Default: the config's ``tolerances:``.
    requirements : sequence of Requirement, optional
        Default: the config's.
    samples : int
        Uniform samples of the box evaluated besides its corners (>= 0).
    seed : int
        Seed of those samples.
    resolution : float
        The local search stops when every step is below this share of its key's width.
    scheduler : str, optional
        Run the evaluations on a dask cluster (``local:N`` or an address).
    bound_cells : int
        Most cells of the guaranteed bound's branch and bound
        (:mod:`cas_freq.analysis.interval_bound`; about 2 s per million); 0: no bound.

    Returns
    -------
    dict
        JSON-ready (:func:`worst_case_text` prints it): the box, per requirement the nominal
        and worst value with the point and how it was found, the stability over the points
        evaluated, and the evaluations counted.
    """
    started = time.perf_counter()
    params = loaded.params
    tolerances = params.tolerance_list if tolerances is None else tolerances
    box = tolerance_box(params, tolerances)
    units = [unit_of(key, params) for key in box.keys]
    if isinstance(samples, bool) or not (isinstance(samples, int) and 0 <= samples <= 100_000):
        raise ConfigError(f"--samples: must be an integer 0..100000, got {samples!r}")
    if not (isinstance(resolution, float | int) and 0 < resolution < 0.5):
        raise ConfigError(f"--resolution: must be in (0, 0.5), got {resolution!r}")
    objectives, skipped, step_rad, fit, sinedwell = _objectives(params, requirements)
    evaluate = _Evaluator(params, box, step_rad, fit, sinedwell, scheduler)
    rng = np.random.default_rng(seed)
    corners = box.corners()
    drawn = box.low + rng.random((samples, len(box.keys))) * box.width
    points = np.vstack([box.nominal[None, :], corners, drawn])
    origin = ["nominal"] + ["corner"] * len(corners) + ["sample"] * samples
    kinds = {o.needs for o in objectives}
    figures, stable, verdicts = evaluate(points, kinds)
    starts, first = [], {}
    for index, objective in enumerate(objectives):
        margins = objective.margins(figures, stable)
        first[index] = margins
        for where in STARTS:
            chosen = [k for k, o in enumerate(origin) if o == where]
            if chosen:
                k = chosen[int(np.argmin(margins[chosen]))]
                starts.append((index, points[k], float(margins[k]), where))
    found, rounds = _search(evaluate, box, objectives, starts, resolution, max_rounds)
    worst = []
    for index in range(len(objectives)):
        k = int(np.argmin(first[index]))
        best = (points[k], float(first[index][k]), origin[k])
        for (owner, point, margin), start in zip(found, starts, strict=True):
            if owner == index and margin < best[1] - 1e-9 * max(1.0, abs(best[1])):
                best = (point, margin, f"local search from the worst {start[3]}")
        worst.append(best)
    # the figures at each worst point, evaluated once more together (their values and verdicts)
    at_worst, stable_worst, verdict_worst = evaluate(np.array([w[0] for w in worst]), kinds)
    results = [
        _result(box, units, objective, point, margin, how, figures, at_worst, index,
                resolution, str(verdict_worst[index]))
        for index, (objective, (point, margin, how)) in enumerate(
            zip(objectives, worst, strict=True))]
    if isinstance(bound_cells, bool) or not (isinstance(bound_cells, int) and bound_cells >= 0):
        raise ConfigError(f"--bound-cells: must be an integer >= 0, got {bound_cells!r}")
    guaranteed, why = (
        (None, "none: not asked for (--bound-cells 0)") if bound_cells == 0 else
        (None, "none: the nominal point is not stable") if not stable[0] else
        (None, "none: the search found points of the box that are not stable")
        if evaluate.not_stable else _guaranteed(params, box, results, bound_cells))
    proved = None if guaranteed is None else guaranteed["stable"]
    return json_ready({
        "config": params.name, "config_path": loaded.source, "variant": loaded.variant,
        "overrides": [f"{k}={v}" for k, v in loaded.overrides],
        "box": [{"key": key, "unit": unit, "nominal": float(n), "low": float(lo),
                 "high": float(hi)}
                for key, unit, n, lo, hi in zip(box.keys, units, box.nominal, box.low,
                                                box.high, strict=True)],
        "step_deg": None if step_rad is None else math.degrees(step_rad),
        "search": {"corners": len(corners), "samples": samples, "seed": seed,
                   "resolution": resolution, "local_rounds": rounds,
                   "evaluations": dict(evaluate.count),
                   "seconds": time.perf_counter() - started},
        "bound": (why if why is not None else
                  "guaranteed for every loop's phase, gain and delay margins and "
                  "sensitivity peak (the current and velocity loops' also with the outer "
                  "loops closed), the bandwidth and the resonance peak over the whole box "
                  f"(interval branch and bound, {guaranteed['cells']} cells); the other "
                  "figures: the worst found by the search"),
        "stability": {
            "proved": proved,
            "points": evaluate.count["analyze"],
            "not_stable": evaluate.not_stable,
            "first_not_stable": (None if evaluate.first_not_stable is None else
                                 {"verdict": evaluate.first_not_stable[1],
                                  "point": _point(box, evaluate.first_not_stable[0],
                                                 units)}),
        },
        "requirements": [r for r in results if r["severity"] != "stability"],
        "stability_margins": [r for r in results if r["severity"] == "stability"],
        "not_evaluated": [{"id": r.id, "metric": r.metric, "reason": why}
                          for r, why in skipped],
    })


#: The figures the interval bound covers, by the bound's key (the outermost loop's two
#: views agree, docs/model.md §7), and those it bounds from above (the negative's lower bound).
_LOOP_VIEWS = {"position_loop": "", "position_loop.loop_at_a_time": "",
               "current_loop": "current_", "current_loop.loop_at_a_time": "current_aat_",
               "velocity_loop": "velocity_", "velocity_loop.loop_at_a_time": "velocity_aat_"}
BOUNDED = {**{f"{view}.{figure}": f"{prefix}{figure}" for view, prefix in _LOOP_VIEWS.items()
              for figure in ("phase_margin_deg", "gain_margin_db", "delay_margin_s")},
           **{f"{view}.sensitivity_peak_db": f"{prefix}negative_sensitivity_peak_db"
              for view, prefix in _LOOP_VIEWS.items()},
           "closed_loop.bandwidth_rad_s": "bandwidth_rad_s",
           "closed_loop.peak_db": "negative_peak_db"}
NEGATED = {name for name in BOUNDED.values() if name.startswith("negative_")
           or "_negative_" in name}


def _guaranteed(params, box, results, cells):
    """The interval bounds of the position loop's margins over the box
    (:func:`cas_freq.analysis.interval_bound.box_bounds`), written into the result rows
    (``bound``, ``gap``): (bounds, None); (None, why there are none); or, where stability
    over the box is not proved, (bounds, why) with no row bounded."""
    nominal = LoopParameters.from_config(params)
    reason = supported(nominal, box.keys)
    if reason:
        return None, f"none: the worst found by the search ({reason})"
    targets = {}
    for row in results:
        name = BOUNDED.get(row["metric"])
        if name is not None and row["worst"] is not None:
            worst = -row["worst"] if name in NEGATED else row["worst"]
            targets[name] = min(targets.get(name, math.inf), worst)
    if "phase_margin_deg" not in targets or "gain_margin_db" not in targets:
        return None, ("none: the worst found by the search (no bound without a stable worst "
                      "phase and gain margin of the position loop)")
    found, why = box_bounds(params, nominal, box.keys, box.low, box.high, targets, cells)
    if found is None:
        return None, f"none: the worst found by the search ({why})"
    if not found["stable"]:
        # a margin's bound means nothing where a variant of the box may be unstable
        return found, (f"none: stability over the whole box not proved (some of the "
                       f"{found['cells']} cells' enclosures hold -1; more with --bound-cells), "
                       "so the worst found by the search")
    for row in results:
        name = BOUNDED.get(row["metric"])
        if name is not None and row["worst"] is not None:
            # a figure bounded from above (a peak): the bound is at or above the worst found
            row["bound_above"] = name in NEGATED
            row["bound"] = -found[name] if row["bound_above"] else found[name]
            row["gap"] = abs(row["worst"] - row["bound"])
    return found, None


def _point(box, point, units):
    """A point of the box: per key its value [SI] with its unit, its offset as a share of the
    half-width (``relative``, -1 .. 1) and its change from the nominal (``change``, a
    fraction; None where the nominal is 0)."""
    return [{"key": key, "value": float(value), "unit": unit, "relative": float(share),
             "change": float(value / nominal - 1.0) if nominal != 0 else None}
            for key, value, share, nominal, unit in zip(
                box.keys, point, box.relative(point), box.nominal, units, strict=True)]


def _result(box, units, objective, point, margin, how, figures, at_worst, index, resolution,
            verdict):
    """One objective's worst found, with its point and the nominal (point 0 of ``figures``)
    beside it."""
    values = figures.get(objective.metric)
    worst_values = at_worst.get(objective.metric)
    nominal = None if values is None else float(values[0])
    worst = None if worst_values is None else float(worst_values[index])
    return {
        "id": objective.id, "metric": objective.metric, "min": objective.minimum,
        "max": objective.maximum, "severity": objective.severity, "kind": objective.kind,
        "nominal": nominal if nominal is not None and math.isfinite(nominal) else None,
        "worst": worst if worst is not None and math.isfinite(worst) else None,
        "worst_margin": None if margin == -np.inf else margin,
        "worst_fails": not margin >= 0, "worst_verdict": verdict,
        "not_stable_or_missing": margin == -np.inf,
        "at": _point(box, point, units), "at_corner": box.at_corner(point, resolution),
        "found_by": how,
    }


def point_text(point):
    """``motor.Km=0.0209 N*m/A (+10 %), motor.J=9.5e-06 kg*m^2 (-5 %)``: each key's value
    with its unit and its change from the nominal."""
    return ", ".join(
        f"{item['key']}={item['value']:.5g}" + (f" {item['unit']}" if item["unit"] else "")
        + ("" if item["change"] is None else f" ({100 * item['change']:+.3g} %)")
        for item in point)


def worst_case_text(data):
    """The text ``cas-freq worstcase`` prints."""
    lines = [f"{data['config']} / {data['variant']}: worst case over the tolerance box "
             f"({len(data['box'])} keys)"]
    for item in data["box"]:
        lines.append(f"  {item['key']:<26} {item['low']:.5g} .. {item['high']:.5g} "
                     f"{item['unit']} (nominal {item['nominal']:.5g})")
    search = data["search"]
    count = search["evaluations"]
    lines.append(f"  search: nominal, {search['corners']} corners, {search['samples']} "
                 f"uniform samples (seed {search['seed']}), then a compass search from each "
                 f"figure's worst corner and sample ({search['local_rounds']} rounds, "
                 f"resolution {search['resolution']:g} of each width): {count['analyze']} loop "
                 f"evaluations, {count['step']} steps simulated, {search['seconds']:.3g} s")
    lines.append(f"  bound: {data['bound']}")
    stability = data["stability"]
    if stability["proved"]:
        lines.append("  stability PROVED over the whole box: 1 + L never 0 on the frequency "
                     "axis from 1e-9 to 1e12 rad/s (zero exclusion, interval enclosures of "
                     "every loop), the nominal stable")
    elif stability["proved"] is False:
        lines.append("  stability over the whole box NOT proved: some cell's enclosure holds -1")
    if stability["not_stable"]:
        where = stability["first_not_stable"]
        lines.append(f"  STABILITY: {stability['not_stable']} of {stability['points']} points "
                     f"evaluated are not stable, e.g. {where['verdict']} at "
                     f"{point_text(where['point'])}")
    else:
        lines.append(f"  stability: every one of the {stability['points']} points evaluated is "
                     "stable")
    lines.append("")
    lines.append(f"  {'requirement':<52} {'nominal':>10} {'worst found':>12}  at")
    for r in [*data["requirements"], *data["stability_margins"]]:
        worst = (r["worst_verdict"] if r["worst_verdict"] != "stable"
                 else "no value" if r["not_stable_or_missing"] else _g(r["worst"]))
        flag = ""
        if r["worst_fails"] and r["severity"] != "stability":
            flag = " FAILS" + (" (advisory)" if r["severity"] == "advisory" else "")
        where = "a corner" if r["at_corner"] else "inside the box"
        lines.append(f"  {r['id'] + ' ' + r['metric']:<52} {_g(r['nominal']):>10} "
                     f"{worst:>12}  {where}: {point_text(r['at'])} (found by "
                     f"{_FOUND.get(r['found_by'], r['found_by'])}){flag}")
        if r.get("bound") is not None:
            side = "≤ " if r.get("bound_above") else "≥ "
            lines.append(f"  {'':<52} {'':>10} {side + _g(r['bound']):>12}  guaranteed over "
                         f"the whole box (gap {r['gap']:.2g})")
    for item in data["not_evaluated"]:
        lines.append(f"  {item['id']} {item['metric']}: not evaluated: {item['reason']}")
    return "\n".join(lines)


_FOUND = {"corner": "the corners", "sample": "the uniform samples", "nominal": "the nominal"}


def _g(value):
    return "—" if value is None else f"{value:.5g}"


__all__ = ["Box", "tolerance_box", "worst_case", "worst_case_text", "point_text"]
