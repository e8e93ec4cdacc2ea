"""Figure of step recordings against their fitted second-order-plus-delay models: data and
model [deg] over time [ms] above, the residuals (data less model) [deg] below.

It only draws: the fits and the model at each sample come from
:func:`cas_freq.identification.fit_recordings`.
"""

import numpy as np

from cas_freq.plots.common import figure, rounded


def recording_fit_figure(fits, output="output"):
    """Data vs fitted model and the residuals of every recording.

    Parameters
    ----------
    fits : RecordingFits
        From :func:`cas_freq.identification.fit_recordings`.
    output : str
        What the labels call the output (the config's ``output_label``).

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
    top.set_ylabel(f"{output} angle [deg]")
    top.set_title("step recordings and second-order-plus-delay fits (dotted: command)")
    top.legend(loc="lower right")
    bottom.set_ylabel("data - fit [deg]")
    bottom.set_xlabel("time from the trigger [ms]")
    return fig


def physical_fit_figure(recordings, fits, best, output="output"):
    """The report's Fig. 10 for a physical fit: data, starting model and fitted model(s).

    Parameters
    ----------
    recordings : sequence of Recording
    fits : sequence of PhysicalFit
        The models fitted (:func:`cas_freq.identification.physical.fit_physical`), all from the
        same start.
    best : str
        Name of the best model: drawn solid; the others dotted.
    output : str
        What the labels call the output (the config's ``output_label``).

    Returns
    -------
    matplotlib.figure.Figure
        Output angle [deg] over time [ms] (data as dots, start dashed, fits), the current [A]
        likewise where it was fitted, and the residuals (data less the best fit) below.
    """
    first = fits[0]
    current = "current" in first.channels
    rows = 3 if current else 2
    fig, axes = figure(rows, 1, (7.0, 3.0 + 2.2 * (rows - 1)), sharex=True,
                       height_ratios=[2, 2, 1][-rows:] if current else [2, 1])
    position, residual = axes[0, 0], axes[rows - 1, 0]
    panels = [("position", position, np.degrees, f"{output} angle [deg]")]
    if current:
        panels.append(("current", axes[1, 0], lambda values: values, "motor current [A]"))
    ordered = sorted(fits, key=lambda fit: fit.name != best)
    for number, r in enumerate(recordings):
        colour = f"C{number % 10}"
        fitted_samples = first.masks[number]
        t_ms = rounded(r.time_s[fitted_samples] * 1e3)
        name = r.source.rsplit("/", 1)[-1]
        for channel, axis, scale, _ in panels:
            data = r.position_rad if channel == "position" else r.current_a
            axis.plot(t_ms, rounded(scale(data[fitted_samples])), ".", color=colour, markersize=2,
                      alpha=0.45, label=f"{name} (data)" if channel == "position" else None)
            model = (first.start_response.position if channel == "position"
                     else first.start_response.current)[number][0]
            axis.plot(t_ms, rounded(scale(model)), "--", color="0.45", linewidth=0.8,
                      label="start" if number == 0 and channel == "position" else None)
            for fit in ordered:
                signal = (fit.fitted_response.position if channel == "position"
                          else fit.fitted_response.current)[number][0]
                solid = fit.name == best
                axis.plot(t_ms, rounded(scale(signal)), "-" if solid else ":", color=colour,
                          linewidth=1.1 if solid else 0.9,
                          label=(f"fit {fit.name!r}" if number == 0 and channel == "position"
                                 else None))
        fitted = next(fit for fit in fits if fit.name == best)
        residual.plot(t_ms, rounded(np.degrees(r.position_rad[fitted_samples]
                                               - fitted.fitted_response.position[number][0])),
                      "-", color=colour, linewidth=0.7)
    for _, axis, _, label in panels:
        axis.set_ylabel(label)
    position.set_title("Recordings, starting model and fitted model")
    position.legend(loc="lower right")
    residual.set_ylabel(f"data − fit {best!r} [deg]")
    residual.set_xlabel("time from the trigger [ms]")
    return fig


def candidates_figure(recordings, fits, best, output="output"):
    """Candidate structures fitted to the same recordings (``fit --candidates``): each
    candidate's fitted step overlaid on the data, and each one's residual below.

    Parameters
    ----------
    recordings : sequence of Recording
    fits : sequence of PhysicalFit
        One per candidate, in the ranking's order (each from its own structure and start).
    best : str
        Name of the best plausible candidate (or the best one): drawn thickest.
    output : str
        What the labels call the output.

    Returns
    -------
    matplotlib.figure.Figure
        Output angle [deg] over time [ms] and the residuals (data less each fit) [deg].
    """
    fig, axes = figure(2, 1, (7.0, 5.2), sharex=True, height_ratios=[2, 1])
    position, residual = axes[0, 0], axes[1, 0]
    for number, r in enumerate(recordings):
        samples = fits[0].masks[number]
        t_ms = rounded(r.time_s[samples] * 1e3)
        name = r.source.rsplit("/", 1)[-1]
        position.plot(t_ms, rounded(np.degrees(r.position_rad[samples])), ".", color="0.35",
                      markersize=2, alpha=0.5, label=f"{name} (data)")
        for rank, fit in enumerate(fits):
            colour = f"C{rank % 10}"
            model = fit.fitted_response.position[number][0]
            solid = fit.name == best
            label = f"{rank + 1}. {fit.name}" if number == 0 else None
            position.plot(t_ms, rounded(np.degrees(model)), "-" if solid else "--",
                          color=colour, linewidth=1.6 if solid else 0.9, label=label)
            residual.plot(t_ms, rounded(np.degrees(r.position_rad[samples] - model)), "-",
                          color=colour, linewidth=1.1 if solid else 0.6)
    position.set_ylabel(f"{output} angle [deg]")
    position.set_title("Candidates fitted to the recording (ranked by AICc)")
    position.legend(loc="lower right", fontsize="small")
    residual.set_ylabel("data − fit [deg]")
    residual.set_xlabel("time from the trigger [ms]")
    return fig
