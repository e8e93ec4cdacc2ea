"""Figure of a profile move: command and output angle, and the tracking error, with and without
feed-forward (the API's ``ProfileResponse.plot()`` and the report's profile section)."""

import numpy as np
from matplotlib.figure import Figure

from cas_freq.config.wording import OutputWords

#: (which run, legend label, line style) of the two runs drawn.
_RUNS = (
    ("result", "with feed-forward", "-"),
    ("result_without_feedforward", "without feed-forward", "--"),
)


def profile_figure(run, figure_class=Figure):
    """Output angle against its profile command, and the tracking error, against time.

    Parameters
    ----------
    run : cas_freq.studies.profile_run.ProfileRun
        The move, simulated with and without feed-forward.
    figure_class : type
        The :class:`matplotlib.figure.Figure` (sub)class to build.

    Returns
    -------
    matplotlib.figure.Figure
        Two axes sharing the time axis [ms]: command and output angle [deg]; tracking error
        delta_cmd - delta [deg]. The move's span is shaded.
    """
    move_end = run.move.start_s + run.move.move_time_s
    # up to the later of the two runs' 2 % arrivals, with room after it (not the whole horizon)
    arrivals = [f.arrival_time_s for f in (run.profile, run.without_feedforward)]
    view_end = run.move.start_s + 1.5 * max([run.move.move_time_s, *(
        a for a in arrivals if np.isfinite(a))])
    fig = figure_class(figsize=(8, 6), layout="constrained")
    angle, error = fig.subplots(2, 1, sharex=True)
    first, unit = run.result, run.output_unit  # deg, or mm at a linear output
    x = OutputWords(run.output, unit.linear).symbol  # δ, or x at a linear output
    keep = first.t <= view_end
    angle.plot(1e3 * first.t[keep], unit.from_si(first.command[keep]), color="k", ls=":", lw=0.9,
               label=f"command {x}_cmd")
    for name, label, style in _RUNS:
        result = getattr(run, name)
        keep = result.t <= view_end
        t_ms = 1e3 * result.t[keep]
        angle.plot(t_ms, unit.from_si(result.delta[keep]), ls=style, label=f"{x}, {label}")
        error.plot(t_ms, unit.from_si(result.command[keep] - result.delta[keep]), ls=style,
                   label=label)
    for ax in (angle, error):
        ax.axvspan(1e3 * run.move.start_s, 1e3 * move_end, color="0.9", zorder=0)
        ax.grid(True, alpha=0.35)
    angle.set_ylabel(f"{run.output} {unit.quantity} [{unit.shown}]")
    angle.set_title(f"profile move of {unit.symbol(run.profile.distance_deg)} (nonlinear, "
                    "limits and "
                    "delays; the move shaded)")
    angle.legend()
    error.axhline(0.0, color="k", lw=0.6)
    error.set_ylabel(f"tracking error {x}_cmd − {x} [{unit.shown}]")
    error.set_xlabel("time [ms]")
    error.legend()
    return fig
