"""Analysis layer: one engine for margins, closed-loop figures and stability.

Every figure is computed for a batch of variants (a single variant is a batch of one):
:func:`batch_analyze` for many, :func:`analyze` for one with every crossing listed.
Imports the model and the parameters only; never python-control or matplotlib.
"""

from cas_freq.analysis.analyze import (
    FIGURES,
    Analysis,
    BatchAnalysis,
    PadeComparison,
    analyze,
    batch_analyze,
    pade_study,
    to_dict,
)
from cas_freq.analysis.closed_loop import ClosedLoopFigures, closed_loop_summary
from cas_freq.analysis.margins import GainCrossover, LoopMargins, PhaseCrossover, loop_margins
from cas_freq.analysis.stability import Stability, closed_loop_stability, stability_verdicts

__all__ = [
    "FIGURES",
    "Analysis",
    "BatchAnalysis",
    "ClosedLoopFigures",
    "GainCrossover",
    "LoopMargins",
    "PadeComparison",
    "PhaseCrossover",
    "Stability",
    "analyze",
    "batch_analyze",
    "closed_loop_stability",
    "closed_loop_summary",
    "loop_margins",
    "pade_study",
    "stability_verdicts",
    "to_dict",
]
