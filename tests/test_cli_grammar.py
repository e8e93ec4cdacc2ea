"""One command-line grammar across the commands (issue 11): negative option values, the
CONFIG default and ``--variant NAME`` (repeatable) / ``--all-variants`` everywhere, help
texts, and what a multi-variant run prints and writes.

The figures themselves are tested with each command; here only the grammar: that the same
options mean the same thing everywhere, and that a single-variant run is unchanged.
"""

import contextlib
import io
import json

import pytest
from clirun import run_cli

from cas_freq.cli import build_parser, join_negative_values, main
from cas_freq.cli.common import load_variants


def _usage_error(argv):
    """(exit status, stderr) of a command line argparse itself refuses."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        try:
            code = main(argv)
        except SystemExit as exc:
            code = exc.code
    return code, err.getvalue()


# --- negative values as option arguments -------------------------------------------------


@pytest.mark.parametrize(("argv", "joined"), [
    (["simulate", "--step", "-5deg"], ["simulate", "--step=-5deg"]),
    (["simulate", "--step", "-0.1rad", "--json"], ["simulate", "--step=-0.1rad", "--json"]),
    (["simulate", "--st", "-.5 deg"], ["simulate", "--st=-.5 deg"]),  # abbreviation, as argparse
    (["sweep", "--set", "position_loop.Kp=2:8:3", "--step", "-10deg"],
     ["sweep", "--set", "position_loop.Kp=2:8:3", "--step=-10deg"]),
    (["sinedwell", "--amplitudes", "-1deg,2deg"], ["sinedwell", "--amplitudes=-1deg,2deg"]),
    (["analyze", "--range", "-1:1e4"], ["analyze", "--range=-1:1e4"]),
    (["sweep", "-o", "-5dir"], ["sweep", "-o=-5dir"]),
    (["fit", "f.csv", "--step", "-10deg"], ["fit", "f.csv", "--step=-10deg"]),
    # not joined: an option without a value, a value that is not a negative number, after --
    (["simulate", "--json", "-5deg"], ["simulate", "--json", "-5deg"]),
    (["simulate", "--step", "--json"], ["simulate", "--step", "--json"]),
    (["simulate", "--step", "-q"], ["simulate", "--step", "-q"]),
    (["fit", "--", "-5.csv"], ["fit", "--", "-5.csv"]),
    (["--version"], ["--version"]),
])
def test_negative_values_joined_to_their_option(argv, joined):
    assert join_negative_values(build_parser(), argv) == joined


def test_negative_step_without_equals_on_simulate():
    code, spaced, err = run_cli(["simulate", "--step", "-5deg", "--json"])
    assert code == 0, err
    assert run_cli(["simulate", "--step=-5deg", "--json"])[1] == spaced
    data = json.loads(spaced)
    assert data["step"]["amplitude_deg"] == pytest.approx(-5.0)
    code, out, err = run_cli(["simulate", "--step", "-0.1rad", "--json", "--variant", "fitted"])
    assert code == 0, err
    assert json.loads(out)["step"]["amplitude_deg"] == pytest.approx(-5.729578, rel=1e-6)


def test_negative_values_on_sweep_and_montecarlo():
    code, out, err = run_cli(["sweep", "--set", "position_loop.Kp=6,8", "--step", "-10deg",
                              "--no-fit", "--json"])
    assert code == 0, err
    assert json.loads(out)["step_deg"] == pytest.approx(-10.0)
    code, out, err = run_cli(["montecarlo", "--samples", "2", "--seed", "1", "--tolerance",
                              "motor.J=5%", "--step", "-10deg", "--json"])
    assert code == 0, err
    assert json.loads(out)["step_deg"] == pytest.approx(-10.0)


def test_negative_value_reaches_the_option_check():
    # the value now reaches --range's own check (a clear message), not argparse's
    # "expected one argument"
    code, err = _usage_error(["analyze", "--range", "-1:1e4"])
    assert code == 2 and "--range" in err and "need 0 < MIN < MAX" in err
    code, _, err = run_cli(["sweep", "--set", "position_loop.Kp=2:8:2", "--sinedwell",
                            "-0.5deg", "--frequencies", "-5:10:2"])
    assert code == 2 and "--frequencies" in err and err.count("\n") == 1


# --- help texts ----------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["montecarlo", "sweep", "report", "compare", "fit",
                                     "simulate", "analyze"])
def test_help_has_no_doubled_percent(command, capsys):
    with pytest.raises(SystemExit) as info:
        main([command, "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    assert "%%" not in text
    if command == "montecarlo":
        assert "KEY=10% (relative)" in text and "motor.Km=10%" in text


# --- variant selection ---------------------------------------------------------------------


@pytest.mark.parametrize(("argv", "variants"), [
    (["analyze"], ["base"]),
    (["analyze", "--variant", "relaxed", "--variant", "base"], ["base", "relaxed"]),
    (["sweep", "--all-variants"], ["base", "fitted", "relaxed", "loaded", "fin_encoder",
                                 "sampled"]),
    (["montecarlo", "--variant", "fitted"], ["fitted"]),
    (["simulate", "--step", "1deg", "--variant", "fitted", "--variant", "fitted"], ["fitted"]),
    (["report"], ["base", "fitted", "relaxed", "loaded", "fin_encoder",
                                 "sampled"]),
    (["report", "--all-variants"], ["base", "fitted", "relaxed", "loaded", "fin_encoder",
                                 "sampled"]),
    (["report", "--variant", "fitted"], ["fitted"]),
])
def test_variant_selection_is_the_same_everywhere(argv, variants):
    args = build_parser().parse_args(argv)
    loaded = load_variants(args, all_by_default=args.command_name == "report")
    assert [item.variant for item in loaded] == variants  # file order, each once


def test_json_is_an_array_when_the_options_ask_for_several():
    code, out, err = run_cli(["analyze", "--variant", "relaxed", "--variant", "base", "--json"])
    assert code == 0, err
    pair = json.loads(out)
    assert [item["variant"] for item in pair] == ["base", "relaxed"]
    everything = json.loads(run_cli(["analyze", "--all-variants", "--json"])[1])
    assert pair == [everything[0], everything[2]]
    # one name (even twice) prints the object alone, as before
    single = json.loads(run_cli(["analyze", "--variant", "relaxed", "--variant", "relaxed",
                                 "--json"])[1])
    assert single == everything[2]


def test_report_command_line_leaves_out_the_default_all_variants():
    from cas_freq.cli.report import _argv_tail, command_text

    for argv, text in ((["report"], "cas-freq report"),
                       (["report", "--all-variants"], "cas-freq report"),
                       (["report", "--variant", "fitted"], "cas-freq report --variant fitted")):
        assert command_text(_argv_tail(build_parser().parse_args(argv))) == text


@pytest.mark.parametrize("command", [["analyze"], ["simulate", "--step", "1deg"],
                                     ["sinedwell"], ["verify"], ["report"], ["compare"],
                                     ["sweep"], ["montecarlo"]])
def test_variant_and_all_variants_exclude_each_other(command):
    code, err = _usage_error([*command, "--variant", "base", "--all-variants"])
    assert code == 2 and "not allowed with" in err


def test_compare_variants_alias_excludes_variant():
    code, err = _usage_error(["compare", "--variants", "base,fitted", "--variant", "relaxed"])
    assert code == 2 and "not allowed with" in err


def test_unknown_variants_named_with_the_file_s():
    code, _, err = run_cli(["sweep", "--set", "position_loop.Kp=2:8:2", "--variant", "base",
                            "--variant", "nope"])
    assert code == 2 and err.count("\n") == 1
    assert "unknown variant 'nope'; the file has 'base', 'fitted', 'relaxed'" in err


@pytest.mark.parametrize(("argv", "text"), [
    (["compare", "configs/qt_cas.yaml"], "cas-freq compare configs/qt_cas.yaml"),
    (["compare", "configs/qt_cas.yaml", "--all-variants"],
     "cas-freq compare configs/qt_cas.yaml"),
    (["compare"], "cas-freq compare"),
    (["compare", "--variants", "base, fitted"], "cas-freq compare --variants base,fitted"),
    (["compare", "--variant", "base", "--variant", "fitted", "--set", "motor.J=6e-7"],
     "cas-freq compare --variant base --variant fitted --set motor.J=6e-7"),
])
def test_compare_command_line_shown_in_the_report(argv, text):
    from cas_freq.cli.compare import command_text, parse_variant_list

    args = build_parser().parse_args(argv)
    names = (parse_variant_list(args.variant_list) if args.variant_list is not None
             else args.variants)
    assert command_text(args, names) == text


def test_compare_without_config_uses_the_shipped_one(tmp_path):
    target = tmp_path / "cmp"
    code, out, err = run_cli(["compare", "--variant", "base", "--variant", "relaxed", "-q",
                              "-o", str(target), "--amplitudes", "0.5deg,10deg",
                              "--frequencies", "600,1200", "--pade-order", "6"])
    assert code == 0, err
    assert out.strip() == str(target / "index.html")
    results = json.loads((target / "results.json").read_text())
    assert results["labels"] == ["qt_cas/base", "qt_cas/relaxed"]


# --- several variants: simulate's CSV files are said -------------------------------------


def test_simulate_csv_per_variant_is_said_on_stderr(tmp_path):
    target = tmp_path / "out.csv"
    code, _, err = run_cli(["simulate", "--step", "1deg", "--variant", "base", "--variant",
                            "fitted", "--csv", str(target), "--json"])
    assert code == 0, err
    written = [tmp_path / "out.base.csv", tmp_path / "out.fitted.csv"]
    assert all(path.is_file() for path in written) and not target.exists()
    assert [line for line in err.splitlines() if line.startswith("wrote")] == [
        f"wrote {path}" for path in written]
    code, _, err = run_cli(["simulate", "--step", "1deg", "--all-variants", "--csv",
                            str(target), "--json", "-q"])
    assert code == 0 and err == ""
    # one variant: the file named, nothing said
    code, _, err = run_cli(["simulate", "--step", "1deg", "--csv", str(target), "--json"])
    assert code == 0 and target.is_file() and "wrote" not in err
