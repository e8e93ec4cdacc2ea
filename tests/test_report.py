"""``cas-freq report``'s library: data gathering, figures (structure, not pixels), the
document, byte-identical and atomic output.

Every run here uses a fast setting (two amplitudes, two sine-dwell frequencies, Padé order 6)
so that the module takes seconds; the figures and tables are the same code as the default run.
Reference values come from the other commands' own functions (analyze, the simulator), so the
test checks that the report shows them unchanged, not new numbers.
"""

import json
import math
import re

import numpy as np
import pytest

from cas_freq.analysis import analyze, to_dict
from cas_freq.config import load_variant
from cas_freq.core.exceptions import CasFreqError
from cas_freq.core.figures import FIGURES
from cas_freq.plots import overlays
from cas_freq.plots import report as plots
from cas_freq.report import html
from cas_freq.report.build import build_report, report_files
from cas_freq.report.data import ReportSettings, gather_variant, variant_results
from cas_freq.report.outdir import write_directory_atomic

FAST = ReportSettings(
    amplitudes_rad=(math.radians(0.5), math.radians(10.0)),
    frequencies_rad_s=(600.0, 1200.0),
    pade_order=6,
)

#: Verdicts as ``cas-freq verify --json`` gives them (constructed here, not measured).
VERDICTS = [
    {"id": "BW-1", "variant": "base", "metric": "closed_loop.bandwidth_rad_s", "value": 1385.0,
     "unit": "rad/s", "min": 300.0, "max": None, "margin": 1085.0, "status": "PASS",
     "severity": "required", "source": "ARL-TR-9136", "message": "meets >= 300 rad/s"},
    {"id": "PM-P", "variant": "base", "metric": "position_loop.phase_margin_deg", "value": 34.7,
     "unit": "deg", "min": 45.0, "max": None, "margin": -10.3, "status": "ADVISORY",
     "severity": "advisory", "source": "practice", "message": "violates >= 45 deg"},
    {"id": "BW-1", "variant": "fitted", "metric": "closed_loop.bandwidth_rad_s",
     "value": 843.5, "unit": "rad/s", "min": 300.0, "max": None, "margin": 543.5,
     "status": "PASS", "severity": "required", "source": "", "message": ""},
]


@pytest.fixture(scope="module")
def base():
    return load_variant(None, "base")


@pytest.fixture(scope="module")
def data(base):
    return gather_variant(base, FAST, verdicts=VERDICTS)


def _files(root):
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


# ---- data ------------------------------------------------------------------------------------

def test_gathered_data_matches_the_commands(data, base):
    results = variant_results(data)
    expected = to_dict(analyze(base, pade_orders=FAST.pade_order))
    expected["config_path"] = results["analyze"]["config_path"]
    assert results["analyze"] == expected  # the same figures as `analyze --json`
    assert [run["step"]["amplitude_deg"] for run in results["simulate"]] == pytest.approx(
        [0.5, 10.0])
    assert results["sinedwell"]["frequencies_rad_s"] == [600.0, 1200.0]
    assert [v["id"] for v in results["verify"]] == ["BW-1", "PM-P"]  # only this variant's
    # results.json never carries this machine's absolute path of the shipped config
    assert not results["analyze"]["config_path"].startswith("/")


def test_small_step_is_small_signal_and_linear_agrees(data):
    small = data.dwell.steps[data.small_index]
    assert not small.step.current_limited and not small.step.voltage_limited
    # no limit acts at 0.5 deg: the nonlinear step is the linear one up to the Padé-6 delays
    # and the 5 us simulation step (1 % of the step size is far above both)
    linear = data.linear_steps[data.small_index]
    assert np.max(np.abs(linear - small.result.delta)) < 0.01 * math.radians(0.5)
    large = data.dwell.steps[data.large_index]
    assert large.step.current_limited  # docs/model.md: a 10 deg step asks ~22 A of 20 A


def test_linear_step_equals_python_controls(base):
    # the doubling recursion of unit_step_response against python-control's own step response
    # of the same Padé-6 closed loop on the same uniform grid (python-control steps the same
    # exact discretisation one sample at a time; the two differ only by round-off, ~1e-13)
    import control

    from cas_freq.analysis.systems import closed_loop_matrices, linear_model
    from cas_freq.report.data import linear_steps, unit_step_response

    closed = linear_model(base.params, 6).closed_loop
    t = np.arange(3001) * 5e-6
    expected = np.asarray(control.step_response(closed, t).outputs, dtype=float)
    ours = unit_step_response(closed_loop_matrices(base.params, 6), t.size, 5e-6)
    assert np.max(np.abs(ours - expected)) < 1e-10
    # several steps share one response when their grids are prefixes of the longest
    short, odd = t[:1001], np.arange(11) * 1e-5
    responses = linear_steps(base.params, [short, t, odd], [0.5, 2.0, 1.0], 6)
    assert np.max(np.abs(responses[0] - 0.5 * expected[:1001])) < 1e-10
    assert np.max(np.abs(responses[1] - 2.0 * expected)) < 1e-10
    other = np.asarray(control.step_response(closed, odd).outputs, dtype=float)
    assert np.max(np.abs(responses[2] - other)) < 1e-10


@pytest.mark.parametrize("variant", ["base", "loaded", "sampled"])
def test_closed_loop_matrices_and_zeros_are_python_controls(variant):
    # T's matrices built without python-control are linear_model's T (python-control's
    # StateSpace of the same matrices) to the bit, and its zeros are python-control's
    # StateSpace.zeros (the same QZ call without slycot; sampled: mapped by ln z / T)
    import control

    from cas_freq.analysis.sampled_stability import z_to_s
    from cas_freq.analysis.systems import closed_loop_matrices, closed_loop_zeros, linear_model

    params = load_variant(None, variant).params
    expected = linear_model(params, 8).closed_loop
    closed = closed_loop_matrices(params, 8)
    for ours, theirs in zip((closed.a, closed.b, closed.c, closed.d),
                            (expected.A, expected.B, expected.C, expected.D), strict=True):
        assert np.array_equal(ours, theirs)
    assert closed.period == (expected.dt if expected.isdtime(strict=True) else None)
    zeros = np.asarray(control.zeros(expected), complex)
    zeros = zeros[np.isfinite(zeros)]
    if closed.period is not None:
        zeros = z_to_s(zeros, closed.period)
    zeros = zeros[np.lexsort((zeros.imag, zeros.real))]
    assert zeros.size > 0 and np.array_equal(closed_loop_zeros(params, 8), zeros)


def test_linear_steps_and_zeros_do_not_import_python_control():
    # the report's linear steps and zeros of T are numpy and scipy: python-control's import
    # (~1 s, scipy.signal) is not paid by `cas-freq report`
    import subprocess
    import sys

    code = (
        "import sys\n"
        "import numpy as np\n"
        "from cas_freq.config import load_variant\n"
        "from cas_freq.analysis.systems import closed_loop_zeros\n"
        "from cas_freq.report.data import linear_steps\n"
        "for variant in ('base', 'sampled'):\n"
        "    params = load_variant(None, variant).params\n"
        "    (step,) = linear_steps(params, [np.arange(2001) * 5e-5], [0.1], 10)\n"
        "    assert abs(step[-1] - 0.1) < 1e-3, step[-1]\n"
        "    assert closed_loop_zeros(params, 10).size\n"
        "assert 'control' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


def test_reference_rows_show_the_configs_bench_numbers(data):
    # the shipped config declares ARL-TR-9136's bench as its reference: section
    results = variant_results(data)
    bench = {row["figure"]: row["reference"] for row in results["reference_comparison"]}
    # ARL-TR-9136 §5 and §7 (docs/model.md §8): rise 5 ms, overshoot 13 %, fit 566 rad/s
    # (labelled as the figure table labels the step's and the fit's figures)
    assert bench[FIGURES["step.rise_time_s"].label] == pytest.approx(5.0)
    assert bench[FIGURES["step.overshoot_pct"].label] == 13.0
    assert bench["fit: " + FIGURES["fit.bandwidth_closed_form_rad_s"].label] == 566.0


def test_settings_reject_bad_grids():
    with pytest.raises(CasFreqError, match="amplitude"):
        ReportSettings(amplitudes_rad=())
    with pytest.raises(CasFreqError, match="frequencies"):
        ReportSettings(frequencies_rad_s=(100.0,))


# ---- figures ---------------------------------------------------------------------------------

def _labels(fig):
    return [(ax.get_xlabel(), ax.get_ylabel()) for ax in fig.axes]


@pytest.mark.parametrize("stem", list(plots.VARIANT_FIGURES))
def test_variant_figure_structure(data, stem):
    draw, _ = plots.VARIANT_FIGURES[stem]
    fig = draw(data)
    title = fig.get_suptitle()
    assert "qt_cas / base" in title
    assert "exact delays" in title or "Padé" in title  # says which delay model
    for ax in fig.axes:
        assert ax.lines, f"{stem}: an axes without lines"
        assert re.search(r"\[.+\]", ax.get_ylabel()), f"{stem}: y label without unit"
    # a frequency, time or angle axis, or the dimensionless plane of a Nyquist plot
    assert any(re.search(r"\[(rad/s|ms|deg|-)\]", x) for x, _ in _labels(fig))


def test_frequency_figures_need_no_simulation(base):
    # the figures the workers draw while the variant is simulated use no sine-dwell, no step
    # and no verdict
    from cas_freq.report.data import gather_frequency

    early = gather_frequency(base, FAST)
    assert early.dwell is None and early.verdicts is None
    for stem in plots.FREQUENCY_FIGURES:
        draw, caption = plots.VARIANT_FIGURES[stem]
        assert draw(early).axes
        assert not callable(caption) or caption(early)


@pytest.mark.parametrize("stem", list(plots.VARIANT_FIGURES))
def test_fixed_layout_keeps_every_label_and_legend_in_the_figure(data, stem):
    # the fixed layout (margins in inches, legends measured) clips nothing: titles, axis labels,
    # tick labels and legends lie inside the figure
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    draw, _ = plots.VARIANT_FIGURES[stem]
    fig = draw(data)
    plots.png_bytes(fig)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    inside = fig.bbox.padded(1.0)
    artists = [*fig.legends, fig._suptitle]
    for ax in fig.axes:
        artists += [ax.get_legend(), ax.title, ax.xaxis.label, ax.yaxis.label]
        artists += [t for t in ax.get_xticklabels() + ax.get_yticklabels() if t.get_text()]
    for artist in artists:
        if artist is None or not artist.get_visible():
            continue
        box = artist.get_window_extent(renderer)
        if box.width == 0:
            continue
        assert inside.x0 <= box.x0 and box.x1 <= inside.x1, (stem, artist)
        assert inside.y0 <= box.y0 and box.y1 <= inside.y1, (stem, artist)


def test_bode_marks_every_crossover_in_range(data):
    fig = plots.bode_loops(data)
    magnitude = fig.axes[0]
    w = data.curves.omega_rad_s
    crossings = [c for loop in (data.analysis.current_loop, data.analysis.position_loop)
                 for c in (*loop.gain_crossovers, *loop.phase_crossovers)
                 if w[0] <= c.frequency_rad_s <= w[-1]]
    markers = [line for line in magnitude.lines if line.get_marker() in ("o", "s")
               and len(line.get_xdata()) == 1]
    assert len(markers) == len(crossings)
    # the margins are in the legend, never text on the axes (no collisions)
    assert not [t for ax in fig.axes for t in ax.texts]
    legend = " ".join(t.get_text() for t in fig.legends[0].get_texts())
    cp, ci = data.analysis.position_loop, data.analysis.current_loop
    assert f"PM {cp.phase_margin_deg:.3g}°" in legend
    assert f"GM {cp.gain_margin_db:+.3g} dB" in legend
    # the current loop's gain margin (its phase crossover near 26,500 rad/s) is drawn too
    assert f"GM {ci.gain_margin_db:+.3g} dB @ {ci.phase_crossover_rad_s:.4g} rad/s" in legend
    assert w[0] <= ci.phase_crossover_rad_s <= w[-1]
    bars = [c for c in magnitude.collections if len(c.get_segments()) == 1
            and c.get_segments()[0][0][0] == pytest.approx(ci.phase_crossover_rad_s)]
    assert bars


def test_plot_range_holds_every_headline_frequency(data):
    low, high = data.curve_range_rad_s
    for loop in (data.analysis.current_loop, data.analysis.position_loop):
        for w in (loop.crossover_rad_s, loop.phase_crossover_rad_s,
                  loop.phase_crossover_low_rad_s, loop.sensitivity_peak_rad_s):
            assert w is None or low <= w <= high
    cl = data.analysis.closed_loop
    assert low <= cl.bandwidth_rad_s <= high and low <= cl.peak_rad_s <= high


def test_closed_loop_figure_shows_bandwidth_and_peak(data):
    fig = plots.closed_loop(data)
    labels = [line.get_label() for line in fig.axes[0].lines]
    bw = data.analysis.closed_loop.bandwidth_rad_s
    assert f"ω_BW = {bw:.4g} rad/s" in labels
    assert "−3.01 dB" in labels
    assert any(label.startswith("peak ") for label in labels)


def test_steps_figure_shades_the_limits(data):
    fig = plots.steps(data)
    assert len(fig.axes) == 6  # (δ, i, V) x (smallest, largest)
    small_top, large_top = fig.axes[0], fig.axes[1]
    assert "no limit hit" in small_top.get_title()
    assert "current limit hit" in large_top.get_title()
    assert not [p for p in small_top.patches]  # nothing shaded at 0.5 deg
    assert large_top.patches  # the current-limit interval(s) at 10 deg
    (legend,) = fig.legends  # one, below the panels
    assert "linear T (Padé 6)" in [t.get_text() for t in legend.get_texts()]


def test_svg_is_reproducible_and_inlines(data):
    first = plots.svg_text(plots.nichols(data))
    second = plots.svg_text(plots.nichols(data))
    assert first == second
    assert "<dc:date>" not in first
    inline = html.inline_svg(first)
    assert inline.startswith("<svg") and "<?xml" not in inline and "DOCTYPE" not in inline


@pytest.mark.parametrize("stem", list(overlays.COMPARE_FIGURES))
def test_overlay_figures(data, stem):
    draw, _ = overlays.COMPARE_FIGURES[stem]
    fig = draw([data, data], ["one", "two"])
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend())]
    texts = [t.get_text() for legend in legends for t in legend.get_texts()]
    assert any(t.startswith("one") for t in texts) and any(t.startswith("two") for t in texts)
    for ax in fig.axes:
        assert re.search(r"\[.+\]", ax.get_ylabel())


# ---- the document and the folder ---------------------------------------------------------------

@pytest.fixture(scope="module")
def folder(data, tmp_path_factory):
    target = tmp_path_factory.mktemp("report") / "qt_cas"
    write_directory_atomic(target, report_files([data], FAST, command="cas-freq report"))
    return target


def test_folder_content(folder):
    names = sorted(_files(folder))
    assert {"index.html", "report.md", "results.json"} <= set(names)
    svgs = [n for n in names if n.endswith(".svg")]
    assert sorted(svgs) == sorted(f"figures/base/{stem}.svg" for stem in plots.VARIANT_FIGURES)
    results = json.loads((folder / "results.json").read_text())
    assert results["config"] == "qt_cas"
    assert [v["variant"] for v in results["variants"]] == ["base"]


def test_html_is_self_contained(folder):
    page = (folder / "index.html").read_text()
    assert page.count("<svg") == len(plots.VARIANT_FIGURES)
    assert "<?xml" not in page
    # the only URLs are XML namespace names inside the SVG, which browsers never fetch
    urls = set(re.findall(r"https?://[^\s\"'<>)]+", page))
    assert urls <= {"http://www.w3.org/2000/svg", "http://www.w3.org/1999/xlink"}
    assert not re.search(r"<(script|link|img)\b", page)


def test_markdown_lists_tables_and_figures(folder):
    text = (folder / "report.md").read_text()
    for heading in ("## Summary", "## Reference vs model", "## Requirement verdicts",
                    "## Variant base", "### Padé vs exact delays (base)"):
        assert heading in text
    for stem in plots.VARIANT_FIGURES:
        assert f"(figures/base/{stem}.svg)" in text
    assert "| BW-1 | base | closed_loop.bandwidth_rad_s |" in text
    assert "| PM-P | base |" in text and "ADVISORY" in text
    assert "no limit is hit" in text  # the 0.5 deg step, said plainly
    assert "linear (Padé 6)" in text


def test_verdict_section_without_requirements(base, data, tmp_path):
    params = base.params.model_copy(update={"requirements": ()})
    loaded = type(base)(base.source, base.variant, params)
    bare = type(data)(**{**data.__dict__, "loaded": loaded, "verdicts": ()})
    target = tmp_path / "r"
    write_directory_atomic(target, report_files([bare], FAST))
    assert "has no requirements" in (target / "report.md").read_text()


def test_verdicts_not_evaluated_are_said_so(data, tmp_path):
    unevaluated = type(data)(**{**data.__dict__, "verdicts": None})
    target = tmp_path / "r"
    write_directory_atomic(target, report_files([unevaluated], FAST))
    assert "were not evaluated for variant(s) base" in (target / "report.md").read_text()


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_same_input_gives_byte_identical_files(base, tmp_path):
    one = build_report([base], tmp_path / "one", settings=FAST, verdicts=VERDICTS)
    two = build_report([base], tmp_path / "two", settings=FAST, verdicts=VERDICTS)
    assert _files(one) == _files(two)


def test_failed_build_leaves_the_previous_report(folder, data, monkeypatch):
    before = _files(folder)

    def broken(_):
        raise RuntimeError("drawing failed")

    monkeypatch.setitem(plots.VARIANT_FIGURES, "nichols", (broken, "Nichols"))
    with pytest.raises(RuntimeError, match="drawing failed"):
        write_directory_atomic(folder, report_files([data], FAST))
    assert _files(folder) == before
    assert sorted(p.name for p in folder.parent.iterdir()) == [folder.name]


def test_report_rejects_mixed_configs(base):
    other = type(base)(base.source, "base", base.params.model_copy(update={"name": "other"}))
    with pytest.raises(CasFreqError, match="compare"):
        build_report([base, other], settings=FAST)


def test_report_verdicts_reuse_its_runs_and_equal_verify(monkeypatch):
    """The report's 10 deg step is the step OS-1 and BW-2 need: verify reuses it (and the
    report's analysis) instead of simulating again, and gives the verdicts ``cas-freq verify``
    gives on its own."""
    import cas_freq.studies.run as run_module
    from cas_freq.verify import verdict_dict, verify_variant

    loaded = load_variant()
    expected = [verdict_dict(v) for v in verify_variant(loaded)]

    def no_new_steps(*args, **kwargs):
        raise AssertionError("verify simulated a step the report already had")

    monkeypatch.setattr(run_module, "step_runs", no_new_steps)
    data = gather_variant(loaded, FAST)
    assert [dict(v) for v in data.verdicts] == expected
