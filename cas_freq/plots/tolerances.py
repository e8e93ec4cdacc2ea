"""The worst corner beside the nominal (the report's tolerance section): the closed loop's
Bode (magnitude and phase) and the nonlinear step of both."""

import numpy as np

from cas_freq.core.output import ANGLE
from cas_freq.plots.common import figure, plain_log_labels, rounded


def worst_corner_figure(omega, nominal_t, worst_t, step_t, nominal_step, worst_step, label,
                        output="output", unit=ANGLE):
    """|T| [dB] and ∠T [deg] over frequency and the output's step over time, nominal and
    worst.

    Parameters
    ----------
    omega : numpy.ndarray
        Frequencies [rad/s].
    nominal_t, worst_t : numpy.ndarray
        T(jω) of the nominal point and of the worst one.
    step_t : numpy.ndarray
        Times of the steps [s].
    nominal_step, worst_step : numpy.ndarray
        The output of each step [rad, or m at a linear output].
    label : str
        What the worst point is (its requirement and its keys' values), for the legend.
    output : str
        What the labels call the output.
    unit : cas_freq.core.output.OutputUnit
        The output's kind: the step is shown in its unit (deg, or mm).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, axes = figure(1, 3, (12.0, 3.4))
    magnitude, phase, step = axes[0]
    for values, style, name in ((nominal_t, "-", "nominal"), (worst_t, "--", label)):
        magnitude.semilogx(rounded(omega), rounded(20.0 * np.log10(np.abs(values))), style,
                           label=name)
        phase.semilogx(rounded(omega), rounded(np.degrees(np.unwrap(np.angle(values)))),
                       style)
    magnitude.axhline(-3.0103, color="0.6", linewidth=0.7)
    magnitude.set_ylabel("|T| [dB]")
    magnitude.set_ylim(-30.0, 10.0)
    fig.legend(loc="outside lower center", ncols=2, fontsize="small")
    phase.set_ylabel("∠T [deg]")
    for ax in (magnitude, phase):
        ax.set_xlabel("frequency [rad/s]")
        plain_log_labels(ax.xaxis)
    for values, style in ((nominal_step, "-"), (worst_step, "--")):
        step.plot(rounded(1e3 * step_t), rounded(unit.from_si(values)), style)
    step.set_xlabel("time [ms]")
    step.set_ylabel(f"{output} {unit.quantity} [{unit.shown}]")
    return fig
