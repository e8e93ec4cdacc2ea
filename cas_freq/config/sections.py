"""The building blocks of the config's schema: a section, and the type of a numeric field
converted and checked as the parameter table declares it."""

from typing import Annotated

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from pydantic_core import PydanticCustomError


def field_type(parameter, key):
    """Annotated float type converting and checking a value as ``parameter`` declares."""

    def convert(value):
        try:
            return parameter.convert(value)
        except TypeError as exc:
            raise PydanticCustomError("cas_type", str(exc)) from None
        except ValueError as exc:
            raise PydanticCustomError("cas_value", str(exc)) from None

    return Annotated[
        float, BeforeValidator(convert),
        Field(description=parameter.meaning, json_schema_extra={"key": key,
                                                                "unit": parameter.unit}),
    ]


class Section(BaseModel):
    """A section of the config: unknown keys refused, frozen once validated."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=False)


__all__ = ["Section", "field_type"]
