"""Read an actuator config file, apply a variant and ``--set`` overrides, validate.

The file is YAML, read with ``yaml.safe_load`` only, and never modified. A variant is a map of
dotted keys to values (``motor.Km: 0.0075``) applied on top of the base; ``--set KEY=VALUE``
overrides are applied after the variant. ``motor.mu_v`` and ``motor.no_load`` are two ways of
giving one quantity: setting one removes the other.
"""

import copy
import dataclasses
from pathlib import Path

import yaml
from pydantic import BaseModel, ValidationError

from cas_freq.config.schema import BASE_VARIANT, ActuatorConfig
from cas_freq.exceptions import ConfigError, ConfigTypeError

#: Keys that give the same quantity another way: setting the key removes its alternative.
_ALTERNATIVES = {"motor.mu_v": "motor.no_load", "motor.no_load": "motor.mu_v"}


def default_config_path():
    """Path of the shipped QT-CAS config (``configs/qt_cas.yaml`` of the source tree)."""
    return Path(__file__).resolve().parents[2] / "configs" / "qt_cas.yaml"


@dataclasses.dataclass(frozen=True)
class LoadedVariant:
    """One variant of a config file, validated and in SI.

    Attributes
    ----------
    source : str
        Path of the config file it came from.
    variant : str
        Name of the variant (``"base"`` for the file without a variant's overrides).
    params : ActuatorConfig
        The validated parameters.
    overrides : tuple of (str, object)
        The ``--set`` overrides applied after the variant, as given.
    """

    source: str
    variant: str
    params: ActuatorConfig
    overrides: tuple = ()


def read_config_file(path):
    """Read a config file into plain Python data, safely.

    Parameters
    ----------
    path : str or Path
        The YAML file.

    Returns
    -------
    dict
        The top-level mapping.

    Raises
    ------
    ConfigError
        If the file cannot be read, is not valid YAML, or is not a mapping.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{path}: config file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read config file ({exc})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"{path}: not valid YAML{where}: {problem}") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: a config must be a YAML mapping, got {type(data).__name__}")
    return data


def variant_names(data):
    """Names of the variants of raw config ``data``: ``"base"`` first, then the file's order."""
    variants = data.get("variants") or {}
    if not isinstance(variants, dict):
        raise ConfigTypeError(
            f"variants: must be a mapping of variant names to overrides, got {variants!r}"
        )
    return [BASE_VARIANT, *variants]


def parse_set_option(text):
    """Parse one ``--set KEY=VALUE`` option; VALUE is read as a YAML scalar.

    Returns
    -------
    tuple of (str, object)
        The dotted key and the value (``"0.4 ms"`` stays a string, ``6.3`` becomes a float).
    """
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError(f"--set {text!r}: expected KEY=VALUE, e.g. position_loop.Kp=6.3")
    try:
        parsed = yaml.safe_load(value)
    except yaml.YAMLError:
        parsed = value
    return key, parsed


def _flatten(overrides, prefix=""):
    """Turn nested override maps into dotted keys (``{'motor': {'J': 1}}`` -> ``motor.J``)."""
    flat = {}
    for key, value in overrides.items():
        dotted = f"{prefix}{key}"
        if isinstance(value, dict):
            flat.update(_flatten(value, f"{dotted}."))
        else:
            flat[dotted] = value
    return flat


def _apply(data, dotted, value, origin):
    """Set ``data[a][b][c] = value`` for ``dotted = 'a.b.c'`` (in place)."""
    parts = dotted.split(".")
    if not all(parts):
        raise ConfigError(f"{origin}: {dotted!r} is not a dotted key such as motor.Km")
    node = data
    for i, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        elif not isinstance(child, dict):
            where = ".".join(parts[: i + 1])
            raise ConfigError(f"{origin}: {dotted}: {where} is a value, not a section")
        node = child
    for key, alternative in _ALTERNATIVES.items():
        if dotted == key or dotted.startswith(key + "."):
            section, _, leaf = alternative.rpartition(".")
            holder = data.get(section) if section else data
            if isinstance(holder, dict):
                holder.pop(leaf, None)
    node[parts[-1]] = value


def _accepted_keys(loc):
    """Keys accepted by the section holding the unknown key at ``loc``."""
    model = ActuatorConfig
    for part in loc[:-1]:
        field = model.model_fields.get(str(part))
        if field is None:
            return None
        candidates = [field.annotation, *getattr(field.annotation, "__args__", ())]
        model = next((c for c in candidates if isinstance(c, type) and
                      issubclass(c, BaseModel)), None)
        if model is None:
            return None
    return ", ".join(model.model_fields)


def _message(error):
    """One line for one pydantic error: ``dotted.key: what is wrong``."""
    loc = ".".join(str(part) for part in error["loc"])
    kind = error["type"]
    value = error.get("input")
    if kind in ("cas_value", "cas_type"):
        text = error["msg"]
    elif kind == "missing":
        text = "required key is missing"
    elif kind == "extra_forbidden":
        accepted = _accepted_keys(error["loc"])
        text = f"unknown key (value {value!r})"
        if accepted:
            section = ".".join(str(part) for part in error["loc"][:-1]) or "the top level"
            text += f"; {section} accepts {accepted}"
    elif kind == "literal_error":
        text = f"must be one of {error['ctx']['expected']}, got {value!r}"
    elif kind in ("dict_type", "model_type", "model_attributes_type"):
        text = f"must be a mapping, got {value!r}"
    elif kind in ("tuple_type", "list_type"):
        text = f"must be a list (of mappings, one per entry), got {value!r}"
    elif kind in ("string_type",):
        text = f"must be a string, got {value!r}"
    else:
        text = f"{error['msg']}, got {value!r}"
    return f"{loc}: {text}" if loc else text


def _is_type_error(error):
    return error["type"] == "cas_type" or error["type"].endswith("_type")


def validate(data, origin):
    """Validate raw config ``data`` into an :class:`ActuatorConfig`.

    Raises
    ------
    ConfigError, ConfigTypeError
        One message listing every problem, each with its dotted key.
    """
    try:
        return ActuatorConfig.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors()
        lines = [_message(error) for error in errors]
        kind = ConfigTypeError if all(_is_type_error(e) for e in errors) else ConfigError
        head = f"{origin}: " if origin else ""
        raise kind(head + "; ".join(lines)) from None


def load_variant(path=None, variant=BASE_VARIANT, overrides=()):
    """Load one variant of a config file.

    Parameters
    ----------
    path : str or Path, optional
        The config file; defaults to the shipped ``configs/qt_cas.yaml``.
    variant : str
        ``"base"``, or the name of an entry of the file's ``variants``.
    overrides : sequence of (str, object)
        ``(dotted key, value)`` pairs applied after the variant (the CLI's ``--set``).

    Returns
    -------
    LoadedVariant
    """
    path = Path(path) if path is not None else default_config_path()
    data = read_config_file(path)
    names = variant_names(data)
    if variant not in names:
        raise ConfigError(f"{path}: unknown variant {variant!r}; the file has {names}")
    resolved = copy.deepcopy(data)
    origin = f"{path}"
    if variant != BASE_VARIANT:
        changes = data["variants"][variant] or {}
        if not isinstance(changes, dict):
            raise ConfigTypeError(
                f"{path}: variants.{variant}: must be a mapping of dotted keys to values, "
                f"got {changes!r}"
            )
        for key, value in _flatten(changes).items():
            _apply(resolved, key, value, f"{path}: variants.{variant}")
        origin = f"{path} (variant {variant!r})"
    for key, value in overrides:
        _apply(resolved, key, value, "--set")
    if overrides:
        origin += " with --set " + ", ".join(f"{k}={v}" for k, v in overrides)
    params = validate(resolved, origin)
    return LoadedVariant(str(path), variant, params, tuple(overrides))


def load_all_variants(path=None, overrides=()):
    """Load the base and every variant of a config file, in file order."""
    path = Path(path) if path is not None else default_config_path()
    names = variant_names(read_config_file(path))
    return [load_variant(path, name, overrides) for name in names]
