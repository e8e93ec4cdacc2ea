"""Read an actuator config file, apply a variant and ``--set`` overrides, validate.

The file is YAML, read with a ``yaml.SafeLoader`` subclass only (on libyaml's parser where
PyYAML has it), and never modified. Plain scalars are resolved as YAML 1.2's core schema
resolves them (whatever ``%YAML`` directive the file has), not as YAML 1.1 (PyYAML's
default), whose sexagesimal and octal integers turn typos
into other numbers silently: ``20:1`` stays the string ``"20:1"`` (a numeric key refuses it:
"a ratio a:b is not a number; write 20"), ``020`` and ``010`` are the decimal 20 and 10 (YAML
1.2; never octal), ``yes``/``on`` and dates stay strings, ``1e-6`` is a float. ``--set`` values
are read the same way.

A variant is a map of dotted keys to values (``motor.Km: 0.0075``) applied on top of the base;
``--set KEY=VALUE`` overrides are applied after the variant, to the selected variants only.
``motor.mu_v`` and ``motor.no_load`` are two ways of giving one quantity: setting one removes
the other.
"""

import copy
import dataclasses
import importlib.resources
import math
import re
from pathlib import Path

import yaml
from pydantic import BaseModel, ValidationError
from yaml.events import AliasEvent, CollectionEndEvent, CollectionStartEvent, ScalarEvent

from cas_freq.config.schema import (
    BASE_VARIANT,
    VARIANT_NAME,
    ActuatorConfig,
    CascadePositionLoop,
)
from cas_freq.core.exceptions import ConfigError, ConfigTypeError, listed
from cas_freq.core.fileio import one_line, read_input

#: Keys that give the same quantity another way: setting the key removes its alternative.
_ALTERNATIVES = {"motor.mu_v": "motor.no_load", "motor.no_load": "motor.mu_v"}


#: Largest config file read [bytes] (the shipped one is 5 kB).
MAX_FILE_BYTES = 1 << 20
#: Deepest nesting of mappings and lists in a config file.
MAX_DEPTH = 32
#: Most nodes a config file may hold, aliases counted as often as they are expanded.
MAX_NODES = 100_000
#: Longest quote of a value in an error message [characters].
QUOTE_CHARS = 60


def shown(value, limit=QUOTE_CHARS):
    """``repr`` of ``value`` on one line, cut to about ``limit`` characters."""
    text = repr(value)
    if len(text) > 20 * limit:  # a huge structure: do not even format the tail
        text = text[: 20 * limit]
    text = one_line(text)
    return text if len(text) <= limit else text[: limit - 3] + "..."


#: YAML 1.2 core schema's plain scalars (https://yaml.org/spec/1.2.2/#1032-tag-resolution); the
#: int and float forms are also what an explicit ``!!int`` / ``!!float`` must look like.
_CORE_NULL = re.compile(r"~|null|Null|NULL|")
_CORE_BOOL = re.compile(r"true|True|TRUE|false|False|FALSE")
_CORE_INT = re.compile(r"[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+")
_CORE_FLOAT = re.compile(r"[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                         r"|[-+]?\.(?:inf|Inf|INF)|\.nan|\.NaN|\.NAN")


#: libyaml's parser where PyYAML was built with it (the wheels are): it scans and parses a
#: config about 10 times faster than the pure-Python one (the constructors below are Python
#: either way). Both are safe loaders: SafeConstructor builds plain data only.
_SafeBase = yaml.CSafeLoader if getattr(yaml, "__with_libyaml__", False) else yaml.SafeLoader


class _CoreSchema:
    """The constructors of :func:`_core_schema_loader`'s loaders (mixed in before the safe
    loader they extend)."""

    def construct_yaml_int(self, node):
        """An integer of the core schema's form (decimal, ``0o``, ``0x``); never base 60 or 8."""
        value = self.construct_scalar(node)
        if not _CORE_INT.fullmatch(value):
            raise ValueError(f"{shown(value)} is not an integer (YAML 1.2: digits, 0o or 0x)")
        if value.startswith("0o"):
            return int(value[2:], 8)
        if value.startswith("0x"):
            return int(value[2:], 16)
        return int(value, 10)

    def construct_yaml_float(self, node):
        """A float of the core schema's form (``.inf``, ``.nan`` included); never base 60."""
        value = self.construct_scalar(node)
        if not _CORE_FLOAT.fullmatch(value):
            raise ValueError(f"{shown(value)} is not a float (YAML 1.2 form, e.g. 1.5e-3)")
        if value.lower().lstrip("+-") == ".inf":
            return -math.inf if value.startswith("-") else math.inf
        if value.lower() == ".nan":
            return math.nan
        return float(value)

    def construct_yaml_bool(self, node):
        """``true`` or ``false`` (three spellings each); never YAML 1.1's yes/no/on/off."""
        value = self.construct_scalar(node)
        if not _CORE_BOOL.fullmatch(value):
            raise ValueError(f"{shown(value)} is not a boolean (YAML 1.2: true or false)")
        return value.lower() == "true"

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            seen = {}
            for key_node, _ in node.value:
                if not isinstance(key_node, yaml.ScalarNode) or key_node.tag.endswith(":merge"):
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    first = seen.setdefault(key, key_node.start_mark.line + 1)
                except TypeError:
                    continue
                line = key_node.start_mark.line + 1
                if first != line:
                    raise ConfigError(f"duplicate key {shown(key)} at line {line} (first at line "
                                      f"{first}); each key may appear once per mapping")
        return super().construct_mapping(node, deep=deep)


def _core_schema_loader(base):
    """A loader on ``base`` (yaml.SafeLoader or yaml.CSafeLoader) with YAML 1.2 core-schema
    scalars that refuses duplicate keys, naming the key and both lines.

    Only the core schema's plain scalars are implicitly typed (null, bool, decimal, ``0o``
    octal and ``0x`` hex integers, floats); everything else is a string. A leading zero is
    decimal (``020`` is 20), explicitly tagged ``!!int``/``!!float``/``!!bool`` values must
    have the core form too (``!!int 1:30`` and ``!!bool yes`` are errors). YAML merge keys
    (``<<: *anchor``) are kept.
    """

    class Loader(_CoreSchema, base):
        # a class attribute of its own: SafeLoader's YAML 1.1 resolvers are not inherited
        yaml_implicit_resolvers = {}

    Loader.add_constructor("tag:yaml.org,2002:int", Loader.construct_yaml_int)
    Loader.add_constructor("tag:yaml.org,2002:float", Loader.construct_yaml_float)
    Loader.add_constructor("tag:yaml.org,2002:bool", Loader.construct_yaml_bool)
    for tag, pattern, first in (
        ("tag:yaml.org,2002:null", _CORE_NULL, ["~", "n", "N", ""]),
        ("tag:yaml.org,2002:bool", _CORE_BOOL, list("tTfF")),
        ("tag:yaml.org,2002:int", _CORE_INT, list("-+0123456789")),
        ("tag:yaml.org,2002:float", _CORE_FLOAT, list("-+.0123456789")),
        ("tag:yaml.org,2002:merge", re.compile(r"<<"), ["<"]),
    ):
        # resolvers match with .match(): anchor the end, as the core schema means the whole
        # scalar
        Loader.add_implicit_resolver(tag, re.compile(f"(?:{pattern.pattern})$"), first)
    return Loader


_Loader = _core_schema_loader(_SafeBase)


def _check_depth(text, path):
    """Raise ConfigError if the YAML ``text`` nests deeper than MAX_DEPTH (measured on the
    event stream, before any node is built, so that depth cannot recurse)."""
    depth = events = 0
    for event in yaml.parse(text, Loader=_Loader):
        events += 1
        if isinstance(event, CollectionStartEvent):
            depth += 1
            if depth > MAX_DEPTH:
                line = event.start_mark.line + 1
                raise ConfigError(f"{path}: nested deeper than {MAX_DEPTH} levels at line {line}; "
                                  "a config is a few levels of mappings")
        elif isinstance(event, CollectionEndEvent):
            depth -= 1
        elif isinstance(event, (ScalarEvent, AliasEvent)) and events > MAX_NODES:
            break


def _check_size(node, path):
    """Raise ConfigError if the node graph holds more than MAX_NODES nodes once its aliases are
    expanded: each node counts once per path that reaches it (an alias bomb is refused after
    MAX_NODES visits, not after expanding it); iterative, so depth cannot recurse."""
    count, stack = 0, [node]
    while stack:
        current = stack.pop()
        count += 1
        if count > MAX_NODES:
            raise ConfigError(f"{path}: more than {MAX_NODES} values once its aliases are "
                              "expanded; a config is a few hundred values")
        if isinstance(current, yaml.SequenceNode):
            stack.extend(current.value)
        elif isinstance(current, yaml.MappingNode):
            for key, value in current.value:
                stack.extend((key, value))


def _load_yaml(text, path):
    """The data of YAML ``text``, bounded in depth and size, duplicate keys refused: its depth
    checked on the events, its size on the node graph, which is then constructed (the text
    composed once)."""
    _check_depth(text, path)
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        _check_size(node, path)
        return _construct(loader, node, path)
    finally:
        loader.dispose()


def _construct(loader, node, path):
    """The data of the composed ``node`` (:func:`_load_yaml`)."""
    try:
        return loader.construct_document(node)
    except ConfigError as exc:
        raise ConfigError(f"{path}: {exc}") from None
    except (yaml.YAMLError, RecursionError):
        raise
    except Exception as exc:  # noqa: BLE001 - PyYAML's constructors raise many kinds
        # a tag whose value does not convert: !!float abc, !!int 0.5, !!bool maybe
        raise ConfigError(f"{path}: a tagged value does not convert ({type(exc).__name__}: "
                          f"{shown(str(exc))}); remove the !!tag or fix the value") from None


def shipped_configs_dir():
    """Folder of the shipped configs (``qt_cas.yaml``, ``dc_servo.yaml``).

    In an installed package, the package data ``cas_freq/configs/`` (read with
    :mod:`importlib.resources`; the wheel maps the repository's ``configs/`` there, see
    pyproject.toml); in a source checkout (``PYTHONPATH``, or an editable install), the
    repository's ``configs/`` itself, so that a report run from the repository root names
    ``configs/qt_cas.yaml``.
    """
    packaged = importlib.resources.files("cas_freq") / "configs"
    if isinstance(packaged, Path) and packaged.is_dir():
        return packaged
    return Path(__file__).resolve().parents[2] / "configs"


def default_config_path():
    """Path of the shipped QT-CAS config, ``qt_cas.yaml`` of :func:`shipped_configs_dir`."""
    return shipped_configs_dir() / "qt_cas.yaml"


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
        If the file cannot be read (:func:`cas_freq.core.fileio.read_input`: not found, not a
        regular file, larger than :data:`MAX_FILE_BYTES`, not UTF-8), is not valid YAML, or is
        not a mapping.
    """
    shown_path = one_line(path)
    text = read_input(path, "config file", MAX_FILE_BYTES)
    try:
        data = _load_yaml(text, shown_path)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"{shown_path}: not valid YAML{where}: "
                          f"{one_line(problem)[:200]}") from None
    except RecursionError:
        raise ConfigError(f"{shown_path}: nested too deep") from None
    if not isinstance(data, dict):
        raise ConfigError(f"{shown_path}: a config must be a YAML mapping, "
                          f"got {type(data).__name__}")
    return data


def variant_names(data):
    """Names of the variants of raw config ``data``: ``"base"`` first, then the file's order.

    Raises
    ------
    ConfigTypeError
        For ``variants`` that is not a mapping.
    ConfigError
        For a name that is not :data:`~cas_freq.config.schema.VARIANT_NAME` (it names output
        files: ``a/b`` or ``../x`` would be a path) or is ``base`` (the file without a
        variant).
    """
    variants = data.get("variants") or {}
    if not isinstance(variants, dict):
        raise ConfigTypeError(
            f"variants: must be a mapping of variant names to overrides, got {shown(variants)}"
        )
    for name in variants:
        if name == BASE_VARIANT:
            raise ConfigError("variants.base: base is the file without a variant (reserved); "
                              "name the variant otherwise")
        if not isinstance(name, str) or not VARIANT_NAME.fullmatch(name):
            raise ConfigError(f"variants: name {shown(name)} is not accepted; a variant's name "
                              "is a letter or _ followed by letters, digits, _ or - (at most 64 "
                              "characters)")
    return [BASE_VARIANT, *variants]


def parse_set_option(text):
    """Parse one ``--set KEY=VALUE`` option; VALUE is read as a YAML scalar, with the config
    file's YAML 1.2 scalars (``20:1`` stays text, ``010`` is 10).

    Returns
    -------
    tuple of (str, object)
        The dotted key and the value (``"0.4 ms"`` stays a string, ``6.3`` becomes a float).
    """
    key, sep, value = text.partition("=")
    key = key.strip()
    if not sep or not key:
        raise ConfigError(f"--set {shown(text)}: expected KEY=VALUE, e.g. position_loop.Kp=6.3")
    if len(value) > 200:
        raise ConfigError(f"--set {key}: value longer than 200 characters: {shown(value)}")
    try:
        parsed = _load_yaml(value, f"--set {key}")
    except yaml.YAMLError:
        parsed = value
    return key, parsed


def check_overrides(overrides, origin="--set"):
    """Raise ConfigError for overrides that would be silently lost: a key of the ``variants``
    section (the variants are read from the file; an override applies to the selected
    variant's values). A key given twice is not lost: the last value wins, as for any option
    given twice.

    Parameters
    ----------
    overrides : sequence of (str, object)
        ``(dotted key, value)`` pairs.
    origin : str
        What the errors call the overrides (``--set``, ``set=``).
    """
    for key, value in overrides:
        if key == "variants" or key.startswith("variants."):
            name, _, rest = key.removeprefix("variants").lstrip(".").partition(".")
            name, rest = (name, rest) if name and rest else ("NAME", "KEY")
            write = (f"--variant {name} --set {rest}={value}" if origin == "--set" else
                     f"variant={name!r} with {origin} {{{rest!r}: {value!r}}}")
            raise ConfigError(f"{origin} {one_line(key)[:80]}: {origin} changes the selected "
                              f"variants' values, not the variants section; write {write}")


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
        raise ConfigError(f"{origin}: {shown(dotted)} is not a dotted key such as motor.Km")
    node = data
    for i, part in enumerate(parts[:-1]):
        if isinstance(node, list):  # filters.0.frequency: an item of a list
            node = _item(node, part, ".".join(parts[:i]), dotted, origin)
            continue
        child = node.get(part)
        if child is None and parts[i + 1].isdigit():  # filters.0.frequency, no filters
            where = ".".join(parts[: i + 1])
            example = (" (e.g. --set 'filters=[{at: current_command, type: lowpass1, "
                       "frequency: 3000 rad/s}]')" if where == "filters" else "")
            raise ConfigError(f"{origin}: {one_line(dotted)[:80]}: the config has no "
                              f"{one_line(where)[:80]} list to take item {parts[i + 1][:20]} "
                              f"of; set the whole list{example}")
        if child is None:
            child = node[part] = {}
        elif not isinstance(child, (dict, list)) or (isinstance(child, list)
                                                     and not parts[i + 1].isdigit()):
            where = ".".join(parts[: i + 1])
            raise ConfigError(f"{origin}: {one_line(dotted)[:80]}: {one_line(where)[:80]} is a "
                              "value, not a section")
        node = child
    for key, alternative in _ALTERNATIVES.items():
        if dotted == key or dotted.startswith(key + "."):
            section, _, leaf = alternative.rpartition(".")
            holder = data.get(section) if section else data
            if isinstance(holder, dict):
                holder.pop(leaf, None)
    if isinstance(node, list):
        raise ConfigError(f"{origin}: {one_line(dotted)[:80]}: set a number of an item, e.g. "
                          f"{'.'.join(parts[:-1])}.0.frequency, or the whole list")
    node[parts[-1]] = value


def _item(items, part, where, dotted, origin):
    """Item ``part`` (an index) of the list ``items`` at dotted ``where``, a mapping."""
    if not part.isdigit() or int(part) >= len(items):
        raise ConfigError(f"{origin}: {one_line(dotted)[:80]}: {one_line(where)[:80]} has "
                          f"{len(items)} item(s), numbered from 0; got {one_line(part)[:20]!r}")
    item = items[int(part)]
    if not isinstance(item, dict):
        raise ConfigError(f"{origin}: {one_line(dotted)[:80]}: {one_line(where)}.{part} is a "
                          "value, not a section")
    return item


def _accepted_keys(loc, cascade=False):
    """Keys accepted by the section holding the unknown key at ``loc`` (of a config with a
    velocity loop if ``cascade``), without the keys the section refuses."""
    model = ActuatorConfig
    for part in loc[:-1]:
        if isinstance(part, int):  # an item of a list of sections (filters.0)
            continue
        field = model.model_fields.get(str(part))
        if field is None:
            return None
        candidates = [field.annotation, *getattr(field.annotation, "__args__", ())]
        models = [c for c in candidates if isinstance(c, type) and issubclass(c, BaseModel)]
        if not models:
            return None
        model = next((m for m in models if (m is CascadePositionLoop) == cascade), models[0])
    return ", ".join(name for name, field in model.model_fields.items()
                     if not (field.json_schema_extra or {}).get("refused"))


def _message(error, cascade=False):
    """One line for one pydantic error: ``dotted.key: what is wrong``."""
    loc = ".".join(str(part) for part in error["loc"])
    kind = error["type"]
    value = error.get("input")
    if kind in ("cas_value", "cas_type"):
        text = error["msg"]
    elif kind == "missing":
        text = "required key is missing"
    elif kind == "extra_forbidden":
        accepted = _accepted_keys(error["loc"], cascade)
        text = f"unknown key (value {shown(value)})"
        if accepted:
            section = ".".join(str(part) for part in error["loc"][:-1]) or "the top level"
            text += f"; {section} accepts {accepted}"
    elif kind == "literal_error":
        text = f"must be one of {error['ctx']['expected']}, got {shown(value)}"
    elif kind in ("dict_type", "model_type", "model_attributes_type"):
        text = f"must be a mapping, got {shown(value)}"
    elif kind in ("tuple_type", "list_type"):
        text = f"must be a list (of mappings, one per entry), got {shown(value)}"
    elif kind in ("string_type",):
        text = f"must be a string, got {shown(value)}"
    else:
        text = f"{error['msg']}, got {shown(value)}"
    return one_line(f"{loc}: {text}" if loc else text)


def _messages(errors, cascade=False):
    """One line per problem, in pydantic's order, except that several unknown keys of one
    section share one line: their names (the first :data:`~cas_freq.core.exceptions.MAX_LISTED`,
    then a count) and, once, what the section accepts."""
    unknown = {}
    for error in errors:
        if error["type"] == "extra_forbidden":
            unknown.setdefault(tuple(error["loc"][:-1]), []).append(error)
    lines = []
    for error in errors:
        section = tuple(error["loc"][:-1])
        group = unknown.get(section) if error["type"] == "extra_forbidden" else None
        if group is None or len(group) == 1:
            lines.append(_message(error, cascade))
        elif error is group[0]:
            names = (one_line(".".join(str(part) for part in e["loc"]))[:QUOTE_CHARS]
                     for e in group)
            accepted = _accepted_keys(error["loc"], cascade)
            where = ".".join(str(part) for part in section) or "the top level"
            lines.append(one_line(f"{len(group):,} unknown keys: {listed(names, ', ')}"
                                  + (f"; {where} accepts {accepted}" if accepted else "")))
    return _accepted_once(lines)


def _accepted_once(lines):
    """``lines`` with a repeated "; accepted: ..." list (the ~100 figure keys after each
    unknown requirement metric) given once, then "as above"."""
    seen, out = set(), []
    for line in lines:
        head, separator, accepted = line.partition("; accepted: ")
        out.append(f"{head}; accepted: as above" if separator and accepted in seen else line)
        seen.add(accepted)
    return out


def _is_type_error(error):
    return error["type"] == "cas_type" or error["type"].endswith("_type")


def validate(data, origin):
    """Validate raw config ``data`` into an :class:`ActuatorConfig`.

    Raises
    ------
    ConfigError, ConfigTypeError
        One message listing the problems, each with its dotted key (the first
        :data:`~cas_freq.core.exceptions.MAX_LISTED`, then how many more).
    """
    try:
        return ActuatorConfig.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors()
        lines = _messages(errors, isinstance(data, dict)
                          and data.get("velocity_loop") is not None)
        kind = ConfigTypeError if all(_is_type_error(e) for e in errors) else ConfigError
        head = f"{origin}: " if origin else ""
        raise kind(head + listed(lines)) from None


def load_variant(path=None, variant=BASE_VARIANT, overrides=(), overrides_name="--set"):
    """Load one variant of a config file.

    Parameters
    ----------
    path : str or Path, optional
        The config file; defaults to the shipped ``configs/qt_cas.yaml``.
    variant : str
        ``"base"``, or the name of an entry of the file's ``variants``.
    overrides : sequence of (str, object)
        ``(dotted key, value)`` pairs applied after the variant (the CLI's ``--set``).
    overrides_name : str
        What the errors call the overrides: ``"--set"`` (the CLI's option), or as the caller
        takes them (the Python API: ``"set="``).

    Returns
    -------
    LoadedVariant
    """
    path = Path(path) if path is not None else default_config_path()
    data = read_config_file(path)
    names = variant_names(data)
    if variant not in names:
        raise ConfigError(f"{one_line(path)}: unknown variant {shown(variant)}; the file has "
                          f"{shown(names, 200)}")
    loaded = _load(data, path, variant, overrides, overrides_name)
    # every variant of the file is checked as the file gives it (the overrides apply to the
    # selected variant only), so a typo in one is reported whichever is used
    for other in names:
        if other != variant:
            _load(data, path, other, ())
    return loaded


def _load(data, path, variant, overrides, overrides_name="--set"):
    """One variant of the raw config ``data`` of ``path``, with ``overrides`` (called
    ``overrides_name`` in errors), validated."""
    check_overrides(overrides, overrides_name)
    resolved = copy.deepcopy(data)
    shown_path = one_line(path)
    origin = shown_path
    if variant != BASE_VARIANT:
        changes = data["variants"][variant] or {}
        name = one_line(variant)[:QUOTE_CHARS]
        if not isinstance(changes, dict):
            raise ConfigTypeError(
                f"{shown_path}: variants.{name}: must be a mapping of dotted keys to values, "
                f"got {shown(changes)}"
            )
        for key, value in _flatten(changes).items():
            _apply(resolved, key, value, f"{shown_path}: variants.{name}")
        origin = f"{shown_path} (variant {shown(variant)})"
    for key, value in overrides:
        _apply(resolved, key, value, overrides_name)
    if overrides:
        if variant == BASE_VARIANT:  # --set applies per variant: say which one it failed in
            origin += f" (variant {shown(variant)})"
        origin += f" with {overrides_name} " + ", ".join(
            one_line(f"{k}={v}")[:80] for k, v in overrides)
    params = validate(resolved, origin)
    return LoadedVariant(str(path), variant, params, tuple(overrides))


def load_all_variants(path=None, overrides=(), selected=None):
    """Load the base and every variant of a config file, in file order.

    Parameters
    ----------
    path : str or Path, optional
        The config file; defaults to the shipped ``configs/qt_cas.yaml``.
    overrides : sequence of (str, object)
        ``(dotted key, value)`` pairs (``--set``) applied after the variant, to the variants in
        ``selected`` only, and validated there.
    selected : collection of str, optional
        The variants the overrides apply to (default: every variant). The others are loaded
        and validated as the file gives them, so a typo in one is reported whichever is used,
        and an override that needs a selected variant's values (``gear.backlash`` with the
        ``loaded`` variant's gear stiffness) is not checked against a variant without them.

    Returns
    -------
    list of LoadedVariant
    """
    path = Path(path) if path is not None else default_config_path()
    data = read_config_file(path)
    return [_load(data, path, name,
                  overrides if selected is None or name in selected else ())
            for name in variant_names(data)]
