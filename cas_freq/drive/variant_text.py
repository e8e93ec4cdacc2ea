"""A variant inserted into a config file's text, every other line kept as it was.

Configs are hand-written YAML with comments that cite their sources (configs/qt_cas.yaml), and
PyYAML drops comments when it writes. So a new variant is written as text: the lines of the
variant are inserted at the end of the file's block-style ``variants:`` mapping (or a
``variants:`` section is appended when the file has none), and nothing else in the file
changes. The caller loads the result with the config loader before writing it, so a text the
loader would read differently is never written.
"""

import re

from cas_freq.config import load_all_variants
from cas_freq.config.loader import MAX_FILE_BYTES, _flatten, read_config_file
from cas_freq.config.schema import VARIANT_NAME
from cas_freq.core.exceptions import CasFreqError, ConfigError
from cas_freq.core.fileio import read_input
from cas_freq.core.parameters import base_values, unit_of

__all__ = ["NAME_PATTERN", "config_with_variant", "insert_variant", "si_text",
           "variant_entries"]

#: Variant names this writer accepts: those the loader accepts (a plain YAML key, no quoting
#: needed, safe in a file name).
NAME_PATTERN = VARIANT_NAME

_TOP_VARIANTS = re.compile(r"variants\s*:(?P<rest>.*)")


def _indent(line):
    return len(line) - len(line.lstrip(" "))


def _is_content(line):
    """True for a line that holds YAML (not blank, not only a comment)."""
    stripped = line.strip()
    return bool(stripped) and not stripped.startswith("#")


def _block(name, entries, comment, indent, step=2):
    """The lines of variant ``name`` at ``indent`` spaces, its keys at ``indent + step``."""
    head = " " * indent + f"{name}:"
    lines = [f"{head}  # {comment}" if comment else head]
    width = max((len(key) + 2 + len(value) for key, value, _ in entries), default=0)
    for key, value, note in entries:
        body = f"{key}: {value}"
        lines.append(" " * (indent + step) + (f"{body.ljust(width)}  # {note}" if note else body))
    return lines


def insert_variant(text, name, entries, comment="", force=False):
    """``text`` (a config file) with variant ``name`` holding ``entries`` added.

    Parameters
    ----------
    text : str
        The config file's text.
    name : str
        The variant's name, matching :data:`NAME_PATTERN`.
    entries : sequence of (str, str, str)
        ``(dotted key, value text, comment)`` lines of the variant (comment may be empty).
    comment : str
        Comment on the variant's own line.
    force : bool
        Replace a variant of that name (its lines, up to the next variant or the end of the
        ``variants`` block) instead of refusing.

    Returns
    -------
    str
        The new text: the file's lines unchanged, the variant's lines inserted after the last
        line of the ``variants`` block (or a ``variants:`` section appended at the end).

    Raises
    ------
    ConfigError
        For a name that is not a plain key, a variant that exists without ``force``, or a
        ``variants`` section not written as a block mapping (``variants: {a: ...}``), which
        cannot be extended without rewriting it.
    """
    if not NAME_PATTERN.fullmatch(name or ""):
        raise ConfigError(f"--variant {name!r}: a new variant's name is a letter or _ followed "
                          "by letters, digits, _ or - (at most 64 characters)")
    if name == "base":
        raise ConfigError("--variant 'base': base is the file without a variant; name the new "
                          "variant otherwise")
    lines = text.splitlines()
    newline = "\r\n" if "\r\n" in text else "\n"
    start = next((i for i, line in enumerate(lines)
                  if _TOP_VARIANTS.fullmatch(line.rstrip())), None)
    if start is None:
        tail = ["", "variants:", *_block(name, entries, comment, 2)]
        while lines and not lines[-1].strip():
            lines.pop()
        return newline.join(lines + tail) + newline

    rest = _TOP_VARIANTS.fullmatch(lines[start].rstrip()).group("rest").strip()
    if rest and not rest.startswith("#"):
        if re.fullmatch(r"(\{\s*\}|null|~)\s*(#.*)?", rest):
            lines[start] = "variants:"
        else:
            raise ConfigError(f"line {start + 1}: 'variants: {rest[:40]}' is a flow-style "
                              "mapping; write the variants as a block (one 'name:' per line) "
                              "so a variant can be added without rewriting the others")
    # the block: every following line that is indented, blank, or an indented comment
    end = start + 1  # one past the last content line of the block
    entry_indent = key_indent = None
    for i in range(start + 1, len(lines)):
        line = lines[i]
        if not line.strip():
            continue
        if _indent(line) == 0:
            break  # a top-level key, or a comment at column 0 that introduces the next section
        if _is_content(line):
            if entry_indent is None:
                entry_indent = _indent(line)
            elif key_indent is None and _indent(line) > entry_indent:
                key_indent = _indent(line)
        end = i + 1
    indent = entry_indent or 2
    step = key_indent - indent if key_indent is not None else 2

    # an existing variant of that name
    pattern = re.compile(rf"{re.escape(name)}\s*:(\s.*)?")
    for i in range(start + 1, end):
        line = lines[i]
        if _is_content(line) and _indent(line) == indent and pattern.fullmatch(line.strip()):
            if not force:
                raise ConfigError(f"variant {name!r} exists (line {i + 1}); choose another "
                                  "--variant name or give --force to replace it")
            stop = i + 1
            for j in range(i + 1, end):
                if _is_content(lines[j]) and _indent(lines[j]) <= indent:
                    break
                stop = j + 1
            # keep a trailing comment or blank line that belongs to the next variant
            while stop > i + 1 and not _is_content(lines[stop - 1]) and (
                    not lines[stop - 1].strip() or _indent(lines[stop - 1]) <= indent):
                stop -= 1
            return newline.join(lines[:i] + _block(name, entries, comment, indent, step)
                                + lines[stop:]) + newline
    new = lines[:end] + _block(name, entries, comment, indent, step) + lines[end:]
    return newline.join(new) + newline


def _scalar(value):
    """A YAML scalar's text that reads back as ``value``."""
    import yaml

    text = yaml.safe_dump(value, default_flow_style=True, width=1000).strip()
    return text.removesuffix("...").strip()


def si_text(key, value, config=None):
    """``'0.0075 N*m/A'``: a value [SI] with its key's unit (in ``config``'s architecture: a
    cascade's ``position_loop.Kp`` is in 1/s; a filter's number in its own unit), 6
    significant digits."""
    unit = unit_of(key, config)
    if unit.startswith("1/"):  # written "s^-1", as the shipped configs write it ("1/s" reads too)
        base, _, power = unit[2:].partition("^")
        unit = f"{base}^-{power or 1}"
    return f"{value:.6g}" if unit == "dimensionless" else f"{value:.6g} {unit}"


def variant_entries(loaded, changed):
    """(key, value text, comment) lines of a new variant: ``loaded``'s own entries as its file
    writes them, its ``--set`` overrides, then ``changed`` (key -> (value text, comment)),
    which replace any of those."""
    entries = {}
    if loaded.variant != "base":
        data = read_config_file(loaded.source)
        for key, value in _flatten(data["variants"][loaded.variant] or {}).items():
            entries[key] = (_scalar(value), f"variant {loaded.variant}")
    for key, value in loaded.overrides:
        entries[key] = (_scalar(value), "--set")
    for key, item in changed.items():
        entries.pop(key, None)
        entries[key] = item
    return [(key, text, note) for key, (text, note) in entries.items()]


def config_with_variant(config, name, entries, comment, expected, what, force=False,
                        tolerance=1e-12):
    """Config file ``config`` with variant ``name`` added, loaded back and checked.

    The variant is inserted (:func:`insert_variant`), the result is loaded with the config
    loader as every command will load it, and each key of ``expected`` must load as its
    value; nothing is written.

    Parameters
    ----------
    config : str or Path
        The config file (it must load as it is).
    name, entries, comment, force
        As :func:`insert_variant`.
    expected : dict of str to float
        Dotted key -> the value [SI] the variant must load.
    what : str
        What the values are, for messages (``"the imported values"``).
    tolerance : float
        Largest relative difference between a loaded and an expected value.

    Returns
    -------
    (str, cas_freq.config.LoadedVariant)
        The new text, and the new variant as the loader read it (from a temporary copy).

    Raises
    ------
    ConfigError
        Naming the file and the variant, for a variant that exists (without ``force``), a text
        that does not load, or a value that loads otherwise.
    """
    import tempfile
    from pathlib import Path

    config = Path(config)
    load_all_variants(config)  # the config must load as it is before it is extended
    if name in (read_config_file(config).get("variants") or {}) and not force:
        raise ConfigError(f"{config}: variant {name!r} exists; choose another name or give "
                          "--force to replace it")
    text = read_input(config, "config file", MAX_FILE_BYTES)
    try:
        new_text = insert_variant(text, name, entries, comment, force=force)
    except ConfigError as exc:
        raise ConfigError(f"{config}: {exc}") from None
    with tempfile.TemporaryDirectory(prefix="cas_freq_variant_") as folder:
        trial = Path(folder) / config.name
        trial.write_text(new_text, encoding="utf-8")
        try:
            loaded = {item.variant: item for item in load_all_variants(trial)}
        except CasFreqError as exc:
            message = str(exc).replace(str(trial), f"{config} with variant {name!r}")
            raise ConfigError(f"{what} do not make a valid variant: {message}") from None
    if name not in loaded:
        raise ConfigError(f"{config}: the variant {name!r} was written but does not load as a "
                          "variant; is 'variants' written as a block mapping?")
    got = base_values(loaded[name].params)
    for key, value in expected.items():
        if abs(got[key] - value) > tolerance * abs(value):
            raise ConfigError(f"{config}: variant {name!r} loads {key} = {got[key]!r}, not "
                              f"{value!r} ({what}); the variants block was not read as "
                              "expected")
    return new_text, loaded[name]
