"""The report's Nyquist plots, pole-zero map and Nichols N contours (issue 11).

Structure and drawn data, not pixels. Expected values are derived here independently of the
figure code: Ms and the disk margin α from the definitions of docs/model.md §7 evaluated on the
model's exact-delay loops, the disk's ends from the skew-0 disk of gains
[(2−α)/(2+α), (2+α)/(2−α)], the zeros of T from the PID and PI numerators, the poles from
python-control's Padé model.

Tolerances: every plotted coordinate is rounded to 6 significant digits (``_r`` in the plot
modules), i.e. an error of at most 5e-6 of the coordinate; on the Nyquist view (|L| ≲ 4) that
is below 2e-5 absolute, so the geometric checks use 1e-4 (relative or absolute as said).
"""

import math
import types

import numpy as np
import pytest

from cas_freq.analysis import analyze
from cas_freq.config import load_variant
from cas_freq.model import ActuatorLoops
from cas_freq.plots import loci
from cas_freq.plots import report as plots
from cas_freq.report.build import report_files
from cas_freq.report.data import ReportSettings, curves, gather_variant, loop_frequency_range
from cas_freq.report.outdir import write_directory_atomic

FAST = ReportSettings(
    amplitudes_rad=(math.radians(0.5), math.radians(10.0)),
    frequencies_rad_s=(600.0, 1200.0),
    pade_order=6,
)

#: Coordinates are rounded to 6 significant digits: well below this on the Nyquist view.
DRAWN = 1e-4


@pytest.fixture(scope="module")
def data():
    return gather_variant(load_variant(None, "base"), FAST, verdicts=[])


def _light(loaded):
    """What the Nyquist and pole-zero figures read of a variant (no simulation needed)."""
    analysis = analyze(loaded)
    grid = curves(loaded.params, loop_frequency_range(analysis), 100)
    return types.SimpleNamespace(loaded=loaded, analysis=analysis, curves=grid,
                                 label=f"{loaded.params.name} / {loaded.variant}")


@pytest.fixture(scope="module")
def unstable():
    """The DC servo with Kp = 500 A/rad: its closed loop is unstable (issue 11)."""
    loaded = load_variant("configs/dc_servo.yaml", "base",
                          overrides=(("position_loop.Kp", 500.0),))
    return _light(loaded)


def _line(ax, start):
    lines = [line for line in ax.lines if line.get_label().startswith(start)]
    assert len(lines) == 1, [line.get_label() for line in ax.lines]
    return lines[0]


def _points(line):
    x, y = (np.asarray(v, dtype=float) for v in line.get_data())
    values = x + 1j * y
    return values[np.isfinite(values)]


def _dense_max(function, around, loop):
    """max of function(L(jω)) over ±10 % of ``around`` [rad/s] on a 20,001-point grid."""
    omega = np.geomspace(0.9 * around, 1.1 * around, 20001)
    values = function(loop(1j * omega))
    k = int(np.argmax(values))
    return float(values[k]), float(omega[k])


# ---- Nyquist ---------------------------------------------------------------------------------

def test_disk_margin_circle_formula():
    # alpha = 1: the disk of gains is [1/3, 3], so the excluded critical points -1/f run from
    # -3 to -1/3: centre -5/3, radius 4/3
    centre, radius = loci.disk_margin_circle(1.0)
    assert centre == pytest.approx(-5.0 / 3.0) and radius == pytest.approx(4.0 / 3.0)
    assert loci.disk_margin_circle(2.0) is None and loci.disk_margin_circle(3.0) is None
    centre, radius = loci.ms_circle(20.0 * math.log10(2.0))
    assert centre == -1 and radius == pytest.approx(0.5)


@pytest.mark.parametrize("panel, name", [(0, "position_loop"), (1, "current_loop")])
def test_ms_circle_is_one_over_ms_and_the_curve_stays_outside(data, panel, name):
    margins = getattr(data.analysis, name)
    loop = getattr(ActuatorLoops(data.loaded.params), name)
    # Ms from its definition, max 1/|1 + L|, on a dense grid around the engine's peak: the
    # engine refines the maximum, so they agree to the grid's 1e-5 spacing squared (quadratic)
    ms, _ = _dense_max(lambda v: 1.0 / np.abs(1.0 + v), margins.sensitivity_peak_rad_s, loop)
    assert 20.0 * math.log10(ms) == pytest.approx(margins.sensitivity_peak_db, abs=1e-6)
    ax = plots.VARIANT_FIGURES["nyquist"][0](data).axes[panel]
    circle = _points(_line(ax, "Ms circle"))
    assert np.abs(circle + 1.0) == pytest.approx(1.0 / ms, abs=DRAWN)
    curve = _points(_line(ax, f"{'L_p' if panel == 0 else 'L_i'}(jω), ω > 0"))
    distance = np.abs(curve + 1.0)
    assert distance.min() >= 1.0 / ms - DRAWN  # never inside the Ms circle
    # ... and touches it: at the peak frequency the exact loop is on the circle; the plotted
    # grid (100 points per decade, 2.3 % apart in ω) comes within 1 % of it
    at_peak = loop(np.array([1j * margins.sensitivity_peak_rad_s]))[0]
    assert abs(at_peak + 1.0) == pytest.approx(1.0 / ms, rel=1e-6)
    assert distance.min() <= 1.01 / ms
    # the nearest-approach marker ends on that point
    marker = _points(_line(ax, "nearest approach"))
    assert marker[-1] == pytest.approx(at_peak, abs=DRAWN)


@pytest.mark.parametrize("panel, name", [(0, "position_loop"), (1, "current_loop")])
def test_disk_margin_disk_is_as_defined_and_the_curve_avoids_it(data, panel, name):
    margins = getattr(data.analysis, name)
    loop = getattr(ActuatorLoops(data.loaded.params), name)
    alpha = margins.disk_margin_alpha
    # alpha from its definition, 1/max |S - 1/2| = 1/max |1 - L|/(2|1 + L|); the maximum lies
    # near the sensitivity peak for these loops (within ±10 %)
    distance, _ = _dense_max(lambda v: np.abs(1.0 - v) / (2.0 * np.abs(1.0 + v)),
                             margins.sensitivity_peak_rad_s, loop)
    assert 1.0 / distance == pytest.approx(alpha, rel=1e-6)
    ax = plots.VARIANT_FIGURES["nyquist"][0](data).axes[panel]
    (patch,) = [p for p in ax.patches if p.get_label().startswith("disk margin")]
    edge = patch.get_xy()[:, 0] + 1j * patch.get_xy()[:, 1]
    # real-axis diameter: the critical points -1/f of the disk of gains' ends
    assert edge.real.min() == pytest.approx(-(2.0 + alpha) / (2.0 - alpha), rel=DRAWN)
    assert edge.real.max() == pytest.approx(-(2.0 - alpha) / (2.0 + alpha), rel=DRAWN)
    # its boundary is the Apollonius circle alpha |1 - L| = 2 |1 + L| of the definition
    assert alpha * np.abs(1.0 - edge) == pytest.approx(2.0 * np.abs(1.0 + edge), rel=DRAWN)
    # and the curve stays outside: alpha |1 - L| <= 2 |1 + L| on every drawn point
    curve = _points(_line(ax, f"{'L_p' if panel == 0 else 'L_i'}(jω), ω > 0"))
    assert np.all(alpha * np.abs(1.0 - curve) <= 2.0 * np.abs(1.0 + curve) * (1.0 + DRAWN))


def test_nyquist_marks_minus_one_zooms_and_clips(data):
    fig = plots.VARIANT_FIGURES["nyquist"][0](data)
    assert len(fig.axes) == 2
    for ax in fig.axes:
        assert _points(_line(ax, "−1 (critical point)")) == pytest.approx([-1.0])
        assert ax.get_xlim() == pytest.approx((-3.0, 1.0))
        assert ax.get_ylim() == pytest.approx((-2.0, 2.0))
        assert [t for t in ax.texts if t.get_text()] == []  # everything else in the legends
        curve = _points(ax.lines[0])
        # clipped: nothing far outside the view is kept (only one sample past each edge)
        outside = (np.abs(curve.real + 1.0) > 3.0) | (np.abs(curve.imag) > 3.0)
        assert outside.sum() <= 0.05 * curve.size
        assert ax.lines[1].get_label().startswith("ω < 0")
    assert "arrows" in fig.get_suptitle() and "clipped" in fig.get_suptitle()


def test_nyquist_of_an_unstable_loop_draws_no_circles(unstable):
    assert not unstable.analysis.stable
    ax = loci.nyquist(unstable).axes[0]
    labels = [line.get_label() for line in ax.lines]
    assert not [label for label in labels if label.startswith("Ms circle")]
    assert "closed loop not stable: no Ms or disk-margin circle" in labels
    assert not ax.patches


# ---- pole-zero map ---------------------------------------------------------------------------

def _poles_drawn(ax):
    return np.concatenate([_points(line) for line in ax.lines if line.get_marker() == "x"])


def test_pole_zero_map_draws_the_engines_poles(data):
    import control

    from cas_freq.analysis.systems import linear_model

    ax = plots.VARIANT_FIGURES["pole_zero"][0](data).axes[0]
    drawn = np.sort_complex(_poles_drawn(ax))
    engine = np.sort_complex(np.array([complex(*p) for p in data.analysis.stability.poles]))
    assert drawn == pytest.approx(engine, rel=1e-5)
    # the engine's poles are python-control's of the same Padé model (to 1e-6 of |p|: two
    # eigenvalue computations of differently assembled matrices)
    order = data.analysis.stability.pade_order
    reference = np.sort_complex(control.poles(linear_model(data.loaded.params, order)
                                              .closed_loop))
    assert engine == pytest.approx(reference, rel=1e-6)


def test_pole_zero_map_zeros_hold_the_controller_zeros(data):
    ax = plots.VARIANT_FIGURES["pole_zero"][0](data).axes[0]
    (line,) = [line for line in ax.lines if line.get_marker() == "o"]
    zeros = _points(line)
    p = data.loaded.params
    cp, ci = p.position_loop, p.current_loop
    tf = cp.filter_time_constant
    # derivative on the error: T's zeros are L_p's, among them the PID's
    # (Kp Tf + Kd) s^2 + (Kp + Ki Tf) s + Ki and the PI current controller's -Ki/Kp
    expected = [*np.roots([cp.Kp * tf + cp.Kd, cp.Kp + cp.Ki * tf, cp.Ki]), -ci.Ki / ci.Kp]
    for z in expected:
        assert np.min(np.abs(zeros - z)) <= 1e-5 * abs(z)
    # 2 n + 3 zeros: PID 2, PI 1, and n per Padé delay
    assert zeros.size == 2 * data.analysis.stability.pade_order + 3


def test_pole_zero_view_and_annotations(data):
    fig = plots.VARIANT_FIGURES["pole_zero"][0](data)
    ax = fig.axes[0]
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert x0 < 0 < x1  # the stability boundary is in view
    assert any(line.get_label().startswith("stability boundary") for line in ax.lines)
    poles = _poles_drawn(ax)
    inside = (poles.real >= x0) & (poles.real <= x1) & (poles.imag >= y0) & (poles.imag <= y1)
    assert 0 < inside.sum() < poles.size  # the Padé poles lie outside
    # the dominant pair (the least damped pair in view) is labelled with its ωn and ζ
    pair = poles[inside & (poles.imag > 0)]
    p = pair[np.argmin(-pair.real / np.abs(pair))]
    texts = [t.get_text() for t in ax.texts]
    assert f"ωn {abs(p):.4g} rad/s\nζ {-p.real / abs(p):.2f}" in texts
    caption = plots.VARIANT_FIGURES["pole_zero"][1](data)
    assert f"{int((~inside).sum())} of {poles.size} poles" in caption


def test_unstable_variant_shows_its_right_half_plane_poles(unstable):
    ax = loci.pole_zero(unstable).axes[0]
    engine = np.array([complex(*p) for p in unstable.analysis.stability.poles])
    rhp = engine[engine.real > 0]
    assert rhp.size  # Kp = 500 A/rad destabilises the DC servo
    (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
    assert np.all((rhp.real >= x0) & (rhp.real <= x1) & (rhp.imag >= y0) & (rhp.imag <= y1))
    line = _line(ax, "right-half-plane poles")
    assert "UNSTABLE" in line.get_label()
    assert np.sort_complex(_points(line)) == pytest.approx(np.sort_complex(rhp), rel=1e-5)
    assert "unstable" in ax.get_title()


# ---- Nichols N contours ----------------------------------------------------------------------

@pytest.mark.parametrize("level", plots.N_CONTOURS_DEG)
def test_n_contour_has_constant_closed_loop_phase(level):
    phase, magnitude = plots.n_contour(level)
    loop = 10.0 ** (magnitude / 20.0) * np.exp(1j * np.radians(phase))
    closed = np.degrees(np.angle(loop / (1.0 + loop)))
    assert np.mod(closed - level + 180.0, 360.0) - 180.0 == pytest.approx(0.0, abs=1e-6)
    assert phase[0] == pytest.approx(level, abs=0.1)  # starts at ∠L = ∠T for small |L|


def test_nichols_n_contour_labels_do_not_collide(data):
    fig = plots.nichols(data)
    ax = fig.axes[0]
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any(text.startswith("N contours") for text in legend)
    n_labels = [t for t in ax.texts if t.get_text().endswith("°")]
    assert len(n_labels) >= 3
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)  # lays the figure out as the SVG writer does
    others = [t for t in ax.texts if t.get_text()]  # M labels, frequency labels, N labels
    for label in n_labels:
        box = label.get_window_extent(renderer)
        hits = [t.get_text() for t in others
                if t is not label and box.overlaps(t.get_window_extent(renderer))]
        assert not hits, (label.get_text(), hits)
        assert ax.bbox.x0 <= box.x0 and box.x1 <= ax.bbox.x1  # inside the chart
        assert ax.bbox.y0 <= box.y0 and box.y1 <= ax.bbox.y1


# ---- in the report ---------------------------------------------------------------------------

def test_new_figures_are_in_the_report_and_reproducible(data, tmp_path):
    target = tmp_path / "qt_cas"
    write_directory_atomic(target, report_files([data], FAST, command="cas-freq report"))
    page = (target / "index.html").read_text()
    text = (target / "report.md").read_text()
    for stem in ("nichols", "nyquist", "pole_zero"):
        svg = target / "figures" / "base" / f"{stem}.svg"
        assert svg.is_file()
        assert f'id="fig-figures/base/{stem}.svg"' in page
        assert f"(figures/base/{stem}.svg)" in text
        # the same figure drawn again gives the same bytes
        assert plots.svg_text(plots.VARIANT_FIGURES[stem][0](data)) == svg.read_text()
    # after the Nichols chart, in the frequency-response part of the variant's section
    assert text.index("figures/base/nichols.svg") < text.index("figures/base/nyquist.svg") \
        < text.index("figures/base/pole_zero.svg") < text.index("### Padé vs exact")
    assert "Ms circle (centre −1, radius 1/Ms)" in text
    assert "outside it:" in text and "outside it:" in page
