"""Report plots of sweeps and Monte Carlo runs (the only module of the package that draws).

matplotlib is imported inside the functions, with the Agg backend; SVG output is made
deterministic (fixed hash salt, no date).
"""

import math

import numpy as np

#: Figures drawn against the swept keys, when present.
SWEEP_PLOT_FIGURES = (
    "position_loop.phase_margin_deg", "position_loop.gain_margin_db",
    "closed_loop.bandwidth_rad_s", "closed_loop.peak_db",
    "position_loop.sensitivity_peak_db", "current_loop.phase_margin_deg",
    "step.overshoot_pct", "step.rise_time_s", "fit.bandwidth_closed_form_rad_s",
)
#: Most lines drawn for the combinations of the other swept keys.
MAX_LINES = 12


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["svg.hashsalt"] = "cas_freq"
    import matplotlib.pyplot as plt

    return plt


def svg_text(figure):
    """The figure as deterministic SVG text (and the figure closed): no date, and the
    coordinates and ids made independent of float noise as the report's
    (:func:`cas_freq.plots.report.tidy_svg`)."""
    import io

    from cas_freq.plots.report import tidy_svg

    plt = _pyplot()
    out = io.StringIO()
    figure.savefig(out, format="svg", metadata={"Date": None})
    plt.close(figure)
    return tidy_svg(out.getvalue())


def _grid_of_axes(count):
    plt = _pyplot()
    columns = min(3, count)
    rows = math.ceil(count / columns)
    figure, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.0 * rows),
                                squeeze=False, layout="constrained")
    for extra in axes.ravel()[count:]:
        extra.set_visible(False)
    return figure, axes.ravel()[:count]


def sweep_figure(points, figures, keys):
    """Figures against the first swept key, one line per combination of the others.

    Parameters
    ----------
    points : dict of str to numpy.ndarray
        Swept key -> value per grid point (first key slowest).
    figures : dict of str to numpy.ndarray
        Figure -> value per grid point.
    keys : list of str
        Swept keys, in order.

    Returns
    -------
    matplotlib.figure.Figure
    """
    names = [name for name in SWEEP_PLOT_FIGURES if name in figures]
    figure, axes = _grid_of_axes(len(names))
    x_key, others = keys[0], keys[1:]
    x = points[x_key]
    combos = {}
    for index in range(x.size):
        label = tuple(float(points[k][index]) for k in others)
        combos.setdefault(label, []).append(index)
    labels = list(combos)[:MAX_LINES]
    for axis, name in zip(axes, names, strict=True):
        for label in labels:
            rows = np.array(combos[label])
            order = np.argsort(x[rows])
            text = ", ".join(f"{k}={v:.4g}" for k, v in zip(others, label, strict=True))
            axis.plot(x[rows][order], figures[name][rows][order], marker=".",
                      label=text or None)
        axis.set_xlabel(x_key)
        axis.set_ylabel(name)
        axis.grid(True, alpha=0.3)
    if others and names:
        axes[0].legend(fontsize="x-small")
    figure.suptitle(f"sweep of {', '.join(keys)}")
    return figure


def histogram_figure(figures, names, limits):
    """Histograms of figures, with requirement bounds as vertical lines.

    Parameters
    ----------
    figures : dict of str to numpy.ndarray
        Figure -> value per sample.
    names : list of str
        Figures to draw.
    limits : dict of str to list of (float, str)
        Figure -> (bound, label) lines to draw.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, axes = _grid_of_axes(len(names))
    for axis, name in zip(axes, names, strict=True):
        values = figures[name]
        finite = values[np.isfinite(values)]
        if finite.size:
            axis.hist(finite, bins=min(50, max(5, int(math.sqrt(finite.size)))))
        for bound, label in limits.get(name, []):
            axis.axvline(bound, color="red", linestyle="--", label=label)
        if limits.get(name):
            axis.legend(fontsize="x-small")
        axis.set_xlabel(name)
        axis.set_ylabel("samples")
    figure.suptitle("Monte Carlo distributions")
    return figure
