"""``cas-freq sinedwell``: the command's contract (JSON keys, bad input, progress), the three
bandwidths side by side, and the sampled-controller option of the config.

The sine-dwell's numerical agreement with the linear loop is tested in test_sinedwell.py; here
the runs use a short frequency list so the module takes a few seconds.
"""

import io
import json
import math

import numpy as np
import pytest
from clirun import run_cli

from cas_freq.cli.common import terminal_progress
from cas_freq.cli.sinedwell import parse_amplitudes, parse_frequencies
from cas_freq.config import load_variant
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.formulas import second_order_bandwidth
from cas_freq.studies.run import step_run, step_run_dict

_run = run_cli


@pytest.fixture(scope="module")
def dwell():
    """0.05 deg (no limit) and 10 deg at three frequencies around the 10 deg bandwidth."""
    code, out, err = _run(["sinedwell", "--amplitudes", "0.05deg,10deg",
                           "--frequencies", "300,450,700", "--json"])
    assert code == 0, err
    return json.loads(out)


def test_json_contract(dwell):
    assert dwell["variant"] == "base" and dwell["feedforward"] is False
    assert dwell["frequencies_rad_s"] == [300.0, 450.0, 700.0]
    assert [a["amplitude_deg"] for a in dwell["amplitudes"]] == pytest.approx([0.05, 10.0])
    for entry in dwell["amplitudes"]:
        assert {"bandwidth_rad_s", "magnitude_db", "phase_deg", "limit_hit", "step", "fit"} <= set(
            entry
        )
        assert len(entry["magnitude_db"]) == 3
    assert dwell["simulation"]["controllers"] == "continuous"


def test_small_amplitude_matches_linear_and_large_one_is_limited(dwell):
    """At 0.05 deg no limit acts and the first harmonic is the exact-delay T(jw) (test_sinedwell
    establishes 0.2 dB / 2 deg up to twice the bandwidth; the same tolerance here); at 10 deg
    the 20 A clamp acts and the response falls well below T."""
    small, large = dwell["amplitudes"]
    linear = dwell["linear"]
    assert not small["limit_hit"]
    np.testing.assert_allclose(small["magnitude_db"], linear["magnitude_db"], atol=0.2)
    np.testing.assert_allclose(small["phase_deg"], linear["phase_deg"], atol=2.0)
    assert large["limit_hit"]
    assert large["magnitude_db"][-1] < linear["magnitude_db"][-1] - 6.0
    assert dwell["limit_onset_amplitude_deg"] == pytest.approx(10.0)


def test_three_bandwidths_side_by_side(dwell):
    """Each row carries the linear -3 dB (the analyze figure), the sine-dwell bandwidth of that
    amplitude and the closed form of its step's second-order fit (recomputed here from the
    fitted wn and zeta with docs/model.md's formula)."""
    rows = dwell["bandwidth_three_ways"]
    assert len(rows) == 2
    code, out, _ = _run(["analyze", "--json"])
    linear = json.loads(out)["closed_loop"]["bandwidth_rad_s"]
    for row, entry in zip(rows, dwell["amplitudes"], strict=True):
        assert row["linear_rad_s"] == pytest.approx(linear, rel=1e-9)
        assert row["sinedwell_rad_s"] == entry["bandwidth_rad_s"]
        fit = entry["fit"]
        assert row["step_fit_rad_s"] == pytest.approx(
            second_order_bandwidth(fit["wn_rad_s"], fit["zeta"]), rel=1e-12
        )
    # the grid 300..700 rad/s brackets the 10 deg crossing but not the small-signal one (1385)
    assert rows[0]["sinedwell_rad_s"] is None
    assert 300.0 < rows[1]["sinedwell_rad_s"] < 700.0
    assert dwell["report_bench"]["bandwidth_rad_s"] == 566.0


def test_table_output():
    code, out, _ = _run(["sinedwell", "--amplitudes", "1deg", "--frequencies", "200,400"])
    assert code == 0
    assert "bandwidth three ways" in out and "1 deg" in out
    # the shipped config's reference: fit (ARL-TR-9136 §7, docs/model.md §8)
    assert "reference, 10 deg step fit: 566 (wn 462 rad/s, zeta 0.54; ARL-TR-9136" in out


@pytest.mark.parametrize(
    ("option", "value", "expect"),
    [
        ("--amplitudes", "10", "angle with a unit"),
        ("--amplitudes", "10deg,,2deg", "expected angles"),
        ("--amplitudes", "100deg", "within ±90 deg"),
        ("--frequencies", "0:100:5", "MIN:MAX:N"),
        ("--frequencies", "100,-5", "positive numbers"),
        ("--frequencies", "100:1000:1", "2 <= N"),
        ("--frequencies", "abc", "rad/s"),
    ],
)
def test_bad_input_exits_2_naming_the_option(option, value, expect):
    code, out, err = _run(["sinedwell", option, value])
    assert code == 2 and out == ""
    assert option in err and expect in err and "Traceback" not in err


def test_parsers():
    assert parse_amplitudes("0.5deg, 2 deg") == pytest.approx([math.radians(0.5), math.radians(2)])
    assert parse_amplitudes("-1deg") == pytest.approx([math.radians(1)])
    assert parse_frequencies("10:1000:3") == pytest.approx([10.0, 100.0, 1000.0])
    assert parse_frequencies("500,100,100") == [100.0, 500.0]
    with pytest.raises(CasFreqError):
        parse_frequencies("")


class _Tty(io.StringIO):
    def isatty(self):
        return True


def test_progress_only_on_a_terminal():
    """No bar on a pipe or log (a line every 10 s instead, so nothing for a short run; see
    tests/test_work_budget.py); on a terminal, tqdm's bar follows (done, planned), also when
    the plan grows (a horizon extension), and ends at 100 %."""
    pipe = io.StringIO()
    periodic = terminal_progress("x", pipe)
    periodic(1, 2)
    periodic.done()
    assert pipe.getvalue() == ""
    stream = _Tty()
    progress = terminal_progress("sine-dwell base", stream)
    for done, planned in ((0, 100), (50, 100), (50, 200), (200, 200)):
        progress(done, planned)
    assert progress.bar.n == 200 and progress.bar.total == 200
    progress.done()
    text = stream.getvalue()
    assert "sine-dwell base" in text and "100%" in text


def test_sampled_controllers_from_the_config():
    """``simulation.controllers: sampled`` runs the controllers at the configured rates with
    zero-order hold; the step then differs from the continuous one (the 2.5 kHz position loop
    adds about half a period, 0.2 ms, of effective delay), and the JSON says which was used."""
    sampled = load_variant(None, "base", [("simulation.controllers", "sampled")])
    assert sampled.params.simulation.rates_hz == (25e3, 2.5e3)
    run = step_run(sampled, math.radians(0.5))
    assert run.result.current_rate_hz == 25e3 and run.result.position_rate_hz == 2.5e3
    data = step_run_dict(run)
    assert data["simulation"]["controllers"].startswith("sampled")
    continuous = step_run(load_variant(None, "base"), math.radians(0.5))
    assert step_run_dict(continuous)["simulation"]["controllers"] == "continuous"
    assert run.step.overshoot_pct > continuous.step.overshoot_pct


def test_sampled_rate_must_be_a_frequency():
    with pytest.raises(CasFreqError, match=r"simulation.current_loop_rate.*Hz"):
        load_variant(None, "base", [("simulation.current_loop_rate", "3 ms")])
