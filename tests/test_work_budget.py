"""Issue 16, work bounded before it starts: the simulator's budget (steps, steps x runs, memory),
its override, the capped horizon extension, progress off a terminal and --quiet."""

import io
import math
import warnings

import numpy as np
import pytest
from clirun import SHIPPED_NOTE, run_cli

import cas_freq.cli.common as common
from cas_freq.config import load_variant
from cas_freq.core.exceptions import CasFreqError, ConfigError
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation import simulator
from cas_freq.simulation.commands import Step
from cas_freq.simulation.simulator import (
    BUDGET_ENV,
    MAX_MEMORY_BYTES,
    MAX_STEP_RUNS,
    MAX_STEPS,
    check_budget,
    memory_estimate,
    simulate_batch,
)


@pytest.fixture(scope="module")
def base():
    return load_variant(None, "base", [])


def test_budget_numbers_in_the_message(monkeypatch):
    monkeypatch.delenv(BUDGET_ENV, raising=False)
    check_budget(1, MAX_STEPS, 5e-6)
    check_budget(MAX_STEP_RUNS // MAX_STEPS, MAX_STEPS, 5e-6, record_every=100)
    with pytest.raises(ConfigError) as error:
        check_budget(3, 10 * MAX_STEPS, 5e-6)
    text = str(error.value)
    assert "2e+07 steps of 5e-06 s (horizon 100 s) x 3 run(s) = 6e+07 step-runs" in text
    assert "GiB" in text and BUDGET_ENV in text and "\n" not in text
    with pytest.raises(ConfigError, match="step-runs"):
        check_budget(1000, MAX_STEPS, 5e-6, record_every=1000)
    per_run = memory_estimate(2, 1000, 1, 0.0, 5e-6) - memory_estimate(1, 1000, 1, 0.0, 5e-6)
    runs = MAX_MEMORY_BYTES // per_run + 1
    with pytest.raises(ConfigError, match="GiB"):
        check_budget(runs, 1000, 5e-6)


def test_budget_factor_from_the_environment(monkeypatch):
    monkeypatch.setenv(BUDGET_ENV, "10")
    check_budget(1, 10 * MAX_STEPS, 5e-6)
    for text in ("0", "-1", "abc", "nan", "inf"):
        monkeypatch.setenv(BUDGET_ENV, text)
        with pytest.raises(ConfigError, match=BUDGET_ENV):
            check_budget(1, 10, 5e-6)


@pytest.mark.parametrize("argv, fragments", [
    # a current loop far faster than the 5 us step: a 5e-11 s step for 0.1 s
    (["simulate", "--step", "10deg", "--set", "motor.L=1e-9 H"],
     ("steps of 5e-11 s", "step-runs")),
    # 1 rad/s sine dwell: a 31.4 s horizon at 5 us, refused before any simulation with the
    # variant, the horizon and the budget factor that would allow it
    (["sinedwell", "--amplitudes", "1deg", "--frequencies", "1,2"],
     ("variant base", "31.4 s horizon", "beyond the simulation budget", "CAS_FREQ_BUDGET=4")),
])
def test_too_large_simulations_exit_2_at_once(argv, fragments, monkeypatch):
    monkeypatch.delenv(BUDGET_ENV, raising=False)
    code, out, err = run_cli([*argv, "--json"])
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert all(fragment in err for fragment in fragments) and BUDGET_ENV in err, err


def test_horizon_extension_stops_at_the_budget(base, monkeypatch):
    """The shipped 10 deg step settles after one extension (0.1 -> 0.2 s); a budget of 30,000
    steps lets the horizon grow only to 0.15 s, and the run says it has not settled."""
    monkeypatch.setenv(BUDGET_ENV, str(30_000 / MAX_STEPS))
    result = simulate_batch([base.params], Step(math.radians(10))).run(0)
    assert result.t_end_s == pytest.approx(0.15) and result.extended and not result.settled
    monkeypatch.setenv(BUDGET_ENV, str(10_000 / MAX_STEPS))
    with pytest.raises(ConfigError, match="2e\\+04 steps"):
        simulate_batch([base.params], Step(math.radians(10)))


def test_sine_dwell_batches_sized_to_the_budget(base, monkeypatch):
    from cas_freq.simulation.sinedwell import DEFAULT_PERIODS_MEASURE, _chunk_within_budget

    params = LoopParameters.from_config(base.params)
    settings = {"periods_settle": 3.0, "periods_measure": DEFAULT_PERIODS_MEASURE,
                "min_settle_s": 0.03, "samples_per_period": 64, "dt": None}
    frequencies = np.geomspace(100.0, 5000.0, 30)
    monkeypatch.delenv(BUDGET_ENV, raising=False)
    full = _chunk_within_budget(params, frequencies, settings, 30, None, None)
    monkeypatch.setenv(BUDGET_ENV, "0.1")
    small = _chunk_within_budget(params, frequencies, settings, 30, None, None)
    assert 1 <= small < full <= 64


def test_no_usable_time_step_is_an_error():
    with pytest.raises(CasFreqError, match="too fast"):
        simulator.default_time_step([1e-4], (), 0.0)


# ---- progress ----------------------------------------------------------------------------------

def test_progress_lines_off_a_terminal(monkeypatch):
    monkeypatch.setattr(common, "PROGRESS_INTERVAL_S", 0.0)
    stream = io.StringIO()
    progress = common.terminal_progress("simulate base", stream)
    progress(5, 20)
    progress(20, 20)
    progress.done()
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith("simulate base: 5 of 20 steps (25 %)")
    assert lines[-1].startswith("simulate base: 20 of 20 steps (100 %)")


def test_quiet_turns_progress_off():
    try:
        common.set_quiet(True)
        assert common.terminal_progress("x", io.StringIO()) is None
    finally:
        common.set_quiet(False)


def test_every_command_takes_quiet():
    from cas_freq.cli import COMMANDS, build_parser

    parser = build_parser()
    for name in COMMANDS:
        text = parser._subparsers._group_actions[0].choices[name].format_help()
        assert "--quiet" in text, name


def test_quiet_run(monkeypatch):
    code, out, err = run_cli(["simulate", "--step", "10deg", "--quiet", "--json"])
    assert code == 0 and err == "" and '"overshoot_pct"' in out


# ---- no warning on a successful run --------------------------------------------------------------

@pytest.mark.parametrize("setting", ["motor.J=1000 kg*m^2", "motor.J=1e-15 kg*m^2"])
def test_extreme_inertia_prints_no_warning(setting):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code, out, err = run_cli(["analyze", "--set", setting, "--json"])
    assert code == 0 and err == SHIPPED_NOTE  # the note of the shipped config alone


def test_absurd_inertia_is_refused_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        code, out, err = run_cli(["analyze", "--set", "motor.J=1e300", "--json"])
    assert code == 2 and err.count("\n") == 1 and "motor.J" in err


def test_stage_progress_of_report_and_compare(monkeypatch):
    stream = io.StringIO()
    progress = common.label_progress("report", stream)
    progress("base")  # off a terminal: nothing before 10 s have passed
    assert stream.getvalue() == ""
    monkeypatch.setattr(common, "PROGRESS_INTERVAL_S", 0.0)
    progress = common.label_progress("report", stream)
    progress("fitted")
    assert stream.getvalue() == "report: fitted ...\n"
    try:
        common.set_quiet(True)
        progress("relaxed")
    finally:
        common.set_quiet(False)
    assert stream.getvalue() == "report: fitted ...\n"
