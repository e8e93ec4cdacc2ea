r"""The report's Nyquist plots and closed-loop pole-zero map (definitions: docs/model.md §7).

Like every report figure these take :class:`cas_freq.report.data.VariantData` and return a
:class:`matplotlib.figure.Figure`; the figures of merit (Ms, the disk margin α, the poles) are
the engine's, read from ``data.analysis``. What is drawn from them:

- **Ms circle**: :math:`|1 + L| = 1/M_s`, centre −1, radius :math:`1/M_s` (linear Ms). Since
  :math:`M_s = \max_\omega 1/|1 + L(j\omega)|`, the curve stays outside and touches it at the
  sensitivity peak's frequency.
- **Disk-margin disk** of the symmetric (skew 0) disk margin
  :math:`\alpha = 1/\max_\omega |S - 1/2|`: :math:`|S - 1/2| \le 1/\alpha` on the curve is
  :math:`\alpha |1 - L| \le 2 |1 + L|`, so the excluded region is the Apollonius disk
  :math:`\alpha |1 - L| > 2 |1 + L|` around −1. For :math:`\alpha < 2` it is the disk whose
  real-axis diameter runs from :math:`-(2+\alpha)/(2-\alpha)` to :math:`-(2-\alpha)/(2+\alpha)`
  (the critical points −1/f of every gain f in the disk of gains
  :math:`[(2-\alpha)/(2+\alpha), (2+\alpha)/(2-\alpha)]`): centre
  :math:`-(4+\alpha^2)/(4-\alpha^2)`, radius :math:`4\alpha/(4-\alpha^2)`
  (:func:`disk_margin_circle`). For :math:`\alpha \ge 2` the region is a half-plane or the
  outside of a circle; it is then not drawn (and said so).
- **Pole-zero map**: the engine's poles of T (:attr:`cas_freq.analysis.Stability.poles`, the
  Padé model of the stability verdict) and the zeros of T of the same Padé order
  (:func:`cas_freq.analysis.systems.closed_loop_zeros`, python-control's ``zeros`` of that T).
"""

import math

import numpy as np

from cas_freq.analysis.systems import closed_loop_zeros as zeros
from cas_freq.core.figures import FIGURES
from cas_freq.model import parts
from cas_freq.model.loops import Selector
from cas_freq.model.sampled import drive_responses as responses
from cas_freq.plots.common import EXACT, Margins, legend_room_below, legend_room_right, loop_color
from cas_freq.plots.common import figure as _figure
from cas_freq.plots.common import rounded as _r

# ---- Nyquist ---------------------------------------------------------------------------------

#: Half-width of the Nyquist view around −1 [-]: −3..1 × −2..2 (the origin, the unit circle, the
#: Ms circle and the phase crossovers of the upper gain margins all lie inside; a disk-margin
#: disk wider than that shows the edge that faces the curve).
NYQUIST_HALF_WIDTH = 2.0


def ms_circle(sensitivity_peak_db):
    """Centre and radius of the Ms circle |1 + L| = 1/Ms.

    Parameters
    ----------
    sensitivity_peak_db : float
        Ms [dB].

    Returns
    -------
    (complex, float)
        Centre (−1) and radius 1/Ms [-].
    """
    return complex(-1.0, 0.0), 10.0 ** (-sensitivity_peak_db / 20.0)


def disk_margin_circle(alpha):
    r"""Centre and radius of the region the symmetric disk margin α excludes in the L plane.

    .. math::
        \alpha |1 - L| > 2 |1 + L| \iff
        \left|L + \frac{4 + \alpha^2}{4 - \alpha^2}\right| < \frac{4 \alpha}{4 - \alpha^2}
        \quad (\alpha < 2)

    i.e. the disk with real-axis diameter from −(2+α)/(2−α) to −(2−α)/(2+α) (Seiler, Packard
    and Gahinet, "An introduction to disk margins", IEEE Control Systems 40(5), 2020, skew 0).

    Parameters
    ----------
    alpha : float
        Disk margin α [-] (α = 1/max_ω |S − 1/2|).

    Returns
    -------
    (complex, float) or None
        Centre and radius [-]; None for α >= 2 (the region is then no disk).
    """
    if not alpha < 2.0:
        return None
    a2 = alpha * alpha
    return complex(-(4.0 + a2) / (4.0 - a2), 0.0), 4.0 * alpha / (4.0 - a2)


def _clipped(values, half):
    """``values`` with samples far outside the view (|L + 1| > 1.5·half on either axis) set to
    NaN, keeping each one next to a kept sample so that the line still reaches the edge."""
    values = np.asarray(values, dtype=complex)
    inside = (np.abs(values.real + 1.0) <= 1.5 * half) & (np.abs(values.imag) <= 1.5 * half)
    keep = inside.copy()
    keep[1:] |= inside[:-1]
    keep[:-1] |= inside[1:]
    return np.where(keep, values, complex(np.nan, np.nan))


def _direction_arrows(ax, omega, values, frequencies, color, half):
    """Arrow heads along the curve at ``frequencies`` [rad/s] inside the view, pointing the way
    ω increases."""
    for w in frequencies:
        if w is None or not omega[0] < w < omega[-1]:
            continue
        k = int(np.searchsorted(omega, w))
        k = min(max(k, 1), len(omega) - 1)
        (x0, x1), (y0, y1) = _r(values[k - 1:k + 1].real), _r(values[k - 1:k + 1].imag)
        start, end = complex(x0, y0), complex(x1, y1)
        if not (abs(start.real + 1.0) < half and abs(start.imag) < half):
            continue
        ax.annotate("", xy=(float(end.real), float(end.imag)),
                    xytext=(float(start.real), float(start.imag)),
                    arrowprops={"arrowstyle": "-|>", "color": color, "lw": 0,
                                "mutation_scale": 14, "shrinkA": 0, "shrinkB": 0})


def _circle(ax, centre, radius, **kwargs):
    t = np.linspace(0.0, 2.0 * math.pi, 361)
    return ax.plot(_r(centre.real + radius * np.cos(t)), _r(centre.imag + radius * np.sin(t)),
                   **kwargs)


def _nyquist_panel(ax, omega, values, margins, exact, name, color):
    """One loop's Nyquist panel: both frequency branches, −1, unit circle, Ms circle, disk."""
    half = NYQUIST_HALF_WIDTH
    shown = _clipped(values, half)
    ax.plot(_r(shown.real), _r(shown.imag), color=color, lw=1.5, label=f"{name}(jω), ω > 0")
    ax.plot(_r(shown.real), _r(-shown.imag), color=color, lw=0.8, ls=":",
            label="ω < 0 (mirror image)")
    _direction_arrows(ax, omega, values, (margins.crossover_rad_s, margins.sensitivity_peak_rad_s,
                                          margins.phase_crossover_rad_s), color, half)
    _circle(ax, complex(0.0, 0.0), 1.0, color="C7", lw=0.7, ls="--", label="|L| = 1")
    if margins.crossover_rad_s is not None:
        p = exact(margins.crossover_rad_s)
        ax.plot([_r(p.real)], [_r(p.imag)], "o", color=color, ms=5,
                label=f"gain crossover {margins.crossover_rad_s:.4g} rad/s "
                f"({FIGURES['position_loop.phase_margin_deg'].short} "
                f"{margins.phase_margin_deg:.3g}°)")
    if margins.phase_crossover_rad_s is not None:
        p = exact(margins.phase_crossover_rad_s)
        ax.plot([_r(p.real)], [_r(p.imag)], "s", color=color, ms=4, mfc="none",
                label=f"phase crossover {margins.phase_crossover_rad_s:.4g} rad/s "
                f"({FIGURES['position_loop.gain_margin_db'].short} "
                f"{margins.gain_margin_db:+.3g} dB)")
    if margins.sensitivity_peak_db is not None:
        centre, radius = ms_circle(margins.sensitivity_peak_db)
        _circle(ax, centre, radius, color="C3", lw=1.1, ls="--",
                label=f"Ms circle: centre −1, radius 1/Ms = {radius:.3g} "
                f"(Ms {margins.sensitivity_peak_db:.2f} dB)")
        p = exact(margins.sensitivity_peak_rad_s)
        ax.plot(_r([-1.0, p.real]), _r([0.0, p.imag]), color="C3", lw=0.9, marker="v", ms=5,
                markevery=[1],
                label=f"nearest approach to −1 at {margins.sensitivity_peak_rad_s:.4g} rad/s")
    disk = (None if margins.disk_margin_alpha is None
            else disk_margin_circle(margins.disk_margin_alpha))
    if disk is not None:
        centre, radius = disk
        t = np.linspace(0.0, 2.0 * math.pi, 361)
        ax.fill(_r(centre.real + radius * np.cos(t)), _r(radius * np.sin(t)), color="C2",
                alpha=0.15, lw=1.0, ec="C2",
                label=f"disk margin α {margins.disk_margin_alpha:.3g} "
                f"(±{margins.disk_margin_gain_db:.3g} dB, ±{margins.disk_margin_phase_deg:.3g}°)"
                f": excluded disk {centre.real - radius:.3g}..{centre.real + radius:.3g}")
    elif margins.disk_margin_alpha is not None:
        ax.plot([], [], " ", label=f"disk margin α {margins.disk_margin_alpha:.3g} ≥ 2: no disk")
    if margins.sensitivity_peak_db is None:
        ax.plot([], [], " ", label="closed loop not stable: no Ms or disk-margin circle")
    ax.plot([-1.0], [0.0], "+", color="r", ms=13, mew=2, label="−1 (critical point)", zorder=6)
    ax.set_xlim(-1.0 - half, -1.0 + half)
    ax.set_ylim(-half, half)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel(f"Re {name} [-]")
    ax.set_ylabel(f"Im {name} [-]")
    return half


def nyquist(data):
    """Nyquist plot of every loop of the structure (exact delays), outermost first, one panel
    each (L_p, L_v with a velocity loop, L_i), zoomed on −1, with the Ms circle and the
    disk-margin disk of each loop (as the engine reports Ms and α); an inner loop with every
    other loop closed is drawn dashed on its loop's panel."""
    c = data.curves
    p = Selector(parts.one_variant(data.loaded.params))()
    described = c.outermost_first()
    panels = len(described)
    layout = Margins(left=0.65, right=0.15, top=1.2, wgap=0.75)  # two-line panel titles
    fig, axes = _figure(1, panels, (5.5 * panels, 7.6), margins=layout)
    legends = []
    sides = ("left", "right") if panels == 2 else ("left", "center", "right")[:panels]
    for ax, side, loop in zip(axes[0], sides, described, strict=True):
        color = loop_color(loop.name)

        def exact(w, name=loop.name):
            return complex(responses(p, np.array([1j * w]), closed=False).loops[name][0])

        margins = getattr(data.analysis, loop.name)
        half = _nyquist_panel(ax, c.omega_rad_s, c.loops[loop.name], margins, exact,
                              loop.symbol, color)
        if loop.name in c.loop_at_a_time:
            shown = _clipped(c.loop_at_a_time[loop.name], half)
            aat = margins.loop_at_a_time
            words = ("" if aat is None or aat.phase_margin_deg is None
                     else f": {FIGURES['position_loop.phase_margin_deg'].short} "
                     f"{aat.phase_margin_deg:.3g}° @ {aat.crossover_rad_s:.4g} rad/s")
            ax.plot(_r(shown.real), _r(shown.imag), color=color, lw=1.1, ls="--",
                    label=f"{loop.symbol} with every other loop closed, ω > 0{words}")
        ax.set_title(f"{loop.title}\n"
                     f"ω {c.omega_rad_s[0]:.3g}..{c.omega_rad_s[-1]:.3g} "
                     f"rad/s; view ±{half:g} around −1")
        handles, labels = ax.get_legend_handles_labels()
        legends.append(fig.legend(handles, labels, loc=f"lower {side}", fontsize=7))
    legend_room_below(fig, layout, legends)
    names = [loop.symbol for loop in described]
    symbols = ", ".join(names[:-1]) + " and " + names[-1]
    fig.suptitle(f"{data.label}: Nyquist plots of {symbols} ({EXACT})\ncurves clipped to "
                 "the view, arrows point to increasing ω")
    return fig


def nyquist_caption(data):
    """Caption of :func:`nyquist` for one variant."""
    described = data.curves.outermost_first()
    places = ("left", "right") if len(described) == 2 else ("left", "middle", "right")
    panels = ", ".join(f"{loop.symbol} ({loop.break_point}; {place})"
                       for loop, place in zip(described, places, strict=False))
    inner = ", ".join(loop.symbol for loop in described[1:])
    return (f"Nyquist plots of {panels}, exact delays: ω > 0 solid with arrows "
            "towards increasing ω, ω < 0 dotted; the −1 point, the unit circle, the Ms circle "
            "(centre −1, radius 1/Ms) and the disk-margin disk (real-axis diameter "
            "−(2+α)/(2−α)..−(2−α)/(2+α)); "
            f"{inner} with every other loop closed dashed; view zoomed to "
            f"±{NYQUIST_HALF_WIDTH:g} around −1, the curve clipped "
            "to it (the low-frequency branch lies outside)")


# ---- pole-zero map ---------------------------------------------------------------------------

#: The pole-zero view spans this many times the loop's own frequency (ω_BW or the gain
#: crossover, whichever is larger) to the left of the imaginary axis.
VIEW_SPAN = 2.5


def closed_loop_zeros(data):
    """Zeros [rad/s] of T of a variant's data: those computed with its time-domain part
    (:func:`cas_freq.report.data.gather_time`), else computed here."""
    known = getattr(data, "closed_loop_zeros", None)  # data of the figure API may lack them
    if known is not None:
        return np.asarray(known, dtype=complex)

    return zeros(data.loaded.params, data.analysis.stability.pade_order)


def engine_poles(analysis):
    """The engine's closed-loop poles [rad/s] (complex) of an analysis."""
    return np.array([complex(re, im) for re, im in analysis.stability.poles], dtype=complex)


def pole_zero_view(analysis, poles):
    """Axis limits [rad/s] of the pole-zero map: the region of the dominant dynamics.

    VIEW_SPAN × the loop's frequency (the larger of ω_BW and the L_p gain crossover; the median
    pole magnitude without either) to the left, a quarter of that to the right, ±0.6 of it up
    and down, widened to hold every right-half-plane pole.

    Returns
    -------
    ((float, float), (float, float))
        (x limits, y limits) [rad/s].
    """
    cl = analysis.closed_loop
    scales = [w for w in (None if cl is None else cl.bandwidth_rad_s,
                          analysis.position_loop.crossover_rad_s) if w is not None]
    scale = max(scales) if scales else float(np.median(np.abs(poles)))
    span = VIEW_SPAN * scale
    right, top = 0.25 * span, 0.6 * span
    for p in poles[poles.real > 0]:
        right, top = max(right, 1.15 * p.real), max(top, 1.15 * abs(p.imag))
    return (-span, right), (-top, top)


def _outside(values, view):
    (x0, x1), (y0, y1) = view
    return int(np.count_nonzero((values.real < x0) | (values.real > x1) | (values.imag < y0)
                                | (values.imag > y1)))


def _real_tolerance(p):
    """|Im p| below which a computed root counts as real [rad/s]."""
    return 1e-9 * max(1.0, abs(p))


def _is_real(p):
    return abs(p.imag) <= _real_tolerance(p)


def _annotated(poles, view):
    """The poles to label with ωn and ζ: the upper member of each complex pair in view and every
    right-half-plane real pole in view."""
    (x0, x1), (y0, y1) = view
    chosen = []
    for p in poles:
        if not (x0 <= p.real <= x1 and y0 <= p.imag <= y1):
            continue
        if p.imag > _real_tolerance(p) or (_is_real(p) and p.real > 0):
            chosen.append(p)
    return chosen


def _pole_words(p):
    wn = abs(p)
    zeta = -p.real / wn
    return f"ωn {wn:.4g} rad/s\nζ {zeta:.2f}"


def _real_roots_in_view(ax, poles, zeros, view):
    """Legend lines with the values of the real poles and zeros in view [rad/s]: near the
    origin they sit on top of each other (a PID zero next to the slow integral pole)."""
    (x0, x1), _ = view
    for name, roots in (("real poles", poles), ("real zeros", zeros)):
        real = sorted((r.real for r in roots if _is_real(r) and x0 <= r.real <= x1),
                      reverse=True)
        if real:
            ax.plot([], [], " ", label=f"{name} in view: "
                    + ", ".join(f"{r:.4g}" for r in real) + " rad/s")


def pole_zero(data):
    """Closed-loop pole-zero map of T (Padé model): poles ×, zeros ○, the stability boundary,
    ωn and ζ of each complex pair in view; the view is the region of the dominant dynamics."""
    a = data.analysis
    order = a.stability.pade_order
    poles = engine_poles(a)
    zeros = closed_loop_zeros(data)
    view = pole_zero_view(a, poles)
    (x0, x1), (y0, y1) = view
    layout = Margins(top=0.6)
    fig, axes = _figure(1, 1, (9.5, 6.2), margins=layout)
    ax = axes[0, 0]
    ax.axvspan(0.0, x1, color="C3", alpha=0.08, lw=0, label="right half-plane (unstable)")
    ax.axvline(0.0, color="k", lw=1.4, label="stability boundary Re s = 0")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.plot(_r(zeros.real), _r(zeros.imag), "o", ms=8, mfc="none", mec="C0", mew=1.3,
            label=f"zeros of T ○ ({len(zeros)}, {_outside(zeros, view)} outside the view)")
    unstable = poles.real > 0
    ax.plot(_r(poles.real[~unstable]), _r(poles.imag[~unstable]), "x", ms=9, mew=1.8,
            color="C1", label=f"poles of T × ({len(poles)}, {_outside(poles, view)} outside "
            "the view)")
    if unstable.any():
        ax.plot(_r(poles.real[unstable]), _r(poles.imag[unstable]), "x", ms=12, mew=2.6,
                color="C3", label=f"right-half-plane poles × ({int(unstable.sum())}): UNSTABLE")
    for k, p in enumerate(_annotated(poles, view)):
        # the label on the side with more room (left of the pole unless it is near the left)
        left = p.real > x0 + 0.4 * (x1 - x0)
        ax.annotate(_pole_words(p), (float(_r(p.real)), float(_r(p.imag))),
                    xytext=(-75 if left else 40, 12 + 26 * (k % 3)), textcoords="offset points",
                    fontsize=8, ha="right" if left else "left",
                    arrowprops={"arrowstyle": "-", "color": "0.4", "lw": 0.7},
                    bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "0.6",
                          "alpha": 0.9})
    _real_roots_in_view(ax, poles, zeros, view)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y0, y1)
    ax.set_aspect("equal", adjustable="box")
    ax.set_xlabel("Re s [rad/s]")
    ax.set_ylabel("Im s [rad/s]")
    legend_room_right(fig, layout, ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0),
                                              fontsize=7.5))
    ax.set_title(f"{a.stability.verdict}; the view holds the dominant dynamics, the Padé delay "
                 "poles and zeros lie further out", fontsize=8.5)
    fig.suptitle(f"{data.label}: closed-loop poles and zeros of T (Padé {order} delays)")
    return fig


def pole_zero_caption(data):
    """Caption of :func:`pole_zero` for one variant: what lies outside the view."""
    a = data.analysis
    poles = engine_poles(a)
    zeros = closed_loop_zeros(data)
    view = pole_zero_view(a, poles)
    (x0, x1), (y0, y1) = view
    model = (f"sampled controllers: the discrete-time poles and zeros mapped by ln z / T, "
             f"T = {1e3 / min(a.sampling['rates_hz'].values()):.4g} ms, those at z = 0 left out"
             if a.sampling else
             f"Padé {a.stability.pade_order} delays, the poles of the stability verdict")
    faster = ("the delay lines and the faster inner-loop dynamics" if a.sampling else
              "the delays' Padé poles and zeros and the faster inner-loop dynamics")
    return (f"Closed-loop pole-zero map of T ({model}): poles ×, zeros ○, the imaginary axis "
            f"as the stability boundary, ωn and ζ beside each complex pair in view; view "
            f"{x0:.4g}..{x1:.4g} × {y0:.4g}..{y1:.4g} rad/s; outside it: "
            f"{_outside(poles, view)} of {len(poles)} poles and {_outside(zeros, view)} of "
            f"{len(zeros)} zeros ({faster})")
