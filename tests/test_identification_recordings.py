"""Bench step recordings (cas_freq.identification) and ``cas-freq fit --data``.

Reference values: the second-order-plus-delay step in closed form
(:func:`cas_freq.simulation.second_order.second_order_step`) with the report's parameters
(ARL-TR-9136 §7: wn 462 rad/s, zeta 0.54, td 2 ms), whose closed-form bandwidth is 565.9 rad/s
(docs/model.md); unit conversions worked out in each test.
"""

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from clirun import run_cli
from docs_pages import doc_section

from cas_freq.core.exceptions import ConfigError
from cas_freq.core.figures import FIGURES
from cas_freq.identification import fit_recordings, read_recording
from cas_freq.identification.columns import parse_column_option
from cas_freq.simulation.second_order import fit_second_order_batch, second_order_step

WN, ZETA, TD = 462.0, 0.54, 2e-3
STEP = math.radians(10.0)
EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "recordings"


def _inside(fit):
    """Whether each true parameter lies inside the fit's interval: (wn, zeta, td)."""
    return (fit.wn_ci_rad_s[0] < WN < fit.wn_ci_rad_s[1],
            fit.zeta_ci[0] < ZETA < fit.zeta_ci[1],
            fit.td_ci_s[0] < TD < fit.td_ci_s[1])


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def _rows(n=12, start=0.0):
    """n rows of time_s, command_deg, position_deg from ``start`` [s] every 1 ms."""
    return "".join(f"{start + k * 1e-3:g},10,{k * 0.5:g}\n" for k in range(n))


HEADER = "time_s,command_deg,position_deg\n"


# --- reader errors: each names the file and the line ------------------------------------------

@pytest.mark.parametrize(("text", "expect"), [
    (HEADER + "0,10,0\n,10,1\n" + _rows(12, 0.01), "line 3: column 'time_s': empty"),
    (HEADER + "0,10,0\n0.002,10,1\n0.001,10,1\n", "line 4: time 0.001 s is before line 3's"),
    (HEADER + "0,10,0\n0.001,10,1\n0.001,10,1\n", "line 4: time 0.001 s repeats line 3's"),
    (HEADER + "0,10,0\n0.001,10,nan\n", "line 3: column 'position_deg': nan (values must be "
     "finite"),
    (HEADER + "0,10,0\n0.001,10,abc\n", "line 3: column 'position_deg': not a number: 'abc'"),
    ("# a comment\nstamp,command_deg,position_deg\n0,1,2\n",
     "line 2: no time column in the header ('stamp', 'command_deg', 'position_deg'); accepted: "
     "time: t, time"),
    ("time_s,command_deg,enc\n0,1,2\n", "line 1: no position column in the header"),
    ("time [blargh],position_deg\n0,1\n", "line 1: column 'time [blargh]' (time): unit "
     "'blargh' not accepted (cannot read '1 blargh': unknown unit"),
    ("time_s,position [m]\n0,1\n", "line 1: column 'position [m]' (position): unit 'm' not "
     "accepted ('1 m' has dimension [length]"),
    ("time_s,position_deg,current [V]\n0,1,2\n", "column 'current [V]' (current): unit 'V'"),
    ("0,10,0\n0.001,10,1\n", "line 1: expected a header naming the columns"),
    (HEADER + "0,10,0\n0.001,10\n", "line 3: expected 3 columns as the header, got 2"),
    (HEADER + "-0.001,0,0\n" + _rows(5), "5 samples from the trigger at t = 0 s (line 3) on; "
     "at least 10 are needed"),
    (HEADER + "".join(f"{k * 1e-3:g},0,0\n" for k in range(-3, 12)),
     "column 'command_deg': the command does not step (it holds 0 deg from line 2 to line 16)"),
    ("time_s,t [ms],position_deg\n0,0,1\n", "line 1: two time columns, 'time_s' and 't [ms]'"),
])
def test_reader_errors_name_file_and_line(tmp_path, text, expect):
    path = _write(tmp_path / "bad.csv", text)
    with pytest.raises(ConfigError) as info:
        read_recording(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and expect in message, message
    assert "line" in message


def test_unreadable_file(tmp_path):
    with pytest.raises(ConfigError, match="none.csv: recording not found"):
        read_recording(tmp_path / "none.csv")


# --- units ---------------------------------------------------------------------------------------

def test_milliseconds_and_radians(tmp_path):
    """time [ms] / 1000 is s; rad angles are taken as they are; deg * pi / 180 is rad."""
    t_ms = np.arange(-2, 12)  # 2 pre-trigger samples, 12 from the trigger at 0 ms
    command_rad = np.where(t_ms >= 0, 0.2, 0.0)
    position_rad = 0.01 * np.maximum(t_ms, 0)
    lines = ["time [ms],command_fin [rad],fin_angle_rad"]
    lines += [f"{a},{b},{c}" for a, b, c in zip(t_ms, command_rad, position_rad, strict=True)]
    r = read_recording(_write(tmp_path / "ms.csv", "\n".join(lines) + "\n"))
    np.testing.assert_allclose(r.time_s, t_ms / 1000.0, rtol=1e-15)
    np.testing.assert_allclose(r.position_rad, position_rad, rtol=1e-15)
    assert r.step_rad == pytest.approx(0.2, rel=1e-15)
    assert r.current_a is None and r.voltage_v is None
    deg = read_recording(_write(tmp_path / "deg.csv", HEADER + "".join(
        f"{k * 1e-3:g},90,{90 * (k > 0):d}\n" for k in range(12))))
    assert deg.step_rad == pytest.approx(math.pi / 2, rel=1e-15)
    assert deg.position_rad[-1] == pytest.approx(math.pi / 2, rel=1e-15)


def test_current_and_voltage_columns(tmp_path):
    """'current_a' is A; 'i [mA]' is mA, 1e-3 A; 'V [V]' and 'voltage_v' are V."""
    body = "".join(f"{k * 1e-3:g},10,{k},{2 * k},{3 * k}\n" for k in range(12))
    r = read_recording(_write(tmp_path / "a.csv", "t [s],cmd,delta [deg],current_a,V [V]\n"
                              + body))
    assert r.current_a[5] == 10.0 and r.voltage_v[5] == 15.0
    r = read_recording(_write(tmp_path / "m.csv", "time_s,command_deg,pos,i [mA],voltage_v\n"
                              + body))
    assert r.current_a[5] == pytest.approx(0.010, rel=1e-15) and r.voltage_v[5] == 15.0


def test_columns_named_explicitly(tmp_path):
    """time=t_ms (its unit from the suffix: ms) and position=enc_deg; an unknown name lists the
    header."""
    body = "".join(f"{k},{k},{10 * (k >= 0)}\n" for k in range(-3, 12))
    path = _write(tmp_path / "x.csv", "t_ms,enc_deg,demand\n" + body)
    with pytest.raises(ConfigError, match="no position column"):  # t_ms is time in ms anyway
        read_recording(path)
    columns = parse_column_option("time=t_ms,position=enc_deg,command=demand")
    r = read_recording(path, columns)
    assert r.time_s[0] == pytest.approx(-0.003) and r.step_rad == pytest.approx(STEP)
    # the pre-trigger mean of the position, (-3 - 2 - 1) / 3 = -2 deg, is removed
    assert r.position_offset_rad == pytest.approx(math.radians(-2.0))
    with pytest.raises(ConfigError, match=r"no column 'enc' \(given for position\); the header "
                       r"has 't_ms', 'enc_deg', 'demand'"):
        read_recording(path, {"time": "t_ms", "position": "enc"})
    with pytest.raises(ValueError, match="unknown role 'speed'"):
        parse_column_option("speed=x")


# --- trigger and offset --------------------------------------------------------------------------

def test_trigger_from_the_command_and_offsets_removed(tmp_path):
    """A logger clock that does not start at the step: the command jumps from 2 deg to 12 deg at
    sample 123 (t = 12.3 ms of the file), the encoder reads 0.7 deg at rest. The recording's
    time is from that sample, the offsets are 0.7 deg and 2 deg, the step 10 deg, and the fit of
    the noise-free response gives the model's parameters back."""
    t = np.arange(700) * 1e-4
    jump = t[123]
    response = np.degrees(second_order_step(t - jump, WN, ZETA, TD, STEP))
    command = np.where(t >= jump, 12.0, 2.0)
    lines = [HEADER.strip()] + [f"{a:.17g},{b:.17g},{c:.17g}" for a, b, c in
                                zip(t, command, response + 0.7, strict=True)]
    r = read_recording(_write(tmp_path / "trig.csv", "\n".join(lines) + "\n"))
    assert r.trigger_s == jump
    assert r.time_s[0] == pytest.approx(-jump) and np.count_nonzero(~r.after) == 123
    assert r.position_offset_rad == pytest.approx(math.radians(0.7), rel=1e-12)
    assert r.command_offset_rad == pytest.approx(math.radians(2.0), rel=1e-12)
    assert r.step_rad == pytest.approx(STEP, rel=1e-12)
    fit = fit_recordings([r]).runs[0].fit
    assert (fit.wn_rad_s, fit.zeta, fit.td_s) == pytest.approx((WN, ZETA, TD), rel=1e-6)


def test_step_size_given_and_checked(tmp_path):
    """Without a command column the step is --step's; with one, --step must agree within 1 %."""
    t = np.arange(-50, 600) * 1e-4
    y = np.degrees(second_order_step(t, WN, ZETA, TD, STEP))
    no_command = "time_s,position_deg\n" + "".join(f"{a:.17g},{b:.17g}\n" for a, b in zip(t, y,
                                                                                 strict=True))
    path = _write(tmp_path / "p.csv", no_command)
    with pytest.raises(ConfigError, match="no command column to take the step size from"):
        fit_recordings([read_recording(path)])
    run = fit_recordings([read_recording(path)], STEP).runs[0]
    assert run.step_source == "given" and run.fit.wn_rad_s == pytest.approx(WN, rel=1e-6)
    with_command = HEADER + "".join(f"{a:.17g},{10.0 * (a >= 0):.17g},{b:.17g}\n"
                                    for a, b in zip(t, y, strict=True))
    path = _write(tmp_path / "c.csv", with_command)
    assert fit_recordings([read_recording(path)], math.radians(10.05)).runs[0].step_source \
        == "command"
    with pytest.raises(ConfigError, match=r"c.csv: the command column steps by 10 deg but "
                       r"--step is 10.2 deg \(more than 1 % apart\)"):
        fit_recordings([read_recording(path)], math.radians(10.2))


def test_what_simulate_writes_is_a_recording(tmp_path):
    """``simulate --step 10deg --csv F``: time 't [s]', command 'command_fin [deg]', position
    'delta [deg]', current 'i [A]', voltage 'V [V]' (theta, omega and the limit flags
    ignored). The command holds 10 deg from t = 0, so the trigger is 0 and the step 10 deg;
    the fit is simulate's own to the CSV's 9 digits (rel 1e-5, as tests/test_cli_fit.py)."""
    path = tmp_path / "sim.csv"
    code, out, err = run_cli(["simulate", "--step", "10deg", "--csv", str(path), "--json"])
    assert code == 0, err
    own = json.loads(out)
    r = read_recording(path)
    assert r.trigger_s == 0.0 and r.step_rad == pytest.approx(STEP, rel=1e-9)
    assert r.position_offset_rad == 0.0 and np.all(r.after)
    assert np.max(np.abs(r.current_a)) == pytest.approx(own["step"]["max_current_a"], rel=1e-6)
    fit = fit_recordings([r]).runs[0].fit
    for key in ("wn_rad_s", "zeta", "td_s", "bandwidth_closed_form_rad_s"):
        assert getattr(fit, key) == pytest.approx(own["fit"][key], rel=1e-5), key


# --- the fit on analytic responses with noise ----------------------------------------------------

def _noisy_runs(seeds, noise_deg=0.05):
    """Analytic 10 deg steps sampled irregularly around 10 kHz for 50 ms, with white Gaussian
    noise of ``noise_deg`` RMS, one per seed."""
    times, responses = [], []
    for seed in seeds:
        rng = np.random.default_rng(seed)
        t = np.cumsum(1e-4 * (1.0 + 0.2 * rng.uniform(-1, 1, 500)))
        y = second_order_step(t, WN, ZETA, TD, STEP)
        times.append(t)
        responses.append(y + math.radians(noise_deg) * rng.standard_normal(t.size))
    return times, responses


def test_seeded_noisy_fit_contains_the_truth():
    (t,), (y,) = _noisy_runs([2024])
    fit = fit_second_order_batch([t], [y], STEP)[0]
    assert all(_inside(fit))
    assert fit.bandwidth_closed_form_rad_s == pytest.approx(565.9, abs=3.0)


def test_interval_coverage_over_40_seeds():
    """The ~95 % intervals hold the true value in about 95 % of noisy runs.

    For 40 independent runs the count inside is binomial(40, 0.95): mean 38, standard deviation
    1.4, so fewer than 32 (80 %) has a probability of about 1e-4 when the intervals are right;
    intervals too narrow by half (true coverage ~68 %) would give ~27 and fail. Measured: 40,
    38 and 40 of 40 for wn, zeta and td (over 1000 seeds: 95.1 %, 94.3 %, 95.1 %).
    """
    times, responses = _noisy_runs(range(40))
    fits = fit_second_order_batch(times, responses, STEP)
    coverage = np.mean([_inside(fit) for fit in fits], axis=0)
    assert np.all(coverage >= 0.8) and np.all(coverage <= 1.0), coverage


# --- the shipped example recordings --------------------------------------------------------------

def _examples():
    return [read_recording(EXAMPLES / f"step_run{k}.csv") for k in (1, 2, 3)]


def test_examples_are_labelled_synthetic_and_reproducible(tmp_path):
    sys.path.insert(0, str(EXAMPLES))
    try:
        import make_recordings
    finally:
        sys.path.remove(str(EXAMPLES))
    for path in make_recordings.main(tmp_path):
        shipped = (EXAMPLES / path.name).read_text(encoding="utf-8")
        assert shipped.startswith("# SYNTHETIC recording")
        assert path.read_text(encoding="utf-8") == shipped
    assert "SYNTHETIC" in (EXAMPLES / "README.md").read_text(encoding="utf-8")


def test_examples_recover_the_report_model():
    """Each run's and the joint fit's intervals hold 462 rad/s, 0.54 and 2 ms, and the
    closed-form bandwidth is 565.9 rad/s within 2 rad/s (the wn interval's half-width, ~1.2
    rad/s on a run, moves the bandwidth by ~1.5 rad/s)."""
    fits = fit_recordings(_examples())
    for run in fits.runs:
        r = run.recording
        assert run.step_source == "command" and run.step_rad == pytest.approx(STEP)
        assert np.count_nonzero(~r.after) >= 45  # 5 ms of pre-trigger at ~10 kHz
        # the encoder offset (0.2-0.5 deg) less the pre-trigger mean's noise (0.03 deg / 50**0.5)
        # and quantisation (0.0044 deg at most)
        assert 0.18 <= math.degrees(r.position_offset_rad) <= 0.52
        assert all(_inside(run.fit)), run.fit
        assert run.fit.bandwidth_closed_form_rad_s == pytest.approx(565.9, abs=2.0)
    assert all(_inside(fits.joint)), fits.joint
    assert fits.joint.bandwidth_closed_form_rad_s == pytest.approx(565.9, abs=2.0)
    assert fits.spread["wn_rad_s"]["min"] <= fits.spread["wn_rad_s"]["mean"] \
        <= fits.spread["wn_rad_s"]["max"]


# --- the CLI -------------------------------------------------------------------------------------

def test_cli_json_and_output_folder(tmp_path):
    files = [str(EXAMPLES / f"step_run{k}.csv") for k in (1, 2, 3)]
    out_dir = tmp_path / "out"
    code, out, err = run_cli(["fit", "--data", *files, "--step", "10deg", "--json",
                              "-o", str(out_dir)])
    assert code == 0, err
    data = json.loads(out)
    assert [rec["source"] for rec in data["recordings"]] == files
    for rec in data["recordings"]:
        assert rec["step_from"] == "command" and rec["step_deg"] == pytest.approx(10.0)
        assert {"wn_ci_rad_s", "zeta_ci", "td_ci_s", "rms_residual_rad",
                "bandwidth_closed_form_rad_s"} <= set(rec["fit"])
    low, high = data["joint"]["wn_ci_rad_s"]
    assert low < WN < high
    assert set(data["spread"]) == {"wn_rad_s", "zeta", "td_s", "bandwidth_closed_form_rad_s"}
    (model,) = data["config_simulated"]
    assert model["variant"] == "base" and model["step"]["amplitude_deg"] == pytest.approx(10.0)
    assert sorted(p.name for p in out_dir.iterdir() if not p.name.startswith(".")) == \
        ["fit.json", "fit.svg"]
    assert json.loads((out_dir / "fit.json").read_text()) == data
    assert (out_dir / "fit.svg").read_text().lstrip().startswith("<?xml")


def test_cli_table_and_column_option(tmp_path):
    t = np.arange(-50, 600) * 1e-4
    y = np.degrees(second_order_step(t, WN, ZETA, TD, STEP))
    path = _write(tmp_path / "enc.csv", "stamp_ms,enc_deg\n" + "".join(
        f"{a * 1e3:.17g},{b:.17g}\n" for a, b in zip(t, y, strict=True)))
    code, out, err = run_cli(["fit", "--data", str(path), "--step", "10deg",
                              "--columns", "time=stamp_ms,position=enc_deg"])
    assert code == 0, err
    assert "step of 10 deg (from the --step option)" in out
    assert f"{FIGURES['fit.wn_rad_s'].label} 462 rad/s" in out  # the figure table's label
    assert "closed-form bandwidth 565.9 rad/s" in out
    assert "model qt_cas / base" in out and "joint fit" not in out
    code, out, err = run_cli(["fit", "--data", str(path), "--step", "10deg", "--variant",
                              "fitted", "--columns", "time=stamp_ms,position=enc_deg"])
    assert code == 0 and "model qt_cas / fitted" in out, err


@pytest.mark.parametrize(("args", "expect"), [
    (["--data", "{bad}"], "line 1: no position column"),
    (["--data", "{good}", "--step", "12deg"], "the command column steps by 10 deg but --step "
     "is 12 deg"),
    (["--data", "{good}", "--columns", "speed=x"], "unknown role 'speed'"),
    (["--data", "{good}", "--step", "10 furlongs"], "--step"),
    ([], "give --data FILE"),
    (["{good}"], "--step ANGLE is required"),
    (["{good}", "--step", "10deg", "-o", "{tmp}/o"], "-o needs --data"),
    (["{good}", "--step", "10deg", "--variant", "fitted"], "--variant needs --data"),
    (["--data", "{good}", "--variant", "nope"], "unknown variant 'nope'"),
])
def test_cli_bad_input_exits_2(tmp_path, args, expect):
    good = EXAMPLES / "step_run1.csv"
    bad = _write(tmp_path / "bad.csv", "time_s,command_deg\n0,1\n")
    args = [a.format(good=good, bad=bad, tmp=tmp_path) for a in args]
    code, out, err = run_cli(["fit", *args])
    assert code == 2 and out == "" and "Traceback" not in err
    assert err.count("\n") == 1 and expect in err, err
    if "{bad}" in str(args) or bad.name in " ".join(args):
        assert str(bad) in err


def test_figure_structure():
    from cas_freq.plots.recordings import recording_fit_figure

    fig = recording_fit_figure(fit_recordings(_examples()))
    top, bottom = fig.axes
    # per run: data, fit, command above; residuals below
    assert len(top.lines) == 9 and len(bottom.lines) == 3 + 1
    assert top.get_ylabel() == "output angle [deg]" and bottom.get_ylabel() == "data - fit [deg]"
    assert top.get_legend().get_texts()[1].get_text().startswith("fit: wn 461.5 rad/s")


def test_readme_quotes_the_example_fit():
    """The "Bench recordings" page (docs/identification.md, moved there from the README) quotes
    the joint fit of the example recordings as ``cas-freq fit --data
    examples/recordings/step_run*.csv`` prints it."""
    joint = fit_recordings(_examples()).joint
    text = " ".join(doc_section("docs/identification.md", "Bench recordings").split())
    wn, zeta, td = joint.wn_ci_rad_s, joint.zeta_ci, joint.td_ci_s
    quoted = (f"ωn {joint.wn_rad_s:.4g} rad/s [{wn[0]:.4g}, {wn[1]:.4g}], ζ {joint.zeta:.4g} "
              f"[{zeta[0]:.4g}, {zeta[1]:.4g}], td {joint.td_s * 1e3:.4g} ms "
              f"[{td[0] * 1e3:.4g}, {td[1] * 1e3:.4g}] and a closed-form bandwidth of "
              f"{joint.bandwidth_closed_form_rad_s:.4g} rad/s")
    assert quoted in text
