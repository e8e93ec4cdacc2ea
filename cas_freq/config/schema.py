"""The validated actuator configuration, as frozen pydantic models.

Every numeric field is stored in SI. Each field's unit and accepted range are declared once,
with :func:`si`; the loader turns pydantic's errors into one message per problem that names the
dotted key, the value and what is accepted (see :mod:`cas_freq.config.loader`).

Keys follow MODEL.md and the report's symbols (``Kp``, ``Ki``, ``Kd``, ``Tf``, ``mu_v``, ...).
"""

import math
from typing import Annotated, Any, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, model_validator
from pydantic_core import PydanticCustomError

from cas_freq.config.requirement import Requirement
from cas_freq.config.units import to_si
from cas_freq.formulas import viscous_friction_from_no_load

BASE_VARIANT = "base"


def _bounds_text(gt, ge):
    if gt is not None:
        return f"> {gt:g}"
    if ge is not None:
        return f">= {ge:g}"
    return "finite"


def si(unit, *, gt=None, ge=None):
    """Type of a float field given in ``unit`` (SI), with an optional lower bound.

    Parameters
    ----------
    unit : str
        SI unit the value is stored in, as pint spells it.
    gt, ge : float, optional
        Strict or non-strict lower bound, in ``unit``.
    """

    def convert(value):
        try:
            number = to_si(value, unit)
        except TypeError as exc:
            raise PydanticCustomError("cas_type", str(exc)) from None
        except ValueError as exc:
            raise PydanticCustomError("cas_value", str(exc)) from None
        shown = f"{value} {unit}" if not isinstance(value, str) else repr(value)
        if not math.isfinite(number):
            raise PydanticCustomError("cas_value", f"must be finite, got {shown}")
        if (gt is not None and not number > gt) or (ge is not None and not number >= ge):
            raise PydanticCustomError(
                "cas_value", f"must be {_bounds_text(gt, ge)} {unit}, got {shown}"
            )
        return number

    return Annotated[float, BeforeValidator(convert), Field(description=unit)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


class NoLoad(_Section):
    """Motor no-load point, from which the viscous friction is derived (report §6)."""

    speed: si("rad/s", gt=0)
    current: si("A", ge=0)


class Motor(_Section):
    """Motor constants (report Table 3), and either ``mu_v`` or ``no_load``."""

    R: si("ohm", gt=0)
    L: si("H", gt=0)
    Km: si("N*m/A", gt=0)
    Ke: si("V*s/rad", gt=0)
    J: si("kg*m^2", gt=0)
    mu_v: si("N*m*s/rad", ge=0) | None = None
    no_load: NoLoad | None = None

    @model_validator(mode="after")
    def _one_friction_source(self):
        if (self.mu_v is None) == (self.no_load is None):
            given = "both" if self.mu_v is not None else "neither"
            raise PydanticCustomError(
                "cas_value",
                f"give exactly one of motor.mu_v or motor.no_load.{{speed, current}}, got {given}",
            )
        return self

    @property
    def viscous_friction(self):
        """Viscous friction [N*m*s/rad]: ``mu_v``, or derived from the no-load point."""
        if self.mu_v is not None:
            return self.mu_v
        return viscous_friction_from_no_load(self.Km, self.no_load.speed, self.no_load.current)


class Gear(_Section):
    """Gear between motor and fin: fin angle = motor angle / ratio."""

    ratio: si("dimensionless", gt=0)


class CurrentLoop(_Section):
    """PI current controller (report Table 1) and its transport delay."""

    Kp: si("V/A", ge=0)
    Ki: si("V/(A*s)", ge=0)
    v_max: si("V", gt=0)
    delay: si("s", ge=0)

    @model_validator(mode="after")
    def _some_gain(self):
        if self.Kp == 0 and self.Ki == 0:
            raise PydanticCustomError("cas_value", "Kp and Ki are both 0: no current loop")
        return self


class PositionLoop(_Section):
    """PID position controller with filtered derivative (report Table 2) and its delay."""

    Kp: si("A/rad", ge=0)
    Ki: si("A/(rad*s)", ge=0)
    Kd: si("A*s/rad", ge=0)
    Tf: si("s", gt=0) | None = None
    ff_v: si("A*s/rad") = 0.0
    ff_a: si("A*s^2/rad") = 0.0
    i_max: si("A", gt=0)
    delay: si("s", ge=0)
    derivative_on: Literal["error", "measurement"] = "error"

    @model_validator(mode="after")
    def _filter_defined(self):
        if self.Kd > 0 and self.Tf is None and self.Kp == 0:
            raise PydanticCustomError(
                "cas_value",
                "Tf defaults to Kd/(10*Kp), which is undefined with Kp = 0 and Kd > 0: set Tf",
            )
        if self.Kp == 0 and self.Ki == 0 and self.Kd == 0:
            raise PydanticCustomError("cas_value", "Kp, Ki and Kd are all 0: no position loop")
        return self

    @property
    def filter_time_constant(self):
        """Derivative filter time constant [s]: ``Tf``, or Kd/(10*Kp) (0 when Kd = 0)."""
        if self.Tf is not None:
            return self.Tf
        if self.Kd == 0:
            return 0.0
        return self.Kd / (10.0 * self.Kp)


class Simulation(_Section):
    """How the nonlinear simulation runs the controllers.

    ``controllers: continuous`` (default) integrates both controllers with the simulator's fine
    step; ``sampled`` runs them at the given rates with zero-order hold (the EPOS4 runs its
    current loop at 25 kHz and its position loop at 2.5 kHz). The frequency-domain analysis is
    continuous-time either way.
    """

    controllers: Literal["continuous", "sampled"] = "continuous"
    current_loop_rate: si("Hz", gt=0) = 25e3
    position_loop_rate: si("Hz", gt=0) = 2.5e3

    @property
    def rates_hz(self):
        """(current, position) sample rates [Hz], or (None, None) for continuous controllers."""
        if self.controllers == "continuous":
            return None, None
        return self.current_loop_rate, self.position_loop_rate


class ActuatorConfig(_Section):
    """A whole actuator: motor, gear, both loops, and the named variants of the file."""

    name: Annotated[str, Field(min_length=1)]
    description: str = ""
    motor: Motor
    gear: Gear
    current_loop: CurrentLoop
    position_loop: PositionLoop
    simulation: Simulation = Simulation()
    requirements: tuple[Requirement, ...] = ()
    variants: dict[str, dict[str, Any] | None] = {}

    @model_validator(mode="after")
    def _unique_requirement_ids(self):
        ids = [requirement.id for requirement in self.requirements]
        repeated = sorted({name for name in ids if ids.count(name) > 1})
        if repeated:
            raise PydanticCustomError(
                "cas_value", f"requirements: ids must be unique, repeated: {', '.join(repeated)}"
            )
        return self
