"""The words follow the config's output on every shipped architecture: its name (``output_name``,
else "output"), its kind (an angle δ, or a position x at a linear output, ``gear.screw_lead``) and
its role: the flight-control words (the flight-control system, delta/delta_cmd, the hinge moment
M) only where the config says the output is a control surface (``control_surface: true``).

Before, ``analyze`` said "closed loop T = delta/delta_cmd", "(1/|delta/M| ...)" and "what the
flight-control system sees" on the industrial cascade axis and the ball-screw EMA, the report had
a section "What the flight-control system sees", ``sinedwell`` said "first harmonic of delta /
command", and the screw report said "rod angle δ = θ / gear ratio" of a rod whose position is
x = θ·lead/(2π·N). The slow test of tests/test_output_wording.py runs every command and every
report file on each shipped architecture.
"""

import math
import types
from pathlib import Path

import pytest
import yaml
from clirun import run_cli
from output_words import SHIPPED, leaks

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = ROOT / "configs"


def _ok(argv):
    code, out, err = run_cli(argv)
    assert code == 0, err
    return out


def test_every_shipped_config_is_covered():
    assert {path.stem for path in CONFIGS.glob("*.yaml")} == set(SHIPPED)


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_output_words_follow_each_config(name):
    from cas_freq.config import load_variant
    from cas_freq.config.wording import OutputWords

    label, quantity, surface = SHIPPED[name]
    words = OutputWords.of(load_variant(CONFIGS / f"{name}.yaml", "base").params)
    assert (words.label, words.quantity, words.control_surface) == (label, quantity, surface)
    assert words.value == f"{label} {quantity}"
    assert words.symbol == ("x" if quantity == "position" else "δ")


def test_the_linear_output_is_defined_by_the_lead_not_the_gear_ratio_alone():
    # ball_screw: 2:1 belt, 5 mm lead. The rod moves one lead per screw turn, so a motor angle θ
    # gives x = θ/(2π·2)·5 mm; the model's ratio N [rad/m] must be 2π·2/0.005 m, the same
    # relation the text states (1e-12: one float rounding of 2π·2/0.005)
    from cas_freq.config import load_variant
    from cas_freq.config.wording import OutputWords
    from cas_freq.core.parameters import LoopParameters

    loaded = load_variant(CONFIGS / "ball_screw.yaml", "base")
    ratio = float(LoopParameters.from_config(loaded.params).ratio[0])
    assert ratio == pytest.approx(2.0 * math.pi * 2.0 / 0.005, rel=1e-12)
    assert OutputWords.of(loaded.params).definition == "rod position x = θ·lead / (2π·gear ratio)"
    assert OutputWords.of(load_variant(CONFIGS / "dc_servo.yaml", "base").params).definition \
        == "output angle δ = θ / gear ratio"


@pytest.fixture(scope="module")
def analyzed():
    """name -> (analyze's text, the report's "stiffness, effort and noise" blocks as text) of
    each shipped config's base variant."""
    from cas_freq.analysis import analyze
    from cas_freq.config import load_variant
    from cas_freq.report.disturbance import disturbance_blocks

    found = {}
    for name in SHIPPED:
        path = CONFIGS / f"{name}.yaml"
        loaded = load_variant(path, "base")
        blocks = disturbance_blocks(types.SimpleNamespace(analysis=analyze(loaded),
                                                          loaded=loaded))
        found[name] = (_ok(["analyze", str(path)]), [repr(block) for block in blocks])
    return found


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_analyze_and_the_report_section_speak_of_the_output(analyzed, name):
    label, quantity, surface = SHIPPED[name]
    text, blocks = analyzed[name]
    assert not leaks(text, label, quantity, surface)
    assert not leaks("\n".join(blocks), label, quantity, surface)
    if surface:  # the QT-CAS's words, as the README shows them
        assert "  closed loop T = delta/delta_cmd\n" in text
        assert "  what the flight-control system sees (every loop closed)\n" in text
        assert "(1/|delta/M| with every loop closed)" in text
        assert "What the flight-control system sees (base)" in blocks[0]
    else:
        assert f"  closed loop T = {label} {quantity} / its command\n" in text
        assert "  stiffness, effort and noise (every loop closed)\n" in text
        load = "load force" if quantity == "position" else "load torque"
        assert f"(1/|{label} {quantity} per {load}| with every loop closed)" in text
        assert f"(|current per {label} {quantity} command| without feed-forward)" in text
        assert "Stiffness, effort and noise (base)" in blocks[0]
    symbols = ("1/|x/F_load|", "|i/x_cmd|") if quantity == "position" else \
        ("1/|δ/M_load|", "|i/δ_cmd|")
    assert all(symbol in blocks[1] for symbol in symbols), blocks[1]


@pytest.mark.parametrize(("name", "amplitude"), [("ball_screw", "0.5mm"),
                                                 ("cascade_axis", "1deg")])
def test_sinedwell_names_the_output(name, amplitude):
    label, quantity, surface = SHIPPED[name]
    text = _ok(["sinedwell", str(CONFIGS / f"{name}.yaml"), "--amplitudes", amplitude,
                "--frequencies", "100,300"])
    assert f"first harmonic of the {label} {quantity} / of its command" in text
    assert not leaks(text, label, quantity, surface)


def test_control_surface_is_a_boolean(tmp_path):
    raw = yaml.safe_load((CONFIGS / "dc_servo.yaml").read_text(encoding="utf-8"))
    raw["control_surface"] = "yes"
    path = tmp_path / "dc.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    code, out, err = run_cli(["analyze", str(path)])
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert ("control_surface: expected true or false (true: the output is a control surface, "
            "e.g. a fin), got 'yes'") in err
    # a config that says so gets the flight-control words, whatever it calls its output
    raw["control_surface"] = True
    path.write_text(yaml.safe_dump(raw, sort_keys=False), encoding="utf-8")
    assert "what the flight-control system sees" in _ok(["analyze", str(path)])


def test_the_api_figures_of_a_linear_output_say_x():
    # before: "T = δ/δ_cmd", "command δ_cmd", "rod position δ" on a rod that moves x [m]
    import matplotlib
    import numpy as np

    import cas_freq as cf

    actuator = cf.load(CONFIGS / "ball_screw.yaml")
    figures = {"frequency_response": actuator.frequency_response(np.geomspace(1.0, 1e4, 50)),
               "analyze": actuator.analyze(), "simulate": actuator.simulate(step="1 mm")}
    texts = {}
    for name, result in figures.items():
        figure = result.plot()
        texts[name] = [text.get_text() for text in figure.findobj(matplotlib.text.Text)] + [
            line.get_label() for axes in figure.axes for line in axes.get_lines()]
    assert "T = x/x_cmd (closed loop)" in texts["frequency_response"]
    assert any(label.startswith("T = x/x_cmd (closed loop)") for label in texts["analyze"])
    assert {"command x_cmd", "rod position x"} <= set(texts["simulate"])
    assert not {name: found for name, text in texts.items()
                if (found := leaks("\n".join(text), "rod", "position", False))}


@pytest.mark.parametrize("name", ["ball_screw", "cascade_axis"])
def test_the_report_closed_loop_figure_names_the_output_symbol(name):
    # the report's closed-loop figure: its title and |T|'s label in the output's symbol (x at
    # the screw), and nothing else where the symbol goes (a number there once: the bandwidth)
    import matplotlib

    from cas_freq.analysis import analyze
    from cas_freq.config import load_variant
    from cas_freq.plots.report import closed_loop
    from cas_freq.report.data import ReportSettings, curves, loop_frequency_range, variant_label

    loaded = load_variant(CONFIGS / f"{name}.yaml", "base")
    analysis = analyze(loaded)
    data = types.SimpleNamespace(
        label=variant_label(loaded), analysis=analysis, loaded=loaded, verdicts=(),
        curves=curves(loaded.params, loop_frequency_range(analysis),
                      ReportSettings().curve_points_per_decade))
    figure = closed_loop(data)
    texts = [text.get_text() for text in figure.findobj(matplotlib.text.Text)]
    labels = [line.get_label() for axes in figure.axes for line in axes.get_lines()]
    x = "x" if SHIPPED[name][1] == "position" else "δ"
    assert f"{name} / base: closed loop T = {x}/{x}_cmd (exact delays)" in texts
    assert f"|T| = |{x}/{x}_cmd|" in labels
