"""The load envelope figure: figures of merit against hinge stiffness (matplotlib).

Three panels sharing the load-spring axis (K_h at the output, N*m/rad): the linear bandwidth, the
position loop's phase and gain margins, and the nonlinear step's overshoot (when simulated).
Requirement bounds are drawn as lines, the stiffness where each required requirement is lost
as a vertical line, and the hinge stiffness where the closed loop is not stable is shaded.
Plotted data are rounded as every report figure (:func:`cas_freq.plots.common.rounded`).
"""

import numpy as np

from cas_freq.core.figures import FIGURES, loop_label
from cas_freq.plots.common import Margins, figure, legend_room_right, rounded

#: (figure key, legend label, panel) of the plotted series: the figure table's labels and
#: units, after the loop or the run they are of.
_SERIES = tuple((key, f"{prefix}: {FIGURES[key].heading}", panel) for key, prefix, panel in (
    ("closed_loop.bandwidth_rad_s", "linear T", 0),
    ("position_loop.phase_margin_deg", loop_label("position_loop"), 1),
    ("position_loop.gain_margin_db", loop_label("position_loop"), 1),
    ("step.overshoot_pct", "nonlinear step", 2),
))
_PANEL_LABELS = (f"ω_BW [{FIGURES['closed_loop.bandwidth_rad_s'].shown_unit}]",
                 "margin [deg], [dB]", FIGURES["step.overshoot_pct"].heading)


def envelope_figure(envelope, config_name):
    """The figure of one :class:`cas_freq.studies.envelope.LoadEnvelope`."""
    panels = 3 if "step.overshoot_pct" in envelope.figures else 2
    margins = Margins(left=0.8, right=2.6, bottom=0.6, top=0.45, hgap=0.15)
    fig, axes = figure(panels, 1, (8.0, 1.9 * panels + 1.0), sharex=True, margins=margins)
    axes = axes[:, 0]
    k = rounded(envelope.hinge_stiffness)
    unstable = envelope.stability.astype(str) != "stable"
    for ax in axes:
        _shade(ax, k, unstable)
        ax.axvline(envelope.nominal_n_m_rad, color="0.4", lw=1, ls=":")
        ax.grid(True, alpha=0.3)
    trusted = {key: _trusted(envelope, key) for key, _, _ in _SERIES}
    for key, label, panel in _SERIES:
        if panel < panels and key in envelope.figures:
            axes[panel].plot(k, rounded(trusted[key]), "o-", ms=3, label=label)
    by_metric = {}
    for requirement in envelope.requirements:
        by_metric.setdefault(requirement.metric, []).append(requirement)
    for key, _, panel in _SERIES:
        if panel >= panels:
            continue
        for requirement in by_metric.get(key, ()):
            _bounds(axes[panel], requirement)
    if panels == 3:  # after the bound lines, which set the panel's top
        _unsettled(axes[2], k, envelope, trusted["step.overshoot_pct"])
    for ax, label in zip(axes, _PANEL_LABELS, strict=False):
        ax.set_ylabel(label)
    axes[-1].set_xlabel(f"{FIGURES['drivetrain.hinge_stiffness_n_m_rad'].heading} "
                        "(load.hinge_stiffness; > 0 opposes, < 0 aids)")
    fig.suptitle(f"Load envelope — {config_name} / {envelope.variant} (dotted: the variant's "
                 "own K_h; shaded: closed loop not stable)", fontsize=9)
    for ax in axes:
        handles, labels = ax.get_legend_handles_labels()
        if handles:
            legend = ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                               fontsize=7, frameon=False)
            legend_room_right(fig, margins, legend)
    return fig


def _trusted(envelope, key):
    """The figure per grid point, NaN where it is not trusted: closed-loop and step figures of
    a loop that is not stable, and the overshoot of a step that did not settle."""
    from cas_freq.studies.envelope import shown_figure

    values = shown_figure(envelope, key)
    if key == "step.overshoot_pct" and "step.settling_time_s" in envelope.figures:
        values = np.where(np.isfinite(envelope.figures["step.settling_time_s"]), values, np.nan)
    return values


def _unsettled(ax, k, envelope, overshoot):
    """Mark the stable points whose step did not settle (diverged under the limits, or still
    moving at the end of the simulation) at the top of the overshoot panel."""
    stable = envelope.stability.astype(str) == "stable"
    missing = stable & ~np.isfinite(overshoot)
    if missing.any():
        top = ax.get_ylim()[1]
        ax.plot(k[missing], np.full(missing.sum(), top), "x", color="C3", clip_on=False,
                label="step did not settle")


def _shade(ax, k, unstable):
    """Shade the runs of grid points where the loop is not stable (half a step either side)."""
    if not unstable.any():
        return
    edges = np.concatenate([[k[0]], 0.5 * (k[1:] + k[:-1]), [k[-1]]])
    start = None
    for j, flag in enumerate(np.append(unstable, False)):
        if flag and start is None:
            start = j
        elif not flag and start is not None:
            ax.axvspan(edges[start], edges[j], color="C3", alpha=0.12, lw=0)
            start = None


def _bounds(ax, requirement):
    """The requirement's bound(s) and where it is lost."""
    for bound in (requirement.min, requirement.max):
        if bound is not None:
            ax.axhline(bound, color="C3", ls="-.", lw=1,
                       label=f"{requirement.id} bound {bound:g}")
    for loss in (requirement.lost_below, requirement.lost_above):
        if loss is not None:
            ax.axvline(loss.at, color="C3", lw=1,
                       label=f"{requirement.id} lost at K_h = {loss.at:.3g}")
