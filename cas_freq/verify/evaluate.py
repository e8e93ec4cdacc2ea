"""Verdicts: each requirement's figure against its bounds, for one variant."""

import dataclasses
import math

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.figures import UNIT_LABELS
from cas_freq.core.fileio import json_ready
from cas_freq.simulation.sinedwell import bound_meets
from cas_freq.studies.worstcase import point_text, worst_case
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
        One line saying why it passed or failed; "not decided" when the data cannot tell (no
        value, or a bound on both sides of the requirement's bounds): then a required
        requirement fails and an advisory one is ADVISORY.
    bound : str or None
        ``">"`` or ``"<"`` when the figure is known only as a bound (a sine-dwell bandwidth
        outside its grid; ``value`` None), else None.
    bound_value : float or None
        The bound's edge in ``unit`` (the grid's top or bottom frequency).
    worst_case : dict or None
        For a requirement with ``worst_case: true``: its worst case over the tolerance box
        (the nominal value, the point that reaches the worst, how it was found); ``value`` is
        then the worst found.
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
    bound: str | None = None
    bound_value: float | None = None
    worst_case: dict | None = None


def bound_text(minimum, maximum, unit):
    """``>= 300 rad/s``, ``<= 15 %`` or ``in [a, b] unit``."""
    suffix = f" {unit}" if unit else ""
    if minimum is not None and maximum is not None:
        return f"in [{minimum:g}, {maximum:g}]{suffix}"
    if minimum is not None:
        return f">= {minimum:g}{suffix}"
    return f"<= {maximum:g}{suffix}"


def _verdict(requirement, variant, value, condition, stable=True, bound=None):
    unit = UNIT_LABELS[requirement.unit]
    suffix = f" {unit}" if unit else ""
    bounds = bound_text(requirement.min, requirement.max, unit)
    known = value is not None and math.isfinite(value)
    if known:
        meets = requirement.passes(value)
    elif bound is not None:
        meets = bound_meets(bound, requirement.min, requirement.max)
    else:
        meets = None
    # A figure of an unstable actuator is shown but never passes, and has no margin.
    passed = bool(meets) and stable
    if passed:
        status = PASS
    else:
        status = FAIL if requirement.severity == "required" else ADVISORY
    if known:
        shown = f"{value:.4g}{suffix}"
    elif bound is not None:
        shown = f"{bound[0]} {bound[1]:.4g}{suffix}"
    if not known and bound is None:
        undecided = " not decided:" if requirement.kind == "sinedwell" else ""
        message = f"{requirement.metric}{undecided} has no value ({condition}); needs {bounds}"
    elif meets is None:
        message = (f"{requirement.metric} {shown} not decided: the bound cannot tell whether it "
                   f"is {bounds} ({condition}; widen the frequencies)")
    else:
        relation = ("meets" if passed else "violates" if not meets
                    else "is within but cannot pass")
        equals = "= " if known else ""  # a bound reads "> 400 rad/s"
        message = f"{requirement.metric} {equals}{shown} {relation} {bounds} ({condition})"
    margin = requirement.margin(value) if stable and known else None
    return Verdict(
        id=requirement.id, variant=variant, metric=requirement.metric,
        value=value if known else None, unit=unit,
        min=requirement.min, max=requirement.max, margin=margin,
        status=status, severity=requirement.severity, source=requirement.source,
        description=requirement.description, condition=condition, message=message,
        bound=None if known or bound is None else bound[0],
        bound_value=None if known or bound is None else bound[1],
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
    nominal = [r for r in requirements if not r.worst_case]
    worst = [r for r in requirements if r.worst_case]
    measured = (measure(variants, nominal, known) if nominal
                else [({}, {}, True, {}) for _ in variants])
    verdicts = {}
    for loaded, (values, context, stable, bounds) in zip(variants, measured, strict=True):
        found = _worst_cases(loaded, worst) if worst else {}
        verdicts[loaded.variant] = [
            found[requirement.id] if requirement.worst_case else
            _verdict(requirement, loaded.variant, values[requirement.id],
                     context[requirement.id], stable, bounds.get(requirement.id))
            for requirement in requirements
        ]
    return verdicts


def _worst_cases(loaded, requirements):
    """Verdicts of the ``worst_case: true`` requirements of one variant: each at its worst
    case over the config's tolerance box."""
    if not loaded.params.tolerances:
        ids = ", ".join(r.id for r in requirements)
        raise ConfigError(f"requirements {ids}: worst_case: true needs a 'tolerances:' section "
                          "in the config (e.g. motor.Km: 10%), the box the worst case searches")
    data = worst_case(loaded, requirements=requirements)
    search = data["search"]
    rows = {row["id"]: row for row in data["requirements"]}
    out = {}
    for item in data["not_evaluated"]:
        requirement = next(r for r in requirements if r.id == item["id"])
        out[requirement.id] = _verdict(requirement, loaded.variant, None,
                                       f"worst case not evaluated: {item['reason']}")
    for requirement in requirements:
        if requirement.id not in rows:
            continue
        row = rows[requirement.id]
        where = "a corner" if row["at_corner"] else "inside the box"
        condition = (f"worst case over the tolerances ({len(data['box'])} keys, "
                     f"{search['evaluations']['analyze']} evaluations) at {where}: "
                     f"{point_text(row['at'])}; nominal "
                     + ("—" if row["nominal"] is None else f"{row['nominal']:.4g}")
                     + ("; worst found, no guaranteed bound" if row.get("bound") is None
                        else f"; guaranteed >= {row['bound']:.4g} over the whole box"))
        verdict = _verdict(requirement, loaded.variant, row["worst"], condition,
                           stable=row["worst_verdict"] == "stable")
        out[requirement.id] = dataclasses.replace(verdict, worst_case={
            "nominal": row["nominal"], "at": row["at"], "at_corner": row["at_corner"],
            "found_by": row["found_by"], "verdict": row["worst_verdict"]})
    return out


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
    data = dataclasses.asdict(verdict)
    if verdict.bound is None:  # only a figure known as a bound carries the two keys
        del data["bound"], data["bound_value"]
    if verdict.worst_case is None:
        del data["worst_case"]
    return json_ready(data)
