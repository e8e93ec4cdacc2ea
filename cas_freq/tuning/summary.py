"""A tune's result as JSON-ready data and as text: the tuned keys, the requirements before and
after, the binding requirements (or, without a feasible tuning, how far the closest candidate
is from each), and the trade-off table."""

import math

import numpy as np

from cas_freq.core.figures import FIGURES, UNIT_LABELS
from cas_freq.tuning.evaluate import MISSING_VIOLATION, TRADE_OFF
from cas_freq.tuning.options import OBJECTIVES
from cas_freq.verify.evaluate import bound_text

#: A held requirement within this relative distance of its tightened bound is binding.
BINDING = 0.02

#: Most rows of the Pareto front printed.
MAX_ROWS = 12


def _bound_text(constraint):
    """The tightened bound as ``verify`` writes a bound: ``>= 306 rad/s``."""
    return bound_text(constraint.low, constraint.high, UNIT_LABELS[constraint.requirement.unit])


def _requirements(result, index, e):
    """Per held requirement: the nominal value, yield, shortfall, binding or not, and why it
    was not assessed (``not_assessed``: the nominal closed loop is unstable, or the figure has
    no value; its shortfall is then :data:`MISSING_VIOLATION`, a rank, not a distance)."""
    rows = []
    for j, c in enumerate(result.held):
        not_assessed = None
        if not e.stable[index]:
            not_assessed = "the closed loop is unstable"
        elif e.violation[index, j] == MISSING_VIOLATION:
            not_assessed = "the figure has no value"

        value = float(e.nominal[c.metric][index])
        bounds = [b for b in (c.low, c.high) if b is not None]
        distance = min((abs(value - b) / max(abs(b), 1e-12) for b in bounds),
                       default=math.inf) if math.isfinite(value) else None
        rows.append({
            "id": c.id, "metric": c.metric, "severity": c.requirement.severity,
            "bound": _bound_text(c), "nominal": value if math.isfinite(value) else None,
            "yield_pct": 100.0 * float(e.passed[index, j]),
            "shortfall": (None if np.isnan(e.violation[index, j])
                          else float(e.violation[index, j])),
            "binding": bool(distance is not None and distance <= BINDING
                            and e.violation[index, j] == 0.0),
            "simulated": not np.isnan(e.violation[index, j]),
            "not_assessed": not_assessed,
        })
    return rows


def _best_reachable(result):
    """Per held requirement, the best nominal value over every candidate."""
    e = result.evaluation
    out = {}
    for c in result.held:
        values = e.nominal[c.metric]
        finite = values[np.isfinite(values)]
        if not finite.size:
            out[c.id] = None
        elif c.low is not None and c.high is None:
            out[c.id] = float(finite.max())
        elif c.high is not None and c.low is None:
            out[c.id] = float(finite.min())
        else:
            out[c.id] = float(finite[np.argmin(c.shortfall(finite))])
    return out


def _candidate(result, index, e=None):
    """A candidate's values, feasibility, yield, objective and requirements (of ``e``,
    default every candidate's evaluation)."""
    e = result.evaluation if e is None else e
    return {
        "values": {key: float(v[index]) for key, v in e.values.items()},
        "feasible": bool(e.feasible[index]),
        "stable": bool(e.stable[index]),
        "yield_pct": 100.0 * float(e.yield_all[index]),
        "objective": None if not math.isfinite(e.objective[index]) else float(e.objective[index]),
        "requirements": _requirements(result, index, e),
    }


def tune_dict(result, config, variant, seconds):
    """JSON-ready dict of a TuneResult."""
    e = result.evaluation
    name, sense = OBJECTIVES[result.objective]
    at_bound = {}
    for key in result.keys:
        value = result.values()[key.key]
        near = [side for side, edge in (("lower", key.lower), ("upper", key.upper))
                if abs(value - edge) <= 1e-3 * abs(edge)]
        at_bound[key.key] = near[0] if near else None
    pareto = [{**result.values(i), **{figure: float(e.nominal[figure][i])
                                      for figure, _ in TRADE_OFF}} for i in result.pareto]
    return {
        "config": config, "variant": variant,
        "objective": {"name": result.objective, "figure": name,
                      "sense": "max" if sense > 0 else "min"},
        "free": [{"key": k.key, "unit": k.unit, "start": k.start, "lower": k.lower,
                  "upper": k.upper, "scale": "log" if k.log else "linear"} for k in result.keys],
        "scenarios": {"label": result.scenarios.label, "count": result.scenarios.count,
                      "target_yield_pct": 100.0 * result.scenarios.target},
        "held": [{"id": c.id, "metric": c.metric, "bound": _bound_text(c)} for c in result.held],
        "not_held": [{"id": r.id, "why": why} for r, why in result.skipped],
        "candidates": int(e.objective.size), "feasible_candidates": int(e.feasible.sum()),
        "seed": result.seed, "seconds": seconds,
        "feasible": result.feasible,
        "before": _candidate(result, 0, result.before),
        "tuned": _candidate(result, result.best),
        "at_bound": at_bound,
        "best_reachable": _best_reachable(result),
        "pareto": pareto,
    }


def _number(value, digits=4):
    return "—" if value is None else f"{value:.{digits}g}"


def tune_text(data):
    """The text output of :func:`tune_dict`'s data."""
    objective = data["objective"]
    lines = [
        f"tune {data['config']} / {data['variant']}: {data['objective']['name']} "
        f"({objective['sense']} {objective['figure']}), {data['scenarios']['label']}"
        + (f", yield >= {data['scenarios']['target_yield_pct']:g} %"
           if data["scenarios"]["count"] > 1 else ""),
        f"  {data['candidates']} candidates ({data['feasible_candidates']} feasible) in "
        f"{data['seconds']:.3g} s, seed {data['seed']}",
        "  held: " + "; ".join(f"{h['id']} {h['metric']} {h['bound']}" for h in data["held"]),
    ]
    for item in data["not_held"]:
        lines.append(f"  not held: {item['id']} ({item['why']})")
    tuned, before = data["tuned"], data["before"]
    verdict = "FEASIBLE" if data["feasible"] else (
        f"INFEASIBLE: none of the {data['candidates']} candidates searched in the bounds meets "
        "every held requirement" + (" at the target yield" if data["scenarios"]["count"] > 1
                                    else ""))
    lines += ["", f"result: {verdict}"]
    lines.append(f"  {'key':<22} {'before':>11} {'tuned':>11}  range")
    for free in data["free"]:
        key = free["key"]
        bound = data["at_bound"][key]
        lines.append(f"  {key:<22} {before['values'][key]:>11.5g} {tuned['values'][key]:>11.5g}"
                     f"  {free['lower']:.4g}..{free['upper']:.4g} {free['unit']} ({free['scale']})"
                     + (f"  AT ITS {bound.upper()} BOUND" if bound else ""))
    lines.append(f"  {'requirement':<40} {'before':>10} {'tuned':>10}  bound (tightened)")
    for b, t in zip(before["requirements"], tuned["requirements"], strict=True):
        note = "  binding" if t["binding"] else ""
        if t["not_assessed"]:
            note = f"  not assessed: {t['not_assessed']}"
        elif t["shortfall"] is None:
            note = "  not simulated: the linear requirements already fail"
        elif t["shortfall"] > 0:
            note = f"  short by {100 * t['shortfall']:.3g} %"
        lines.append(f"  {t['id'] + ' ' + t['metric']:<40} {_number(b['nominal']):>10} "
                     f"{_number(t['nominal']):>10}  {t['bound']}"
                     + (f"  yield {t['yield_pct']:.4g} %" if data["scenarios"]["count"] > 1
                        else "") + note)
    if not data["feasible"]:
        failing = [t for t in tuned["requirements"] if t["shortfall"]]
        lines.append("  the closest candidate misses: " + (
            "every requirement (its closed loop is unstable)" if not tuned["stable"] else
            ", ".join(f"{t['id']} (no value)" if t["not_assessed"] else
                      f"{t['id']} (by {100 * t['shortfall']:.3g} % of its bound)"
                      for t in failing)))
        lines.append("  best value of each over every candidate: " + ", ".join(
            f"{key} {_number(value)}" for key, value in data["best_reachable"].items()))
    if data["pareto"]:
        front = data["pareto"]
        shown = front if len(front) <= MAX_ROWS else [
            front[int(i)] for i in np.unique(np.linspace(0, len(front) - 1, MAX_ROWS).round())]
        simulated = any(point["step.overshoot_pct"] is not None for point in front)
        figures = [(FIGURES[key], sense) for key, sense in TRADE_OFF]
        aims = [f"{figure.label} ({'up' if sense > 0 else 'down'})" for figure, sense in figures]
        lines += ["", f"trade-off: {len(front)} feasible candidates on the Pareto front of "
                  f"{', '.join(aims[:-1])} and {aims[-1]}, nominal"
                  + ("" if simulated else " (the steps not simulated: no "
                     f"{FIGURES['step.overshoot_pct'].label})")
                  + (f"; {len(shown)} shown, evenly by {figures[0][0].label} (all in --json)"
                     if len(shown) < len(front) else "")]
        keys = [free["key"] for free in data["free"]]
        labels = [column_label(key) for key in keys]
        widths = [max(10, len(label)) for label in labels]
        head = "  " + " ".join(f"{label:>{width}}" for label, width in zip(labels, widths,
                                                                          strict=True))
        columns = [(figure, len(figure.heading)) for figure, _ in figures]
        lines.append(head + "".join(f" {figure.heading}" for figure, _ in figures))
        for point in shown:
            lines.append("  " + " ".join(f"{point[key]:>{width}.4g}"
                                         for key, width in zip(keys, widths, strict=True))
                         + "".join(f" {_cell(figure.shown(point[figure.key]), width, '.4g')}"
                                   for figure, width in columns))
    return "\n".join(lines)


def column_label(key):
    """The header of a free key's column: the key with its loop named, ``_loop`` dropped
    (``position.Kp``, ``velocity.Kp``, ``current.Ki``), so two loops' gains are told apart."""
    return key.replace("_loop.", ".")


def _cell(value, width, spec):
    """A number right-aligned in ``width`` characters, "—" for none (not computed)."""
    return f"{'—' if value is None else format(value, spec):>{width}}"


__all__ = ["BINDING", "tune_dict", "tune_text"]
