"""The docs site's generated pages, written at build time so that they cannot drift.

- ``reference/config.md``: every key of the config, from the config schema
  (:mod:`cas_freq.config.schema`) walked field by field, the numeric keys' unit, accepted range
  and meaning read from the parameter tables (:data:`cas_freq.core.parameters.PARAMETERS`,
  :data:`cas_freq.core.parameters.CASCADE_PARAMETERS`, :data:`cas_freq.core.filters_config.
  FILTER_PARAMETERS`), the very records that convert and check a config's values;
- ``reference/cli.md``: every command and option of ``cas-freq`` with its help, from the
  argument parser (:func:`cas_freq.cli.build_parser`);
- ``readme.md``: the README, its links into ``docs/`` made relative to the site.

MkDocs runs this file as a hook (``hooks:`` in mkdocs.yml): :func:`on_files` adds the pages.
The generators are plain functions, which tests/test_docs_reference.py calls without MkDocs.
"""

import argparse
import inspect
import re
import types
import typing
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: Generated page path (in the site) -> generator.
PAGES = {}


def _page(path):
    def register(function):
        PAGES[path] = function
        return function

    return register


# --- the config reference -------------------------------------------------------------------


def accepted_range(record):
    """The values a numeric parameter accepts, from its bounds (``0 or 1e-09..1e+09``)."""
    lower, upper, smallest = record.lower, record.upper, record.smallest
    if smallest is not None and lower is not None and lower <= 0:
        sign = "±" if lower < 0 else ""
        top = _number(upper) if upper is not None else "∞"
        return f"0 or {sign}{_number(smallest)}..{top}"
    if lower is None and upper is None:
        return "any finite value"
    if upper is None:
        return f"{'>' if record.strict else '≥'} {_number(lower)}"
    if lower is None:
        return f"≤ {_number(upper)}"
    return f"{'> ' if record.strict else ''}{_number(lower)}..{_number(upper)}"


def _numeric_record(key, cascade):
    """The parameter record of dotted ``key`` (``filters[].frequency`` for a filter's), or
    None for a key that is not numeric."""
    from cas_freq.core.filters_config import FILTER_PARAMETERS
    from cas_freq.core.parameters import CASCADE_PARAMETERS, PARAMETERS

    if key.startswith("filters[]."):
        return FILTER_PARAMETERS.get(key.rpartition(".")[2])
    if cascade and key in CASCADE_PARAMETERS:
        return CASCADE_PARAMETERS[key]
    return PARAMETERS.get(key)


def _models_in(annotation):
    """The pydantic models an annotation holds (a section, an optional one, a union of two, a
    tuple of items), and whether it is a list of them."""
    from pydantic import BaseModel

    origin = typing.get_origin(annotation)
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation], False
    if origin is tuple:
        models, _ = _models_in(typing.get_args(annotation)[0])
        return models, True
    if origin in (typing.Union, types.UnionType):
        models = [m for arg in typing.get_args(annotation) for m in _models_in(arg)[0]]
        return models, False
    return [], False


def _kind(annotation):
    """What a non-numeric, non-section value is, in words."""
    origin = typing.get_origin(annotation)
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    if origin is typing.Literal:
        return ", ".join(f"`{a}`" for a in args)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_kind(a) for a in args)
    if origin is typing.Annotated:
        return _kind(args[0])
    if origin is dict:
        return "mapping"
    if origin is tuple:
        return "list"
    if annotation is typing.Any:
        return "any"
    return getattr(annotation, "__name__", str(annotation))


def _default(field):
    from pydantic import BaseModel
    from pydantic_core import PydanticUndefined

    if field.is_required():
        return "required"
    default = field.default
    if default is PydanticUndefined:
        return "derived"
    if default is None or default in ((), {}, ""):
        return "none"
    if isinstance(default, BaseModel):
        return "the section's defaults"
    return f"`{_number(default)}`" if isinstance(default, float) else f"`{default}`"


def _number(value):
    """A bound as the tables write it: ``1e-09`` as ``1e-9``, ``1e+06`` as ``1e6``."""
    return re.sub(r"e([+-])0*(\d)", lambda m: f"e{m[1].replace('+', '')}{m[2]}", f"{value:g}")


def _docstring(model):
    """A section's docstring: its text as Markdown paragraphs (up to a numpydoc section) and
    the meaning of each key its ``Attributes`` section describes."""
    doc = inspect.cleandoc(model.__doc__ or "")
    body, _, attributes = doc.partition("\nAttributes\n----------\n")
    text = "\n\n".join(" ".join(line.strip() for line in p.splitlines())
                       for p in body.strip().split("\n\n"))
    meanings, names = {}, []
    for line in attributes.splitlines():
        if line and not line[0].isspace():
            if re.fullmatch(r"-+", line.strip()):  # the next numpydoc section
                break
            names = [n.strip() for n in line.split(" : ", 1)[0].split(",")]
        elif line.strip():
            for name in names:
                meanings[name] = f"{meanings.get(name, '')} {line.strip()}".strip()
    return _code(text), {name: _code(m) for name, m in meanings.items()}


def _code(text):
    """Sphinx roles and reST literals as Markdown code."""
    return re.sub(r":\w+:`~?([^`]+)`", r"`\1`", text).replace("``", "`")


def _rows(model, prefix, cascade, sections):
    """Table rows of ``model``'s keys under ``prefix``; its sub-sections go to ``sections``."""
    meanings = _docstring(model)[1]
    rows = []
    for name, field in model.model_fields.items():
        key = f"{prefix}{name}"
        models, is_list = _models_in(field.annotation)
        extra = field.json_schema_extra if isinstance(field.json_schema_extra, dict) else {}
        record = _numeric_record(key, cascade)
        if models:
            inner = f"{key}[]." if is_list else f"{key}."
            for sub in models:
                sections.append((inner, sub, cascade or sub.__name__.startswith("Cascade")))
            where = ", ".join(f"[{m.__name__}](#{m.__name__.lower()})" for m in models)
            rows.append((f"`{key}`", "—", f"{'a list of ' if is_list else ''}{where}",
                         _default(field), "a section"))
        elif "refused" in extra:
            rows.append((f"`{key}`", "—", "refused", "—", extra["refused"]))
        elif record is not None:
            meaning = re.sub(r"\s*\[[^\]]*\]$", "", record.meaning)  # the unit: own column
            unit = record.unit if record.unit != "dimensionless" else "—"
            if record.datasheet_unit:
                unit += f" (a unit required, e.g. {record.datasheet_unit})"
            rows.append((f"`{key}`", unit, accepted_range(record), _default(field), meaning))
        else:
            rows.append((f"`{key}`", "—", _kind(field.annotation), _default(field),
                         meanings.get(name, "")))
    return rows


@_page("reference/config.md")
def config_reference():
    """The config reference page (Markdown): every key of every section."""
    from cas_freq.config.schema import ActuatorConfig

    out = ["# Config reference", "",
           "Generated when the docs are built from the config schema "
           "(`cas_freq/config/schema.py`) and the parameter tables that convert and check "
           "every value (`cas_freq/core/parameters.py`, `cas_freq/core/filters_config.py`): "
           "what is "
           "here is what the loader accepts. [Config format](../config.md) explains the file "
           "(units, value strings, variants, requirements). Numbers are SI, or strings with "
           "a unit (`\"0.4 ms\"`); \"0 or a..b\" means 0, or a magnitude within a..b; a "
           "filter's number is the dotted key `filters.<i>.<name>` for `--set` and studies.", ""]
    sections = [("", ActuatorConfig, False)]
    seen = set()
    while sections:
        prefix, model, cascade = sections.pop(0)
        if (prefix, model) in seen:
            continue
        seen.add((prefix, model))
        title = f"`{prefix.rstrip('.')}`" if prefix else "The file's top level"
        out += [f"## {model.__name__}", "", f"{title}: {_docstring(model)[0]}", "",
                "| key | unit | accepted | default | meaning |", "| --- | --- | --- | --- | --- |"]
        found = []
        out += ["| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |"
                for row in _rows(model, prefix, cascade, found)]
        out.append("")
        sections.extend(found)
    return "\n".join(out)


# --- the CLI reference ----------------------------------------------------------------------


def _subcommands(parser):
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            helps = {a.dest: a.help for a in action._choices_actions}
            return [(name, sub, helps.get(name)) for name, sub in action.choices.items()]
    return []


def _option_lines(parser):
    formatter = parser._get_formatter()
    lines = []
    for action in parser._actions:
        if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        if action.option_strings:
            name = ", ".join(f"`{o}`" for o in action.option_strings)
            if action.nargs != 0:
                name += f" `{formatter._format_args(action, action.dest.upper())}`"
        else:
            name = f"`{formatter._metavar_formatter(action, action.dest)(1)[0]}`"
        help_text = formatter._expand_help(action) if action.help else ""
        if action.choices and not isinstance(action.choices, dict):
            help_text += f" (one of: {', '.join(map(str, action.choices))})"
        lines.append(f"- {name}: {' '.join(help_text.split())}")
    return lines


def _command_section(parser, path, help_text, level):
    usage = " ".join(parser.format_usage().split())
    out = [f"{'#' * level} {path}", ""]
    if help_text:
        out += [" ".join(help_text.split()), ""]
    if parser.description:
        out += [" ".join(parser.description.split()), ""]
    out += ["```text", usage.removeprefix("usage: "), "```", "", *_option_lines(parser), ""]
    for name, sub, sub_help in _subcommands(parser):
        out += _command_section(sub, f"{path} {name}", sub_help, level + 1)
    return out


@_page("reference/cli.md")
def cli_reference():
    """The CLI reference page (Markdown): every command and option with its help."""
    from cas_freq.cli import build_parser

    parser = build_parser()
    out = ["# CLI reference", "",
           "Generated when the docs are built from `cas-freq`'s argument parser "
           "(`cas_freq.cli.build_parser`): every command and option with its help, as "
           "`cas-freq COMMAND --help` prints them. [The command-line interface](../cli.md) "
           "explains them with examples. `python -m cas_freq` is the same as `cas-freq`.", "",
           "```text", " ".join(parser.format_usage().split()).removeprefix("usage: "), "```",
           "", *_option_lines(parser), ""]
    for name, sub, help_text in _subcommands(parser):
        out += _command_section(sub, f"cas-freq {name}", help_text, 2)
    return "\n".join(out)


# --- the README on the site -----------------------------------------------------------------


@_page("readme.md")
def readme():
    """The README as a site page: links into docs/ made relative to the site's root, links to
    other files of the repository written as plain text."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    text = re.sub(r"\]\(docs/", "](", text)

    def outside(match):
        label, target = match.group(1), match.group(2)
        if re.match(r"[a-z][a-z0-9+.-]*:|#", target) or (ROOT / "docs" / target).exists():
            return match.group(0)
        return f"{label} (`{target}` in the repository)"

    return re.sub(r"\[([^\]]*)\]\(([^)\s]+)\)", outside, text)


# --- MkDocs hooks ---------------------------------------------------------------------------


def on_files(files, config):
    """Add the generated pages to the site."""
    from mkdocs.structure.files import File

    for path, generate in PAGES.items():
        files.append(File.generated(config, path, content=generate()))
    return files


def on_page_markdown(markdown, page, config, files):
    """docs/index.md's link to the README (outside docs/) points at its page on the site, and
    a run of citation tags (``[B] [C]``, docs/epos4.md) stays text: Markdown would read two
    bracketed words in a row as a reference link ``[B][C]``."""
    markdown = re.sub(r"(\[[A-Z]{1,4}\]) \[", r"\1 \\[", markdown)
    return markdown.replace("](../README.md)", "](readme.md)")
