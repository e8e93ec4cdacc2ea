"""One tune from its options, as ``cas-freq tune`` and :meth:`cas_freq.api.Actuator.tune` give
them."""

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.tolerances import parse_tolerance
from cas_freq.tuning import search
from cas_freq.tuning.evaluate import constraints
from cas_freq.tuning.options import GLOBAL_COUNT, ROUNDS
from cas_freq.tuning.scenarios import scenarios
from cas_freq.tuning.space import default_free, parse_bounds, parse_free, tune_keys


def tune_variant(loaded, free=None, bounds=(), objective="max-bandwidth", robust=None,
                 tolerances=(), yield_pct=99.0, margin_pct=2.0, required_only=False, seed=0,
                 load_cases=False, distribution="normal", scheduler=None,
                 candidates=GLOBAL_COUNT, rounds=ROUNDS, progress=None):
    """Tune a loaded variant.

    Parameters
    ----------
    loaded : cas_freq.config.LoadedVariant
    free : str, optional
        ``KEY,KEY`` (default :func:`~cas_freq.tuning.space.default_free`).
    bounds : sequence of str
        ``KEY=LO:HI`` texts.
    tolerances : sequence of str
        ``KEY=TOL`` texts, as ``montecarlo --tolerance``.
    load_cases : bool
        Also at every hinge stiffness of the config's ``load_envelope`` grid.
    Other parameters as ``cas-freq tune``'s options (:func:`cas_freq.tuning.search.tune`).

    Returns
    -------
    TuneResult

    Raises
    ------
    ConfigError
        For a bad option (naming it), a config without requirements, or load cases asked of a
        config without a load envelope.
    """
    params = loaded.params
    keys = parse_free(free if free is not None else ",".join(default_free(params)), params)
    held, skipped = constraints(params.requirements, margin_pct / 100.0,
                                advisory=not required_only)
    if not held:
        raise ConfigError(f"{loaded.source}: no requirement to tune to (the config's "
                          "requirements: section)")
    cases = None
    if load_cases:
        if params.load_envelope is None:
            raise ConfigError(f"--load-cases: {loaded.source} declares no load_envelope")
        cases = list(params.load_envelope.hinge_stiffness)
    scenario_set = scenarios(params, robust, [parse_tolerance(t, params) for t in tolerances],
                             yield_pct, seed, cases, distribution)
    return search.tune(params, tune_keys(params, keys, parse_bounds(bounds, keys, params)),
                       scenario_set, held, skipped, objective, seed=seed,
                       global_count=candidates, rounds=rounds, scheduler=scheduler,
                       progress=progress)


__all__ = ["tune_variant"]
