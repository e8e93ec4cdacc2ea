"""Inputs that were silently ignored or misread are refused at load, in one line, exit 2: a
variant's name that is not safe in a file name or is ``base``, ``--set`` on the variants
section, a swept key also fixed (a plain ``--set`` given twice is not lost: the last wins), an
item of a list the config lacks, a fractional encoder count, an output file on a file system
that takes none."""

import os
from pathlib import Path

import pytest
import yaml
from clirun import run_cli

from cas_freq.config import load_variant
from cas_freq.core.exceptions import ConfigError
from cas_freq.core.fileio import check_output_file

ROOT = Path(__file__).resolve().parents[1]
DC_SERVO = ROOT / "configs" / "dc_servo.yaml"


def _with_variants(tmp_path, variants):
    raw = yaml.safe_load(DC_SERVO.read_text(encoding="utf-8"))
    raw["variants"] = variants
    path = tmp_path / "servo.yaml"
    path.write_text(yaml.safe_dump(raw), encoding="utf-8")
    return path


@pytest.mark.parametrize("name", ["a/b", "../../x", "a b", "1st", "x" * 65])
def test_an_unsafe_variant_name_is_refused_at_load(tmp_path, name):
    path = _with_variants(tmp_path, {name: {"motor.R": 2.0}})
    with pytest.raises(ConfigError, match=r"variants: name .* is not accepted; a variant's name "
                                          "is a letter or _"):
        load_variant(path)


def test_a_variant_named_base_is_refused_not_ignored(tmp_path):
    # base code: listed twice, both with the file's values (the variant's motor.R lost)
    path = _with_variants(tmp_path, {"base": {"motor.R": 2.0}})
    with pytest.raises(ConfigError, match=r"variants\.base: base is the file without a "
                                          "variant \\(reserved\\)"):
        load_variant(path)


def test_simulate_csv_with_an_unsafe_name_is_exit_2_before_any_run(tmp_path):
    path = _with_variants(tmp_path, {"a/b": {"motor.R": 2.0}})
    code, _, err = run_cli(["simulate", str(path), "--all-variants", "--step", "10deg",
                            "--csv", str(tmp_path / "out.csv")])
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err


def test_set_on_the_variants_section_is_refused():
    # base code: accepted and ignored (the variants are read from the file)
    with pytest.raises(ConfigError, match=r"--set variants\.relaxed\.motor\.R: .* write "
                                          r"--variant relaxed --set motor\.R=1"):
        load_variant(DC_SERVO, overrides=[("variants.relaxed.motor.R", 1)])


def test_sweep_refuses_a_key_both_swept_and_fixed():
    code, _, err = run_cli(["sweep", str(DC_SERVO), "--set", "position_loop.Kp=2:12:5",
                            "--set", "position_loop.Kp=3"])
    assert code == 2, err
    assert "position_loop.Kp: both swept and fixed" in err and err.count("\n") == 1


def test_an_item_of_a_missing_list_says_what_to_write():
    # base code: "filters: must be a list" for the dotted form, though the list form works
    with pytest.raises(ConfigError, match=r"filters\.0\.frequency: the config has no filters "
                                          r"list .* set the whole list \(e\.g\. --set 'filters="):
        load_variant(DC_SERVO, overrides=[("filters.0.frequency", "900 rad/s")])
    written = "[{at: current_command, type: lowpass1, frequency: 3000 rad/s}]"
    loaded = load_variant(DC_SERVO, overrides=[("filters", yaml.safe_load(written))])
    assert loaded.params.filters[0].frequency == 3000.0  # what the message says to write


def test_a_fractional_encoder_count_is_refused():
    with pytest.raises(ConfigError, match=r"sensors\.counts_per_rev: must be a whole number "
                                          ">= 1 .* got 4096.5"):
        load_variant(DC_SERVO, overrides=[("sensors.counts_per_rev", 4096.5)])
    assert load_variant(DC_SERVO, overrides=[("sensors.counts_per_rev", 4096)]
                        ).params.sensors.counts_per_rev == 4096


@pytest.mark.skipif(not (Path("/proc/version").is_file() and os.access("/proc", os.W_OK)),
                    reason="needs Linux's /proc with permissions that let this user write")
def test_an_output_file_on_a_virtual_file_system_is_refused_when_checked():
    # /proc's permissions let root write; no file can be created there (base code: "No such
    # file or directory" after the whole run)
    from cas_freq.core.exceptions import CasFreqError

    with pytest.raises(CasFreqError, match=r"--csv /proc/version: no file can be created in "
                                           "the folder /proc"):
        check_output_file("/proc/version", "--csv")
