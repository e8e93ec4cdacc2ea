"""Sweep recordings (issue 14): reading, sweep/step detection, the H1 estimate and coherence
against an analytic system, irregular sampling, stepped sines, the CLI on the shipped example.

The analytic case: H(s) = wn^2 / (s^2 + 2 zeta wn s + wn^2) e^(-s td), driven by a log chirp
and simulated by scipy.signal.lsim at 100 kHz (then every 10th sample kept: the linear
interpolation of the input between the fine samples changes the response by sinc^2(w dt / 2),
below 1e-4 dB at the 3000 rad/s top of the band), the delay an exact shift of 20 fine samples,
Gaussian noise added to the output. Its exact FRF is H(j w).
"""

import json
import math
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from clirun import run_cli
from scipy import signal

from cas_freq.core.exceptions import ConfigError
from cas_freq.identification import frf
from cas_freq.identification.sweep import is_sweep, median_crossings, read_sweep

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "recordings" / "sweep"
CHIRP = EXAMPLE / "sweep_chirp.csv"
WN, ZETA, TD = 600.0, 0.5, 2e-4
FINE_DT, KEEP = 1e-5, 10


def exact(omega):
    """H(j omega) of the analytic system."""
    s = 1j * np.asarray(omega)
    return WN**2 / (s * s + 2 * ZETA * WN * s + WN**2) * np.exp(-s * TD)


def simulate(command, fine_t):
    """The analytic system's response to ``command`` sampled at ``fine_t`` (FINE_DT apart)."""
    system = signal.lti([WN**2], [1.0, 2 * ZETA * WN, WN**2])
    _, y, _ = signal.lsim(system, command, fine_t)
    shift = round(TD / FINE_DT)
    return np.concatenate([np.zeros(shift), y[:-shift]])


def chirp_run(seed=1, noise=0.01, duration=1.0):
    """(fine times, command, response with noise) of a 30..3000 rad/s log chirp of amplitude 1
    after 20 ms at 0."""
    t = np.arange(0.0, duration + 0.04, FINE_DT)
    active = (t >= 0.02) & (t <= 0.02 + duration)
    command = np.where(active, signal.chirp(t - 0.02, 30 / (2 * np.pi), duration,
                                            3000 / (2 * np.pi), method="logarithmic",
                                            phi=-90), 0.0)
    y = simulate(command, t)
    rng = np.random.default_rng(seed)
    return t, command, y + noise * rng.standard_normal(t.size)


def errors(estimate):
    """(coherent mask, |dB error|, |phase error| [deg]) of an estimate against H."""
    ratio = estimate.response / exact(estimate.omega_rad_s)
    return estimate.coherent, np.abs(frf.db(ratio)), np.abs(np.degrees(np.angle(ratio)))


def write_csv(path, t, columns, header):
    """A recording CSV with ``header`` (cells) and ``columns`` (arrays) at times ``t`` [s]."""
    rows = [",".join(header)]
    rows += [",".join(f"{v:.9g}" for v in row) for row in zip(t, *columns, strict=True)]
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return path


# With coherence >= 0.9 and 8 Welch averages the random error of H1 is at most
# sqrt((1 - g2) / (2 n g2)) = 0.083 relative (Bendat & Piersol), 0.72 dB and 4.8 deg at one
# standard deviation at the worst coherent point; most points have g2 > 0.99 (0.2 dB, 1.4 deg).
# The chirp's non-stationarity within a segment (the response's memory, ~3 ms, against 0.22 s
# segments) adds a bias well below that. Bounds: RMS 0.3 dB / 2 deg, every point 1.5 dB / 9 deg
# (about two standard deviations at the worst coherent point).
def test_chirp_estimate_matches_the_exact_response():
    t, command, y = chirp_run()
    estimate = frf.estimate(command[::KEEP], y[::KEEP], FINE_DT * KEEP)
    assert estimate.averages == frf.AVERAGES
    assert estimate.omega_rad_s[0] < 60 and estimate.omega_rad_s[-1] > 2500
    coherent, db_error, deg_error = errors(estimate)
    assert np.count_nonzero(coherent) > 0.8 * coherent.size
    assert np.sqrt(np.mean(db_error[coherent] ** 2)) < 0.3
    assert np.sqrt(np.mean(deg_error[coherent] ** 2)) < 2.0
    assert db_error[coherent].max() < 1.5 and deg_error[coherent].max() < 9.0
    comparison = frf.compare(estimate, exact(estimate.omega_rad_s))
    assert comparison["coherent"] == np.count_nonzero(coherent)
    value, note = frf.bandwidth(estimate)
    truth = frf.crossing_bandwidth(np.geomspace(100, 3000, 20000),
                                   frf.db(exact(np.geomspace(100, 3000, 20000))),
                                   frf.HALF_POWER_DB)
    assert note is None and abs(value / truth - 1) < 0.02


def test_more_noise_lowers_the_coherence_not_the_estimate():
    t, command, y = chirp_run(seed=2, noise=0.2)
    estimate = frf.estimate(command[::KEEP], y[::KEEP], FINE_DT * KEEP)
    coherent, db_error, deg_error = errors(estimate)
    assert np.count_nonzero(~coherent) > 10  # the attenuated top of the band
    assert db_error[coherent].max() < 1.5 and deg_error[coherent].max() < 9.0


def test_irregular_sampling_is_resampled(tmp_path):
    t, command, y = chirp_run(seed=3)
    rng = np.random.default_rng(4)
    times = np.cumsum(1e-4 * (1 + 0.2 * rng.uniform(-1, 1, 11000)))
    times = times[times < t[-1]]
    path = write_csv(tmp_path / "irregular.csv", times,
                     [np.degrees(np.interp(times, t, command)),
                      np.degrees(np.interp(times, t, y))],
                     ["time_s", "command_deg", "position_deg"])
    recording = read_sweep(path)
    assert recording.resampled and 0.15 < recording.interval_spread < 0.21
    assert np.allclose(np.diff(recording.time_s), recording.interval_s)
    estimate = frf.estimate(recording.command_rad, recording.position_rad,
                            recording.interval_s)
    coherent, db_error, deg_error = errors(estimate)
    assert np.sqrt(np.mean(db_error[coherent] ** 2)) < 0.3
    assert np.sqrt(np.mean(deg_error[coherent] ** 2)) < 2.0
    assert read_sweep(write_csv(tmp_path / "regular.csv", t[::KEEP], [command[::KEEP],
                                y[::KEEP]], ["t [s]", "cmd [rad]", "delta [rad]"])).resampled \
        is False


def test_stepped_sine_gives_its_dwell_frequencies():
    dwell_hz = [20.0, 50.0, 100.0, 200.0, 400.0]
    t = np.arange(0.0, 0.25 * len(dwell_hz), FINE_DT)
    k = np.minimum((t / 0.25).astype(int), len(dwell_hz) - 1)
    frequency = np.asarray(dwell_hz)[k]
    command = np.sin(2 * np.pi * frequency * (t - 0.25 * k))
    y = simulate(command, t) + 0.01 * np.random.default_rng(5).standard_normal(t.size)
    estimate = frf.estimate(command[::KEEP], y[::KEEP], FINE_DT * KEEP)
    kept_hz = estimate.omega_rad_s / (2 * np.pi)
    resolution = 1.0 / (estimate.nperseg * FINE_DT * KEEP)
    for f in dwell_hz:
        near = np.abs(kept_hz - f) <= 1.5 * resolution
        assert near.any(), f
        index = np.flatnonzero(near)[np.argmin(np.abs(kept_hz[near] - f))]
        ratio = estimate.response[index] / exact(2 * np.pi * f)
        assert estimate.coherence[index] > 0.95
        assert abs(frf.db(ratio)) < 0.3 and abs(np.degrees(np.angle(ratio))) < 2.0, f
    # frequencies without power are dropped: the switches between dwells spread some (at
    # -30 dB) below the 200 Hz dwell, none between the 200 and 400 Hz dwells' lobes
    gap = (kept_hz > 200 + 12 * resolution) & (kept_hz < 400 - 12 * resolution)
    assert not gap.any()


@pytest.mark.parametrize("command, sweep", [
    (np.where(np.arange(500) >= 100, 10.0, 0.0), False),
    (np.where(np.arange(500) >= 100, 10.0, 0.0)
     + 0.3 * np.random.default_rng(0).standard_normal(500), False),
    (np.zeros(500), False),
    (np.sin(np.linspace(0, 40, 500)), True),
    (np.concatenate([np.zeros(100), np.sin(np.linspace(0, 40, 400))]), True),
    (None, False),
])
def test_sweep_or_step(command, sweep):
    assert is_sweep(command) is sweep


def test_median_crossings_of_a_chirp():
    _, command, _ = chirp_run(duration=0.2)
    assert median_crossings(command[::KEEP]) > 10


def test_shipped_example_is_synthetic_and_reproducible(tmp_path):
    text = CHIRP.read_text(encoding="utf-8")
    assert text.startswith("# SYNTHETIC")
    assert CHIRP.stat().st_size < 400_000
    sys.path.insert(0, str(EXAMPLE))
    try:
        import make_sweep
    finally:
        sys.path.remove(str(EXAMPLE))
    written = make_sweep.main(tmp_path)
    assert written[0].read_bytes() == CHIRP.read_bytes()


@pytest.fixture(scope="module")
def example_json():
    code, out, err = run_cli(["fit", "--variant", "fitted", "--data", str(CHIRP), "--json"])
    assert code == 0, err
    return json.loads(out)


# The example is the fitted variant itself (simulated below every limit, feed-forward off),
# so the data and the model differ only by the noise, the quantisation, the resampling and the
# estimate's own errors; measured 0.20 dB / 1.3 deg (T), 0.15 dB / 1.1 deg (i/delta_cmd),
# 0.026 dB / 0.12 deg (T_i); bounds as the analytic case's, T_i (noise on a large current
# against 1 mA) a tenth of them.
def test_cli_example_matches_the_model(example_json):
    (rec,) = example_json["recordings"]
    assert example_json["model"]["variant"] == "fitted"
    assert example_json["model"]["feedforward"] is False
    assert rec["resampled"] is True
    lo, hi = rec["band_rad_s"]
    assert lo < 40 and hi > 2500
    position = rec["responses"]["position"]["comparison"]
    assert position["coherent"] > 80
    assert position["rms_db"] < 0.3 and position["rms_deg"] < 2.0
    current = rec["responses"]["current"]["comparison"]
    assert current["rms_db"] < 0.3 and current["rms_deg"] < 2.0
    loop = rec["responses"]["current_loop"]["comparison"]
    assert loop["rms_db"] < 0.05 and loop["rms_deg"] < 0.3
    model_bw = example_json["model"]["bandwidth_rad_s"]
    assert abs(rec["bandwidth_rad_s"] / model_bw - 1) < 0.02
    response = rec["responses"]["position"]
    assert len(response["omega_rad_s"]) == len(response["magnitude_db"]) \
        == len(response["phase_deg"]) == len(response["coherence"]) \
        == len(response["model_phase_deg"]) == rec["frequencies"]
    assert all(0 <= c <= 1 for c in response["coherence"])


def test_cli_table_two_recordings_and_output(tmp_path):
    copy = tmp_path / "copy.csv"
    shutil.copy(CHIRP, copy)
    out_dir = tmp_path / "out"
    code, out, err = run_cli(["fit", "--variant", "fitted", "--data", str(CHIRP), str(copy),
                              "-o", str(out_dir)])
    assert code == 0, err
    assert "current / current command (T_i)" in out and "-3 dB bandwidth: data" in out
    assert "against the first's" in out and "0 dB, 0 deg RMS" in out
    assert (out_dir / "frf.json").is_file() and (out_dir / "frf.svg").is_file()
    data = json.loads((out_dir / "frf.json").read_text(encoding="utf-8"))
    assert len(data["recordings"]) == 2 and data["between_recordings"][0]["rms_db"] == 0
    svg = (out_dir / "frf.svg").read_text(encoding="utf-8")
    from cas_freq.plots.common import svg_text
    from cas_freq.plots.frf import frf_figure

    assert svg_text(frf_figure(data)) == svg


def test_bad_inputs_exit_2_naming_the_file(tmp_path):
    short = write_csv(tmp_path / "short.csv", np.arange(50) * 1e-3,
                      [np.sin(np.arange(50)), np.sin(np.arange(50))],
                      ["time_s", "command_deg", "position_deg"])
    code, _, err = run_cli(["fit", "--data", str(short)])
    assert code == 2 and "short.csv" in err and "at least" in err
    step = ROOT / "examples" / "recordings" / "step_run1.csv"
    code, _, err = run_cli(["fit", "--data", str(CHIRP), str(step)])
    assert code == 2 and "sweep_chirp.csv" in err and "step_run1.csv" in err
    t = np.arange(400) * 1e-3
    no_position = write_csv(tmp_path / "nopos.csv", t, [np.sin(40 * t)],
                            ["time_s", "command_deg"])
    code, _, err = run_cli(["fit", "--data", str(no_position)])
    assert code == 2 and "nopos.csv" in err and "no position column" in err
    code, _, err = run_cli(["fit", "--data", str(CHIRP), "--step", "10deg"])
    assert code == 2 and "--step" in err


def test_reader_needs_a_command_that_oscillates(tmp_path):
    t = np.arange(400) * 1e-3
    path = write_csv(tmp_path / "flat.csv", t, [np.where(t > 0.1, 1.0, 0.0), 0 * t],
                     ["time_s", "command_deg", "position_deg"])
    with pytest.raises(ConfigError, match="flat.csv.*step recording"):
        read_sweep(path)
    path = write_csv(tmp_path / "nocmd.csv", t, [np.sin(40 * t)], ["time_s", "position_deg"])
    with pytest.raises(ConfigError, match="nocmd.csv.*command column"):
        read_sweep(path)


def test_current_command_column_names(tmp_path):
    t = np.arange(400) * 1e-3
    wave = np.sin(300 * t)
    path = write_csv(tmp_path / "names.csv", t, [wave, wave, 1000 * wave, 2000 * wave],
                     ["t [s]", "cmd [deg]", "delta [deg]", "i [mA]", "i_cmd [mA]"])
    recording = read_sweep(path)
    assert np.allclose(recording.current_a, wave) and np.allclose(recording.current_command_a,
                                                                  2 * wave)
    assert math.isclose(recording.interval_s, 1e-3)
