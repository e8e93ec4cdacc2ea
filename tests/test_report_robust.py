"""Reports that never fail whole, and sine-dwell bandwidths outside their grid (issue 24).

- A variant whose sine-dwell is beyond the simulation budget (a hinge spring comparable to the
  loop stiffness: ω_BW 3.79 rad/s, so the 0.1..5 × ω_BW grid needs an 83 s horizon) is refused
  before anything is simulated; the report and the comparison are written whole, that figure
  "not computed" with the reason and the option that changes it.
- A bandwidth outside the grid is a bound ("> 400", "< 2000"), judged against a requirement
  only where the bound decides it ("not decided" otherwise).
- ``cas-freq sinedwell``'s default grid is the report's rule.
"""

import json
import math

import numpy as np
import pytest
from clirun import run_cli

from cas_freq.cli.common import selected_variants
from cas_freq.report.data import ReportSettings, gather_variant, not_computed_notice
from cas_freq.simulation.sinedwell import bandwidth_bound, bound_meets, dwell_frequencies

#: The shipped config's base part, with a variant "slow": the shipped ``loaded`` variant's
#: drivetrain with K_h = 30 N·m/rad (analyze: ω_BW 3.791 rad/s, stable).
SLOW_VARIANT = """
variants:
  slow:
    motor.Km: 0.0075 N*m/A
    motor.mu_v: 1.2e-6 N*m*s/rad
    gear.efficiency: 0.7
    gear.backdrive_efficiency: 0
    gear.stiffness: 3000 N*m/rad
    gear.damping: 0.03 N*m*s/rad
    load.inertia: 4.62e-5 kg*m^2
    load.hinge_stiffness: 30 N*m/rad
"""


def shipped_base():
    """configs/qt_cas.yaml without its variants, envelope, reference and requirements."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[1] / "configs" / "qt_cas.yaml").read_text()
    return text[:text.index("\nvariants:")] + "\n"


@pytest.fixture(scope="module")
def slow_config(tmp_path_factory):
    path = tmp_path_factory.mktemp("slow") / "slow.yaml"
    path.write_text(shipped_base() + SLOW_VARIANT)
    return path


ONE_DEGREE = ReportSettings(amplitudes_rad=(math.radians(1.0),), pade_order=6)


@pytest.fixture(scope="module")
def datas(slow_config):
    """base (a normal variant) and slow, gathered as report and compare gather them."""
    variants = selected_variants(str(slow_config), ["base", "slow"], [])
    return [gather_variant(loaded, ONE_DEGREE) for loaded in variants]


def test_budget_is_checked_before_any_simulation(slow_config, monkeypatch):
    """The slow variant's sine-dwell is refused by the budget check, before an engine is built
    (no simulation step is taken), with the needed CAS_FREQ_BUDGET in the error."""
    from cas_freq.analysis import analyze
    from cas_freq.simulation import simulator
    from cas_freq.simulation.sinedwell import sine_dwell
    from cas_freq.studies.run import dwell_parameters

    loaded = selected_variants(str(slow_config), ["slow"], [])[0]
    grid = dwell_frequencies(analyze(loaded))
    assert grid[0] == pytest.approx(0.3791, rel=1e-3)  # 0.1 × ω_BW 3.791 rad/s

    def no_engine(*args, **kwargs):
        raise AssertionError("an engine was built for a batch beyond the budget")

    monkeypatch.setattr(simulator, "engine_class", no_engine)
    with pytest.raises(simulator.BudgetError) as caught:
        sine_dwell(dwell_parameters(loaded.params, False), [math.radians(1.0)], grid)
    # horizon 3 settling + 2 measured periods of 0.3791 rad/s = 5 x 2 pi / 0.3791 = 82.9 s
    assert caught.value.horizon_s == pytest.approx(5 * 2 * math.pi / 0.3791, rel=1e-3)
    assert caught.value.factor_needed > 1


def test_report_is_written_whole_with_the_sinedwell_not_computed(slow_config, tmp_path):
    out = tmp_path / "report"
    code, stdout, err = run_cli(["report", str(slow_config), "--variant", "slow",
                                 "--amplitudes", "1deg", "-o", str(out)])
    assert code == 0, err
    # stderr names the variant, the figure and why, with the option that changes it
    assert "variant slow" in err and "sinedwell" in err and "CAS_FREQ_BUDGET=" in err
    results = json.loads((out / "results.json").read_text())
    entry = results["variants"][0]
    assert entry["sinedwell"] is None
    assert "82.9 s horizon" in entry["not_computed"]["sinedwell"]
    assert "--frequencies" in entry["not_computed"]["sinedwell"]
    figures = results["figures"]["slow"]
    assert "figures/slow/steps.svg" in figures and "figures/slow/bode_loops.svg" in figures
    assert "figures/slow/sinedwell.svg" not in figures
    assert (out / "figures/slow/steps.svg").is_file()
    assert not (out / "figures/slow/sinedwell.svg").exists()
    markdown = (out / "report.md").read_text()
    assert "Sine-dwell response per amplitude — qt_cas / slow: not computed: the sine-dwell " \
           "grid 0.3791..18.96 rad/s needs" in markdown
    assert "| sine-dwell bandwidth ω_BW (−3.01 dB) at 1° | rad/s | not computed |" in markdown
    assert "not computed" in (out / "index.html").read_text()


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_report_and_compare_of_a_normal_and_a_slow_variant(datas):
    from cas_freq.report.build import report_files
    from cas_freq.report.compare import compare_files

    base, slow = datas
    assert base.dwell.result is not None and slow.dwell.result is None
    files = dict(report_files(datas, ONE_DEGREE, rendered=None))
    results = json.loads(files["results.json"])
    normal, missing = results["variants"]
    assert normal["sinedwell"]["amplitudes"][0]["bandwidth_rad_s"] > 0
    assert "not_computed" not in normal and missing["sinedwell"] is None
    assert "figures/base/sinedwell.svg" in files and "figures/slow/sinedwell.svg" not in files
    labels = ["qt_cas/base", "qt_cas/slow"]
    compared = dict(compare_files(datas, labels, ONE_DEGREE))
    table = json.loads(compared["results.json"])["figures_table"]
    row = next(r for r in table if r["figure"] == "sinedwell.bandwidth_rad_s 1°")
    assert row["values"][0] > 0 and row["values"][1] == "not computed"
    assert "figures/bandwidth_overlay.svg" in compared
    assert "not computed" in compared["report.md"]
    # the line build_report and build_compare pass to their notice (stderr in the CLI)
    assert not_computed_notice(base) is None
    assert not_computed_notice(slow).startswith("variant slow: sine-dwell (figure sinedwell")


# ---- bounds ---------------------------------------------------------------------------------

def test_bandwidth_bound_of_a_grid_without_a_crossing():
    w = [100.0, 200.0, 400.0]
    assert bandwidth_bound(w, [0.5, 1.0, 2.0]) == (">", 400.0)  # still above −3.01 dB at the top
    assert bandwidth_bound(w, [-4.0, -8.0, -12.0]) == ("<", 100.0)  # below from the bottom
    assert bandwidth_bound(w, [0.0, -1.0, -6.0]) is None  # a crossing inside the grid


@pytest.mark.parametrize(("bound", "minimum", "maximum", "expect"), [
    ((">", 400.0), 300.0, None, True),     # every value above 400 is >= 300
    ((">", 400.0), 500.0, None, None),     # 450 or 600: cannot tell
    (("<", 100.0), 300.0, None, False),    # every value below 100 is < 300
    (("<", 100.0), 50.0, None, None),
    (("<", 100.0), None, 200.0, True),
    ((">", 400.0), None, 300.0, False),
    ((">", 400.0), 300.0, 1000.0, None),   # meets the min, cannot tell the max
    (("<", 100.0), 300.0, 1000.0, False),
])
def test_bound_meets_decides_only_what_the_bound_proves(bound, minimum, maximum, expect):
    assert bound_meets(bound, minimum, maximum) is expect


def test_sinedwell_text_gives_bounds_never_low_for_a_met_requirement():
    """qt_cas base (ω_BW 1385 rad/s, BW-1 requires >= 300 rad/s) dwelt at 0.5° over 100..400
    rad/s: the response is still above −3 dB at 400 rad/s, which proves >= 300."""
    code, out, err = run_cli(["sinedwell", "--amplitudes", "0.5deg", "--frequencies",
                              "100,200,400"])
    assert code == 0, err
    row = next(line for line in out.splitlines() if line.strip().startswith("0.5 deg"))
    assert "> 400 ok" in row and "LOW" not in row
    code, out, err = run_cli(["sinedwell", "--amplitudes", "0.5deg", "--frequencies",
                              "100,200,400", "--json"])
    entry = json.loads(out)["amplitudes"][0]
    assert entry["bandwidth_rad_s"] is None
    assert entry["bandwidth_bound"] == {"relation": ">", "edge_rad_s": 400.0}
    three = json.loads(out)["bandwidth_three_ways"][0]
    assert three["meets_requirement"]["sinedwell_rad_s"] is True


def test_verify_judges_a_sinedwell_bound(tmp_path):
    """PASS where the bound proves the requirement, a required FAIL saying "not decided" where
    it cannot tell, an advisory where it proves a violation."""
    config = tmp_path / "bw.yaml"
    requirement = """
  - id: {id}
    metric: sinedwell.bandwidth_rad_s
    min: {min} rad/s
    amplitude: 0.5 deg
    frequencies: "{grid}"
    severity: {severity}"""
    config.write_text(shipped_base() + "requirements:" + "".join(
        requirement.format(id=i, min=m, grid=g, severity=s) for i, m, g, s in (
            ("PROVEN", 300, "100,200,400", "required"),
            ("OPEN", 500, "100,200,400", "required"),
            ("LOW", 3000, "2000,4000", "advisory"))) + "\n")
    code, out, err = run_cli(["verify", str(config), "--json"])
    assert code == 1, err  # OPEN is required and not decided
    verdicts = {v["id"]: v for v in json.loads(out)["verdicts"]}
    assert verdicts["PROVEN"]["status"] == "PASS"
    assert verdicts["PROVEN"]["value"] is None
    assert (verdicts["PROVEN"]["bound"], verdicts["PROVEN"]["bound_value"]) == (">", 400.0)
    assert verdicts["OPEN"]["status"] == "FAIL" and "not decided" in verdicts["OPEN"]["message"]
    assert verdicts["LOW"]["status"] == "ADVISORY" and verdicts["LOW"]["bound"] == "<"
    assert "violates" in verdicts["LOW"]["message"]


def test_sinedwell_default_grid_is_the_reports():
    """No --frequencies: the grid is 16 points over 0.1..5 × the variant's linear ω_BW, the
    function the report uses (not 100..5000 rad/s for every actuator)."""
    from cas_freq.analysis import analyze
    from cas_freq.config import load_variant

    code, out, err = run_cli(["sinedwell", "--amplitudes", "0.5deg", "--json"])
    assert code == 0, err
    expected = dwell_frequencies(analyze(load_variant(None, "base")))
    assert json.loads(out)["frequencies_rad_s"] == pytest.approx(list(expected), rel=1e-12)
    assert expected[0] == pytest.approx(138.5, rel=1e-3)  # 0.1 × 1385 rad/s


# ---- what sets the small step apart from the linear model -------------------------------------

@pytest.mark.parametrize("efficiency", [1.0, 0.75])
def test_small_step_sentence_names_the_nonlinear_elements(tmp_path, efficiency):
    """A rigid load on the output (J_L 4.62e-5 kg·m², nothing else nonlinear). With η = 1 the
    0.5° step of the simulator is the linear model's (overshoot within 0.05 % of the step: what
    is left is the Padé-10 delays), and the sentence blames the Padé delays only; with η = 0.75
    the simulator's direction-dependent efficiency (docs/model.md §5) moves the overshoot by
    several % (34.8 vs 40.5 %), and the sentence names the efficiency, not the Padé delays."""
    from cas_freq.report.build import small_signal_sentence

    config = tmp_path / f"eta{efficiency}.yaml"
    config.write_text(shipped_base() + "variants:\n  loaded:\n    load.inertia: 4.62e-5 kg*m^2\n"
                      f"    gear.efficiency: {efficiency}\n")
    loaded = selected_variants(str(config), ["loaded"], [])[0]
    settings = ReportSettings(amplitudes_rad=(math.radians(0.5),), pade_order=10,
                              frequencies_rad_s=(500.0, 1000.0))
    data = gather_variant(loaded, settings)
    nonlinear = data.dwell.steps[0].step.overshoot_pct
    linear = data.linear_step_figures[0].overshoot_pct
    text = small_signal_sentence(data)
    assert "no limit is hit" in text
    if efficiency == 1.0:
        assert nonlinear == pytest.approx(linear, abs=0.05)
        assert "Padé order 10 delays" in text and "efficiency" not in text
    else:
        assert abs(nonlinear - linear) > 3.0
        assert "gear efficiency" in text and "η = 0.75" in text and "Padé" not in text


def test_nonlinear_elements_of_the_shipped_loaded_variant(tmp_path):
    """The shipped ``loaded`` variant: η 0.7 with a self-locking worm (η_b 0), 1 mN·m Coulomb
    friction and a 0.1 N·m hinge bias, continuous controllers, no backlash."""
    from cas_freq.config import load_variant
    from cas_freq.report.nonlinear import nonlinear_elements

    params = load_variant(None, "loaded").params
    found = nonlinear_elements(params, loaded=True)
    assert len(found) == 3
    assert "η = 0.7 " in found[0] and "η_b = 0 " in found[0]
    assert found[1].startswith("Coulomb friction of 1 mN·m")
    # the shipped config names its output (output_name: fin): the text says so
    assert "while the motor drives the fin, η_b = 0 while the fin drives" in found[0]
    assert found[2] == "a constant load moment of 0.1 N·m on the fin"
    assert nonlinear_elements(load_variant(None, "base").params, loaded=False) == []
    # backlash and sampled controllers when set
    config = tmp_path / "play.yaml"
    config.write_text(shipped_base().replace("controllers: continuous", "controllers: sampled")
                      + "variants:\n  play:\n    gear.stiffness: 3000 N*m/rad\n"
                      "    load.inertia: 4.62e-5 kg*m^2\n    gear.backlash: 0.1 deg\n")
    found = nonlinear_elements(load_variant(config, "play").params, loaded=True)
    assert "a gear backlash of 0.1°" in found
    assert found[-1].startswith("sampled controllers (25000 Hz and 2500 Hz")


# ---- overlays: axis ranges from the region that matters, readable legends -------------------

def test_phase_window_follows_the_curves_to_past_the_crossover():
    """A delay's phase −ωτ − 90° runs to −2880° at the top of the range; the window keeps what
    the curve takes up to 3 × the crossover (here ω ≤ 300 rad/s: −90° .. −90 − 300 τ deg), in
    multiples of 45° with at most 9 ticks."""
    from cas_freq.plots.ranges import phase_window

    omega = np.geomspace(1.0, 1e5, 500)
    tau_deg = 0.5  # deg per rad/s
    phase = -90.0 - tau_deg * omega
    low, high, step = phase_window([(omega, phase)], [100.0])
    lowest_shown = -90.0 - tau_deg * 300.0  # −240°
    assert low <= lowest_shown and low > lowest_shown - 60.0
    assert high >= -90.0 and high < -90.0 + 60.0
    assert low % 45 == 0 and high % 45 == 0 and (high - low) / step <= 8


def test_time_window_is_the_median_settling_times_2_5():
    from cas_freq.plots.ranges import time_window

    window, off = time_window([0.01, 0.012, 0.5], [0.013, 0.016, 0.65])
    assert window == pytest.approx(2.5 * 0.012)
    assert off == [2]
    # an unsettled step counts with its own window, and the axis never exceeds the longest
    window, off = time_window([None, 0.01], [0.02, 0.013])
    assert window == pytest.approx(0.02) and off == []


def _legends(fig):
    return list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]


def test_overlays_have_bounded_axes_and_readable_legends(datas):
    from cas_freq.plots import overlays
    from cas_freq.plots import steps as step_panels
    from cas_freq.plots.ranges import time_window

    labels = ["qt_cas/base", "qt_cas/slow"]
    bode = overlays.bode_overlay(datas, labels)
    phase_axis = bode.axes[1]
    low, high = phase_axis.get_ylim()
    assert low >= -720.0 and high <= 180.0
    assert len([t for t in phase_axis.get_yticks() if low <= t <= high]) <= 9
    steps = overlays.step_overlay(datas, labels)
    runs = [d.dwell.steps[d.small_index] for d in datas]
    settle = [r.step.settling_time_s for r in runs]
    own = [step_panels._step_window_s(r, step_panels._linear_figures(d, d.small_index))
           for r, d in zip(runs, datas, strict=True)]
    expected, _ = time_window(settle, own)
    assert steps.axes[0].get_xlim()[1] == pytest.approx(1e3 * expected)
    for fig in (bode, steps, overlays.bandwidth_overlay(datas, labels)):
        legends = _legends(fig)
        assert legends and all(legend in fig.legends for legend in legends)  # outside the axes
        assert min(text.get_fontsize() for legend in legends
                   for text in legend.get_texts()) >= 8.0
    # the caption names the rule that set the axis: here the slow variant's whole run (it does
    # not settle, 2.5 × the median of the two would be longer), not the median
    caption = overlays.step_overlay_caption(datas, labels)
    longest = max(own)
    assert expected == pytest.approx(longest)
    assert (f"smallest steps over {1e3 * longest:.3g} ms (the longest of the variants' own "
            "step panels)") in caption


def test_html_prints_wide_tables_whole():
    from cas_freq.report import html
    from cas_freq.report.document import Table

    page = html.render([Table(("a", "b"), (("1", "2"),), "t")], "t")
    rules = page[page.index("@media print"):]
    assert "table-layout: fixed" in rules and "width: 100%" in rules


def test_html_cells_break_only_between_words_and_after_key_separators():
    """What the browser may break in a table cell: text at its spaces and a long key after its
    dots and underscores; never a number (Chromium broke 1.341e-06 after its hyphen) nor a
    short one-word cell (a status, a variant)."""
    from cas_freq.report import html
    from cas_freq.report.document import Table

    page = html.render([Table(("parameter", "base"), (
        ("viscous friction μv", "1.341e-06"),
        ("closed_loop.bandwidth_rad_s", "PASS"),
        ("x = 1.2e-06 N*m*s/rad (derived)", "−3.5 dB"),
    ), "t")], "t")
    body = page[page.index("<tbody>"):]
    assert '<td class="v">1.341e-06</td>' in body and '<td class="PASS v">PASS</td>' in body
    assert "<td>closed_<wbr>loop.<wbr>bandwidth_<wbr>rad_<wbr>s</td>" in body
    assert '<td>x = <span class="v">1.2e-06</span> N*m*s/rad (derived)</td>' in body
    assert "<td>viscous friction μv</td>" in body and "<td>−3.5 dB</td>" in body
    assert ".v { white-space: nowrap; }" in page
