r"""Tune free keys to the config's requirements: a global quasi-random search, then local
refinement, every candidate a row of one batch.

1. **Global.** ``global_count`` scrambled Sobol points of the keys' box (logarithmic for
   positive ranges, :mod:`~cas_freq.tuning.space`), plus the variant's own values.
2. **Refinement.** ``rounds`` rounds of ``round_count`` Sobol points, shared between boxes
   around the incumbent and the next best candidates that lie outside its box (up to
   :data:`CENTRES` in all), the half-width a quarter of the range, halved every round once
   some candidate is feasible (clipped to the range).
3. **Incumbent.** The best feasible candidate by the objective (its nominal figure); without a
   feasible one, the one whose requirements fall shortest (summed relative shortfall,
   :mod:`~cas_freq.tuning.evaluate`).

Every draw comes from the seed, so a seed reproduces the tune. The trade-off is the Pareto
front of the feasible candidates in (bandwidth up, phase margin up, overshoot down), nominal
figures.
"""

import dataclasses

import numpy as np

from cas_freq.core.summary import Summary
from cas_freq.tuning.evaluate import TRADE_OFF, evaluate, joined
from cas_freq.tuning.options import GLOBAL_COUNT, OBJECTIVES, ROUND_COUNT, ROUNDS
from cas_freq.tuning.space import sobol

#: Centres each refinement round searches around (the best, then the next best far enough).
CENTRES = 3


@dataclasses.dataclass(frozen=True, eq=False, repr=False)
class TuneResult(Summary):
    """What a tune found.

    Attributes
    ----------
    keys : list of TuneKey
    held, skipped : list
        Constraints held; (requirement, why) not held.
    scenarios : Scenarios
    objective : str
    evaluation : Evaluation
        Every candidate evaluated (index 0: the variant's own values, brought into the
        bounds where they lie outside).
    before : Evaluation
        The variant's own values, as they are (outside the bounds, maybe), every figure
        simulated.
    best : int
        Index of the chosen candidate.
    feasible : bool
        Whether it meets every held requirement at the target yield.
    pareto : numpy.ndarray
        Indices of the feasible candidates on the trade-off front, by bandwidth.
    seed : int
    """

    keys: list
    held: list
    skipped: list
    scenarios: object
    objective: str
    evaluation: object
    before: object
    best: int
    feasible: bool
    pareto: np.ndarray
    seed: int

    def _summary(self):
        units = {key.key: key.unit for key in self.keys}
        rows = [("feasible", self.feasible, "")]
        rows += [(key, value, units.get(key, "")) for key, value in self.values().items()]
        rows.append(("candidates evaluated", len(self.evaluation.objective), ""))
        return f"{self.objective}, candidate {self.best} of seed {self.seed}", rows

    def values(self, index=None):
        """Key -> value [SI] of a candidate (default: the best)."""
        index = self.best if index is None else index
        return {key: float(v[index]) for key, v in self.evaluation.values.items()}


def _order(evaluation, objective):
    """Candidates from best to worst: the feasible ones by the objective, then the others by
    their summed shortfall (of the requirements evaluated)."""
    _, sense = OBJECTIVES[objective]
    feasible = evaluation.feasible & np.isfinite(evaluation.objective)
    score = np.where(feasible, -sense * evaluation.objective, np.inf)
    return np.lexsort((np.nansum(evaluation.violation, axis=1), score))


def _rank(evaluation, objective):
    """Index of the incumbent."""
    return int(_order(evaluation, objective)[0])


def _centres(points, order, half, count=CENTRES):
    """Up to ``count`` of the best candidates, each more than ``half`` (unit box, max norm)
    from those before: the refinement searches around each."""
    chosen = []
    for index in order:
        if all(np.max(np.abs(points[index] - points[c])) > half for c in chosen):
            chosen.append(index)
            if len(chosen) == count:
                break
    return chosen


def pareto_front(evaluation):
    """Indices of the feasible candidates no other feasible candidate beats in every
    trade-off figure (ties kept once), ordered by bandwidth."""
    rows = np.flatnonzero(evaluation.feasible)
    # a figure no candidate has (the overshoot when the steps were not simulated) is left out
    figures = [(name, sense) for name, sense in TRADE_OFF
               if np.isfinite(evaluation.nominal[name]).any()]
    if not figures:
        return np.array([], dtype=int)
    points = np.column_stack([sense * evaluation.nominal[name][rows] for name, sense in figures])
    good = np.all(np.isfinite(points), axis=1)
    rows, points = rows[good], points[good]
    front = []
    for i, point in enumerate(points):
        beaten = np.all(points >= point, axis=1) & np.any(points > point, axis=1)
        duplicate = [j for j in front if np.array_equal(points[j], point)]
        if not beaten.any() and not duplicate:
            front.append(i)
    chosen = rows[front]
    order = np.argsort(evaluation.nominal[TRADE_OFF[0][0]][chosen], kind="stable")
    return chosen[order]


def tune(params, keys, scenario_set, held, skipped, objective="max-bandwidth", seed=0,
         global_count=GLOBAL_COUNT, rounds=ROUNDS, round_count=ROUND_COUNT, scheduler=None,
         progress=None, simulate=True):
    """Search the keys' box for the best tuning (module docstring).

    Parameters
    ----------
    params : cas_freq.config.ActuatorConfig
        The variant tuned.
    keys : list of TuneKey
    scenario_set : Scenarios
    held, skipped : list
        From :func:`cas_freq.tuning.evaluate.constraints`.
    objective : str
        A key of :data:`~cas_freq.tuning.evaluate.OBJECTIVES`.
    seed : int
    global_count, rounds, round_count : int
        Candidates of the global stage; refinement rounds and candidates per round.
    scheduler : str, optional
        Evaluate on a dask.distributed cluster (``local:N`` or an address).
    progress : callable, optional
        ``progress(done, total)`` in candidates.
    simulate : bool
        Simulate the steps of the trade-off and of the held requirements (False: a loop
        structure the simulator does not run yet; the frequency-domain figures only).

    Returns
    -------
    TuneResult
    """
    k = len(keys)
    total = 1 + global_count + rounds * round_count
    own = np.array([[key.unit_of(key.start) for key in keys]])
    start = np.clip(own, 0.0, 1.0)
    batches = [np.vstack([start, sobol(global_count, k, seed)])]
    evaluations = [evaluate(params, keys, batches[0], scenario_set, held, objective, scheduler,
                            simulate=simulate)]
    # the variant as it is (outside the bounds, maybe: then not a candidate), every figure
    before = evaluate(params, keys, own, scenario_set, held, objective, scheduler, screen=False,
                      simulate=simulate)
    done = batches[0].shape[0]
    if progress:
        progress(done, total)
    shrinks = 0
    for number in range(rounds):
        everything = joined(evaluations)
        points = np.vstack(batches)
        half = 0.25 * 0.5**shrinks
        shrinks += bool(everything.feasible.any())  # the box shrinks once something is feasible
        centres = _centres(points, _order(everything, objective), half)
        draws = sobol(round_count, k, seed + 1 + number)
        shares = np.array_split(np.arange(round_count), len(centres))
        batch = np.vstack([np.clip(points[c] + (2.0 * draws[rows] - 1.0) * half, 0.0, 1.0)
                           for c, rows in zip(centres, shares, strict=True)])
        batches.append(batch)
        evaluations.append(evaluate(params, keys, batch, scenario_set, held, objective,
                                    scheduler, simulate=simulate))
        done += batch.shape[0]
        if progress:
            progress(done, total)
    everything = joined(evaluations)
    best = _rank(everything, objective)
    return TuneResult(keys=keys, held=held, skipped=skipped, scenarios=scenario_set,
                      objective=objective, evaluation=everything, before=before, best=best,
                      feasible=bool(everything.feasible[best]),
                      pareto=pareto_front(everything), seed=seed)


__all__ = ["GLOBAL_COUNT", "ROUNDS", "ROUND_COUNT", "TuneResult", "pareto_front", "tune"]
