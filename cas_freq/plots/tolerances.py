"""The worst corner beside the nominal (the report's tolerance section): the closed loop's
magnitude and the nonlinear step of both."""

import numpy as np

from cas_freq.plots.common import figure, plain_log_labels, rounded


def worst_corner_figure(omega, nominal_t, worst_t, step_t, nominal_step, worst_step, label,
                        output="output"):
    """|T| [dB] over frequency and the output's step [deg] over time, nominal and worst.

    Parameters
    ----------
    omega : numpy.ndarray
        Frequencies [rad/s].
    nominal_t, worst_t : numpy.ndarray
        T(jω) of the nominal point and of the worst one.
    step_t : numpy.ndarray
        Times of the steps [s].
    nominal_step, worst_step : numpy.ndarray
        The output angle of each step [rad].
    label : str
        What the worst point is (its requirement and its keys' offsets), for the legend.
    output : str
        What the labels call the output.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, axes = figure(1, 2, (9.0, 3.4))
    bode, step = axes[0, 0], axes[0, 1]
    for values, style, name in ((nominal_t, "-", "nominal"), (worst_t, "--", label)):
        bode.semilogx(rounded(omega), rounded(20.0 * np.log10(np.abs(values))), style,
                      label=name)
    bode.axhline(-3.0103, color="0.6", linewidth=0.7)
    bode.set_xlabel("frequency [rad/s]")
    bode.set_ylabel("|T| [dB]")
    bode.set_ylim(-30.0, 10.0)
    plain_log_labels(bode.xaxis)
    bode.legend(loc="lower left", fontsize="small")
    for values, style in ((nominal_step, "-"), (worst_step, "--")):
        step.plot(rounded(1e3 * step_t), rounded(np.degrees(values)), style)
    step.set_xlabel("time [ms]")
    step.set_ylabel(f"{output} angle [deg]")
    return fig
