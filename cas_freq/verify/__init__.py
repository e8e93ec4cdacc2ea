"""Requirements checked against the figures of every variant (the ``verify`` command's data).

:func:`measure` runs what the requirements need (the frequency analysis, nonlinear steps,
sine-dwells) and :func:`verify_variant` compares each figure with its bounds. Nothing here
imports matplotlib or python-control.
"""

from cas_freq.verify.evaluate import (
    Verdict,
    failed_required,
    verdict_dict,
    verify_variant,
    verify_variants,
)
from cas_freq.verify.junit import junit_xml

__all__ = [
    "Verdict", "failed_required", "junit_xml", "verdict_dict", "verify_variant", "verify_variants",
]
