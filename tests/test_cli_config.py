"""The CLI's config handling a user hits by accident (issue 24): ``--set`` on the selected
variants only, the shipped config said when CONFIG is omitted, bad input from the API caught
as ``ValueError``."""

import math
from pathlib import Path

import pytest
from clirun import SHIPPED_NOTE, run_cli

import cas_freq as cf
import cas_freq.cli.analyze as analyze_command
from cas_freq.cli import main
from cas_freq.config import default_config_path, load_variant
from cas_freq.core.exceptions import (
    CasFreqError,
    ConfigError,
    ConfigTypeError,
    ModelError,
)

RECORDING = Path(__file__).resolve().parents[1] / "examples" / "recordings" / "step_run1.csv"


# --- --set applies to the selected variants and is validated there -------------------------------


def test_the_readmes_backlash_override_on_the_loaded_variant_runs():
    # docs/cli.md: --set "gear.backlash=0.1 deg" with --variant loaded. base has no gear stiffness,
    # so the override used to be refused there although base was not selected (exit 2).
    code, out, err = run_cli(["analyze", "--variant", "loaded", "--set", "gear.backlash=0.1 deg",
                              "--json"])
    assert code == 0, err
    loaded = load_variant(None, "loaded", [("gear.backlash", "0.1 deg")])
    assert loaded.params.gear.backlash == pytest.approx(math.radians(0.1), rel=1e-12)


def test_an_override_is_still_validated_on_the_selected_variant():
    code, _, err = run_cli(["analyze", "--set", "gear.backlash=0.1 deg"])  # base: no stiffness
    assert code == 2 and err.count("\n") == 1
    assert "gear.backlash" in err and "gear.stiffness" in err


def test_variants_not_selected_are_validated_as_the_file_gives_them(shipped_raw, write_config):
    shipped_raw["variants"]["typo"] = {"motor.R": -1}
    path = write_config(shipped_raw)
    code, _, err = run_cli(["analyze", str(path), "--variant", "fitted",
                            "--set", "position_loop.Kp=5"])
    assert code == 2 and "variant 'typo'" in err and "motor.R" in err
    assert "--set" not in err  # the override is not applied there


# --- CONFIG omitted: the command says which config it used ---------------------------------------


@pytest.mark.parametrize("argv", [
    ["analyze"],
    ["verify"],
    ["fit", "--data", str(RECORDING)],  # a user's recording compared with the QT-CAS
])
def test_the_shipped_config_is_said_when_config_is_omitted(argv):
    code, _, err = run_cli(argv)
    assert code in (0, 1), err
    assert err.endswith(SHIPPED_NOTE) and err.count(SHIPPED_NOTE) == 1
    assert str(default_config_path()) in SHIPPED_NOTE


def test_no_note_with_a_config_or_with_quiet():
    code, _, err = run_cli(["analyze", str(default_config_path())])
    assert code == 0 and err == ""
    code, _, err = run_cli(["analyze", "-q"])
    assert code == 0 and err == ""


def test_a_bad_input_error_stays_one_line():
    code, _, err = run_cli(["simulate", "--step", "200deg"])
    assert code == 2 and err.count("\n") == 1 and "--step" in err


# --- cas_freq's errors are ValueError / TypeError ----------------------------------------------


def test_every_error_is_a_value_error_or_a_type_error():
    assert issubclass(CasFreqError, ValueError)
    for kind in (ConfigError, ModelError):
        assert issubclass(kind, CasFreqError) and issubclass(kind, ValueError)
    assert issubclass(ConfigTypeError, CasFreqError) and issubclass(ConfigTypeError, TypeError)


def test_bad_input_from_the_api_is_caught_as_value_error():
    actuator = cf.load()
    with pytest.raises(ValueError, match=r"step: must be non-zero and within ±90 deg"):
        actuator.simulate(step="100 deg")


def test_the_cli_maps_only_cas_freq_errors_to_exit_2(monkeypatch, capsys):
    # bad input (a CasFreqError, now also a ValueError) exits 2 with one line; any other
    # ValueError is a bug and is not passed off as bad input
    def bad_input(args):
        raise CasFreqError("bad input")

    def bug(args):
        raise ValueError("a bug")

    monkeypatch.setattr(analyze_command, "run", bad_input)
    assert main(["analyze"]) == 2
    assert capsys.readouterr().err == "cas-freq analyze: error: bad input\n"
    monkeypatch.setattr(analyze_command, "run", bug)
    with pytest.raises(ValueError, match="a bug"):
        main(["analyze"])
