"""The compare report's overlays: several variants' L_p, T, steps and bandwidths in one figure
each (:data:`COMPARE_FIGURES`), drawn with the report's figure helpers
(:mod:`cas_freq.plots.report`).
"""

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.ticker import MultipleLocator

from cas_freq.config.wording import OutputWords, common_output_label
from cas_freq.plots.common import EXACT, Margins, legend_below
from cas_freq.plots.common import figure as _figure
from cas_freq.plots.common import rounded as _r
from cas_freq.plots.ranges import (
    LEGEND_FONT_PT,
    PAST_CROSSOVER,
    SETTLING_FACTOR,
    legend_columns,
    phase_window,
    time_window,
)
from cas_freq.plots.report import (
    HALF_POWER_DB,
    _amplitude_axis,
    _bandwidth_series,
    _db,
    _in_range,
    _log_axes,
    _phase_deg,
    _reference_point,
)
from cas_freq.plots.steps import _limit_words, _linear_figures, _step_window_s, _thin


def _colors(datas):
    return [f"C{k % 10}" for k in range(len(datas))]


def _overlay_legend(fig, layout, handles, labels):
    """One legend below the axes of an overlay, in 8 pt type, in columns of at most
    :data:`~cas_freq.plots.ranges.LEGEND_ROWS` entries (:func:`legend_below`)."""
    return legend_below(fig, layout, handles, labels, LEGEND_FONT_PT,
                        legend_columns(len(labels)))


def bode_overlay(datas, labels):
    """|L_p|, ∠L_p and |T| of several variants overlaid; the phase axis covers what the curves
    take up to a little past the highest gain crossover (:func:`~cas_freq.plots.ranges.
    phase_window`), where the margins are read. When a variant has a velocity loop, |L_v| and
    ∠L_v follow (broken at the current command; with every other loop closed dashed, in the
    variant's colour)."""
    velocity = [d for d in datas if "velocity_loop" in d.curves.loops]
    layout = Margins(hgap=0.25)
    rows = 5 if velocity else 3
    fig, axes = _figure(rows, 1, (8, 8.5 + (4.5 if velocity else 0.0)), sharex=True,
                        margins=layout)
    mag, ph, cl = axes[:3, 0]
    phases, crossovers = [], []
    for data, label, color in zip(datas, labels, _colors(datas), strict=True):
        c = data.curves
        w = _r(c.omega_rad_s)
        phase = _phase_deg(c.position_loop, c.omega_rad_s)
        mag.plot(w, _db(c.position_loop), color=color, label=label)
        ph.plot(w, phase, color=color)
        cl.plot(w, _db(c.closed_loop), color=color)
        bw = data.analysis.closed_loop.bandwidth_rad_s if data.analysis.closed_loop else None
        if _in_range(w, bw):
            cl.plot([bw], [HALF_POWER_DB], "o", color=color)
        phases.append((w, phase))
        crossovers += [x.frequency_rad_s for x in data.analysis.position_loop.gain_crossovers
                       if _in_range(w, x.frequency_rad_s)]
    mag.axhline(0.0, color="k", lw=0.8)
    ph.axhline(-180.0, color="k", lw=0.8)
    cl.axhline(HALF_POWER_DB, color="k", ls="--", lw=0.9, label="−3.01 dB")
    mag.set_ylim(max(mag.get_ylim()[0], -80.0), mag.get_ylim()[1])
    cl.set_ylim(max(cl.get_ylim()[0], -60.0), cl.get_ylim()[1])
    low, high, step = phase_window(phases, crossovers)
    ph.set_ylim(low, high)
    ph.yaxis.set_major_locator(MultipleLocator(step))
    position = _loop(datas, "position_loop").symbol
    mag.set_ylabel(f"|{position}| [dB]")
    ph.set_ylabel(f"∠{position} [deg]")
    cl.set_ylabel("|T| [dB] (● ω_BW)")
    handles, names = mag.get_legend_handles_labels()
    more, more_names = cl.get_legend_handles_labels()
    if velocity:
        _velocity_rows(axes[3, 0], axes[4, 0], datas)
        more = [*more, Line2D([], [], color="k", ls="--", lw=1.0)]
        more_names = [*more_names, f"{_loop(datas, 'velocity_loop').symbol} with every other "
                      "loop closed (dashed)"]
    _overlay_legend(fig, layout, handles + more, names + more_names)
    _log_axes(list(axes[:, 0]), [min(d.curves.omega_rad_s[0] for d in datas),
                                 max(d.curves.omega_rad_s[-1] for d in datas)])
    shown = ", ".join(loop.symbol for loop in (_loop(datas, "position_loop"),
                                               _loop(datas, "velocity_loop")) if loop)
    fig.suptitle(f"{shown} and T of {len(datas)} variants ({EXACT}); phase shown up to "
                 f"{PAST_CROSSOVER:g}× the highest crossover")
    return fig


def _loop(datas, name):
    """The :class:`~cas_freq.report.data.CurveLoop` ``name`` (its structure's symbol and break
    point) of the first variant that has that loop, None when none has it."""
    return next((loop for d in datas for loop in d.curves.described if loop.name == name), None)


def bode_overlay_caption(datas):
    """Caption of :func:`bode_overlay`."""
    position, velocity = _loop(datas, "position_loop"), _loop(datas, "velocity_loop")
    if velocity is None:
        return f"{position.symbol} and T overlaid"
    return (f"{position.symbol}, {velocity.symbol} (broken at {velocity.breaks_at}; every "
            "other loop closed dashed) and T overlaid")


def _velocity_rows(mag, ph, datas):
    """|L_v| and ∠L_v of the variants that have a velocity loop: broken at the current command
    (solid), with every other loop closed (dashed)."""
    phases, crossovers = [], []
    for data, color in zip(datas, _colors(datas), strict=True):
        c = data.curves
        if "velocity_loop" not in c.loops:
            continue
        w = _r(c.omega_rad_s)
        margins = data.analysis.velocity_loop
        for values, style, figures in ((c.loops["velocity_loop"], "-", margins),
                                       (c.loop_at_a_time.get("velocity_loop"), "--",
                                        margins.loop_at_a_time)):
            if values is None:
                continue
            phase = _phase_deg(values, c.omega_rad_s)
            mag.plot(w, _db(values), color=color, ls=style, lw=1.5 if style == "-" else 1.1)
            ph.plot(w, phase, color=color, ls=style, lw=1.5 if style == "-" else 1.1)
            phases.append((w, phase))
            if figures is not None:
                crossovers += [x.frequency_rad_s for x in figures.gain_crossovers
                               if _in_range(w, x.frequency_rad_s)]
    mag.axhline(0.0, color="k", lw=0.8)
    ph.axhline(-180.0, color="k", lw=0.8)
    mag.set_ylim(max(mag.get_ylim()[0], -80.0), mag.get_ylim()[1])
    low, high, step = phase_window(phases, crossovers)
    ph.set_ylim(low, high)
    ph.yaxis.set_major_locator(MultipleLocator(step))
    symbol = _loop(datas, "velocity_loop").symbol
    mag.set_ylabel(f"|{symbol}| [dB]")
    ph.set_ylabel(f"∠{symbol} [deg]")


def _step_overlay_window(datas, which):
    """(window [s], labels' indices off the panel) of the step ``which`` of every variant."""
    indices = [getattr(d, which) for d in datas]
    runs = [d.dwell.steps[k] for d, k in zip(datas, indices, strict=True)]
    return time_window([run.step.settling_time_s for run in runs],
                       [_step_window_s(run, _linear_figures(d, k))
                        for run, d, k in zip(runs, datas, indices, strict=True)])


def step_overlay(datas, labels):
    """Smallest and largest nonlinear steps of several variants, normalised by the amplitude,
    over :data:`~cas_freq.plots.ranges.SETTLING_FACTOR` × the median settling time (slower
    variants run off the panel; :func:`step_overlay_caption` names them)."""
    layout = Margins(top=0.65, wgap=0.7)
    fig, axes = _figure(1, 2, (10, 4.8), margins=layout)
    for col, which in enumerate(("small_index", "large_index")):
        ax = axes[0, col]
        amplitudes = []
        window_s, _ = _step_overlay_window(datas, which)
        for data, color in zip(datas, _colors(datas), strict=True):
            k = getattr(data, which)
            run = data.dwell.steps[k]
            a = run.step.amplitude_deg
            amplitudes.append(a)
            keep = _thin(run.result.t, window_s)
            t_ms = _r(1e3 * np.asarray(run.result.t)[keep])
            ax.plot(t_ms, _r(np.degrees(run.result.delta[keep]) / a), color=color)
            ax.plot(t_ms, _r(np.degrees(data.linear_steps[k][keep]) / a), color=color, ls=":",
                    lw=1)
        ax.set_xlim(0.0, 1e3 * window_s)
        ax.set_xlabel("time [ms]")
        unit = datas[0].dwell.steps[0].output_unit  # deg, or mm at a linear output
        ax.set_ylabel(f"{OutputWords(linear=unit.linear).symbol} / step size [-]")
        size = "/".join(sorted({unit.symbol(a) for a in amplitudes}))
        ax.set_title(f"{'smallest' if col == 0 else 'largest'} step ({size})")
    handles = [Line2D([], [], color=color) for color in _colors(datas)]
    names = [f"{label}: {_limit_words(d.dwell.steps[d.small_index].step)} (smallest), "
             f"{_limit_words(d.dwell.steps[d.large_index].step)} (largest)"
             for d, label in zip(datas, labels, strict=True)]
    handles.append(Line2D([], [], color="k", ls=":", lw=1))
    names.append(f"linear T (Padé {datas[0].pade_order}), dotted")
    _overlay_legend(fig, layout, handles, names)
    output = common_output_label(d.loaded.params for d in datas)
    fig.suptitle(f"nonlinear {output} steps (limits, exact delays) vs linear (dotted)")
    return fig


def step_overlay_caption(datas, labels):
    """The step overlay's caption: its time axes, and the variants that run off them."""
    parts = []
    for which, name in (("small_index", "smallest"), ("large_index", "largest")):
        window_s, off = _step_overlay_window(datas, which)
        # the median rule shortens the axis only when some variant's own panel is longer
        why = (f"{SETTLING_FACTOR:g}× the median settling time" if off
               else "the longest of the variants' own step panels")
        text = f"{name} steps over {1e3 * window_s:.3g} ms ({why})"
        if off:
            text += f"; {', '.join(labels[k] for k in off)} settle later and run off the panel"
        parts.append(text)
    return "Steps overlaid: " + "; ".join(parts)


def bandwidth_overlay(datas, labels):
    """Bandwidth versus amplitude of several variants."""
    layout = Margins()
    fig, axes = _figure(1, 1, (10, 5), margins=layout)
    ax = axes[0, 0]
    for data, color in zip(datas, _colors(datas), strict=True):
        _bandwidth_series(ax, data, color)
    _reference_point(ax, datas)
    _amplitude_axis(ax, datas)
    ax.set_ylabel("bandwidth ω_BW [rad/s]")
    ax.set_ylim(0.0, ax.get_ylim()[1] * 1.05)
    # colour: the variant; line and marker: the estimate (one entry each, not one per pair)
    handles = [Line2D([], [], color=color, lw=2) for color in _colors(datas)]
    names = [label + ("" if d.dwell.result is not None else " (sine-dwell not computed)")
             for d, label in zip(datas, labels, strict=True)]
    handles += [Line2D([], [], color="k", marker="o", ls="-"),
                Line2D([], [], color="k", marker="s", mfc="none", ls=":"),
                Line2D([], [], color="k", ls="--", lw=1)]
    names += ["sine-dwell −3 dB", "second-order fit to the step", "linear −3 dB of T"]
    for handle, name in zip(*ax.get_legend_handles_labels(), strict=True):
        if name.startswith("reference"):
            handles.append(handle)
            names.append(name)
    _overlay_legend(fig, layout, handles, names)
    fig.suptitle("bandwidth vs amplitude (sine-dwell of the nonlinear loop; linear T dashed)")
    return fig


#: The overlay figures of a comparison: file stem -> (function, caption); a caption is a string
#: or a function of (datas, labels) that returns one.
COMPARE_FIGURES = {
    "bode_overlay": (bode_overlay, lambda datas, labels: bode_overlay_caption(datas)),
    "step_overlay": (step_overlay, step_overlay_caption),
    "bandwidth_overlay": (bandwidth_overlay, "Bandwidth versus amplitude overlaid"),
}
