"""The report's figures, drawn with matplotlib (only :mod:`cas_freq.plots` imports it).

Each function takes :class:`cas_freq.report.data.VariantData` (one, or a list to overlay) and
returns a :class:`matplotlib.figure.Figure`; nothing here computes a figure of merit. Figures
are built without pyplot (no global figure registry to leak), on the Agg backend, and
:func:`svg_text` writes them reproducibly: fixed hash salt, no date, text kept as text.

The SVG files must not depend on the last bits of floating point (which differ between CPUs),
so the plotted data are rounded to 6 significant digits (:func:`_r`, i.e.
:func:`cas_freq.core.numbers.round_array`) before they are drawn, and :func:`svg_text` rounds
every coordinate in the SVG to 0.01 pt and renames matplotlib's content-hash ids (both in
:mod:`cas_freq.plots.common`, re-exported here). The Nyquist and pole-zero figures are in
:mod:`cas_freq.plots.loci`.

Titles name the variant and the delay model; every axis label carries its unit.
"""

import math

import numpy as np
from matplotlib.ticker import MultipleLocator

from cas_freq.analysis.frequency import continuous_phase
from cas_freq.analysis.rate_envelope import rate_envelope
from cas_freq.config.wording import common_output_label
from cas_freq.core.figures import FIGURES
from cas_freq.core.output import output_unit
from cas_freq.core.parameters import LoopParameters
from cas_freq.plots import loci
from cas_freq.plots.common import (  # noqa: F401  (svg_text, png_bytes, tidy_svg re-exported)
    EXACT,
    STYLE,
    SVG_DECIMALS,
    Margins,
    legend_below,
    legend_room_below,
    legend_room_right,
    loop_color,
    plain_log_labels,
    png_bytes,
    svg_text,
    tidy_svg,
)
from cas_freq.plots.common import figure as _figure
from cas_freq.plots.common import output_symbol as _symbol
from cas_freq.plots.common import rounded as _r
from cas_freq.plots.steps import step_fit, steps
from cas_freq.plots.stiffness import caption as stiffness_caption
from cas_freq.plots.stiffness import stiffness as stiffness_figure

HALF_POWER_DB = 20.0 * math.log10(1.0 / math.sqrt(2.0))


def _db(values):
    return _r(20.0 * np.log10(np.abs(values)))


def _phase_deg(response, omega):
    return _r(np.degrees(continuous_phase(response, omega)))


def _at(omega, values, w):
    """``values`` interpolated at ``w`` in log frequency."""
    return float(np.interp(math.log(w), np.log(omega), values))


def _in_range(omega, w):
    return w is not None and omega[0] <= w <= omega[-1]


def _log_axes(axes, omega):
    for ax in axes:
        ax.set_xscale("log")
        plain_log_labels(ax.xaxis)
        ax.set_xlim(omega[0], omega[-1])
    axes[-1].set_xlabel("frequency ω [rad/s]")


def _margin_words(margins):
    """The loop's headline margins for its legend entry (no text on the axes: none collides)."""
    pm, gm, low = (FIGURES[f"position_loop.{name}"] for name in (
        "phase_margin_deg", "gain_margin_db", "gain_margin_low_db"))  # their short names
    words = []
    if margins.phase_margin_deg is not None:
        words.append(f"{pm.short} {margins.phase_margin_deg:.3g}° @ "
                     f"{margins.crossover_rad_s:.4g} rad/s")
    if margins.gain_margin_db is not None:
        words.append(f"{gm.short} {margins.gain_margin_db:+.3g} dB @ "
                     f"{margins.phase_crossover_rad_s:.4g} rad/s")
    if margins.gain_margin_low_db is not None:
        words.append(f"{low.short} {margins.gain_margin_low_db:+.3g} dB @ "
                     f"{margins.phase_crossover_low_rad_s:.4g} rad/s")
    return "; ".join(words) if words else "no crossover in range"


def loop_views(data):
    """(CurveLoop, response, margins, dashed) of every loop drawn in the loop figures,
    innermost first: each loop broken with the loops inside closed, then (dashed, same colour)
    each inner loop with every other loop closed."""
    c, a = data.curves, data.analysis
    views = []
    for loop in c.described:
        margins = getattr(a, loop.name)
        views.append((loop, c.loops[loop.name], margins, False))
        if loop.name in c.loop_at_a_time and margins.loop_at_a_time is not None:
            views.append((loop, c.loop_at_a_time[loop.name], margins.loop_at_a_time, True))
    return views


def loops_words(curves):
    """``"L_i and L_p"``, ``"L_i, L_v and L_p"``: the symbols of the loops, innermost first."""
    symbols = [loop.symbol for loop in curves.described]
    return ", ".join(symbols[:-1]) + " and " + symbols[-1]


def bode_loops(data, with_closed_loop=False, figure_class=None):
    """Bode of every loop of the structure (L_i, L_v with a velocity loop, L_p), each named
    with its break point: every gain ● and phase □ crossover in range marked, the headline
    margins drawn as bars and stated in the legend (never as text on the axes). The inner
    loops with every other loop closed are drawn dashed in their loop's colour, their margins
    in the legend.

    ``with_closed_loop`` adds T = δ/δ_cmd with its bandwidth ▽ (the API's
    :meth:`cas_freq.analysis.Analysis.plot`); ``figure_class`` is the Figure subclass to build
    (default :class:`matplotlib.figure.Figure`)."""
    c = data.curves
    w = _r(c.omega_rad_s)
    layout = Margins(hgap=0.25)
    fig, axes = _figure(2, 1, (9, 7.2), sharex=True, margins=layout,
                        **({"figure_class": figure_class} if figure_class else {}))
    mag, ph = axes[:, 0]
    lowest_phase = 0.0
    solid = [view for view in loop_views(data) if not view[3]]
    dashed = [view for view in loop_views(data) if view[3]]
    for loop, response, margins, _ in solid:
        color = loop_color(loop.name)
        m, p = _db(response), _phase_deg(response, c.omega_rad_s)
        mag.plot(w, m, color=color, label=f"{loop.title}: {_margin_words(margins)}")
        ph.plot(w, p, color=color)
        for cross in margins.gain_crossovers:
            if not _in_range(w, cross.frequency_rad_s):
                continue
            x = cross.frequency_rad_s
            mag.plot([x], [0.0], "o", color=color, ms=5)
            # the margin from the -180° + k 360° line below or above the continuous phase
            ph.plot([x], [cross.phase_deg], "o", color=color, ms=5)
            ph.vlines(x, cross.phase_deg - cross.phase_margin_deg, cross.phase_deg, color=color,
                      lw=2)
        headline = {margins.phase_crossover_rad_s, margins.phase_crossover_low_rad_s}
        for cross in margins.phase_crossovers:
            if not _in_range(w, cross.frequency_rad_s):
                continue
            x = cross.frequency_rad_s
            y = _at(w, p, x)
            mag.plot([x], [-cross.gain_margin_db], "s", color=color, ms=4, mfc="none")
            ph.plot([x], [y], "s", color=color, ms=4, mfc="none")
            if x in headline:
                mag.vlines(x, -cross.gain_margin_db, 0.0, color=color, lw=2)
                lowest_phase = min(lowest_phase, y)
        for x in (margins.crossover_rad_s,):
            if _in_range(w, x):
                lowest_phase = min(lowest_phase, _at(w, p, x))
    for loop, response, margins, _ in dashed:
        color = loop_color(loop.name)
        p = _phase_deg(response, c.omega_rad_s)
        mag.plot(w, _db(response), color=color, ls="--", lw=1.1,
                 label=f"{loop.symbol} with every other loop closed (dashed): "
                 f"{_margin_words(margins)}")
        ph.plot(w, p, color=color, ls="--", lw=1.1)
        if _in_range(w, margins.crossover_rad_s):
            lowest_phase = min(lowest_phase, _at(w, p, margins.crossover_rad_s))
    if with_closed_loop:
        _closed_loop_curve(mag, ph, w, c, data.analysis.closed_loop, _symbol(data))
    mag.axhline(0.0, color="k", lw=0.8)
    ph.axhline(-180.0, color="k", lw=0.8)
    mag.set_ylabel("magnitude [dB]")
    ph.set_ylabel("phase [deg]")
    # the delays turn the phase without bound: show down to one turn below the lowest
    # headline crossing (every headline marker stays visible)
    bottom = max(ph.get_ylim()[0], 180.0 * math.floor(lowest_phase / 180.0) - 360.0)
    ph.set_ylim(bottom, max(ph.get_ylim()[1], 0.0))
    ph.yaxis.set_major_locator(MultipleLocator(180 if ph.get_ylim()[1] - bottom <= 1440
                                               else 360))
    mag.set_ylim(max(mag.get_ylim()[0], -80.0), mag.get_ylim()[1])
    mag.plot([], [], "ko", ms=4, label="gain crossover ● (bar: phase margin)")
    mag.plot([], [], "ks", ms=4, mfc="none", label="phase crossover □ (bar: gain margin)")
    handles, labels = mag.get_legend_handles_labels()
    legend = fig.legend(handles, labels, loc="lower center", ncols=1, fontsize=7.5)
    legend_room_below(fig, layout, [legend])
    _log_axes([mag, ph], w)
    symbols = loops_words(c)
    loops = (f"{symbols.replace(' and ', ', ')} and closed loop T" if with_closed_loop
             else f"open loops {symbols}")
    fig.suptitle(f"{data.label}: {loops} ({EXACT}); margins in the legend")
    return fig


def _closed_loop_curve(mag, ph, w, c, figures, symbol="δ"):
    """T = δ/δ_cmd (``symbol``: x at a linear output) on the open loops' axes, its bandwidth ▽
    at |T(0)| − 3.01 dB in the legend (none when the closed loop is not stable: ``figures``
    None)."""
    words = "not stable: no closed-loop figures"
    if figures is not None:
        peak = ("no resonance peak" if figures.peak_db is None
                else f"peak {figures.peak_db:.2f} dB")
        words = (f"ω_BW {figures.bandwidth_rad_s:.4g} rad/s, {peak}"
                 if figures.bandwidth_rad_s is not None else peak)
    mag.plot(w, _db(c.closed_loop), color="C2",
             label=f"T = {symbol}/{symbol}_cmd (closed loop): {words}")
    ph.plot(w, _phase_deg(c.closed_loop, c.omega_rad_s), color="C2")
    if figures is not None and _in_range(w, figures.bandwidth_rad_s):
        mag.plot([figures.bandwidth_rad_s], [figures.dc_gain_db + HALF_POWER_DB], "v",
                 color="C2", ms=6)


def closed_loop(data):
    """|T| with the -3 dB line, the bandwidth and the resonance peak; phase of T with -90°."""
    c = data.curves
    w = _r(c.omega_rad_s)
    figures = data.analysis.closed_loop
    fig, axes = _figure(2, 1, (8, 6), sharex=True, margins=Margins())
    mag, ph = axes[:, 0]
    m, p = _db(c.closed_loop), _phase_deg(c.closed_loop, c.omega_rad_s)
    symbol = _symbol(data)
    mag.plot(w, m, color="C2", label=f"|T| = |{symbol}/{symbol}_cmd|")
    ph.plot(w, p, color="C2", label="∠T")
    dc = figures.dc_gain_db if figures is not None else 0.0
    mag.axhline(dc + HALF_POWER_DB, color="k", ls="--", lw=0.9, label="−3.01 dB")
    ph.axhline(-90.0, color="k", ls="--", lw=0.9, label="−90°")
    if figures is not None:
        if _in_range(w, figures.bandwidth_rad_s):
            x = figures.bandwidth_rad_s
            mag.axvline(x, color="C3", lw=1)
            mag.plot([x], [dc + HALF_POWER_DB], "o", color="C3",
                     label=f"ω_BW = {x:.4g} rad/s")
        if _in_range(w, figures.peak_rad_s):
            mag.plot([figures.peak_rad_s], [dc + figures.peak_db], "^", color="C4",
                     label=f"peak {figures.peak_db:.2f} dB @ {figures.peak_rad_s:.4g} rad/s")
        if _in_range(w, figures.phase_90_rad_s):
            ph.plot([figures.phase_90_rad_s], [-90.0], "o", color="C3",
                    label=f"−90° @ {figures.phase_90_rad_s:.4g} rad/s")
    else:
        mag.set_title("closed loop not stable: no closed-loop figures")
    for bound in _bandwidth_bounds(data.verdicts):
        if _in_range(w, bound):
            mag.axvline(bound, color="C3", ls="-.", lw=1,
                        label=f"requirement ω_BW ≥ {bound:g} rad/s")
    mag.set_ylim(max(mag.get_ylim()[0], -60.0), mag.get_ylim()[1])
    ph.set_ylim(max(ph.get_ylim()[0], -720.0), 45.0)
    ph.yaxis.set_major_locator(MultipleLocator(90))
    mag.set_ylabel("magnitude [dB]")
    ph.set_ylabel("phase [deg]")
    mag.legend(loc="lower left")
    ph.legend(loc="lower left")
    _log_axes([mag, ph], w)
    fig.suptitle(f"{data.label}: closed loop T = {symbol}/{symbol}_cmd ({EXACT})")
    return fig


def sensitivity(data):
    """|S| and |T| of the position loop together, with the sensitivity peak."""
    c = data.curves
    w = _r(c.omega_rad_s)
    fig, axes = _figure(1, 1, (8, 4.2), margins=Margins())
    ax = axes[0, 0]
    ax.plot(w, _db(c.sensitivity), color="C0", label=f"|S| = |1/(1+{c.described[-1].symbol})|")
    ax.plot(w, _db(c.closed_loop), color="C2", label="|T|")
    margins = data.analysis.position_loop
    if _in_range(w, margins.sensitivity_peak_rad_s):
        ax.plot([margins.sensitivity_peak_rad_s], [margins.sensitivity_peak_db], "v", color="C3",
                label=f"Ms {margins.sensitivity_peak_db:.2f} dB @ "
                f"{margins.sensitivity_peak_rad_s:.4g} rad/s")
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_ylim(max(ax.get_ylim()[0], -60.0), ax.get_ylim()[1])
    ax.set_ylabel("magnitude [dB]")
    ax.legend(loc="lower right")
    _log_axes([ax], w)
    fig.suptitle(f"{data.label}: sensitivity S and complementary sensitivity T ({EXACT})")
    return fig


#: Closed-loop magnitudes |T| = |L/(1+L)| drawn as M contours on the Nichols chart [dB].
M_CONTOURS_DB = (-6.0, -3.0, 0.0, 1.0, 3.0, 6.0)


def _m_contours(ax, phase_range_deg, magnitude_range_db):
    """Constant-|T| (M) contours over the chart, labelled in dB, one legend entry."""
    phase = np.linspace(*phase_range_deg, 361)
    magnitude = np.linspace(*magnitude_range_db, 201)
    p_grid, m_grid = np.meshgrid(np.radians(phase), magnitude)
    loop = 10.0 ** (m_grid / 20.0) * np.exp(1j * p_grid)
    with np.errstate(divide="ignore", invalid="ignore"):
        closed = _r(20.0 * np.log10(np.abs(loop / (1.0 + loop))))
    closed = np.where(np.isfinite(closed), closed, 100.0)
    contours = ax.contour(phase, magnitude, closed, levels=M_CONTOURS_DB, colors="C7",
                          linewidths=0.6, linestyles=":")
    ax.clabel(contours, fmt="%g dB", fontsize=7, inline=True)
    ax.plot([], [], color="C7", lw=0.6, ls=":",
            label="M contours: |T| = " + ", ".join(f"{m:g}" for m in M_CONTOURS_DB) + " dB")


#: Closed-loop phases ∠T = ∠(L/(1+L)) drawn as N contours on the Nichols chart [deg]; ∠T is
#: taken in (−360°, 0°], so −330° is a lead of 30°.
N_CONTOURS_DEG = (-30.0, -60.0, -90.0, -120.0, -150.0, -210.0, -240.0, -270.0, -300.0, -330.0)


def n_contour(level_deg, points=400):
    """One N contour ∠T = ``level_deg`` in Nichols coordinates: (phase of L [deg], |L| [dB]).

    With T = r e^{jφ}, r over (0, ∞), L = T/(1 − T) runs along an arc from the origin (|L| → 0,
    ∠L → φ) to −1; its phase is continued from φ at r → 0, so the curve lies on the branch
    φ..−180° (shift by 360° for the other turns).
    """
    r = np.geomspace(1e-3, 1e3, points)
    t = r * np.exp(1j * math.radians(level_deg))
    loop = t / (1.0 - t)
    phase = np.unwrap(np.angle(loop))
    phase += 2.0 * math.pi * np.round((math.radians(level_deg) - phase[0]) / (2.0 * math.pi))
    return np.degrees(phase), 20.0 * np.log10(np.abs(loop))


#: Rows along which the N contours are labelled, above the bottom of the chart [dB]: the first
#: where a label fits.
N_LABEL_ROWS_DB = (3.0, 11.0)
#: Width of a frequency label of the Nichols chart ("10000 rad/s") [fraction of the chart].
FREQUENCY_LABEL_WIDTH = 0.13


def _n_label_spot(at_row, rows, placed, obstacles, low, high):
    """(x, row) of the first label position that keeps clear of the placed labels and the
    obstacles, or None. ``at_row(row)`` is the contour's phase on that row [deg]; ``placed``
    holds (x, row) of the labels so far; ``obstacles`` (x, y, width) the curve's samples (width
    0) and the frequency labels, which reach ``width`` [deg] to the right of x."""
    spacing = (high - low) / 16.0
    for row in rows:
        at = at_row(row)
        if not low + spacing / 2 <= at <= high - spacing / 2:
            continue
        if any(r == row and abs(at - x) < spacing for x, r in placed):
            continue
        if any(abs(y - row) < 5.0 and x - spacing / 2 < at < x + width + spacing / 2
               for x, y, width in obstacles):
            continue
        return at, row
    return None


def _n_contours(ax, phase_range_deg, magnitude_range_db, obstacles=()):
    """Constant-∠T (N) contours over the chart, every 360° turn of it; each turn of a level
    labelled once near the bottom of the chart, where the contours are spread out (∠L ≈ ∠T
    there), on the first of N_LABEL_ROWS_DB where the label keeps 1/16 of the chart from the
    other labels and from the ``obstacles`` (see :func:`_n_label_spot`); else not labelled."""
    low, high = phase_range_deg
    rows = [magnitude_range_db[0] + r for r in N_LABEL_ROWS_DB]
    obstacles = [(x, y, FREQUENCY_LABEL_WIDTH * (high - low) if width is None else width)
                 for x, y, width in obstacles]
    placed = []
    for level in N_CONTOURS_DEG:
        phase, magnitude = n_contour(level)
        for k in range(math.floor((low - phase.max()) / 360.0),
                       math.ceil((high - phase.min()) / 360.0) + 1):
            x = phase + 360.0 * k
            if x.max() < low or x.min() > high:
                continue
            ax.plot(_r(x), _r(magnitude), color="C4", lw=0.6, ls="-.", alpha=0.6)
            spot = _n_label_spot(lambda row, x=x, m=magnitude: float(np.interp(row, m, x)), rows,
                                 placed, obstacles, low, high)
            if spot is not None:
                placed.append(spot)
                ax.text(*spot, f"{level:g}°", color="C4", fontsize=6.5, ha="center",
                        va="center", bbox={"boxstyle": "square,pad=0.1", "fc": "white",
                                           "ec": "none", "alpha": 0.8})
    ax.plot([], [], color="C4", lw=0.6, ls="-.", alpha=0.6,
            label=f"N contours: ∠T every {abs(N_CONTOURS_DEG[1] - N_CONTOURS_DEG[0]):g}°\n"
            "(labelled near the bottom)")


def nichols(data, magnitude_range_db=(-40.0, 60.0)):
    """Nichols chart of every loop of the structure (the parts within ``magnitude_range_db``;
    the inner loops with every other loop closed dashed), critical points marked, frequencies
    marked on the outermost loop, with M (constant |T|) and N (constant ∠T) contours (each
    loop's own closure L/(1 + L))."""
    c = data.curves
    w = _r(c.omega_rad_s)
    layout = Margins()
    fig, axes = _figure(1, 1, (9.5, 5.5), margins=layout)
    ax = axes[0, 0]
    outermost = c.described[-1].name
    drawn, phases = [], []
    for loop, response, margins, dashed in loop_views(data):
        m, p = _db(response), _phase_deg(response, c.omega_rad_s)
        shown = (m >= magnitude_range_db[0]) & (m <= magnitude_range_db[1])
        if not shown.any():
            continue
        drawn.append((m, p, shown))
        color = loop_color(loop.name)
        label = (f"{loop.symbol} with every other loop closed (dashed)" if dashed
                 else loop.title)
        ax.plot(np.where(shown, p, np.nan), np.where(shown, m, np.nan), color=color,
                label=label, **({"ls": "--", "lw": 1.1} if dashed else {}))
        if not dashed:
            for cross in margins.gain_crossovers:
                if _in_range(w, cross.frequency_rad_s):
                    ax.plot([cross.phase_deg], [0.0], "o", color=color, ms=5)
        if loop.name == outermost and not dashed:
            phases = (m, p)
    # no loop within the magnitude range: one turn around the critical point
    low = min((np.nanmin(p[shown]) for _, p, shown in drawn), default=-360.0)
    high = max((np.nanmax(p[shown]) for _, p, shown in drawn), default=0.0)
    first = True
    for k in range(int(math.floor((low + 180.0) / 360.0)), int(math.ceil((high + 180) / 360)) + 1):
        x = -180.0 + 360.0 * k
        if low - 30 <= x <= high + 30:
            ax.plot([x], [0.0], "r+", ms=12, mew=2, label="critical point (−1)" if first else None)
            first = False
    obstacles = [(float(x), float(y), 0.0) for m, p, shown in drawn
                 for x, y in zip(p[shown], m[shown], strict=True)
                 if y < magnitude_range_db[0] + 20.0]
    if phases:
        m, p = phases
        for target in (10.0, 100.0, 1000.0, 10000.0):
            if w[0] <= target <= w[-1]:
                x, y = _at(w, p, target), _at(w, m, target)
                if magnitude_range_db[0] <= y <= magnitude_range_db[1]:
                    ax.plot([x], [y], ".", color="k")
                    ax.annotate(f"{target:g} rad/s", (x, y), xytext=(5, 3),
                                textcoords="offset points", fontsize=8)
                    obstacles.append((x, y, None))  # the label reaches to the right
    _m_contours(ax, (low - 30.0, high + 30.0), magnitude_range_db)
    _n_contours(ax, (low - 30.0, high + 30.0), magnitude_range_db, obstacles)
    ax.set_xlim(low - 30.0, high + 30.0)
    ax.set_ylim(*magnitude_range_db)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.xaxis.set_major_locator(MultipleLocator(90 if high - low <= 720.0 else 180))
    ax.set_xlabel("phase of L [deg]")
    ax.set_ylabel("magnitude of L [dB]")
    legend_room_right(fig, layout, ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0)))
    fig.suptitle(f"{data.label}: Nichols chart of {loops_words(c)} ({EXACT}); frequencies "
                 f"marked on {c.described[-1].symbol}")
    return fig


def _bandwidth_bounds(verdicts):
    """The distinct lower bounds of the closed-loop bandwidth requirements [rad/s]."""
    bounds = []
    for verdict in verdicts or ():
        bound = verdict.get("min")
        if (str(verdict.get("metric", "")) == "closed_loop.bandwidth_rad_s"
                and bound is not None and bound not in bounds):
            bounds.append(bound)
    return bounds


def _requirement_lines(ax, verdicts):
    shown = set()
    for verdict in verdicts or ():
        metric = str(verdict.get("metric", ""))
        bound = verdict.get("min")
        if metric.endswith("bandwidth_rad_s") and bound is not None and bound not in shown:
            shown.add(bound)
            ax.axhline(bound, color="C3", ls="-.", lw=1,
                       label=f"requirement ω_BW ≥ {bound:g} rad/s")


def _step_amplitudes_deg(data):
    """The variant's amplitudes [deg, or mm at a linear output]: one step (and one sine-dwell,
    if computed) each."""
    return np.array([run.output_unit.value(run.step.amplitude_deg) for run in data.dwell.steps])


def _bandwidth_series(ax, data, color, prefix=""):
    dwell = data.dwell
    amplitudes = _step_amplitudes_deg(data)
    fits = _r([s.fit.bandwidth_closed_form_rad_s if s.fit.success else np.nan
               for s in dwell.steps])
    if dwell.result is None:  # beyond the simulation budget: said in the legend
        ax.plot([], [], "o-", color=color, label=f"{prefix}sine-dwell −3 dB: not computed")
    else:
        sine = _r([np.nan if b is None else b for b in dwell.result.bandwidth_rad_s])
        ax.plot(amplitudes, sine, "o-", color=color, label=f"{prefix}sine-dwell −3 dB")
    ax.plot(amplitudes, fits, "s:", color=color, mfc="none",
            label=f"{prefix}second-order fit to the step")
    if dwell.linear_bandwidth_rad_s is not None:
        ax.axhline(dwell.linear_bandwidth_rad_s, color=color, ls="--", lw=1,
                   label=f"{prefix}linear −3 dB of T ({dwell.linear_bandwidth_rad_s:.4g} rad/s)")


def _amplitude_axis(ax, datas):
    """Log amplitude axis with a tick at each amplitude, labelled in plain degrees."""
    amplitudes = sorted({round(float(a), 12) for d in datas for a in _step_amplitudes_deg(d)}
                        | {round(a, 12) for a, _, _ in _reference_points(datas)})
    ax.set_xscale("log")
    ax.set_xticks(amplitudes, [f"{a:g}" for a in amplitudes])
    ax.minorticks_off()
    output = common_output_label(d.loaded.params for d in datas)
    ax.set_xlabel(f"{output} amplitude [{output_unit(datas[0].loaded.params).shown}]")


def _reference_points(datas):
    """(step amplitude [deg], bandwidth [rad/s], source) of each distinct reference fit the
    configs of ``datas`` declare with a step amplitude and a bandwidth."""
    points = []
    for data in datas:
        reference = data.reference
        if reference is None or reference.fit is None or reference.step_amplitude is None:
            continue
        bandwidth = reference.fit.bandwidth_rad_s
        if bandwidth is None:
            continue
        point = (math.degrees(reference.step_amplitude), bandwidth, reference.source)
        if point not in points:
            points.append(point)
    return points


def _reference_point(ax, datas):
    markers = "*PXD"
    for k, (amplitude, bandwidth, source) in enumerate(_reference_points(datas)):
        name = f"reference ({source})" if source else "reference"
        ax.plot([amplitude], [bandwidth], markers[k % len(markers)], color="k", ms=11,
                label=f"{name}, {amplitude:g}° step fit ({bandwidth:.4g} rad/s)")


def bandwidth_vs_amplitude(data):
    """Bandwidth versus amplitude: sine-dwell, step fit, linear, the reference point (if the
    config declares one)."""
    layout = Margins()
    fig, axes = _figure(1, 1, (10, 4.8), margins=layout)
    ax = axes[0, 0]
    _bandwidth_series(ax, data, "C0")
    _reference_point(ax, [data])
    _requirement_lines(ax, data.verdicts)
    _amplitude_axis(ax, [data])
    ax.set_ylabel("bandwidth ω_BW [rad/s]")
    ax.set_ylim(0.0, ax.get_ylim()[1] * 1.05)
    legend_room_right(fig, layout, ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0)))
    fig.suptitle(f"{data.label}: bandwidth vs amplitude (nonlinear loop and linear T, "
                 "exact delays)")
    return fig


#: Width of the linear T's band under the sine-dwell traces [pt] (theirs: 1 pt).
LINEAR_BAND_LW = 6.0


def sinedwell(data):
    """Sine-dwell magnitude and phase per amplitude over the linear T; limited points hollow."""
    r = data.dwell.result
    w = _r(r.frequencies_rad_s)
    fig, axes = _figure(3, 1, (8, 8.6), sharex=True, margins=Margins())
    mag, ph, amp = axes[:, 0]
    lin = np.asarray(data.dwell.linear_response)
    unit = output_unit(data.loaded.params)
    for k, amplitude in enumerate(np.degrees(np.asarray(r.amplitudes_rad))):
        color = f"C{k % 10}"
        hit = np.asarray(r.limit_hit[k], bool)
        magnitude, phase = _r(r.magnitude_db[k]), _r(r.phase_deg[k])
        for ax, values in ((mag, magnitude), (ph, phase)):
            ax.plot(w, values, "-", color=color, lw=1,
                    label=unit.symbol(amplitude) if ax is mag else None)
            ax.plot(w[hit], values[hit], "o", color=color, mfc="none", ms=5)
            ax.plot(w[~hit], values[~hit], "o", color=color, ms=4)
    # the linear T underneath, a wide pale band: the small-signal trace, which lies on it, is
    # drawn over it and the band shows on either side (drawn over, dashed, T hid the trace)
    for ax, values in ((mag, _db(lin)), (ph, _r(np.degrees(np.unwrap(np.angle(lin)))))):
        ax.plot(w, values, color="k", lw=LINEAR_BAND_LW, alpha=0.25, solid_capstyle="butt",
                zorder=1.5, label="linear T (exact delays)" if ax is mag else None)
    mag.plot([], [], "ko", mfc="none", label="a limit acts (hollow)")
    mag.axhline(HALF_POWER_DB, color="C7", ls=":", lw=1, label="−3.01 dB")
    symbol = _symbol(data)
    mag.set_ylabel(f"|{symbol}/{symbol}_cmd| first harmonic [dB]")
    ph.set_ylabel("phase [deg]")
    mag.legend(loc="lower left", ncols=2)
    _envelope_map(amp, data, r, w)
    _log_axes([mag, ph, amp], w)
    fig.suptitle(f"{data.label}: sine-dwell of the nonlinear loop per amplitude (exact delays)")
    return fig


def _envelope_map(ax, data, r, w):
    """The sine-dwell map in amplitude x frequency: the largest sine inside the current and the
    voltage limit (:mod:`cas_freq.analysis.rate_envelope`, with the dwell's feed-forward
    setting), each dwell point (hollow where a limit acted) and each amplitude's sine-dwell
    bandwidth (a star): where an amplitude's line crosses a limit curve, that limit bends its
    response."""
    unit = output_unit(data.loaded.params)
    dense = np.geomspace(float(w[0]), float(w[-1]), 200)
    envelope = rate_envelope(data.loaded.params, LoopParameters.from_config(data.loaded.params),
                             dense, feedforward=bool(data.dwell.feedforward))
    ax.plot(dense, _r(unit.from_si(envelope.current_amplitude_rad)), color="C3", lw=1.5,
            label=f"current limit ±{envelope.current_limit_a:g} A")
    volts = min(envelope.voltage_limit_v, envelope.supply_voltage_v)
    ax.plot(dense, _r(unit.from_si(envelope.voltage_amplitude_rad)), color="C1", lw=1.5,
            ls="--", label=f"voltage limit ±{volts:g} V")
    for k, amplitude in enumerate(np.asarray(r.amplitudes_rad)):
        color = f"C{k % 10}"
        hit = np.asarray(r.limit_hit[k], bool)
        level = np.full(w.size, _r(unit.from_si(amplitude)))
        ax.plot(w[hit], level[hit], "o", color=color, mfc="none", ms=5)
        ax.plot(w[~hit], level[~hit], "o", color=color, ms=4)
        bandwidth = r.bandwidth_rad_s[k]
        if bandwidth is not None:
            ax.plot([bandwidth], [level[0]], "*", color=color, ms=11)
    ax.plot([], [], "k*", ms=9, label="sine-dwell −3 dB at that amplitude")
    ax.set_yscale("log")
    ax.set_ylabel(f"amplitude [{unit.shown}]")
    basis = "" if envelope.basis == "continuous loops" else " (continuous loops)"
    ax.set_title(f"largest sine inside the limits{basis}", fontsize="medium")
    ax.legend(loc="lower left", fontsize="small")


def _dashed_words(curves):
    """``"; L_i with every other loop closed dashed"`` (the inner loops' other view)."""
    inner = [loop.symbol for loop in curves.described if loop.name in curves.loop_at_a_time]
    return f"; {' and '.join(inner)} with every other loop closed dashed" if inner else ""


#: The figures of one variant: file stem -> (function, caption); a caption is a string or a
#: function of the variant's data that returns one.
VARIANT_FIGURES = {
    "bode_loops": (bode_loops, lambda data: (
        f"Bode of {loops_words(data.curves)} with every crossover and the margins"
        + _dashed_words(data.curves))),
    "closed_loop": (closed_loop, "Closed loop T with the −3 dB line, ω_BW and the peak"),
    "sensitivity": (sensitivity, "S and T together"),
    "nichols": (nichols, lambda data: (
        f"Nichols chart of {loops_words(data.curves)} with M contours (constant |T|, dB) and N "
        "contours (constant ∠T, deg)" + _dashed_words(data.curves))),
    "nyquist": (loci.nyquist, loci.nyquist_caption),
    "pole_zero": (loci.pole_zero, loci.pole_zero_caption),
    "stiffness": (stiffness_figure, stiffness_caption),
    "steps": (steps, "Step responses, linear vs nonlinear, limits shaded"),
    "step_fit": (step_fit, "Second-order fit over the simulated step"),
    "bandwidth_vs_amplitude": (bandwidth_vs_amplitude, "Bandwidth versus amplitude"),
    "sinedwell": (sinedwell, "Sine-dwell response per amplitude"),
}

#: The figures drawn from the frequency responses alone (``data.curves`` and ``data.analysis``,
#: no simulation, no verdicts and no python-control): they can be drawn from
#: :func:`cas_freq.report.data.gather_frequency`'s data while the variant is simulated. (The
#: pole-zero map takes T's zeros, which the time-domain part computes with python-control.)
FREQUENCY_FIGURES = ("bode_loops", "sensitivity", "nichols", "nyquist", "stiffness")
