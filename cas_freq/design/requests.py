"""The design page's request bodies, each field's type and range declared once (pydantic).

A request the page did not send (a field of the wrong type, a number out of range, a key no
endpoint takes) is refused with one line naming the field, the value and what is accepted:
``seq: expected an integer, got None``. The models are strict: ``1e400`` (JSON's infinity),
``null`` or ``[1]`` where an integer is expected are refused, never coerced.
"""

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, StringConstraints, ValidationError

from cas_freq.core.exceptions import CasFreqError

#: A session's name: the page makes one per browser tab.
SessionName = Annotated[str, StringConstraints(min_length=1, max_length=64)]
#: A sequence number: an integer that a JSON double holds exactly.
Sequence = Annotated[int, Field(ge=-(2 ** 53), le=2 ** 53)]
#: A value typed into a control: its text (with a unit) or a plain number.
Value = Annotated[str, StringConstraints(max_length=200)] | float | int


class _Request(BaseModel):
    """A request body: strict types, no field the endpoint does not read."""

    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)


class StateRequest(_Request):
    """``POST /api/state``: the figures of the session's values."""

    session: SessionName = "default"
    seq: Sequence = 0
    values: dict[Annotated[str, StringConstraints(max_length=200)], Value] = {}
    step: Annotated[str, StringConstraints(max_length=100)] | None = None
    nonlinear: bool = True


class ControlRequest(_Request):
    """``POST /api/control``: a control for one more key."""

    session: SessionName = "default"
    key: Annotated[str, StringConstraints(min_length=1, max_length=200)]


class TuneRequest(_Request):
    """``POST /api/tune``: ``cas-freq tune`` from the session's values (its option ranges)."""

    session: SessionName = "default"
    candidates: Annotated[int, Field(ge=1, le=2000)] | None = None
    rounds: Annotated[int, Field(ge=0, le=20)] | None = None


class SaveRequest(_Request):
    """``POST /api/save``: the session's values as a new variant in a file of the save folder.

    ``file`` is a file name in the save folder (a path is accepted only when it names a file
    directly in it); ``overwrite`` replaces an existing file (the page sends it only after
    the user confirmed); ``force`` replaces a variant of the same name in the config's text.
    """

    session: SessionName = "default"
    name: Annotated[str, StringConstraints(min_length=1, max_length=64)] = "designed"
    file: Annotated[str, StringConstraints(max_length=4096)] | None = None
    overwrite: bool = False
    force: bool = False


def parsed(model, body):
    """``body`` (a decoded JSON value) as a ``model`` instance.

    Raises
    ------
    CasFreqError
        One line naming each refused field, its value and what it accepts.
    """
    if not isinstance(body, dict):
        raise CasFreqError(f"expected a JSON object, got {type(body).__name__}")
    try:
        return model.model_validate(body)
    except ValidationError as exc:
        fields = {}  # a union's branches give one error each: said once, together
        for error in exc.errors():
            fields.setdefault(_field(error), []).append(error)
        raise CasFreqError("; ".join(_said(name, errors) for name, errors in fields.items())) \
            from None


def _field(error):
    """The dotted field of a pydantic error (without a union's branch names)."""
    return ".".join(str(part) for part in error["loc"] if not _branch(part)) or "body"


def _branch(part):
    """Whether a pydantic error location's part names a union's branch (``str``,
    ``constrained-str``, ``function-after[...]``), not a field or a key."""
    part = str(part)
    return part in ("str", "float", "int", "bool") or part.startswith(
        ("constrained-", "function-"))


def _said(field, errors):
    """A field's pydantic errors as ``field: what is accepted, got value``."""
    if errors[0]["type"] == "extra_forbidden":
        return f"{field}: not a field of this request"
    got = repr(errors[0].get("input"))
    got = got if len(got) <= 60 else got[:57] + "..."
    messages = [error["msg"] for error in errors]
    if all(message.startswith("Input should be ") for message in messages):
        wanted = "expected " + " or ".join(dict.fromkeys(
            message.removeprefix("Input should be ") for message in messages))
    else:
        wanted = "; ".join(dict.fromkeys(message[0].lower() + message[1:]
                                         for message in messages))
    return f"{field}: {wanted}, got {got}"


__all__ = ["ControlRequest", "SaveRequest", "StateRequest", "TuneRequest", "parsed"]
