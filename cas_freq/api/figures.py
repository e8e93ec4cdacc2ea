"""Figures of the Python API's ``plot()`` methods (:mod:`cas_freq.api`).

Each function returns a new :class:`~cas_freq.plots.common.NotebookFigure` (a
:class:`matplotlib.figure.Figure`) built with the object-oriented API: no pyplot state, no
backend switch, no change to the global rcParams. In a notebook the returned figure displays
itself as a cell's value (no ``%matplotlib`` needed); elsewhere call ``fig.savefig(...)``.
"""

import types

import numpy as np

from cas_freq.analysis.frequency import continuous_phase
from cas_freq.config.wording import OutputWords
from cas_freq.plots import profile
from cas_freq.plots.common import NotebookFigure as Figure
from cas_freq.plots.report import bode_loops
from cas_freq.report.data import ReportSettings, curves, loop_frequency_range, variant_label

#: The loops of the Bode figure (attributes of FrequencyResponse; each loop's legend is its
#: structure's title, T's names the output).
BODE_LOOPS = ("current_loop", "position_loop", "closed_loop")


def bode_figure(response):
    """Bode plot of L_i, L_p and T.

    Parameters
    ----------
    response : cas_freq.api.FrequencyResponse
        The responses and their grid [rad/s].

    Returns
    -------
    matplotlib.figure.Figure
        Two axes sharing the frequency axis: magnitude [dB] and phase [deg], one line per loop.
    """
    w = response.omega_rad_s
    fig = Figure(figsize=(8, 6), layout="constrained")
    magnitude, phase = fig.subplots(2, 1, sharex=True)
    titles = {loop.name: loop.title for loop in response.described}
    x = response.output_symbol
    for name in BODE_LOOPS:
        label = titles.get(name, f"T = {x}/{x}_cmd (closed loop)")
        values = getattr(response, name)
        magnitude.semilogx(w, 20.0 * np.log10(np.abs(values)), label=label)
        phase.semilogx(w, np.degrees(continuous_phase(values, w)), label=label)
    magnitude.set_ylabel("magnitude [dB]")
    magnitude.set_title(f"Bode ({response.delay_model} delays)")
    magnitude.legend()
    phase.set_ylabel("phase [deg]")
    phase.set_xlabel("frequency ω [rad/s]")
    for ax in (magnitude, phase):
        ax.grid(True, which="both", alpha=0.35)
    return fig


def step_figure(response):
    """Output angle with its command, and motor current, against time.

    Parameters
    ----------
    response : cas_freq.api.StepResponse
        The simulated step.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes sharing the time axis [ms]: output angle and command [deg] (labelled with the
        config's ``output_name``); current [A].
    """
    t_ms = 1e3 * response.time_s
    fig = Figure(figsize=(8, 6), layout="constrained")
    angle, current = fig.subplots(2, 1, sharex=True)
    unit = response.run.output_unit  # deg, or mm at a linear output
    command, output = ((response.command_mm, response.output_mm) if unit.linear else
                       (response.command_deg, response.output_angle_deg))
    name = response.run.output
    symbol = OutputWords(name, unit.linear).symbol  # δ, or x at a linear output
    angle.plot(t_ms, command, color="k", ls=":", lw=0.9, label=f"command {symbol}_cmd")
    angle.plot(t_ms, output, label=f"{name} {unit.quantity} {symbol}")
    angle.set_ylabel(f"{name} {unit.quantity} [{unit.shown}]")
    angle.set_title(f"{unit.symbol(response.step.amplitude_deg)} step (nonlinear, limits and "
                    "delays)")
    angle.legend()
    current.plot(t_ms, response.current_a, label="motor current i")
    current.set_ylabel("current [A]")
    current.set_xlabel("time [ms]")
    for ax in (angle, current):
        ax.grid(True, alpha=0.35)
    return fig


def analysis_figure(analysis):
    """Bode of L_i, L_p and T of an analysed variant, margins marked (the report's open-loop
    figure, :func:`cas_freq.plots.report.bode_loops`, with T added).

    Parameters
    ----------
    analysis : cas_freq.analysis.Analysis
        With its ``loaded`` variant, whose loops are evaluated (exact delays) on the report's
        plotting range around the analysis' crossovers [rad/s].

    Returns
    -------
    matplotlib.figure.Figure
    """
    loaded = analysis.loaded
    data = types.SimpleNamespace(
        label=variant_label(loaded), analysis=analysis, loaded=loaded,
        curves=curves(loaded.params, loop_frequency_range(analysis),
                      ReportSettings().curve_points_per_decade))
    return bode_loops(data, with_closed_loop=True, figure_class=Figure)


def profile_figure(run):
    """:func:`cas_freq.plots.profile.profile_figure` as a figure that displays itself."""
    return profile.profile_figure(run, figure_class=Figure)
