"""Issue 28: the docs site's generated references (docs/_hooks/reference.py) list every config
key with the unit and range the loader checks, and every command and option of the CLI."""

import argparse
import importlib.util
import re
from pathlib import Path

import pytest

from cas_freq.cli import build_parser
from cas_freq.filters_config import FILTER_PARAMETERS
from cas_freq.parameter_record import Parameter
from cas_freq.parameters import CASCADE_PARAMETERS, PARAMETERS

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
    from cas_freq.parameters import LINEAR_ONLY

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
