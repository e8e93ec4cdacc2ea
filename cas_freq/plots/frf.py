"""Figure of sweep recordings' empirical frequency responses against the model: magnitude [dB],
phase [deg] and coherence over frequency [rad/s] (log).

It only draws, from the dict :func:`cas_freq.cli.fit_sweep.results` makes (values already
rounded to 6 significant digits, so the SVG regenerates byte-identically). Data points are
drawn filled where the coherence is >= the threshold and hollow, pale, below it; the model is a
line: T for the output angle per output command, and T_i where the current per current command was
measured (the current per output command is left to frf.json: its unit differs).
"""

import numpy as np

from cas_freq.plots.common import figure, plain_log_labels, rounded

#: Responses drawn: key, marker, label of the model line.
DRAWN = (("position", "o", "model T"), ("current_loop", "s", "model T_i"))


def frf_figure(data):
    """Magnitude, phase and coherence of every recording's responses, with the model's.

    Parameters
    ----------
    data : dict
        From :func:`cas_freq.cli.fit_sweep.results`.

    Returns
    -------
    matplotlib.figure.Figure
        Three axes sharing a log frequency axis [rad/s].
    """
    fig, axes = figure(3, 1, (7.0, 7.5), sharex=True, height_ratios=[2, 2, 1])
    magnitude, phase, coherence = axes[0, 0], axes[1, 0], axes[2, 0]
    threshold = data["coherence_threshold"]
    for number, rec in enumerate(data["recordings"]):
        name = rec["source"].rsplit("/", 1)[-1]
        for k, (key, marker, model_label) in enumerate(DRAWN):
            response = rec["responses"].get(key)
            if response is None:
                continue
            colour = f"C{(2 * number + k) % 10}"
            w = rounded(np.asarray(response["omega_rad_s"]))
            good = np.asarray(response["coherence"]) >= threshold
            for values, axis, model_key in ((response["magnitude_db"], magnitude,
                                             "model_magnitude_db"),
                                            (response["phase_deg"], phase, "model_phase_deg")):
                values = rounded(np.asarray(values))
                axis.plot(w[good], values[good], marker, color=colour, markersize=3,
                          label=(f"{name}: {response['label']}" if axis is magnitude
                                 else None))
                axis.plot(w[~good], values[~good], marker, color=colour, markersize=3,
                          markerfacecolor="none", alpha=0.4)
                axis.plot(w, rounded(np.asarray(response[model_key])), "-", color=colour,
                          linewidth=1.0, label=model_label if axis is magnitude else None)
            coherence.plot(w, rounded(np.asarray(response["coherence"])), marker + "-",
                           color=colour, markersize=2.5, linewidth=0.7)
    magnitude.axhline(-3.0103, color="0.5", linewidth=0.7, linestyle=":")
    coherence.axhline(threshold, color="0.5", linewidth=0.7, linestyle=":")
    magnitude.set_ylabel("magnitude [dB]")
    model = data["model"]
    magnitude.set_title(f"empirical frequency responses (H1) vs model {model['variant']} "
                        f"(exact delays)\nhollow: coherence below {threshold:g}")
    magnitude.legend(loc="lower left")
    phase.set_ylabel("phase [deg]")
    coherence.set_ylabel("coherence [-]")
    coherence.set_ylim(0.0, 1.05)
    coherence.set_xlabel("frequency [rad/s]")
    coherence.set_xscale("log")
    plain_log_labels(coherence.xaxis)
    return fig
