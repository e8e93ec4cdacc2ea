"""Issue 28: the docs site's generated references (docs/_hooks/reference.py) list every config
key with the unit and range the loader checks, and every command and option of the CLI."""

import argparse
import importlib.util
import re
from pathlib import Path

import pytest

from cas_freq.cli import build_parser
from cas_freq.core.filters_config import FILTER_PARAMETERS
from cas_freq.core.parameter_record import Parameter
from cas_freq.core.parameters import CASCADE_PARAMETERS, PARAMETERS

ROOT = Path(__file__).resolve().parents[1]
_SPEC = importlib.util.spec_from_file_location("docs_reference", ROOT / "docs/_hooks/reference.py")
reference = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(reference)


@pytest.fixture(scope="module")
def config_page():
    return reference.config_reference()


def _row(page, key, after=None):
    """The table row of ``key`` (after the heading ``after``, for a key in two sections)."""
    text = page.split(f"\n## {after}\n", 1)[1] if after else page
    rows = [line for line in text.splitlines() if line.startswith(f"| `{key}` |")]
    assert rows, f"{key} is not in the config reference"
    cells = re.split(r"(?<!\\)\|", rows[0].strip().strip("|"))
    return [cell.strip().replace("\\|", "|") for cell in cells]


@pytest.mark.parametrize("key", list(PARAMETERS))
def test_every_numeric_key_is_listed_with_its_unit_and_range(config_page, key):
    record = PARAMETERS[key]
    # a key of both position loops: the PID-on-PI's row; omega_max: the cascade's (PID-on-PI
    # refuses it)
    # a linear output's keys (refused in the rotary sections): their own section's row
    from cas_freq.core.parameters import LINEAR_ONLY

    after = ("CascadePositionLoop" if key == "position_loop.omega_max" else
             "PositionLoop" if key.startswith("position_loop.") else
             ("LinearGear" if key.startswith("gear.") else "LinearLoad") if key in LINEAR_ONLY
             else None)
    _, unit, accepted, _, meaning = _row(config_page, key, after)
    assert unit.startswith(record.unit if record.unit != "dimensionless" else "—"), unit
    assert accepted == reference.accepted_range(record)
    assert meaning and meaning in record.meaning


@pytest.mark.parametrize("key", list(CASCADE_PARAMETERS))
def test_the_cascade_s_position_gains_are_listed_in_its_units(config_page, key):
    _, unit, accepted, _, _ = _row(config_page, key, after="CascadePositionLoop")
    assert unit == (CASCADE_PARAMETERS[key].unit.replace("dimensionless", "—"))
    assert accepted == reference.accepted_range(CASCADE_PARAMETERS[key])


def test_the_filters_numbers_and_refused_keys_are_listed(config_page):
    for name, record in FILTER_PARAMETERS.items():
        assert _row(config_page, f"filters[].{name}")[2] == reference.accepted_range(record)
    assert _row(config_page, "position_loop.Kd", after="CascadePositionLoop")[2] == "refused"
    assert _row(config_page, "simulation.controllers")[2] == "`continuous`, `sampled`"
    assert _row(config_page, "sampling.method")[2:4] == ["`backward`, `tustin`", "`backward`"]


def test_the_range_is_read_from_the_bounds():
    # hand-made records: each way a bound is written
    def record(lower, strict, upper, smallest=None):
        return Parameter("k", None, "s", lower, strict, upper, "m [s]", smallest)

    assert reference.accepted_range(record(0.0, False, 1e9, 1e-9)) == "0 or 1e-9..1e9"
    assert reference.accepted_range(record(-1e9, False, 1e9, 1e-12)) == "0 or ±1e-12..1e9"
    assert reference.accepted_range(record(0.0, True, 100.0)) == "> 0..100"
    assert reference.accepted_range(record(-300.0, False, None)) == "≥ -300"
    assert reference.accepted_range(record(1e-6, False, 1e6)) == "1e-6..1e6"


def _parsers(parser, path=("cas-freq",)):
    yield " ".join(path), parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _parsers(sub, (*path, name))


def test_every_command_and_option_is_in_the_cli_reference():
    page = reference.cli_reference()
    sections = re.split(r"\n#+ ", page)
    for path, parser in _parsers(build_parser()):
        if path != "cas-freq":
            (section,) = [s for s in sections if s.startswith(f"{path}\n")]
        else:
            section = sections[0]
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            name = action.option_strings[-1] if action.option_strings else None
            shown = f"`{name}`" if name else f"`{action.metavar or action.dest}`"
            assert shown in section, f"{path}: {shown}"
            if action.help:
                assert " ".join(action.help.split()[:4]).split("%")[0] in section, (path, shown)


# ---- the site as a reader sees it ------------------------------------------------------------


def _rendered_modules():
    """The modules docs/reference/api.md has mkdocstrings render (``::: module`` lines)."""
    page = (ROOT / "docs/reference/api.md").read_text(encoding="utf-8")
    return re.findall(r"^::: (\S+)", page, re.MULTILINE)


def _docstrings(module):
    """(name, docstring) of a module, its public classes and functions and their methods."""
    import inspect

    yield module.__name__, module.__doc__
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__:
            continue
        if inspect.isclass(obj) or inspect.isfunction(obj):
            yield f"{module.__name__}.{name}", obj.__doc__
        if inspect.isclass(obj):
            for member, value in vars(obj).items():
                if not member.startswith("_") and (inspect.isfunction(value)
                                                   or isinstance(value, property)):
                    yield f"{module.__name__}.{name}.{member}", value.__doc__


def test_doctest_lines_of_the_api_reference_sit_in_examples_sections():
    """A ``>>>`` line outside a numpydoc ``Examples`` section is text to mkdocstrings' numpy
    parser, and Markdown makes the lines one run-on nested quote (the ``cas_freq.api`` module's
    example lost its code block); inside ``Examples`` they render as code."""
    import importlib
    import inspect

    modules = _rendered_modules()
    assert "cas_freq.api" in modules
    misplaced = []
    for module in modules:
        for name, doc in _docstrings(importlib.import_module(module)):
            lines = inspect.cleandoc(doc or "").splitlines()
            section = None
            for k, line in enumerate(lines):
                if k + 1 < len(lines) and line.strip() and re.fullmatch(r"-{3,}",
                                                                         lines[k + 1].strip()):
                    section = line.strip()
                if line.lstrip().startswith(">>>") and section != "Examples":
                    misplaced.append(f"{name} (in {section or 'its text'}): {line.strip()}")
                    break
    assert not misplaced, misplaced


def _mkdocs_config():
    """mkdocs.yml read as MkDocs reads it (PyYAML's full Loader: ``!!python/...`` tags run)."""
    import yaml

    with open(ROOT / "mkdocs.yml", encoding="utf-8") as handle:
        return yaml.load(handle, Loader=yaml.Loader)  # noqa: S506 (our own file, as MkDocs)


def test_mkdocs_config_silences_only_the_gallery_s_deprecation_warning():
    """MkDocs shows every DeprecationWarning (``simplefilter("module")``, with a stack) from
    before it reads mkdocs.yml; the file's filter drops mkdocs-gallery's import of
    ``mkdocs.utils.warning_filter`` and nothing else."""
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("module", DeprecationWarning)  # as mkdocs' CLI sets it
        _mkdocs_config()
        # the message MkDocs 1.6 gives (mkdocs/utils/__init__.py), and another one
        warnings.warn("warning_filter doesn't do anything since MkDocs 1.2 and will be removed "
                      "soon.", DeprecationWarning, stacklevel=1)
        warnings.warn("something else is deprecated", DeprecationWarning, stacklevel=1)
    assert [str(w.message) for w in caught] == ["something else is deprecated"]


def test_a_key_in_a_table_s_first_column_stays_whole():
    """Material lets inline code break anywhere: the config reference's narrow key column
    showed "velocity_loo p". The site's stylesheet, listed in mkdocs.yml, keeps the first
    column's code on one line."""
    config = _mkdocs_config()
    assert "stylesheets/extra.css" in config["extra_css"]
    css = (ROOT / "docs/stylesheets/extra.css").read_text(encoding="utf-8")
    rule = re.search(r"\.md-typeset td:first-child > code\s*\{([^}]*)\}", css)
    assert rule and "white-space: nowrap" in rule.group(1)
    # the config reference's keys are that column's code
    assert "| `velocity_loop.Kp` |" in reference.config_reference()
