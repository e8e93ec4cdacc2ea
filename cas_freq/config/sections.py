"""The building blocks of the config's schema: a section, the type of a numeric field
converted and checked as the parameter table declares it (:func:`param` and its cascade and
linear-output twins), a key a section refuses, and the position loop's feedback."""

from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field
from pydantic_core import PydanticCustomError

from cas_freq.core.parameters import CASCADE_PARAMETERS, LINEAR_PARAMETERS, PARAMETERS


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


def param(key):
    """Type of the float field of dotted config ``key``, as :data:`PARAMETERS` declares it.

    The value is a number in the key's SI unit or a string with a unit; it is converted and
    checked against the key's bound by :meth:`cas_freq.core.parameters.Parameter.convert`, the
    conversion :func:`cas_freq.core.parameters.parse_value` uses.
    """
    return field_type(PARAMETERS[key], key)


def cascade_param(key):
    """Type of the float field of dotted config ``key`` in a cascade (a velocity loop), as
    :data:`CASCADE_PARAMETERS` declares it."""
    return field_type(CASCADE_PARAMETERS[key], key)


def linear_param(key):
    """Type of the float field of dotted config ``key`` at a linear output, as
    :data:`LINEAR_PARAMETERS` declares it."""
    return field_type(LINEAR_PARAMETERS[key], key)


def refused(why, quote=False):
    """Type of a key that this section refuses with the message ``why`` whenever given (null
    is taken as absent); ``quote``: the message ends with the value given."""

    def refuse(value):
        if value is None:  # absent (a dumped config writes it so)
            return None
        if quote:
            raise PydanticCustomError("cas_value", why + ", got {value}", {"value": repr(value)})
        raise PydanticCustomError("cas_value", why)

    return Annotated[Any, BeforeValidator(refuse), Field(json_schema_extra={"refused": why})]


def _feedback(value):
    if value not in ("motor", "output"):
        raise PydanticCustomError("cas_value", "must be motor or output, got {value}",
                                  {"value": repr(value)})
    return value


#: ``position_loop.feedback``: the position loop measures the motor (default) or the output.
Feedback = Annotated[str, BeforeValidator(_feedback)]


__all__ = ["Feedback", "Section", "cascade_param", "field_type", "linear_param", "param",
           "refused"]
