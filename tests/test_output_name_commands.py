"""Issue 25, "Generic words": "output", never "fin", unless the config names its output.

tests/test_output_wording.py (issue 24) covers analyze, simulate, sinedwell, verify's table and
report on dc_servo; here every other command (compare, sweep, montecarlo, tune, epos4, fit,
verify's JSON and JUnit, simulate --command), the Python API's text, HTML tables and figure
labels, and the texts that name the output of several configs at once (compare) or of the
shipped config, which names it (``output_name: fin``).
"""

import re
from pathlib import Path

import matplotlib
import pytest
import yaml
from clirun import run_cli
from output_words import leaks as words_leaks

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]
DC_SERVO = ROOT / "configs" / "dc_servo.yaml"
RECORDINGS = ROOT / "examples" / "recordings"

#: "fin" as a word or a part of a name (``fin``, ``fin_angle``, ``Fin``), not inside a longer
#: word (``final``, ``finite``, ``define``).
FIN = re.compile(r"(?<![a-z])fin(?![a-z])", re.IGNORECASE)

#: Small grids: what is printed, not the numbers, is tested here.
SMALL = ["--amplitudes", "1deg", "--frequencies", "100,300", "--pade-order", "4"]
STEP_5 = ["--step", "5deg"]


def _ok(argv):
    code, out, err = run_cli(argv)
    assert code == 0, err
    return out + err


@pytest.fixture(scope="module")
def dc_config(tmp_path_factory):
    """dc_servo (no output_name) with a load, a second variant and requirements on a step, a
    sine-dwell and a profile move, so that verify prints every kind of condition."""
    raw = yaml.safe_load(DC_SERVO.read_text(encoding="utf-8"))
    raw["load"] = {"inertia": "1e-3 kg*m^2", "hinge_stiffness": "1 N*m/rad",
                   "hinge_bias": "0.1 N*m"}
    raw["variants"] = {"stiff": {"position_loop.Kp": "8 A/rad"}}
    raw["requirements"] += [
        {"id": "OS", "metric": "step.overshoot_pct", "max": "50 %", "step": "5 deg"},
        {"id": "SD", "metric": "sinedwell.bandwidth_rad_s", "min": "50 rad/s",
         "amplitude": "1 deg", "frequencies": "100:300:2", "severity": "advisory"},
        {"id": "PR", "metric": "profile.tracking_error_max_deg", "max": "5 deg",
         "profile": {"distance": "10 deg", "velocity": "500 deg/s",
                     "acceleration": "1e4 deg/s^2"}, "severity": "advisory"},
    ]
    path = tmp_path_factory.mktemp("dc") / "dc.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def dc_texts(dc_config, tmp_path_factory):
    """name -> every text a user sees of each command on ``dc_config``: stdout and stderr, and
    the text files it writes (Markdown, HTML, JSON, CSV, SVG with its text as text, YAML, XML)."""
    out = tmp_path_factory.mktemp("out")
    config = str(dc_config)
    command = out / "command.csv"
    command.write_text("t [s],output_angle [deg]\n0,0\n0.002,2\n0.01,2\n", encoding="utf-8")
    texts = {}
    for name, argv in {
        "compare": ["compare", config, *SMALL, "-o", str(out / "compare"), "-q"],
        "sweep": ["sweep", config, "--set", "position_loop.Kp=4,6", *STEP_5],
        "sweep -o": ["sweep", config, "--set", "position_loop.Kp=4,6", *STEP_5,
                     "--sinedwell", "1deg", "--frequencies", "100,300", "-o",
                     str(out / "sweep"), "-q"],
        "montecarlo": ["montecarlo", config, "--samples", "4", "--tolerance", "motor.Km=10%",
                       "--seed", "1", *STEP_5, "-o", str(out / "mc"), "-q"],
        "tune": ["tune", config, "--candidates", "1", "--rounds", "0", "-o",
                 str(out / "tuned.yaml"), "-q"],
        "tune --json": ["tune", config, "--candidates", "1", "--rounds", "0", "-o",
                        str(out / "tuned2.yaml"), "-q", "--json"],
        "epos4 export": ["epos4", "export", config],
        "epos4 import": ["epos4", "import", str(ROOT / "examples/epos4/qt_cas_tuned.dcf"),
                         config, "--variant", "imported"],
        "verify": ["verify", config, "--all-variants", "--junit", str(out / "junit.xml")],
        "verify --json": ["verify", config, "--json"],
        "fit --data step": ["fit", config, "--data", str(RECORDINGS / "step_run1.csv"),
                            "-o", str(out / "fit_step"), "-q"],
        "fit --data sweep": ["fit", config, "--data",
                             str(RECORDINGS / "sweep" / "sweep_chirp.csv"),
                             "-o", str(out / "fit_sweep"), "-q"],
        "simulate --command": ["simulate", config, "--command", str(command)],
    }.items():
        texts[name] = _ok(argv)
    for name, argv in {  # bad input: the message names the output
        "simulate --step 100deg": ["simulate", config, "--step", "100deg"],
        "sinedwell --amplitudes 100deg": ["sinedwell", config, "--amplitudes", "100deg"],
    }.items():
        code, stdout, stderr = run_cli(argv)
        assert code == 2 and "at the output" in stderr, stderr
        texts[name] = stdout + stderr
    for path in sorted(out.rglob("*")):
        if path.is_file() and path.name != "command.csv":
            texts[f"file {path.relative_to(out)}"] = path.read_text(encoding="utf-8")
    return texts


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_every_command_says_output_for_an_actuator_that_does_not_name_it(dc_texts):
    written = {name.removeprefix("file ") for name in dc_texts if name.startswith("file ")}
    # each command wrote what it should (a missing file would leave nothing to check)
    for expected in ("compare/report.md", "compare/index.html", "compare/results.json",
                     "sweep/sweep.svg", "sweep/sweep.csv", "mc/histograms.svg", "junit.xml",
                     "fit_step/fit.svg", "fit_sweep/frf.svg", "tuned.yaml"):
        assert expected in written, sorted(written)
    assert any(name.startswith("compare/figures/") and name.endswith(".svg") for name in written)
    leaks = {name: sorted(set(FIN.findall(text))) for name, text in dc_texts.items()}
    assert not {name: words for name, words in leaks.items() if words}
    # nor the flight-control words (dc_servo's output is not a control surface), in the texts a
    # user reads (JSON and CSV keys are the same for every config)
    flight = {name: sorted(set(words_leaks(text, "output", "angle", False)))
              for name, text in dc_texts.items()
              if not name.endswith((".json", "--json", ".csv", ".xml", ".yaml"))}
    assert not {name: words for name, words in flight.items() if words}
    # the compare report names the output where it names it at all
    assert "amplitudes at the output: 1°" in dc_texts["file compare/report.md"]
    assert "output angle" in dc_texts["file fit_step/fit.svg"]
    assert "output angle / output command" in dc_texts["file fit_sweep/frf.svg"]


def test_svg_figures_hold_their_labels_as_text(dc_texts):
    # the leak check above reads labels only if matplotlib writes them as <text>, not as paths
    svg = dc_texts["file compare/figures/step_overlay.svg"]
    labels = re.findall(r"<text[^>]*>([^<]*)</text>", svg)
    assert "nonlinear output steps (limits, exact delays) vs linear (dotted)" in labels


def _figure_texts(figure):
    """Every text of a matplotlib figure: titles, axis labels, ticks, legends, annotations."""
    texts = [text.get_text() for text in figure.findobj(matplotlib.text.Text)]
    return texts + [line.get_label() for axes in figure.axes for line in axes.get_lines()]


def _api_texts(config):
    """name -> text of the Python API's results for ``config``: ``repr``, ``_repr_html_`` and
    the texts of each ``.plot()``."""
    import numpy as np

    import cas_freq as cf

    actuator = cf.load(config)
    results = {
        "actuator": actuator,
        "analyze": actuator.analyze(),
        "simulate": actuator.simulate(step="5 deg"),
        "simulate_profile": actuator.simulate_profile(distance="10 deg"),
        "frequency_response": actuator.frequency_response(np.array([10.0, 100.0])),
        "vary": actuator.vary({"position_loop.Kp": [4, 6]}),
        "vary.analyze": actuator.vary({"position_loop.Kp": [4, 6]}).analyze(),
        "tune": actuator.tune(candidates=1, rounds=0),
    }
    texts = {}
    for name, result in results.items():
        texts[name] = repr(result)
        if hasattr(result, "_repr_html_"):
            texts[f"{name} html"] = result._repr_html_()
        if hasattr(result, "plot"):
            texts[f"{name}.plot()"] = "\n".join(_figure_texts(result.plot()))
    return texts


def test_the_python_api_says_output_unless_the_config_names_it(dc_config):
    import matplotlib.pyplot as plt

    try:
        dc = _api_texts(dc_config)
        shipped = _api_texts(None)
    finally:
        plt.close("all")
    assert not {name: FIN.findall(text) for name, text in dc.items() if FIN.search(text)}
    assert "5° step of the output (nonlinear)" in dc["simulate"]
    assert "output angle [deg]" in dc["simulate.plot()"]
    assert "output angle [deg]" in dc["simulate_profile.plot()"]
    # the shipped config names its output: the same texts say "fin"
    assert "5° step of the fin (nonlinear)" in shipped["simulate"]
    assert "5° step of the fin (nonlinear)" in shipped["simulate html"]
    assert "fin angle [deg]" in shipped["simulate.plot()"]
    assert "fin angle [deg]" in shipped["simulate_profile.plot()"]


# --- several configs: the name they share, else "output" -----------------------------------------

def _meanings(variants):
    from cas_freq.report.compare import parameter_differences

    rows, _ = parameter_differences(variants)
    return {row[0]: row[1] for row in rows}


def test_compare_names_the_output_the_configs_share(tmp_path):
    # before: the compare report's parameter meanings said "at the output" for the shipped
    # config, whose output is a fin (its report's parameter table said "at the fin")
    from cas_freq.config import load_variant
    from cas_freq.config.wording import common_output_label

    qt = [load_variant(None, "base"), load_variant(None, "loaded")]
    assert _meanings(qt)["load.inertia"] == "load inertia J_L at the fin"
    assert _meanings(qt)["gear.backdrive_efficiency"].startswith(
        "backdrive efficiency eta_b (the fin drives the motor;")
    raw = yaml.safe_load(DC_SERVO.read_text(encoding="utf-8"))
    raw["variants"] = {"loaded": {"load.inertia": "1e-3 kg*m^2"}}
    rudder = tmp_path / "rudder.yaml"
    rudder.write_text(yaml.safe_dump({**raw, "output_name": "rudder"}, sort_keys=False))
    plain = tmp_path / "plain.yaml"
    plain.write_text(yaml.safe_dump(raw, sort_keys=False))
    assert _meanings([load_variant(plain, "base"), load_variant(plain, "loaded")])[
        "load.inertia"] == "load inertia J_L at the output"
    assert _meanings([load_variant(rudder, "base"), load_variant(rudder, "loaded")])[
        "load.inertia"] == "load inertia J_L at the rudder"
    # configs naming their outputs differently: "output"
    mixed = [load_variant(None, "base"), load_variant(rudder, "loaded")]
    assert _meanings(mixed)["load.inertia"] == "load inertia J_L at the output"
    assert common_output_label(v.params for v in mixed) == "output"
    assert common_output_label(v.params for v in qt) == "fin"


def test_the_shipped_config_compare_report_says_fin(tmp_path):
    # before: "amplitudes at the output" and "nonlinear output steps" for the shipped config,
    # whose output is a fin (its own report said "fin"); two variants, one amplitude
    _ok(["compare", "--variants", "base,fitted", *SMALL, "-o", str(tmp_path / "c"), "-q"])
    assert "- amplitudes at the fin: 1°;" in (tmp_path / "c" / "report.md").read_text()
    svg = (tmp_path / "c" / "figures" / "step_overlay.svg").read_text(encoding="utf-8")
    assert "nonlinear fin steps (limits, exact delays) vs linear (dotted)" in re.findall(
        r"<text[^>]*>([^<]*)</text>", svg)
