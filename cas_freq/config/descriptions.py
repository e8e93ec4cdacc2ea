"""Descriptions from which a config derives its parameters (docs/model.md §5): a worm gear's
geometry gives its two efficiencies, an inertia simulant's geometry the load inertia."""

import math
from typing import Annotated

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from cas_freq.config.sections import Section, field_type
from cas_freq.core.formulas import disc_inertia, worm_efficiencies
from cas_freq.core.parameters import Parameter

#: The numeric keys of a worm's geometry (``gear.worm``) and of an inertia simulant
#: (``load.simulant``): static descriptions from which the config derives ``gear.efficiency``,
#: ``gear.backdrive_efficiency`` and ``load.inertia`` (those are the keys a sweep varies).
DERIVING_PARAMETERS = {
    p.key: p for p in (
        Parameter("gear.worm.lead_angle", None, "rad", 0.0, True, 1.5533,
                  "lead angle of the worm, (0, 89] deg [rad]"),
        Parameter("gear.worm.friction_coefficient", None, "dimensionless", 0.0, False, 1.0,
                  "friction coefficient of the worm's mesh, 0..1 [dimensionless]"),
        Parameter("gear.worm.pressure_angle", None, "rad", 0.0, False, 0.7854,
                  "normal pressure angle of the worm, 0..45 deg, default 20 deg [rad]"),
        Parameter("load.simulant.diameter", None, "m", 0.0, True, 10.0,
                  "outer diameter of the simulant disc, (0, 10] [m]"),
        Parameter("load.simulant.thickness", None, "m", 0.0, True, 10.0,
                  "thickness of the simulant disc, (0, 10] [m]"),
        Parameter("load.simulant.bore", None, "m", 0.0, False, 10.0,
                  "bore of the simulant disc, 0 (solid) .. its diameter [m]"),
        Parameter("load.simulant.density", None, "kg/m^3", 0.0, True, 1e5,
                  "density of the simulant, default 7850 (steel), (0, 1e5] [kg/m^3]"),
    )
}


def deriving_param(key):
    """Type of a float field of ``gear.worm`` or ``load.simulant`` (like :func:`param`)."""
    return field_type(DERIVING_PARAMETERS[key], key)


class Worm(Section):
    """A worm gear's geometry: its efficiencies follow (docs/model.md §5, "Worm gear")."""

    lead_angle: deriving_param("gear.worm.lead_angle")
    friction_coefficient: deriving_param("gear.worm.friction_coefficient")
    pressure_angle: deriving_param("gear.worm.pressure_angle") = math.radians(20.0)

    @property
    def efficiencies(self):
        """(forward, backdrive) efficiency [-]
        (:func:`cas_freq.core.formulas.worm_efficiencies`)."""
        return worm_efficiencies(self.lead_angle, self.friction_coefficient,
                                 self.pressure_angle)


def worm_efficiencies_of(gear):
    """Set a gear's efficiencies from its worm's geometry (refused beside given ones)."""
    if gear.worm is None:
        return gear
    given = sorted({"efficiency", "backdrive_efficiency"} & gear.model_fields_set)
    if given:
        raise PydanticCustomError(
            "cas_value", f"worm: the worm's geometry gives the efficiencies; remove "
            f"gear.{given[0]} (or gear.worm)")
    forward, back = gear.worm.efficiencies
    if not forward > 0:
        raise PydanticCustomError(
            "cas_value", "worm: the worm cannot drive the wheel with this friction and "
            "lead angle (forward efficiency 0): a friction_coefficient below "
            f"{math.cos(gear.worm.pressure_angle) / math.tan(gear.worm.lead_angle):.3g} is "
            "needed")
    object.__setattr__(gear, "efficiency", forward)
    object.__setattr__(gear, "backdrive_efficiency", back)
    return gear


class Simulant(Section):
    """An inertia simulant on the output (report §3: "a steel inertia simulant ... to emulate
    the control-surface inertia"): a disc, optionally bored, of a given material. Its inertia
    about the output's axis becomes ``load.inertia`` (docs/model.md §5, "Inertia simulant")."""

    name: Annotated[str, Field(min_length=1, max_length=80)] = "inertia simulant"
    diameter: deriving_param("load.simulant.diameter")
    thickness: deriving_param("load.simulant.thickness")
    bore: deriving_param("load.simulant.bore") = 0.0
    density: deriving_param("load.simulant.density") = 7850.0

    @model_validator(mode="after")
    def _bore_inside(self):
        if not self.bore < self.diameter:
            raise PydanticCustomError(
                "cas_value", f"bore: {self.bore:g} m must be below the diameter "
                f"{self.diameter:g} m")
        return self

    @property
    def inertia(self):
        """Its inertia about the output's axis [kg*m^2]
        (:func:`cas_freq.core.formulas.disc_inertia`)."""
        return disc_inertia(self.diameter, self.thickness, self.density, self.bore)


__all__ = ["DERIVING_PARAMETERS", "Simulant", "Worm", "deriving_param", "worm_efficiencies_of"]
