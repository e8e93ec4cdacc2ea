"""Verdicts: each requirement's figure against its bounds, for one variant."""

import dataclasses
import math

from cas_freq.config.requirement import UNIT_LABELS
from cas_freq.verify.measure import measure

PASS, FAIL, ADVISORY = "PASS", "FAIL", "ADVISORY"


@dataclasses.dataclass(frozen=True)
class Verdict:
    """One requirement checked on one variant.

    Attributes
    ----------
    id, metric, severity, source, description : str
        From the requirement.
    variant : str
        The variant checked.
    value : float or None
        The measured figure in ``unit`` (None: the figure does not exist).
    unit : str
        Unit of ``value``, ``min``, ``max`` and ``margin``, as shown.
    min, max : float or None
        The bounds.
    margin : float or None
        Distance to the nearest bound, positive inside the bounds.
    status : str
        ``PASS``; ``FAIL`` (a required one is violated); ``ADVISORY`` (an advisory one is).
    condition : str
        What was run to measure the figure.
    message : str
        One line saying why it passed or failed.
    """

    id: str
    variant: str
    metric: str
    value: float | None
    unit: str
    min: float | None
    max: float | None
    margin: float | None
    status: str
    severity: str
    source: str
    description: str
    condition: str
    message: str


def bound_text(minimum, maximum, unit):
    """``>= 300 rad/s``, ``<= 15 %`` or ``in [a, b] unit``."""
    suffix = f" {unit}" if unit else ""
    if minimum is not None and maximum is not None:
        return f"in [{minimum:g}, {maximum:g}]{suffix}"
    if minimum is not None:
        return f">= {minimum:g}{suffix}"
    return f"<= {maximum:g}{suffix}"


def _verdict(requirement, variant, value, condition, stable=True):
    unit = UNIT_LABELS[requirement.unit]
    bounds = bound_text(requirement.min, requirement.max, unit)
    # A figure of an unstable actuator is shown but never passes, and has no margin.
    passed = requirement.passes(value) and stable
    if passed:
        status = PASS
    else:
        status = FAIL if requirement.severity == "required" else ADVISORY
    if value is None or not math.isfinite(value):
        message = f"{requirement.metric} has no value ({condition}); needs {bounds}"
    else:
        shown = f"{value:.4g}{(' ' + unit) if unit else ''}"
        relation = ("meets" if passed else "violates" if not requirement.passes(value)
                    else "is within but cannot pass")
        message = f"{requirement.metric} = {shown} {relation} {bounds} ({condition})"
    margin = requirement.margin(value) if stable else None
    return Verdict(
        id=requirement.id, variant=variant, metric=requirement.metric, value=value, unit=unit,
        min=requirement.min, max=requirement.max, margin=margin,
        status=status, severity=requirement.severity, source=requirement.source,
        description=requirement.description, condition=condition, message=message,
    )


def verify_variants(variants, requirements=None, known=None):
    """Check every requirement (default: the config's own) on each variant.

    Parameters
    ----------
    variants : sequence of cas_freq.config.LoadedVariant
        The variants.
    requirements : sequence of Requirement, optional
        Default: each variant's ``params.requirements``; all variants of one config share them.
    known : sequence of dict, optional
        Results already computed per variant, not computed again (see
        :func:`cas_freq.verify.measure.measure`).

    Returns
    -------
    dict of str to list of Verdict
        Variant name -> its verdicts, in the order of the requirements.
    """
    requirements = variants[0].params.requirements if requirements is None else requirements
    if not requirements:
        return {loaded.variant: [] for loaded in variants}
    measured = measure(variants, requirements, known)
    return {
        loaded.variant: [
            _verdict(requirement, loaded.variant, values[requirement.id],
                     context[requirement.id], stable)
            for requirement in requirements
        ]
        for loaded, (values, context, stable) in zip(variants, measured, strict=True)
    }


def verify_variant(loaded, requirements=None, known=None):
    """:func:`verify_variants` of one variant (``known``: its one dict): its verdicts."""
    return verify_variants([loaded], requirements, None if known is None else [known])[
        loaded.variant
    ]


def failed_required(verdicts):
    """The verdicts that fail a required requirement."""
    return [verdict for verdict in verdicts if verdict.status == FAIL]


def verdict_dict(verdict):
    """JSON-ready dict of a verdict."""
    from cas_freq.fileio import json_ready

    return json_ready(dataclasses.asdict(verdict))
