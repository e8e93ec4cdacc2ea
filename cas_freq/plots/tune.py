"""The trade-off of a tune: every candidate's bandwidth against its phase margin (nominal),
feasible ones coloured by the overshoot of the step, the Pareto front joined, the variant's own
values and the tuned ones marked.

It only draws: the data are :func:`cas_freq.tuning.summary.tune_dict`'s plus the candidates'
figures (:func:`trade_off_figure`).
"""

import numpy as np

from cas_freq.plots.common import figure, rounded


def trade_off_figure(result):
    """Bandwidth [rad/s] against phase margin [deg] of every candidate of a TuneResult.

    Returns
    -------
    matplotlib.figure.Figure
    """
    e = result.evaluation
    bandwidth = rounded(e.nominal["closed_loop.bandwidth_rad_s"])
    margin = rounded(e.nominal["position_loop.phase_margin_deg"])
    overshoot = rounded(e.nominal["step.overshoot_pct"])
    fig, axes = figure(1, 1, (7.0, 4.8))
    axis = axes[0, 0]
    shown = np.isfinite(bandwidth) & np.isfinite(margin)
    infeasible = shown & ~e.feasible
    axis.plot(margin[infeasible], bandwidth[infeasible], ".", color="0.7", markersize=3,
              label="infeasible")
    feasible = shown & e.feasible
    if feasible.any():
        points = axis.scatter(margin[feasible], bandwidth[feasible], c=overshoot[feasible], s=10,
                              cmap="viridis", label="feasible (colour: overshoot)")
        fig.colorbar(points, ax=axis, label="overshoot of the step [%]")
    front = result.pareto
    if front.size:
        order = np.argsort(margin[front])
        axis.plot(margin[front][order], bandwidth[front][order], "-", color="C3", linewidth=1.0,
                  label="Pareto front")
    before = result.before.nominal
    axis.plot(rounded(before["position_loop.phase_margin_deg"]),
              rounded(before["closed_loop.bandwidth_rad_s"]), "s", color="k", markersize=6,
              fillstyle="none", label="before")
    axis.plot(margin[result.best], bandwidth[result.best], "*", color="C3", markersize=11,
              label="tuned")
    axis.set_xlabel("position-loop phase margin [deg]")
    axis.set_ylabel("closed-loop bandwidth [rad/s]")
    axis.set_title(f"Tune ({result.objective}): every candidate, nominal")
    axis.legend(loc="best")
    return fig


__all__ = ["trade_off_figure"]
