"""A requirement of a config's ``requirements:`` list, and the figures it may refer to.

A requirement names a figure by its dotted key in the JSON of ``analyze``
(``closed_loop.bandwidth_rad_s``), ``simulate`` (``step.overshoot_pct``, ``fit.zeta``),
``sinedwell`` (``sinedwell.bandwidth_rad_s``) or ``simulate --profile``
(``profile.tracking_error_max_deg``), bounds it with ``min`` and/or ``max``, and states the test
condition the figure needs (``step`` for step and fit figures, ``amplitude`` for the sine-dwell,
``profile`` -- distance, velocity, acceleration -- for a profile move). The accepted figures, their
units and the command that measures each are those of the figure table
(:data:`cas_freq.core.figures.FIGURES`, ``requirement=True``). Bounds are stored in the figure's own
unit, the one its key's suffix names (``_rad_s`` rad/s, ``_deg`` deg, ``_db`` dB, ``_pct`` %,
``_s`` s, ``_a`` A, ``_v`` V); a bound may be a plain number in that unit or a string with any
unit of the same dimension.
"""

import math
import re
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator
from pydantic_core import PydanticCustomError

from cas_freq.config.units import has_unit, to_si
from cas_freq.core.figures import FIGURES, METRICS, UNIT_LABELS, accepted_metrics
from cas_freq.core.output import ANGLE, LENGTH, wrong_kind

__all__ = ["METRICS", "UNIT_LABELS", "ProfileCondition", "Requirement", "convert_bound",
           "metric_unit", "parse_frequency_spec"]


def metric_unit(metric):
    """Unit of a requirement's figure (:data:`cas_freq.core.figures.FIGURES`; pint spelling, "" for
    dimensionless)."""
    figure = FIGURES.get(metric)
    if figure is None:
        raise ValueError(f"no unit known for {metric!r}")
    return figure.unit


def convert_bound(value, metric):
    """A bound as a float in the figure's unit.

    Raises
    ------
    ValueError, TypeError
        For text that does not parse, or a unit of another dimension, an angle counted as one
        (:func:`cas_freq.core.units.angle_problem`: ``Hz`` for an angular frequency is 2π off).
    """
    unit = metric_unit(metric)
    if unit == "dB":
        if isinstance(value, str):
            match = re.fullmatch(r"\s*([-+]?[0-9.]+(?:[eE][-+]?[0-9]+)?)\s*(dB)?\s*", value)
            if not match:
                raise ValueError(f"expected a number of dB such as '6 dB', got {value!r}")
            value = float(match.group(1))
        number = to_si(value, "dimensionless")
    else:
        number = to_si(value, unit or "dimensionless")
    if not math.isfinite(number):
        raise ValueError(f"must be finite, got {value!r}")
    return number


#: Accepted sine-dwell frequencies [rad/s]: below 1 rad/s a dwell of a few periods is millions
#: of 5 µs steps per point (the simulator also refuses a sine too fast for its step).
MIN_DWELL_RAD_S, MAX_DWELL_RAD_S = 1.0, 1e7


def parse_frequency_spec(spec):
    """``"MIN:MAX:N"`` (N log-spaced) or a list/comma text of frequencies [rad/s] → sorted tuple.

    Raises
    ------
    ValueError
        Naming what is accepted.
    """
    shown = repr(spec) if len(repr(spec)) <= 60 else repr(spec)[:56] + "...'"
    accepted = (f"expected MIN:MAX:N with {MIN_DWELL_RAD_S:g} <= MIN < MAX <= "
                f"{MAX_DWELL_RAD_S:g} and 2 <= N <= 1000, or a list of at most 1000 positive "
                f"numbers within {MIN_DWELL_RAD_S:g}..{MAX_DWELL_RAD_S:g}, in rad/s; got {shown}")
    try:
        if isinstance(spec, str) and ":" in spec:
            low, high, count = spec.split(":")
            low, high, n = float(low), float(high), int(count)
            if not (MIN_DWELL_RAD_S <= low < high <= MAX_DWELL_RAD_S and 2 <= n <= 1000):
                raise ValueError
            values = np.geomspace(low, high, n)
        else:
            items = spec.split(",") if isinstance(spec, str) else list(spec)
            if len(items) > 1000 or any(isinstance(item, bool) for item in items):
                raise ValueError
            values = np.array([float(item) for item in items])
            if values.size == 0 or not np.all((values >= MIN_DWELL_RAD_S)
                                              & (values <= MAX_DWELL_RAD_S)):
                raise ValueError
    except (ValueError, TypeError, OverflowError):
        raise ValueError(accepted) from None
    return tuple(sorted(set(values.tolist())))


def _quantity_field(value, unit, example, what):
    """A value with a unit (a string; a plain number is refused) as a float in ``unit``."""
    text = f"give {what} with a unit (e.g. '{example}'), got {value!r}"
    if not isinstance(value, str):
        raise PydanticCustomError("cas_value", text)
    try:
        number = to_si(value, unit)
        unitless = not has_unit(value)
    except (TypeError, ValueError) as exc:
        raise PydanticCustomError("cas_value", f"{text} ({exc})") from None
    if unitless:
        raise PydanticCustomError("cas_value", text)
    return number


class ProfileCondition(BaseModel):
    """The move a ``profile.*`` requirement is measured on (values at the output, SI inside).

    Attributes
    ----------
    distance : float
        The move [rad], non-zero, within ±90 deg (negative: the other way).
    velocity : float
        Velocity limit [rad/s], > 0.
    acceleration : float
        Acceleration limit [rad/s^2], > 0.
    deceleration : float or None
        Deceleration limit [rad/s^2], > 0; None: the acceleration.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    distance: float
    velocity: float
    acceleration: float
    deceleration: float | None = None

    @field_validator("distance", mode="before")
    @classmethod
    def _distance(cls, value, info):
        if (info.context or {}).get("linear"):  # a linear output: a length
            wrong = wrong_kind(value, LENGTH, "") if isinstance(value, str) else None
            if wrong:
                raise PydanticCustomError("cas_value", wrong)
            number = _quantity_field(value, "m", "5 mm", "the move at the output")
            if not (number != 0 and abs(number) <= LENGTH.largest):
                raise PydanticCustomError(
                    "cas_value", f"must be non-zero and within ±{LENGTH.largest_text} at the "
                    f"output, got {value!r}")
            return number
        number = _quantity_field(value, "rad", "10 deg", "the move at the output")
        if not (number != 0 and abs(number) <= math.pi / 2):
            raise PydanticCustomError(
                "cas_value", f"must be non-zero and within ±90 deg at the output, got {value!r}"
            )
        return number

    @field_validator("velocity", "acceleration", "deceleration", mode="before")
    @classmethod
    def _limit(cls, value, info):
        if value is None:
            return value
        unit, example, what = (("rad/s", "2000 deg/s", "a speed at the output")
                               if info.field_name == "velocity" else
                               ("rad/s^2", "1e5 deg/s^2", "an acceleration at the output"))
        if (info.context or {}).get("linear"):  # a linear output: per metre
            unit, example = (("m/s", "100 mm/s") if info.field_name == "velocity" else
                             ("m/s^2", "2000 mm/s^2"))
        number = _quantity_field(value, unit, example, what)
        if not number > 0:
            raise PydanticCustomError("cas_value", f"must be > 0, got {value!r}")
        return number


class Requirement(BaseModel):
    """One requirement on one figure, checked for every variant by ``cas-freq verify``.

    Attributes
    ----------
    id : str
        Short unique name (``BW-1``).
    metric : str
        Dotted key of the figure (:data:`METRICS`).
    min, max : float or None
        Bounds in the figure's unit (:func:`metric_unit`), inclusive.
    severity : str
        ``required`` (a failure fails verify) or ``advisory`` (reported only).
    source : str
        Where the requirement comes from (free text).
    step : float or None
        Output step [rad] the step and fit figures are measured on.
    amplitude : float or None
        Output sine amplitude [rad] the sine-dwell bandwidth is measured at.
    frequencies : tuple of float or None
        Sine-dwell frequencies [rad/s] (``MIN:MAX:N`` log-spaced or a list in the config);
        None for the ``sinedwell`` command's default grid.
    profile : ProfileCondition or None
        The profile move (``distance``, ``velocity``, ``acceleration``, optional
        ``deceleration``, each with a unit) the ``profile.*`` figures are measured on.
    description : str
        Free text shown beside the verdict.
    worst_case : bool
        ``verify`` checks the figure at its worst case over the config's ``tolerances:`` box
        (:mod:`cas_freq.studies.worstcase`) instead of at the nominal point.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    id: Annotated[str, Field(min_length=1)]
    metric: str
    min: float | None = None
    max: float | None = None
    severity: Literal["required", "advisory"] = "required"
    source: str = ""
    step: float | None = None
    amplitude: float | None = None
    frequencies: tuple[float, ...] | None = None
    profile: ProfileCondition | None = None
    description: str = ""
    worst_case: bool = False

    @field_validator("metric")
    @classmethod
    def _known_metric(cls, value, info):
        if value not in METRICS:
            raise PydanticCustomError(
                "cas_value",
                f"unknown figure {value!r}; accepted: {accepted_metrics()}",
            )
        figure = FIGURES[value]
        linear = bool((info.context or {}).get("linear"))
        if figure.output == ("angle" if linear else "length"):
            kind = "an angle" if linear else "a length"
            output = "linear" if linear else "rotary"
            raise PydanticCustomError(
                "cas_value", f"{value} is {kind} of the output; this actuator's output is "
                f"{output}: use {figure.twin}")
        return value

    @field_validator("min", "max", mode="before")
    @classmethod
    def _bound_in_metric_unit(cls, value, info):
        metric = info.data.get("metric")
        if value is None or metric is None:  # an unknown metric is reported on its own
            return value
        try:
            return convert_bound(value, metric)
        except TypeError as exc:
            raise PydanticCustomError("cas_type", f"{exc} (the unit of {metric})") from None
        except ValueError as exc:
            raise PydanticCustomError(
                "cas_value", f"{exc} (the unit of {metric} is {metric_unit(metric) or '-'})"
            ) from None

    @field_validator("step", "amplitude", mode="before")
    @classmethod
    def _angle(cls, value, info):
        if value is None:
            return value
        linear = bool(info is not None and (info.context or {}).get("linear"))
        unit, what, example = ((LENGTH, "an output length", "5 mm") if linear else
                               (ANGLE, "an output angle", "10 deg"))
        text = f"give {what} with a unit (e.g. '{example}'), got {value!r}"
        if not isinstance(value, str):
            raise PydanticCustomError("cas_value", text)
        try:
            number = to_si(value, unit.si)
            unitless = not has_unit(value)
        except (TypeError, ValueError) as exc:
            wrong = wrong_kind(value, unit, "")
            raise PydanticCustomError("cas_value", wrong or f"{text} ({exc})") from None
        if unitless:
            raise PydanticCustomError("cas_value", text)
        if not 0 < number <= unit.largest:
            raise PydanticCustomError(
                "cas_value", f"must be > 0 and at most {unit.largest_text} at the output, got "
                f"{value!r}"
            )
        return number

    @field_validator("frequencies", mode="before")
    @classmethod
    def _frequency_grid(cls, value):
        if value is None:
            return value
        try:
            return parse_frequency_spec(value)
        except ValueError as exc:
            raise PydanticCustomError("cas_value", str(exc)) from None

    @model_validator(mode="after")
    def _consistent(self):
        if self.min is None and self.max is None:
            raise PydanticCustomError("cas_value", f"{self.id}: give min, max or both")
        if self.min is not None and self.max is not None and self.min > self.max:
            raise PydanticCustomError(
                "cas_value", f"{self.id}: min {self.min:g} is above max {self.max:g}"
            )
        kind = METRICS[self.metric]
        needs = {"step": "step", "sinedwell": "amplitude", "profile": "profile"}.get(kind)
        if self.frequencies is not None and kind != "sinedwell":
            raise PydanticCustomError(
                "cas_value", f"{self.id}: 'frequencies' does not apply to {self.metric}"
            )
        for condition in ("step", "amplitude", "profile"):
            given = getattr(self, condition) is not None
            if condition == needs and not given:
                example = ("{distance: 10 deg, velocity: 2000 deg/s, acceleration: 1e5 deg/s^2}"
                           if condition == "profile" else "10 deg")
                raise PydanticCustomError(
                    "cas_value",
                    f"{self.id}: {self.metric} needs the test condition '{condition}' "
                    f"(e.g. {condition}: {example})",
                )
            if condition != needs and given:
                raise PydanticCustomError(
                    "cas_value", f"{self.id}: '{condition}' does not apply to {self.metric}"
                )
        return self

    @property
    def unit(self):
        """The figure's unit (pint spelling; "" for dimensionless)."""
        return metric_unit(self.metric)

    @property
    def kind(self):
        """``analyze``, ``step``, ``sinedwell`` or ``profile``: what must run to measure the
        figure."""
        return METRICS[self.metric]

    def passes(self, value):
        """True when ``value`` is within the bounds (None or NaN never passes)."""
        if value is None or not math.isfinite(value):
            return False
        return (self.min is None or value >= self.min) and (self.max is None or value <= self.max)

    def margin(self, value):
        """Distance to the nearest bound in the figure's unit, positive inside; None for None."""
        if value is None or not math.isfinite(value):
            return None
        distances = []
        if self.min is not None:
            distances.append(value - self.min)
        if self.max is not None:
            distances.append(self.max - value)
        return min(distances)
