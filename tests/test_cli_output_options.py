"""An empty output path is bad input, for every option that names an output (issue 24).

``tune -o ""`` exited 0 and wrote nothing: the empty word read as "no -o". Every output option
(``-o``, ``--csv``, ``--junit``, ``--report``, ``--compare``) now has the argument type
:func:`cas_freq.cli.common.output_path`, which refuses an empty or blank path at parse time:
exit 2, one line naming the option.
"""

import argparse

import pytest
from clirun import run_cli

from cas_freq.cli import build_parser
from cas_freq.cli.common import output_path

#: The option strings that name an output file or folder.
OUTPUT_OPTIONS = {"-o", "--csv", "--junit", "--report", "--compare"}


def _output_actions():
    """(command words, option string) of every output option of every (sub-)command."""
    found = []

    def walk(parser, words):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    walk(sub, [*words, name])
            elif OUTPUT_OPTIONS & set(action.option_strings):
                found.append((words, action))

    walk(build_parser(), [])
    return found


def test_every_output_option_has_the_output_path_type():
    actions = _output_actions()
    # report, compare, sweep (2), montecarlo, simulate, fit, verify, tune (3), epos4 (2)
    assert len(actions) >= 13
    for words, action in actions:
        assert action.type is output_path, (words, action.option_strings)


@pytest.mark.parametrize("value", ["", " "])
def test_an_empty_output_is_refused_by_every_command(value):
    for words, action in _output_actions():
        with pytest.raises(SystemExit) as info:
            build_parser().parse_args([*words, action.option_strings[0], value])
        assert info.value.code == 2, (words, action.option_strings)


def test_tune_with_an_empty_output_exits_2_naming_the_option(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli(["tune", "-o", ""])  # argparse's usage error: exit 2
    assert code == 2 and out == ""
    assert err.endswith("error: argument -o/--output: expected a file or folder name, got ''\n")
    assert list(tmp_path.iterdir()) == []
