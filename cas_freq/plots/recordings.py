"""Figure of step recordings against their fitted second-order-plus-delay models: data and
model [deg] over time [ms] above, the residuals (data less model) [deg] below.

It only draws: the fits and the model at each sample come from
:func:`cas_freq.identification.fit_recordings`.
"""

import numpy as np

from cas_freq.plots.common import figure, rounded


def recording_fit_figure(fits):
    """Data vs fitted model and the residuals of every recording.

    Parameters
    ----------
    fits : RecordingFits
        From :func:`cas_freq.identification.fit_recordings`.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes (shared time axis [ms]): position and model [deg], residual [deg].
    """
    fig, axes = figure(2, 1, (7.0, 5.5), sharex=True, height_ratios=[2, 1])
    top, bottom = axes[0, 0], axes[1, 0]
    for number, run in enumerate(fits.runs):
        r, f = run.recording, run.fit
        colour = f"C{number % 10}"
        t_ms = rounded(r.time_s * 1e3)
        name = r.source.rsplit("/", 1)[-1]
        top.plot(t_ms, rounded(np.degrees(r.position_rad)), ".", color=colour, markersize=2,
                 alpha=0.5, label=f"{name} (data)")
        top.plot(t_ms, rounded(np.degrees(run.model_rad)), "-", color=colour, linewidth=1.0,
                 label=f"fit: wn {f.wn_rad_s:.4g} rad/s, zeta {f.zeta:.3g}, "
                       f"td {f.td_s * 1e3:.3g} ms")
        if r.command_rad is not None:
            top.plot(t_ms, rounded(np.degrees(r.command_rad)), ":", color=colour,
                     linewidth=0.8)
        bottom.plot(t_ms, rounded(np.degrees(run.residual_rad)), ".", color=colour,
                    markersize=2, alpha=0.6)
    bottom.axhline(0.0, color="k", linewidth=0.6)
    top.set_ylabel("fin angle [deg]")
    top.set_title("step recordings and second-order-plus-delay fits (dotted: command)")
    top.legend(loc="lower right")
    bottom.set_ylabel("data - fit [deg]")
    bottom.set_xlabel("time from the trigger [ms]")
    return fig
