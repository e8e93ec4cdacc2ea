"""Analysis layer: margins, closed-loop figures, stability (imports model and config only)."""

from cas_freq.analysis.analyze import Analysis, analyze, pade_study, to_dict
from cas_freq.analysis.closed_loop import ClosedLoopFigures, closed_loop_figures
from cas_freq.analysis.margins import LoopMargins, loop_margins

__all__ = [
    "Analysis",
    "ClosedLoopFigures",
    "LoopMargins",
    "analyze",
    "closed_loop_figures",
    "loop_margins",
    "pade_study",
    "to_dict",
]
