"""The report's step figures: the smallest and largest nonlinear steps against the linear
model, with the limit intervals shaded (:func:`steps`), and the largest step's second-order fit
(:func:`step_fit`); each panel runs over its step's transient
(:func:`transient_end_s`)."""

import math

import numpy as np
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from cas_freq.core.parameters import current_limit
from cas_freq.plots.common import Margins, legend_below
from cas_freq.plots.common import figure as _figure
from cas_freq.plots.common import output_symbol as _symbol
from cas_freq.plots.common import rounded as _r
from cas_freq.simulation.second_order import second_order_step

#: Most samples drawn per time-domain line (the simulations have tens of thousands).
MAX_LINE_POINTS = 800


def _thin(t, window_s):
    """Indices of the samples up to ``window_s`` [s], strided to at most MAX_LINE_POINTS."""
    t = np.asarray(t)
    last = min(int(np.searchsorted(t, window_s, side="right")) + 1, t.size)
    stride = max(1, math.ceil(last / MAX_LINE_POINTS))
    keep = np.arange(0, last, stride)
    return keep if keep[-1] == last - 1 else np.append(keep, last - 1)


#: Gaps between limit intervals narrower than this fraction of the window are bridged when
#: shaded (a clamp that chatters would otherwise draw thousands of spans below one pixel).
SHADE_MERGE_FRACTION = 1e-3


def _intervals(t, mask, merge_gap=0.0, end=None):
    """(start, end) times of the runs where ``mask`` is true, at full resolution; runs
    separated by at most ``merge_gap`` are joined, and only those starting by ``end`` kept."""
    mask = np.asarray(mask, bool)
    if not mask.any():
        return []
    edges = np.diff(np.concatenate(([0], mask.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    t = np.asarray(t)
    intervals = []
    for a, b in zip(t[starts], t[ends], strict=True):
        if end is not None and a > end:
            break
        if intervals and a - intervals[-1][1] <= merge_gap:
            intervals[-1][1] = float(b)
        else:
            intervals.append([float(a), float(b)])
    return [tuple(interval) for interval in intervals]


def _shade_limits(ax, t_ms, result, window_ms=None):
    gap = 0.0 if window_ms is None else SHADE_MERGE_FRACTION * window_ms
    for mask, color, alpha in ((result.current_limited, "C3", 0.15),
                               (result.voltage_limited, "C1", 0.25)):
        for start, end in _intervals(t_ms, mask, gap, window_ms):
            ax.axvspan(start, max(end, start + 1e-3), color=color, alpha=alpha, lw=0)


def _limit_words(step):
    hit = [name for name, flag in (("current", step.current_limited),
                                   ("voltage", step.voltage_limited)) if flag]
    return ("no limit hit" if not hit else " and ".join(hit) + " limit hit")


#: A step's own panel runs to this many times the end of its transient
#: (:func:`transient_end_s`), and at least :data:`STEP_WINDOW_MIN_S` [s].
STEP_WINDOW_FACTOR = 1.3
STEP_WINDOW_MIN_S = 0.02


def _finite(value):
    return value is not None and math.isfinite(value)


def transient_end_s(run, linear=None):
    """When a step's transient is over [s]: the nonlinear output within ±5 % of the step for
    good, the linear step (``linear``, its :class:`~cas_freq.simulation.StepFigures`) too, and
    the last current or voltage limit released; None when the output never stays within ±5 %.

    A creep inside ±5 % (a 10° step that overshoots by 3 % and settles within ±2 % only after
    80 ms, when everything else is over by 15 ms) does not stretch the panel; the step table
    gives both settling times and the label of the panel's time axis the ±2 % one it leaves out.
    """
    settle = run.step.settling_time_5pct_s
    if not _finite(settle):
        return None
    ends = [settle]
    if linear is not None and _finite(linear.settling_time_5pct_s):
        ends.append(linear.settling_time_5pct_s)
    r = run.result
    limited = np.asarray(r.current_limited, bool) | np.asarray(r.voltage_limited, bool)
    if limited.any():
        ends.append(float(np.asarray(r.t)[np.flatnonzero(limited)[-1]]))
    return max(ends)


def _step_window_s(run, linear=None):
    """A step's own panel [s]: :data:`STEP_WINDOW_FACTOR` × the end of its transient
    (:func:`transient_end_s`), at least :data:`STEP_WINDOW_MIN_S`, the whole run when it does
    not settle."""
    end = transient_end_s(run, linear)
    t_end = float(run.result.t[-1])
    if end is None:
        return t_end
    return min(t_end, max(STEP_WINDOW_FACTOR * end, STEP_WINDOW_MIN_S))


def _time_label(run, window_s):
    """``"time [ms]"``, with the ±2 % settling time when it lies beyond the panel."""
    settle = run.step.settling_time_s
    if _finite(settle) and settle > window_s:
        return f"time [ms]; within ±2 % from {1e3 * settle:.3g} ms, past the panel"
    return "time [ms]"


def _linear_figures(data, k):
    """The step figures of the linear step ``k`` of ``data``, None when it has none."""
    figures = data.linear_step_figures
    return figures[k] if k < len(figures) else None


def steps(data):
    """Smallest and largest step: nonlinear vs linear output angle, current and voltage, with the
    intervals where a limit acts shaded."""
    indices = sorted({data.small_index, data.large_index})
    layout = Margins(top=0.65, hgap=0.4)
    fig, axes = _figure(3, len(indices), (5.2 * len(indices), 7.5), margins=layout)
    params = data.loaded.params
    for col, k in enumerate(indices):
        run = data.dwell.steps[k]
        r = run.result
        window_s = _step_window_s(run, _linear_figures(data, k))
        keep = _thin(r.t, window_s)
        t_ms = _r(1e3 * np.asarray(r.t)[keep])
        unit = run.output_unit
        top, mid, bottom = axes[:, col]
        for ax in (top, mid, bottom):
            _shade_limits(ax, 1e3 * np.asarray(r.t), r, 1e3 * window_s)
            ax.set_xlim(0.0, 1e3 * window_s)
        top.plot(t_ms, _r(unit.from_si(r.command[keep])), color="k", lw=0.8, ls=":",
                 label=f"command {_symbol(data)}_cmd")
        top.plot(t_ms, _r(unit.from_si(r.delta[keep])), color="C0",
                 label="nonlinear (limits, exact delays)")
        top.plot(t_ms, _r(unit.from_si(data.linear_steps[k][keep])), color="C1", ls="--",
                 label=f"linear T (Padé {data.pade_order})")
        top.set_ylabel(f"{params.output_label} {unit.quantity} {_symbol(data)} [{unit.shown}]")
        top.set_title(f"{unit.symbol(run.step.amplitude_deg)} step: {_limit_words(run.step)}")
        mid.plot(t_ms, _r(r.i[keep]), color="C0", label="motor current i")
        for sign in (1, -1):
            mid.axhline(sign * current_limit(params), color="C3", ls="--", lw=0.9)
            bottom.axhline(sign * params.current_loop.v_max, color="C1", ls="--", lw=0.9)
        mid.set_ylabel("current i [A]")
        bottom.plot(t_ms, _r(r.V[keep]), color="C0", label="motor voltage V")
        bottom.set_ylabel("voltage V [V]")
        bottom.set_xlabel(_time_label(run, window_s))
    # one legend below the panels: inside them it covered the curves and the ±i_max lines
    handles, labels = [], []
    for ax in axes[:, 0]:  # the curves, each once
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.append(handle)
            labels.append(label)
    handles += [Patch(color="C3", alpha=0.15), Patch(color="C1", alpha=0.25),
                Line2D([], [], color="C3", ls="--", lw=0.9),
                Line2D([], [], color="C1", ls="--", lw=0.9)]
    labels += ["current limit active", "voltage limit active", "±i_max", "±v_max"]
    legend_below(fig, layout, handles, labels, "small", 3)
    fig.suptitle(f"{data.label}: {params.output_label} steps, nonlinear simulation vs linear model "
                 f"(Padé {data.pade_order}); limit intervals shaded")
    return fig


def _reference_fit(data):
    """(reference, its fit) when the config declares a reference fit with ωn and ζ, else
    None."""
    reference = data.reference
    fit = None if reference is None else reference.fit
    if fit is None or fit.wn is None or fit.zeta is None:
        return None
    return reference, fit


def step_fit(data):
    """The largest step with its second-order fit and, when the config declares one, the
    reference's fit."""
    run = data.dwell.steps[data.large_index]
    r, fit = run.result, run.fit
    window_s = _step_window_s(run, _linear_figures(data, data.large_index))
    keep = _thin(r.t, window_s)
    t = np.asarray(r.t)[keep]
    unit = run.output_unit
    a_deg = unit.value(run.step.amplitude_deg)  # the step in the unit the axis shows
    fig, axes = _figure(1, 1, (8, 4.5), margins=Margins(top=0.6))
    ax = axes[0, 0]
    window = 1e3 * window_s
    t_ms = _r(1e3 * t)
    ax.plot(t_ms, _r(unit.from_si(r.delta[keep])), color="C0", lw=2.2, alpha=0.7,
            label="nonlinear simulation (data)")
    if fit.success:
        ax.plot(t_ms, _r(second_order_step(t, fit.wn_rad_s, fit.zeta, fit.td_s, a_deg)),
                color="C3", ls="--", label=f"fit: ωn {fit.wn_rad_s:.4g} rad/s, ζ {fit.zeta:.3g}, "
                f"td {1e3 * fit.td_s:.3g} ms")
    ref = _reference_fit(data)
    if ref is not None:
        reference, fit_ref = ref
        source = f" ({reference.source})" if reference.source else ""
        ax.plot(t_ms, _r(second_order_step(t, fit_ref.wn, fit_ref.zeta, fit_ref.td or 0.0,
                                           a_deg)),
                color="k", ls=":", label=f"reference fit{source}: ωn {fit_ref.wn:g} rad/s, "
                f"ζ {fit_ref.zeta:g}, td {1e3 * (fit_ref.td or 0.0):g} ms")
    ax.set_xlim(0.0, window)
    ax.set_xlabel("time [ms]")
    ax.set_ylabel(f"{data.loaded.params.output_label} {unit.quantity} {_symbol(data)} "
                  f"[{unit.shown}]")
    ax.legend(loc="lower right")
    ax.set_title(f"{unit.symbol(run.step.amplitude_deg)} step: second-order-plus-delay fit "
                 "(docs/model.md §7)")
    fig.suptitle(f"{data.label}: second-order fit to the nonlinear step (exact delays)")
    return fig
