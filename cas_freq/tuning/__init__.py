"""Tuning to requirements (issue 15): free keys searched for the best objective subject to the
config's requirements, on the nominal model or over a tolerance set and load cases
(:mod:`~cas_freq.tuning.space`, :mod:`~cas_freq.tuning.scenarios`,
:mod:`~cas_freq.tuning.evaluate`, :mod:`~cas_freq.tuning.search`).
"""

from cas_freq.tuning.search import TuneResult, pareto_front, tune

__all__ = ["TuneResult", "pareto_front", "tune"]
