"""The ``montecarlo`` command's data: figures of randomly toleranced variants.

Each ``--tolerance KEY=TOL`` draws KEY independently around its base value: TOL is relative
(``10%``) or absolute (a number in the key's SI unit, or with a unit: ``0.02 ms``).

- ``uniform``: uniform on [base - TOL, base + TOL];
- ``normal``: normal with standard deviation TOL / 3 (TOL is the 3-sigma band: 99.7 % of the
  samples fall within ±TOL), not truncated.

A sample outside what the config accepts (e.g. a negative gain) is an error naming the key,
value and sample, never silently clipped. Draws use ``numpy.random.default_rng(seed)``, one
key after the other in the order given, so a seed reproduces every sample.

Yield: the fraction of samples that pass each requirement of the config whose figure the batch
computes (analyze figures always, the stiffness, effort and noise figures where a requirement
names one; step and fit figures when a step is simulated, at the
requirement's own step size), sine-dwell requirements at the first one's amplitude and grid;
other requirements are listed as not evaluated.
"""

import dataclasses
import math

import numpy as np

from cas_freq.analysis.disturbance import PREFIXES as DISTURBANCE
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import json_ready
from cas_freq.core.parameters import LoopParameters, base_values, unit_of
from cas_freq.model.sampled import TIME_VARYING, time_varying_views
from cas_freq.studies.run import DEFAULT_SINEDWELL_FREQUENCIES_RAD_S
from cas_freq.studies.sweep import evaluate_figures, figure_names

DISTRIBUTIONS = ("normal", "uniform")
#: Percentiles reported for each figure.
PERCENTILES = (1, 5, 25, 50, 75, 95, 99)
#: Worst samples listed per requirement.
WORST_COUNT = 5


#: Most samples of one Monte Carlo run (checked before anything is allocated).
MAX_SAMPLES = 1_000_000


def fresh_seed():
    """A seed from fresh entropy, small enough to print and type (below 2**32)."""
    return int(np.random.SeedSequence().entropy % (2**32))


def draw(params, tolerances, samples, distribution="normal", seed=None):
    """Sampled values of each toleranced key.

    Returns
    -------
    (dict of str to numpy.ndarray, int)
        Key -> (samples,) values [SI], and the seed used (drawn from fresh entropy if None).
    """
    if distribution not in DISTRIBUTIONS:
        raise ConfigError(f"--distribution: must be one of {DISTRIBUTIONS}, got {distribution!r}")
    if isinstance(samples, bool) or not (isinstance(samples, int) and
                                         1 <= samples <= MAX_SAMPLES):
        raise ConfigError(f"--samples: must be an integer 1..{MAX_SAMPLES}, got {samples!r}")
    if seed is None:
        seed = fresh_seed()
    elif (isinstance(seed, bool) or not isinstance(seed, (int, np.integer))
          or not 0 <= seed < 2**128):
        raise ConfigError(f"--seed: must be an integer >= 0 (below 2**128), got {seed!r}")
    rng = np.random.default_rng(seed)
    base = base_values(params)
    values = {}
    for tolerance in tolerances:
        nominal = base[tolerance.key]
        if nominal is None:
            if tolerance.key == "motor.mu_v":
                raise ConfigError("motor.mu_v: the config derives it from motor.no_load; put the "
                                  "tolerance on motor.no_load.current or motor.no_load.speed")
            raise ConfigError(f"{tolerance.key}: not set in the config (derived), cannot be "
                              "toleranced")
        if tolerance.key in values:
            raise ConfigError(f"--tolerance {tolerance.key}: given twice")
        width = tolerance.half_width(nominal)
        if distribution == "uniform":
            values[tolerance.key] = rng.uniform(nominal - width, nominal + width, samples)
        else:
            values[tolerance.key] = rng.normal(nominal, width / 3.0, samples)
    return values, seed


@dataclasses.dataclass(frozen=True, eq=False)
class MonteCarlo:
    """Figures of the sampled variants and their statistics (see :func:`montecarlo_dict`)."""

    config: str
    config_path: str
    variant: str
    overrides: tuple
    tolerances: tuple
    distribution: str
    seed: int
    samples: dict
    figures: dict
    stability: np.ndarray
    step_deg: float | None
    requirements: tuple
    sinedwell: tuple | None = None
    units: dict = dataclasses.field(default_factory=dict)
    #: The loops whose loop-at-a-time figures are not defined (a slower sampled loop is
    #: around them: cas_freq.model.sampled.time_varying_views).
    time_varying: tuple = ()

    def unit(self, key):
        """SI unit of toleranced ``key`` in the config's architecture."""
        return self.units.get(key) or unit_of(key)


def run_montecarlo(loaded, tolerances, samples, *, distribution="normal", seed=None,
                   step_rad=None, simulate=True, progress=None, scheduler=None):
    """Draw the samples, compute their figures; returns :class:`MonteCarlo`.

    A step is simulated when ``step_rad`` is given (with the second-order fit) or a
    requirement needs step/fit figures (at the first such requirement's step, with the fit
    only if a fit requirement needs it; requirements at another step than the simulated one
    are not evaluated), unless ``simulate`` is False.
    """
    if not tolerances:
        raise ConfigError("--tolerance: give at least one, e.g. --tolerance motor.Km=10%")
    requirements = loaded.params.requirements
    fit_needed = step_rad is not None
    sinedwell = None
    if simulate:
        stepped = [r for r in requirements if r.kind == "step"]
        if step_rad is None and stepped:
            step_rad = stepped[0].step
        fit_needed = fit_needed or any(
            r.metric.startswith("fit.") and math.isclose(r.step, step_rad) for r in stepped
        )
        dwelt = [r for r in requirements if r.kind == "sinedwell"]
        if dwelt:
            sinedwell = dwell_condition(dwelt[0])
    values, seed = draw(loaded.params, tolerances, samples, distribution, seed)
    disturbance = any(r.metric.startswith(DISTURBANCE)
                      for r in requirements)
    figures, stability = evaluate_figures(loaded.params, values, step_rad=step_rad,
                                          fit=fit_needed, sinedwell=sinedwell,
                                          disturbance=disturbance, progress=progress,
                                          scheduler=scheduler)
    return MonteCarlo(
        config=loaded.params.name, config_path=loaded.source, variant=loaded.variant,
        overrides=tuple(f"{k}={v}" for k, v in loaded.overrides), tolerances=tuple(tolerances),
        distribution=distribution, seed=seed, samples=values, figures=figures,
        stability=stability, step_deg=None if step_rad is None else math.degrees(step_rad),
        requirements=requirements, sinedwell=sinedwell,
        units={t.key: unit_of(t.key, loaded.params) for t in tolerances},
        time_varying=time_varying_views(LoopParameters.from_config(loaded.params).sample_rates),
    )


def dwell_condition(requirement):
    """(amplitude [rad], frequencies [rad/s]) a sine-dwell requirement is measured at."""
    return (requirement.amplitude,
            tuple(requirement.frequencies or DEFAULT_SINEDWELL_FREQUENCIES_RAD_S))


def not_defined(metric, time_varying):
    """Why ``metric`` does not exist for a drive whose loops ``time_varying`` sit inside a
    slower sampled loop (:func:`cas_freq.model.sampled.time_varying_views`): their
    loop-at-a-time figures; None for every other figure."""
    if metric.startswith(tuple(f"{loop}.loop_at_a_time." for loop in time_varying)):
        return f"not defined: {TIME_VARYING}"
    return None


def requirement_results(mc):
    """Per requirement: evaluated or not (and why), yield, and the worst samples."""
    out = []
    for requirement in mc.requirements:
        entry = {"id": requirement.id, "metric": requirement.metric,
                 "min": requirement.min, "max": requirement.max,
                 "severity": requirement.severity}
        kind = requirement.kind
        step = requirement.step
        values = mc.figures.get(requirement.metric)
        reason = None
        undefined = not_defined(requirement.metric, mc.time_varying)
        if undefined:
            reason = undefined
        elif kind == "sinedwell" and mc.sinedwell != dwell_condition(requirement):
            reason = ("sine-dwell not simulated" if mc.sinedwell is None else
                      "only the first sine-dwell condition of the requirements is simulated")
        elif values is None and requirement.metric.startswith("fit.") and mc.step_deg:
            reason = "the second-order fit was not run"
        elif values is None:
            reason = "figure not computed by the batch"
        elif kind == "step" and (mc.step_deg is None or step is None or
                                 not math.isclose(math.degrees(step), mc.step_deg)):
            reason = (f"needs a {math.degrees(step):g} deg step, simulated "
                      f"{'none' if mc.step_deg is None else f'{mc.step_deg:g} deg'}")
        if reason:
            entry.update(evaluated=False, reason=f"not evaluated in montecarlo: {reason}")
            out.append(entry)
            continue
        # as verify: no figure of an unstable (or marginal) sample is trusted, so it fails
        stable = mc.stability.astype(str) == "stable"
        passed = np.array([bool(ok) and requirement.passes(None if math.isnan(v) else float(v))
                           for v, ok in zip(values, stable, strict=True)])
        order = _worst_order(values, requirement)
        entry.update(
            evaluated=True, passed=int(passed.sum()), failed=int((~passed).sum()),
            yield_pct=100.0 * float(passed.mean()),
            worst=[_sample_record(mc, int(i), requirement.metric)
                   for i in order[:WORST_COUNT]],
        )
        out.append(entry)
    return out


def _worst_order(values, requirement):
    """Sample indices from worst to best for a requirement (missing figures first)."""
    low, high = requirement.min, requirement.max
    if low is not None and high is not None:
        score = np.maximum(low - values, values - high)
    elif low is not None:
        score = -values
    elif high is not None:
        score = values
    else:
        score = np.zeros(values.size)
    score = np.where(np.isnan(values), np.inf, score)
    return np.argsort(-score, kind="stable")


def _sample_record(mc, index, metric):
    record = {"sample": index, metric: float(mc.figures[metric][index]),
              "stability": str(mc.stability[index])}
    record.update({key: float(values[index]) for key, values in mc.samples.items()})
    return record


def statistics(values):
    """Count, mean, std, min, max and percentiles of the finite values (None if none)."""
    finite = values[np.isfinite(values)]
    stats = {"count": int(finite.size), "missing": int(values.size - finite.size)}
    if finite.size == 0:
        return stats
    stats.update(mean=float(finite.mean()), std=float(finite.std()), min=float(finite.min()),
                 max=float(finite.max()))
    for q, v in zip(PERCENTILES, np.percentile(finite, PERCENTILES), strict=True):
        stats[f"p{q}"] = float(v)
    return stats


def montecarlo_dict(mc):
    """JSON-ready dict: inputs, seed, per-figure statistics, requirement yields."""
    names = figure_names(mc.figures)
    verdicts, counts = np.unique(mc.stability.astype(str), return_counts=True)
    return json_ready({
        "config": mc.config,
        "config_path": mc.config_path,
        "variant": mc.variant,
        "overrides": list(mc.overrides),
        "samples": int(len(mc.stability)),
        "distribution": mc.distribution,
        "distribution_note": ("normal: sigma = tolerance / 3" if mc.distribution == "normal"
                              else "uniform on nominal ± tolerance"),
        "seed": mc.seed,
        "tolerances": [{"key": t.key, "unit": mc.unit(t.key), "relative": t.relative,
                        "absolute": t.absolute} for t in mc.tolerances],
        "step_deg": mc.step_deg,
        "sinedwell_deg": None if mc.sinedwell is None else math.degrees(mc.sinedwell[0]),
        "stability": dict(zip(verdicts.tolist(), counts.tolist(), strict=True)),
        "figures": {name: statistics(mc.figures[name]) for name in names},
        "requirements": requirement_results(mc),
    })


def montecarlo_samples_csv(mc):
    """CSV text of every sample: drawn values, stability, every figure."""
    import io

    names = figure_names(mc.figures)
    keys = list(mc.samples)
    out = io.StringIO()
    out.write(",".join(["sample", *(f"{k} [{mc.unit(k)}]" for k in keys), "stability",
                        *names]) + "\n")
    for index in range(len(mc.stability)):
        cells = [str(index), *(f"{mc.samples[k][index]:.10g}" for k in keys),
                 str(mc.stability[index])]
        for name in names:
            value = mc.figures[name][index]
            cells.append(f"{value:.10g}" if math.isfinite(value) else "")
        out.write(",".join(cells) + "\n")
    return out.getvalue()
