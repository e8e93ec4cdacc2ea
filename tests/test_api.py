"""The Python API (cas_freq.api): the README example, and each call equal to the CLI or
engine result it wraps."""

import contextlib
import io
import json
import re
import subprocess
import sys

import numpy as np
import pytest
from clirun import run_cli
from docs_pages import doc_section

import cas_freq as cf
from cas_freq.config import default_config_path

ROOT = default_config_path().parents[1]
KP_VALUES = np.linspace(2, 12, 200)


@pytest.fixture(scope="module")
def act():
    return cf.load(default_config_path(), variant="fitted", set={"position_loop.Kp": "5 A/rad"})


def _readme_example():
    """The first code block of docs/api.md ("Python API", moved there from the README) and the
    output shown after it."""
    section = doc_section("docs/api.md", "Python API")
    code, output = re.findall(r"```(?:python|text)\n(.*?)```", section, flags=re.S)[:2]
    return code, output


def test_readme_example_runs_as_written_and_prints_what_the_readme_shows(monkeypatch):
    code, shown = _readme_example()
    monkeypatch.chdir(ROOT)  # the example names configs/qt_cas.yaml relative to the repository
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "docs/api.md", "exec"), {})
    assert out.getvalue() == shown


def test_to_dict_is_the_cli_json():
    code, out, err = run_cli(["analyze", "--json", "--variant", "fitted",
                              "--set", "position_loop.Kp=5"])
    assert code == 0, err
    res = cf.load(variant="fitted", set={"position_loop.Kp": 5}).analyze()
    assert json.loads(json.dumps(res.to_dict())) == json.loads(out)


@pytest.mark.parametrize("overrides, words", [
    ({"motor.Km": -1}, ["with set= motor.Km=-1", "motor.Km: must be >= 1e-09"]),
    ({"motor..Km": 1}, ["set=: 'motor..Km' is not a dotted key"]),
], ids=["bad-value", "bad-key"])
def test_set_errors_name_the_api_argument_not_the_cli_option(overrides, words):
    """Issue 24 review: errors of ``load(set=...)`` said "with --set", an option the API has
    not; they name ``set=``, and the CLI keeps "--set"."""
    from cas_freq.core.exceptions import ConfigError

    with pytest.raises(ConfigError) as caught:
        cf.load(set=overrides)
    message = str(caught.value)
    assert "--set" not in message
    for word in words:
        assert word in message, (word, message)
    code, _, err = run_cli(["analyze", "--set", "motor.Km=-1"])
    assert code == 2 and "with --set motor.Km=-1" in err


def test_load_defaults_to_the_shipped_base_variant():
    act = cf.load()
    assert act.variant == "base"
    assert act.config_path == str(default_config_path())
    assert act.overrides == ()
    assert act.params.name == "qt_cas"
    assert act.variants == ["base", "fitted", "relaxed", "loaded", "fin_encoder",
                            "sampled"]


def test_analyze_takes_the_delay_and_range_of_the_cli(act):
    res = act.analyze(delay="pade:4", frequency_range=(0.1, 1e5))
    assert res.delay_model == "pade:4"
    assert res.frequency_range_rad_s == pytest.approx((0.1, 1e5))


def test_vary_gives_the_figures_of_one_at_a_time(act):
    many = act.vary({"position_loop.Kp": KP_VALUES}).analyze()
    assert many.closed_loop.bandwidth_rad_s.shape == (200,)
    for index in (0, 77, 199):
        one = cf.load(variant="fitted", set={"position_loop.Kp": float(KP_VALUES[index])})
        res = one.analyze()
        assert bool(many.stable[index]) == res.stable
        assert many.stability.verdict[index] == res.stability.verdict
        groups = [(group, getattr(res, group), getattr(many, group))
                  for group in ("current_loop", "position_loop", "closed_loop")]
        for group, figures, batches in groups:
            for name, value in vars(figures).items():
                if isinstance(value, tuple):  # the lists of crossings are not batch figures
                    continue
                if name == "loop_at_a_time":  # the same figures with every other loop closed
                    if value is not None:
                        groups.append((f"{group}.{name}", value, getattr(batches, name)))
                    continue
                batch = getattr(batches, name)[index]
                if value is None:
                    assert np.isnan(batch), (index, group, name)
                else:
                    assert batch == pytest.approx(value, rel=1e-6), (index, group, name)


def test_frequency_response_is_the_model_at_j_omega(act):
    from cas_freq.model import ActuatorLoops

    omega = np.geomspace(1.0, 1e5, 50)
    fr = act.frequency_response(omega)
    loops = ActuatorLoops(act.params)
    assert fr.delay_model == "exact"
    np.testing.assert_array_equal(fr.closed_loop, loops.closed_loop(1j * omega))
    np.testing.assert_array_equal(fr.position_loop, loops.position_loop(1j * omega))
    np.testing.assert_allclose(fr.sensitivity, 1.0 / (1.0 + fr.position_loop))


def test_plots_are_figures_with_the_expected_axes_and_lines(act):
    from matplotlib.figure import Figure

    fig = act.frequency_response(np.geomspace(1.0, 1e5, 200)).plot()
    assert isinstance(fig, Figure)
    magnitude, phase = fig.axes
    assert [line.get_label() for line in magnitude.lines] == [
        "L_i (current loop, broken at V)", "L_p (position loop, broken at i_cmd)",
        "T = δ/δ_cmd (closed loop)"]
    assert len(phase.lines) == 3
    assert magnitude.get_xscale() == "log"
    assert "[dB]" in magnitude.get_ylabel() and "[deg]" in phase.get_ylabel()

    st = act.simulate(step="10 deg")
    fig = st.plot()
    assert isinstance(fig, Figure)
    angle, current = fig.axes
    assert [line.get_label() for line in angle.lines] == ["command δ_cmd", "fin angle δ"]
    assert len(current.lines) == 1
    np.testing.assert_array_equal(current.lines[0].get_ydata(), st.current_a)


def test_simulate_is_the_cli_step():
    st = cf.load(variant="fitted").simulate(step="10 deg")
    code, out, err = run_cli(["simulate", "--variant", "fitted", "--step", "10deg", "--json"])
    assert code == 0, err
    assert json.loads(json.dumps(st.to_dict())) == json.loads(out)
    assert st.step.amplitude_deg == pytest.approx(10.0)
    assert st.output_angle_deg.shape == st.time_s.shape == st.current_a.shape
    assert st.command_deg[-1] == pytest.approx(10.0)


def test_to_control_matches_the_frequency_response_at_low_frequency(act):
    import control

    systems = act.to_control(pade=6)
    omega = np.geomspace(1.0, 300.0, 40)
    fr = act.frequency_response(omega)
    # At omega*tau <= 300 rad/s * 0.46 ms = 0.14 the order-6 Padé error of e^(-s tau) is
    # (6!)^2/(12! 13!) (omega tau)^13 ~ 1e-24: the Padé model equals the exact-delay response
    # here up to rounding in the state-space evaluation, far below 1e-6.
    for name in ("current_loop", "current_closed_loop", "position_loop", "sensitivity",
                 "closed_loop"):
        system = getattr(systems, name)
        assert isinstance(system, control.StateSpace)
        np.testing.assert_allclose(system(1j * omega), getattr(fr, name), rtol=1e-6,
                                   err_msg=name)


def test_importing_cas_freq_imports_neither_matplotlib_nor_control():
    code = ("import sys, cas_freq; cas_freq.load; "
            "print(sorted(m for m in ('matplotlib', 'control') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"
