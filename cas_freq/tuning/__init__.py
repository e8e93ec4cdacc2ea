"""Tuning to requirements (``cas-freq tune``): free keys searched for the best objective
subject to the config's requirements, on the nominal model or over a tolerance set and load cases
(:mod:`~cas_freq.tuning.space`, :mod:`~cas_freq.tuning.scenarios`,
:mod:`~cas_freq.tuning.evaluate`, :mod:`~cas_freq.tuning.search`).

Nothing is imported here: the CLI reads :mod:`~cas_freq.tuning.options` at start-up, and the
search (scipy, the batch engine) loads only when a tune runs.
"""

__all__ = ["TuneResult", "pareto_front", "tune"]


def __getattr__(name):
    if name in __all__:
        from cas_freq.tuning import search

        return getattr(search, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
