"""The report's loop figures and tables on every architecture (issue 25, section 3).

The open-loop Bode, the Nichols chart and the Nyquist plots draw every loop of the declared
structure (L_i, L_v with a velocity loop, L_p), each named with its break point, and the inner
loops with every other loop closed (dashed). Checked on configs/cascade_axis.yaml (P -> PI -> PI
with a notch at the current command) and on the PID-on-PI of configs/qt_cas.yaml, from the
frequency-domain data alone (no simulation).

Expected values are independent of cas_freq's loop algebra: the drawn curves against
tests/architecture_oracle.py (all signal equations of the block diagram solved at each
frequency), and the notch from its own formula. Tolerances: plotted values are rounded to 6
significant digits (|dB| < 200 here: < 1e-3 dB), the oracle agrees with cas_freq to ~1e-10.
"""

import math
import types

import numpy as np
import pytest
from architecture_oracle import example_cascade, loop_response, qt_cas_drive, replace

from cas_freq.analysis import analyze
from cas_freq.config import load_variant
from cas_freq.plots import loci
from cas_freq.plots import report as plots
from cas_freq.report.build import analysis_loops, margins_table
from cas_freq.report.data import curves, loop_frequency_range, variant_label
from cas_freq.report.text import analysis_table

AXIS = "configs/cascade_axis.yaml"
#: Plotted dB are rounded to 6 significant digits: below this for |dB| < 200.
DRAWN_DB = 1e-3

CASCADE_TITLES = ("L_i (current loop, broken at V)", "L_v (velocity loop, broken at i_cmd)",
                  "L_p (position loop, broken at ω_cmd)")
PID_TITLES = ("L_i (current loop, broken at V)", "L_p (position loop, broken at i_cmd)")


def _light(path, variant="base", curve_range=None):
    """What the frequency figures read of a variant (no simulation)."""
    loaded = load_variant(path, variant)
    analysis = analyze(loaded)
    grid = curves(loaded.params, curve_range or loop_frequency_range(analysis), 100)
    return types.SimpleNamespace(loaded=loaded, analysis=analysis, curves=grid,
                                 label=variant_label(loaded), verdicts=None)


@pytest.fixture(scope="module")
def axis():
    return _light(AXIS, curve_range=(1.0, 1e5))


@pytest.fixture(scope="module")
def no_notch():
    return _light(AXIS, "no_notch", curve_range=(1.0, 1e5))


@pytest.fixture(scope="module")
def qt():
    return _light("configs/qt_cas.yaml")


def _labelled(ax, start):
    lines = [line for line in ax.lines if line.get_label().startswith(start)]
    assert len(lines) == 1, (start, [line.get_label() for line in ax.lines])
    return lines[0]


def _axis_drive(variant="base"):
    """configs/cascade_axis.yaml as the oracle's Drive (as in tests/test_architectures.py)."""
    drive = example_cascade(cv_Kp=1.3)
    return replace(drive, filters=drive.filters[1:]) if variant == "no_notch" else drive


# ---- the Bode of the loops -------------------------------------------------------------------

def test_cascade_bode_draws_every_loop_named_with_its_break_point(axis):
    mag, ph = plots.bode_loops(axis).axes[:2]
    w = axis.curves.omega_rad_s
    reference = _axis_drive()
    every = np.arange(0, w.size, 37)  # a sample of the grid (the oracle solves per frequency)
    for title, loop in zip(CASCADE_TITLES, ("current", "velocity", "position"), strict=True):
        line = _labelled(mag, title)
        assert line.get_linestyle() == "-"
        expected = 20.0 * np.log10(np.abs(loop_response(reference, loop, "L", w[every])))
        assert np.asarray(line.get_ydata())[every] == pytest.approx(expected, abs=DRAWN_DB)
    # the inner loops with every other loop closed: dashed, the colour of their loop
    for symbol, loop in (("L_i", "current"), ("L_v", "velocity")):
        line = _labelled(mag, f"{symbol} with every other loop closed")
        assert line.get_linestyle() == "--"
        assert line.get_color() == _labelled(mag, symbol + " (").get_color()
        expected = 20.0 * np.log10(np.abs(loop_response(reference, loop, "L_aat", w[every])))
        assert np.asarray(line.get_ydata())[every] == pytest.approx(expected, abs=DRAWN_DB)
    # the outermost loop's two views are one: drawn once
    assert not [line for line in mag.lines if line.get_label().startswith("L_p with")]
    assert "L_i, L_v and L_p" in plots.bode_loops(axis).get_suptitle()
    assert len([line for line in ph.lines if len(line.get_xdata()) == w.size]) == 5


def test_the_notch_is_visible_on_the_velocity_loop_it_shapes(axis, no_notch):
    # the notch sits at the current command, after the velocity controller: L_v with it over
    # L_v without it is the notch itself, N(s) = (s^2/w0^2 + 2 d z s/w0 + 1)/(s^2/w0^2 +
    # 2 z s/w0 + 1), z = width/(2 w0), d = 10^(depth/20) (docs/model.md, "Filters"), so the
    # drawn difference is 20 log10 |N(jw)|: -20 dB at w0 = 800 rad/s. L_i (broken at the
    # voltage, the outer loops open) does not see it.
    w = axis.curves.omega_rad_s
    assert np.array_equal(w, no_notch.curves.omega_rad_s)
    with_notch = _labelled(plots.bode_loops(axis).axes[0], "L_v (")
    without = _labelled(plots.bode_loops(no_notch).axes[0], "L_v (")
    w0, zeta, depth = 800.0, 400.0 / 1600.0, 0.1
    x = 1j * w / w0
    notch = 20.0 * np.log10(np.abs((x * x + 2 * depth * zeta * x + 1) / (x * x + 2 * zeta * x + 1)))
    drawn = np.asarray(with_notch.get_ydata()) - np.asarray(without.get_ydata())
    assert drawn == pytest.approx(notch, abs=2 * DRAWN_DB)
    k = int(np.argmin(np.abs(np.log(w / w0))))
    assert drawn[k] == pytest.approx(notch[k], abs=2 * DRAWN_DB) and notch[k] < -17.0
    assert np.asarray(_labelled(plots.bode_loops(axis).axes[0], "L_i (").get_ydata()) \
        == pytest.approx(_labelled(plots.bode_loops(no_notch).axes[0], "L_i (").get_ydata())


def test_pid_on_pi_bode_keeps_its_two_loops_and_adds_the_current_loop_at_a_time(qt):
    mag = plots.bode_loops(qt).axes[0]
    for title in PID_TITLES:
        assert _labelled(mag, title).get_linestyle() == "-"
    line = _labelled(mag, "L_i with every other loop closed")
    w = qt.curves.omega_rad_s
    every = np.arange(0, w.size, 41)
    expected = 20.0 * np.log10(np.abs(loop_response(qt_cas_drive(), "current", "L_aat",
                                                    w[every])))
    assert np.asarray(line.get_ydata())[every] == pytest.approx(expected, abs=DRAWN_DB)
    assert not [ln for ln in mag.lines if ln.get_label().startswith("L_v")]
    assert "open loops L_i and L_p" in plots.bode_loops(qt).get_suptitle()


# ---- Nichols and Nyquist ---------------------------------------------------------------------

def test_nichols_draws_every_loop_of_the_cascade(axis, qt):
    ax = plots.nichols(axis).axes[0]
    for title in CASCADE_TITLES:
        assert _labelled(ax, title).get_linestyle() == "-"
    for symbol in ("L_i", "L_v"):
        assert _labelled(ax, f"{symbol} with every other loop closed").get_linestyle() == "--"
    ax = plots.nichols(qt).axes[0]
    for title in PID_TITLES:
        _labelled(ax, title)
    assert "L_i and L_p" in plots.nichols(qt).get_suptitle()


def test_nyquist_has_one_panel_per_loop_named_with_its_break_point(axis, qt):
    fig = loci.nyquist(axis)
    assert len(fig.axes) == 3
    for ax, title in zip(fig.axes, reversed(CASCADE_TITLES), strict=True):
        assert ax.get_title().startswith(title)
    # each panel: its loop, and (inner loops) the loop with every other loop closed, dashed
    assert [ln.get_label() for ln in fig.axes[0].lines if "every other" in ln.get_label()] == []
    for ax, symbol in ((fig.axes[1], "L_v"), (fig.axes[2], "L_i")):
        _labelled(ax, f"{symbol}(jω), ω > 0")
        assert _labelled(ax, f"{symbol} with every other loop closed").get_linestyle() == "--"
    caption = loci.nyquist_caption(axis)
    assert "L_p (position loop, broken at the velocity command; left)" in caption
    assert "L_v (velocity loop, broken at the current command; middle)" in caption
    fig = loci.nyquist(qt)
    assert [ax.get_title().split(",")[0] for ax in fig.axes] == [
        "L_p (position loop", "L_i (current loop"]
    assert "broken at i_cmd" in fig.axes[0].get_title()


def test_curves_are_the_loops_of_the_structure(axis, qt):
    assert list(axis.curves.loops) == ["current_loop", "velocity_loop", "position_loop"]
    assert list(axis.curves.loop_at_a_time) == ["current_loop", "velocity_loop"]
    assert [loop.breaks_at for loop in axis.curves.described] == [
        "the voltage", "the current command", "the velocity command"]
    assert list(qt.curves.loops) == ["current_loop", "position_loop"]
    assert qt.curves.described[-1].breaks_at == "the current command"
    # S is the outermost loop's
    assert axis.curves.sensitivity == pytest.approx(1.0 / (1.0 + axis.curves.position_loop))


# ---- the tables and the text name the break points -------------------------------------------

def test_tables_and_text_name_each_break_point(axis, qt):
    columns = margins_table(axis.analysis).header
    assert "L_p (position loop, broken at the velocity command)" in columns
    assert "L_v (velocity loop, broken at the current command)" in columns
    assert "L_v (velocity loop, broken at the current command, every other loop closed)" \
        in columns
    text = analysis_table(axis.analysis)
    assert "position loop L_p (broken at the velocity command)" in text
    assert "position loop L_p (broken at the current command)" in analysis_table(qt.analysis)
    keys = [key for key, *_ in analysis_loops(qt.analysis)]
    assert keys == ["current_loop", "position_loop", "current_loop.loop_at_a_time"]
    assert math.isfinite(qt.analysis.current_loop.loop_at_a_time.phase_margin_deg)


@pytest.mark.parametrize("stem", ["bode_loops", "nichols", "nyquist"])
def test_cascade_figures_keep_every_label_inside(axis, stem):
    # as tests/test_report.py checks the PID-on-PI: titles, labels and legends inside
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = plots.VARIANT_FIGURES[stem][0](axis)
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    inside = fig.bbox.padded(1.0)
    artists = [*fig.legends, fig._suptitle]
    for ax in fig.axes:
        artists += [ax.get_legend(), ax.title, ax.xaxis.label, ax.yaxis.label]
    for artist in artists:
        if artist is None or not artist.get_visible():
            continue
        box = artist.get_window_extent(renderer)
        if box.width:
            assert inside.x0 <= box.x0 and box.x1 <= inside.x1, (stem, artist)
            assert inside.y0 <= box.y0 and box.y1 <= inside.y1, (stem, artist)


# ---- compare ---------------------------------------------------------------------------------

def test_compare_overlay_shows_the_velocity_loop_of_a_cascade(axis, no_notch, qt):
    from cas_freq.plots.overlays import COMPARE_FIGURES, bode_overlay

    fig = bode_overlay([axis, no_notch], ["base", "no_notch"])
    assert [ax.get_ylabel() for ax in fig.axes] == [
        "|L_p| [dB]", "∠L_p [deg]", "|T| [dB] (● ω_BW)", "|L_v| [dB]", "∠L_v [deg]"]
    velocity = fig.axes[3]
    curves_drawn = [line for line in velocity.lines if len(line.get_xdata()) > 2]
    # per variant: L_v broken at the current command (solid), with every other loop closed
    # (dashed), in the variant's colour
    assert [line.get_linestyle() for line in curves_drawn] == ["-", "--", "-", "--"]
    for line, data in zip(curves_drawn[::2], (axis, no_notch), strict=True):
        expected = 20.0 * np.log10(np.abs(data.curves.loops["velocity_loop"]))
        assert np.asarray(line.get_ydata()) == pytest.approx(expected, abs=DRAWN_DB)
    caption = COMPARE_FIGURES["bode_overlay"][1]([axis, no_notch], ["base", "no_notch"])
    assert "L_v" in caption
    # a PID-on-PI comparison keeps its three rows
    assert len(bode_overlay([qt], ["base"]).axes) == 3
    assert COMPARE_FIGURES["bode_overlay"][1]([qt], ["base"]) == "L_p and T overlaid"


def test_compare_tables_list_the_velocity_loop_from_the_figure_table(axis, no_notch):
    # the every-figure table of compare reads labels from cas_freq.core.figures: a cascade's
    # velocity loop and its loop-at-a-time view get their rows, valued as analyze gives them
    from cas_freq.analysis import to_dict
    from cas_freq.report.compare import difference_rows

    results = [{"analyze": to_dict(d.analysis), "simulate": [], "linear_steps": [],
                "sinedwell": None} for d in (axis, no_notch)]
    rows, _, keys = difference_rows(results)
    by_label = {row[0]: row for row in rows}
    row = by_label["velocity loop: phase margin [deg]"]
    assert float(row[1]) == pytest.approx(axis.analysis.velocity_loop.phase_margin_deg,
                                          rel=1e-4)
    row = by_label["velocity loop, every other loop closed: phase margin [deg]"]
    assert float(row[1]) == pytest.approx(
        axis.analysis.velocity_loop.loop_at_a_time.phase_margin_deg, rel=1e-4)
    assert "analyze.velocity_loop.loop_at_a_time.crossover_rad_s" in keys


def test_parameter_table_of_a_cascade(axis, no_notch, qt):
    # a cascade's gains in their own units (the position loop commands the speed: 1/s), its
    # filters by point and type ("—" where a variant has none), no PID-only keys
    from cas_freq.core.parameters import current_limit
    from cas_freq.report.parameter_table import parameter_table

    rows = {row[0]: row[1:] for row in parameter_table([axis, no_notch]).rows}
    assert rows["velocity-loop proportional gain"] == ("A·s/rad", "1.3", "1.3")
    assert rows["velocity-loop integral gain"] == ("A/rad", "15", "15")
    kp = next(label for label in rows if label.startswith("position-loop proportional gain"))
    assert rows[kp] == ("1/s", "40", "40")
    assert rows["notch at the current command: filter frequency ω0"] == ("rad/s", "800", "—")
    assert rows["notch at the current command: depth of a notch filter at its frequency"] == (
        "dB", "-20", "—")
    assert rows["lowpass2 at the velocity feedback: filter frequency ω0"] == (
        "rad/s", "3000", "3000")
    assert "derivative on" not in rows
    assert not [label for label in rows if "derivative gain" in label]
    assert current_limit(axis.loaded.params) == 10.0  # velocity_loop.i_max
    assert current_limit(qt.loaded.params) == qt.loaded.params.position_loop.i_max
    pid = {row[0] for row in parameter_table([qt]).rows}
    assert "derivative on" in pid and not [label for label in pid if "velocity-loop" in label]
