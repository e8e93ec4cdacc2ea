"""Other actuators (issue 24): nothing of the QT-CAS leaks into another config's output.

- the bench line of ``sinedwell`` (text and ``report_bench`` in its JSON) comes from the config's
  ``reference:`` section, and only where it declares one;
- the second-order-plus-delay fit cites docs/model.md §7, not the ARL report;
- labels and text say "output" unless the config names its output (``output_name: fin`` in the
  shipped config); data keys (CSV columns, JSON fields) are the same for every config, and the
  former CSV column names are still read;
- ``tune`` prints the gains in EPOS4 units only for a config whose ``drive:`` is ``epos4``;
- the words follow each shipped architecture's output (tests/output_words.py): its name, its kind
  (an angle, or a position at a linear output) and the flight-control words only where the
  config says the output is a control surface (the slow test runs every command and report on
  the cascade axis and the ball screw).
"""

import csv
import io
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from clirun import run_cli
from output_words import SHIPPED, leaks

ROOT = Path(__file__).resolve().parents[1]
DC_SERVO = ROOT / "configs" / "dc_servo.yaml"

#: "fin" as a word or a part of a name (``fin``, ``fin_angle``, ``command_fin``, ``Fin``), not
#: inside a longer word (``final``, ``finite``, ``define``).
FIN = re.compile(r"(?<![a-z])fin(?![a-z])", re.IGNORECASE)
#: "hinge" is allowed only as the config's key names and the JSON fields named after them.
HINGE_KEYS = re.compile(
    r"load\.hinge_(stiffness|bias)|\"(nominal_|stable_)?hinge_stiffness_n_m_rad\"")

#: A short sine-dwell: one amplitude below every limit, two frequencies (seconds, not minutes).
DWELL = ["--amplitudes", "1deg", "--frequencies", "100,300"]


def _config(tmp_path, name="dc.yaml", **changes):
    """dc_servo (no reference, no output_name, no drive) with top-level ``changes``."""
    raw = yaml.safe_load(DC_SERVO.read_text(encoding="utf-8"))
    raw.update(changes)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    return path


def _ok(argv):
    code, out, err = run_cli(argv)
    assert code == 0, err
    return out


def _leaks(text):
    """The QT-CAS words in ``text``: "fin" in any form, "hinge" outside the config's keys."""
    return FIN.findall(text) + re.findall("hinge", HINGE_KEYS.sub("", text), re.IGNORECASE)


# --- 1. the reference (bench) line of sinedwell --------------------------------------------------

def test_sinedwell_shows_a_reference_only_where_the_config_declares_one(tmp_path):
    # dc_servo declares no reference: no bench line, no report_bench key (before: ARL-TR-9136's
    # "566 (wn 462 rad/s, zeta 0.54)" and its report_bench for every config)
    text = _ok(["sinedwell", str(DC_SERVO), *DWELL])
    data = json.loads(_ok(["sinedwell", str(DC_SERVO), *DWELL, "--json"]))
    assert "report_bench" not in data
    assert "reference" not in text and "bench" not in text and "566" not in text
    # a reference: of its own is shown, with its own numbers: the closed form of docs/model.md
    # §7 worked out here, wn sqrt((1 - 2 zeta^2) + sqrt(4 zeta^4 - 4 zeta^2 + 2)); zeta = 0.5
    # gives a = 0.5, sqrt(0.25 - 1 + 2) = sqrt(1.25), so 200 sqrt(0.5 + 1.118034) = 254.40 rad/s
    path = _config(tmp_path, reference={"source": "my bench", "step_amplitude": "5 deg",
                                        "fit": {"wn": "200 rad/s", "zeta": 0.5}})
    expected = 200.0 * math.sqrt(0.5 + math.sqrt(1.25))
    bench = json.loads(_ok(["sinedwell", str(path), *DWELL, "--json"]))["report_bench"]
    assert bench["bandwidth_rad_s"] == pytest.approx(expected, rel=1e-12)
    assert bench["step_deg"] == pytest.approx(5.0, rel=1e-12)
    assert (bench["wn_rad_s"], bench["zeta"], bench["source"]) == (200.0, 0.5, "my bench")
    assert ("reference, 5 deg step fit: 254.4 (wn 200 rad/s, zeta 0.5; my bench)"
            in _ok(["sinedwell", str(path), *DWELL]))


# --- 2. and 3. no QT-CAS words for an actuator that does not name its output ---------------------

@pytest.fixture(scope="module")
def loaded_dc_servo(tmp_path_factory):
    """dc_servo with a load (inertia, load spring, constant moment) and a 2-point load envelope,
    so that the drivetrain notes, the load rows and the envelope text are all shown."""
    raw = yaml.safe_load(DC_SERVO.read_text(encoding="utf-8"))
    raw["load"] = {"inertia": "1e-3 kg*m^2", "hinge_stiffness": "1 N*m/rad",
                   "hinge_bias": "0.1 N*m"}
    raw["load_envelope"] = {"hinge_stiffness": "0:2:2"}
    path = tmp_path_factory.mktemp("dc") / "dc_loaded.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    return path


def _every_output(config, folder, step, profile, dwell, amplitudes):
    """name -> text of every output a user sees of ``config``: each command's, the CSV header
    and every report file (``step``, ``profile``, ``dwell``, ``amplitudes``: the sizes in the
    output's own unit)."""
    outputs = {}
    for name, argv in {
        "analyze": ["analyze", config],
        "analyze --json": ["analyze", config, "--json"],
        "simulate": ["simulate", config, "--step", step],
        "simulate --json": ["simulate", config, "--step", step, "--json", "--csv",
                            str(folder / "step.csv")],
        "simulate --profile": ["simulate", config, *profile],
        "simulate --profile --json": ["simulate", config, *profile, "--json"],
        "sinedwell": ["sinedwell", config, *dwell],
        "sinedwell --json": ["sinedwell", config, *dwell, "--json"],
        "verify": ["verify", config],
        "report": ["report", config, "--amplitudes", amplitudes, "--frequencies",
                   "100,400", "--pade-order", "4", "-o", str(folder / "report"), "-q"],
    }.items():
        outputs[name] = _ok(argv)
    outputs["simulate --csv header"] = (folder / "step.csv").read_text().splitlines()[0]
    for path in sorted((folder / "report").rglob("*")):
        if path.is_file() and path.suffix in {".md", ".json", ".svg", ".html"}:
            outputs[str(path.relative_to(folder))] = path.read_text(encoding="utf-8")
    return outputs


@pytest.fixture(scope="module")
def dc_outputs(loaded_dc_servo, tmp_path_factory):
    """name -> text of every output a user sees for the loaded dc_servo."""
    profile = ["--profile", "10deg", "--velocity", "500deg/s", "--acceleration", "1e4deg/s^2"]
    return _every_output(str(loaded_dc_servo), tmp_path_factory.mktemp("dc_out"), "10deg",
                         profile, DWELL, "0.5deg,10deg")


def _text_leaks(outputs, name):
    """{output: words} of ``outputs`` that do not belong to the shipped config ``name``'s
    output (:func:`output_words.leaks`), read in the texts a user reads: the data keys (JSON,
    the CSV header) are the same for every config and keep their names."""
    label, quantity, surface = SHIPPED[name]
    found = {key: sorted(set(leaks(text, label, quantity, surface)))
             for key, text in outputs.items()
             if not key.endswith((".json", "--json", "csv header"))}
    return {key: words for key, words in found.items() if words}


def test_no_qt_cas_words_for_another_actuator(dc_outputs):
    # before: "at the fin", "command_fin", "hinge stiffness", "(fin)" rows, "report §7", ...
    assert len(dc_outputs) > 12  # every command, and the report's files and figures
    leaks = {name: sorted(set(_leaks(text))) for name, text in dc_outputs.items()}
    assert not {name: words for name, words in leaks.items() if words}
    for name, text in dc_outputs.items():
        assert "report §7" not in text and "ARL" not in text, name
    assert dc_outputs["simulate --csv header"].startswith("t [s],command_output [deg],delta [deg]")
    assert "at the output" in dc_outputs["simulate"]
    assert "load spring K_h" in dc_outputs["analyze"]
    assert "second-order-plus-delay fit (docs/model.md §7)" in dc_outputs["simulate"]
    assert "second-order-plus-delay fits (docs/model.md §7)" in dc_outputs["report/report.md"]
    assert "load spring K_h at the output" in dc_outputs["report/report.md"]
    # nor the flight-control words: dc_servo's output is not a control surface
    assert not _text_leaks(dc_outputs, "dc_servo")
    assert "### Stiffness, effort and noise (base)" in dc_outputs["report/report.md"]


#: The other shipped architectures as shipped: (step, profile move, sine-dwell, report amplitudes)
#: in their output's unit (small sizes: what is printed, not the numbers, is tested here).
ARCHITECTURES = {
    "cascade_axis": ("2deg", ["--profile", "10deg", "--velocity", "500deg/s", "--acceleration",
                              "1e4deg/s^2"], DWELL, "0.5deg,2deg"),
    "ball_screw": ("5mm", ["--profile", "5mm", "--velocity", "100mm/s", "--acceleration",
                           "2000mm/s^2"], ["--amplitudes", "0.5mm", "--frequencies", "100,300"],
                   "0.5mm,5mm"),
}


@pytest.mark.slow  # every command and a report per architecture (.ci/run runs it)
@pytest.mark.parametrize("name", sorted(ARCHITECTURES))
def test_every_output_of_each_architecture_speaks_of_its_output(name, tmp_path):
    # before: "closed loop T = delta/delta_cmd", "what the flight-control system sees", "first
    # harmonic of delta", and on the screw "rod angle δ = θ / gear ratio", "rod position δ"
    step, profile, dwell, amplitudes = ARCHITECTURES[name]
    outputs = _every_output(str(ROOT / "configs" / f"{name}.yaml"), tmp_path, step, profile,
                            dwell, amplitudes)
    assert len(outputs) > 12  # every command, and the report's files and figures
    assert not _text_leaks(outputs, name)
    label, quantity, _ = SHIPPED[name]
    report = outputs["report/report.md"]
    assert "### Stiffness, effort and noise (base)" in report
    assert f"closed loop T = {label} {quantity} / its command" in outputs["analyze"]
    assert f"first harmonic of the {label} {quantity} / of its command" in outputs["sinedwell"]
    definition = ("rod position x = θ·lead / (2π·gear ratio)" if quantity == "position"
                  else "output angle δ = θ / gear ratio")
    assert f"figure definitions: docs/model.md (motor-shaft loops, {definition})" in report
    x = "x" if quantity == "position" else "δ"  # the output's symbol in the figures
    figures = "report/figures/base/"
    assert f"{name} / base: closed loop T = {x}/{x}_cmd (exact delays)" in outputs[
        f"{figures}closed_loop.svg"]
    assert f"|{x}/{x}_cmd| first harmonic [dB]" in outputs[f"{figures}sinedwell.svg"]
    assert f"{label} {quantity} {x} [" in outputs[f"{figures}steps.svg"]


def test_the_shipped_config_names_its_output_fin():
    # configs/qt_cas.yaml: output_name: fin, in the text and the labels
    assert "nonlinear step of 2 deg at the fin" in _ok(["simulate", "--step", "2deg"])
    assert "at the fin; it is lost" in _ok(["analyze", "--variant", "loaded"])
    import cas_freq as cf

    for config, name in ((None, "fin"), (DC_SERVO, "output")):
        figure = cf.load(config).simulate(step="1 deg").plot()
        angle = figure.axes[0]
        assert angle.get_ylabel() == f"{name} angle [deg]"
        assert angle.lines[1].get_label() == f"{name} angle δ"


def test_data_keys_do_not_depend_on_the_output_name(tmp_path):
    # the JSON and the CSV header of a config naming its output "rudder" are dc_servo's
    plain, named = DC_SERVO, _config(tmp_path, output_name="rudder")
    runs = {}
    for path in (plain, named):
        csv_path = tmp_path / f"{path.stem}.csv"
        data = json.loads(_ok(["simulate", str(path), "--step", "5deg", "--json", "--csv",
                               str(csv_path)]))
        runs[path] = (data, csv_path.read_text().splitlines()[0])

    def keys(value, prefix=""):
        if isinstance(value, dict):
            return {k for key, item in value.items() for k in keys(item, f"{prefix}.{key}")} \
                | {prefix}
        return {prefix}

    assert keys(runs[plain][0]) == keys(runs[named][0])
    assert runs[plain][1] == runs[named][1]
    assert "at the rudder" in _ok(["simulate", str(named), "--step", "5deg"])


# --- 3. the former CSV column names still fit ----------------------------------------------------

def _second_order_csv(header, scale=1.0):
    """A CSV of the closed-form second-order-plus-delay step of ARL-TR-9136 §7 (wn 462 rad/s,
    zeta 0.54, td 2 ms; docs/model.md §7), 10 deg, every 50 us for 40 ms: time, command and
    angle columns under ``header`` (``scale``: the columns' angle unit per deg)."""
    from cas_freq.simulation.second_order import second_order_step

    t = np.arange(0, 801) * 5e-5
    angle = second_order_step(t, 462.0, 0.54, 2e-3, 10.0)
    rows = io.StringIO()
    writer = csv.writer(rows)
    writer.writerow(header)
    writer.writerows(zip(t, np.full(t.size, 10.0 * scale), angle * scale, strict=True))
    return rows.getvalue()


@pytest.mark.parametrize(("header", "scale"), [
    (["t [s]", "command_fin [deg]", "delta [deg]"], 1.0),  # simulate --csv before issue 24
    (["t [s]", "command_output [deg]", "delta [deg]"], 1.0),  # simulate --csv now
    (["time_s", "command_fin_deg", "fin_angle_deg"], 1.0),
    (["time_s", "command_output_rad", "output_angle_rad"], math.pi / 180.0),
])
def test_old_and_new_column_names_fit(tmp_path, header, scale):
    # the fit recovers the closed form's parameters (noise-free data: 1e-6 leaves room for the
    # CSV's decimal rounding and the optimiser's tolerance, and catches a wrong column or unit)
    path = tmp_path / "step.csv"
    path.write_text(_second_order_csv(header, scale), encoding="utf-8")
    fit = json.loads(_ok(["fit", str(path), "--step", "10deg", "--json"]))["fit"]
    assert fit["wn_rad_s"] == pytest.approx(462.0, rel=1e-6)
    assert fit["zeta"] == pytest.approx(0.54, rel=1e-6)
    # the same file as a bench recording (fit --data): the command column sets the step
    data = json.loads(_ok(["fit", str(DC_SERVO), "--data", str(path), "--json"]))
    recording = data["recordings"][0]
    assert recording["step_from"] == "command" and recording["step_deg"] == pytest.approx(10.0)
    assert recording["fit"]["wn_rad_s"] == pytest.approx(462.0, rel=1e-6)


# --- schema: output_name and drive ---------------------------------------------------------------

@pytest.mark.parametrize(("changes", "expect"), [
    ({"output_name": "fin!"}, "output_name: expected a name for labels (1 to 40 letters, "
     "digits, spaces, '_' or '-', starting with a letter, e.g. fin), got 'fin!'"),
    ({"output_name": 3}, "output_name: must be a string, got 3"),
    ({"drive": "epos5"}, "drive: must be one of 'epos4', got 'epos5'"),
])
def test_bad_output_name_or_drive_exit_2_naming_the_key(tmp_path, changes, expect):
    code, out, err = run_cli(["analyze", str(_config(tmp_path, **changes))])
    assert code == 2 and out == "" and err.count("\n") == 1 and expect in err, err


def test_output_label_defaults_to_output():
    from cas_freq.config import load_variant

    assert load_variant(DC_SERVO, "base").params.output_label == "output"
    shipped = load_variant(None, "base").params
    assert (shipped.output_name, shipped.output_label, shipped.drive) == ("fin", "fin", "epos4")


# --- 4. tune's EPOS4 table only for an EPOS4 drive -----------------------------------------------

def test_tune_prints_epos4_units_only_for_an_epos4_drive(tmp_path):
    # one candidate, no refinement: what is printed, not the search, is tested here
    small = ["--candidates", "1", "--rounds", "0", "-o"]
    out = _ok(["tune", str(DC_SERVO), *small, str(tmp_path / "a.yaml")])
    data = json.loads(_ok(["tune", str(DC_SERVO), *small, str(tmp_path / "b.yaml"), "--json"]))
    assert "EPOS4" not in out and data["drive"] is None
    epos4 = _config(tmp_path, "epos4.yaml", drive="epos4")
    out = _ok(["tune", str(epos4), *small, str(tmp_path / "c.yaml")])
    data = json.loads(_ok(["tune", str(epos4), *small, str(tmp_path / "d.yaml"), "--json"]))
    assert "EPOS4 units" in out and "EPOS4 units" in data["drive"]["table"]
    # on request the export stays available for any config
    assert "EPOS4" in _ok(["epos4", "export", str(DC_SERVO)])
