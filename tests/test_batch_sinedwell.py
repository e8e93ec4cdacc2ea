"""Sine-dwells of many actuators in one batch (sweeps and Monte Carlo) against the single
sine-dwell of each: the same settling, windows and first-harmonic fit, so the same figures up
to the rounding of the least-squares fit on another batch shape (measured 4e-13 rad/s and
4e-13 dB; bound 1e-9)."""

import json
import math

import numpy as np
import pytest
from clirun import run_cli

from cas_freq.config import load_all_variants
from cas_freq.core.parameters import LoopParameters
from cas_freq.simulation.sinedwell import sine_dwell, sine_dwell_bandwidths

FREQUENCIES = (300.0, 420.0, 600.0)  # brackets the 10 deg bandwidths (~320..430 rad/s)


def test_batch_equals_single_dwells():
    # one batch has one loop structure: the continuous variants on the motor encoder
    variants = [v for v in load_all_variants() if v.params.position_loop.feedback == "motor"
                and not v.params.sampling.sample_rates]
    params = LoopParameters.from_configs([v.params for v in variants])
    bandwidth, magnitude, limited = sine_dwell_bandwidths(
        params, math.radians(10), FREQUENCIES, chunk_size=2  # two chunks: 2 + 1 actuators
    )
    for index, loaded in enumerate(variants):
        single = sine_dwell(loaded.params, [math.radians(10)], FREQUENCIES)
        assert bandwidth[index] == pytest.approx(single.bandwidth_rad_s[0], abs=1e-9)
        np.testing.assert_allclose(magnitude[index], single.magnitude_db[0], atol=1e-9)
        np.testing.assert_array_equal(limited[index], single.limit_hit[0])


def test_no_crossing_is_nan():
    params = LoopParameters.from_configs([load_all_variants()[0].params])
    bandwidth, _, _ = sine_dwell_bandwidths(params, math.radians(0.1), (100.0, 200.0))
    assert np.isnan(bandwidth[0])  # small signal: |T| > -3 dB up to ~1385 rad/s


def test_sweep_with_sinedwell_matches_the_sinedwell_command():
    code, out, err = run_cli(["sweep", "--set", "position_loop.Kp=6.3435,5", "--sinedwell",
                              "10deg", "--frequencies", "300,420,600", "--json"])
    assert code == 0, err
    points = json.loads(out)["points"]
    code, out, _ = run_cli(["sinedwell", "--amplitudes", "10deg", "--frequencies",
                            "300,420,600", "--json"])
    single = json.loads(out)["amplitudes"][0]["bandwidth_rad_s"]
    assert points[0]["sinedwell.bandwidth_rad_s"] == pytest.approx(single, abs=1e-9)
    assert points[1]["sinedwell.bandwidth_rad_s"] != points[0]["sinedwell.bandwidth_rad_s"]


def test_frequencies_need_sinedwell():
    code, _, err = run_cli(["sweep", "--set", "position_loop.Kp=5,6", "--frequencies", "1:2:3"])
    assert code == 2 and "only with --sinedwell" in err


def test_montecarlo_evaluates_a_sinedwell_requirement(shipped_raw, write_config):
    shipped_raw["requirements"] = [
        {"id": "BW-3", "metric": "sinedwell.bandwidth_rad_s", "min": "300 rad/s",
         "amplitude": "10 deg", "frequencies": "300,420,600", "severity": "advisory"},
    ]
    path = str(write_config(shipped_raw))
    code, out, err = run_cli(["montecarlo", path, "--samples", "4", "--seed", "1",
                              "--tolerance", "motor.Km=10%", "--json"])
    assert code == 0, err
    data = json.loads(out)
    requirement = data["requirements"][0]
    assert requirement["evaluated"] is True and data["sinedwell_deg"] == pytest.approx(10.0)
    assert requirement["passed"] + requirement["failed"] == 4
    assert data["figures"]["sinedwell.bandwidth_rad_s"]["count"] >= 1
