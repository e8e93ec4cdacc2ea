"""What every report figure shares: the fixed style, the figure factory with its fixed layout
(:class:`Margins`), the rounding of plotted data, plain-text log-axis labels and the
deterministic SVG/PNG writers (only :mod:`cas_freq.plots` imports matplotlib).

The SVG files must not depend on the last bits of floating point (which differ between CPUs),
so the plotted data are rounded to 6 significant digits (:func:`rounded`, i.e.
:func:`cas_freq.core.numbers.round_array`) before they are drawn, and :func:`svg_text` rounds
every coordinate in the SVG to 0.01 pt and renames matplotlib's content-hash ids (see
:func:`tidy_svg`).
"""

import dataclasses
import hashlib
import io
import re

import numpy as np

# No matplotlib.use(): the figures are built without pyplot and drawn by savefig's canvas for
# the format, so no backend is needed, and a notebook's backend (inline) is left as it is.
from matplotlib import rc_context
from matplotlib.figure import Figure
from matplotlib.ticker import Locator, LogFormatterSciNotation

from cas_freq.config.wording import OutputWords
from cas_freq.core.numbers import round_array

#: Style of every figure (and of the SVG writer): fixed, so output does not depend on a user's
#: matplotlibrc.
STYLE = {
    "svg.hashsalt": "cas_freq-report",
    "svg.fonttype": "none",
    "font.size": 9,
    "axes.titlesize": 10,
    "figure.titlesize": 11,
    "axes.grid": True,
    "grid.alpha": 0.35,
    "grid.linewidth": 0.6,
    "legend.fontsize": 8,
    "legend.framealpha": 0.85,
    "lines.linewidth": 1.4,
    "savefig.dpi": 100,
    "path.simplify": False,
}

#: How every report figure names the exact-delay model in its title.
EXACT = "exact delays"


@dataclasses.dataclass(frozen=True)
class Margins:
    """A fixed layout: room around and between the axes of a figure [in].

    The report's figures are laid out with these instead of matplotlib's constrained layout,
    whose passes over every tick label's extent cost about as much as drawing the figure; the
    room for tick labels and axis labels is a constant (their font is fixed, :data:`STYLE`), the
    room for a legend beside or below the axes is measured (:func:`legend_room_right`,
    :func:`legend_room_below`).

    Attributes
    ----------
    left, right, bottom, top : float
        Figure edge to the axes grid [in]: y tick and axis labels on the left, x tick and axis
        labels below, the suptitle (and axes titles) above.
    hgap, wgap : float
        Between rows and between columns of axes [in].
    """

    left: float = 0.75
    right: float = 0.2
    bottom: float = 0.55
    top: float = 0.4
    hgap: float = 0.3
    wgap: float = 0.8


def figure(rows, cols, size, sharex=False, margins=None, figure_class=Figure, **kwargs):
    """A figure in :data:`STYLE` with a (rows, cols) array of axes: laid out with ``margins``
    (:class:`Margins`, fixed) or, without, by matplotlib's constrained layout; an instance of
    ``figure_class`` (a :class:`matplotlib.figure.Figure` subclass, e.g.
    :class:`NotebookFigure`)."""
    with rc_context(STYLE):
        fig = figure_class(figsize=size, layout=None if margins is not None else "constrained")
        axes = fig.subplots(rows, cols, sharex=sharex, squeeze=False, **kwargs)
    if margins is not None:
        place(fig, margins)
    return fig, axes


class NotebookFigure(Figure):
    """A :class:`matplotlib.figure.Figure` that displays itself in a notebook.

    The API's ``plot()`` figures are built without pyplot (no global figure registry, no backend
    switch), so IPython's matplotlib integration, which shows pyplot's figures and is set up only
    by ``%matplotlib inline`` or by importing pyplot, does not know them. As a cell's last value
    this one gives IPython a PNG itself (``_repr_png_``); everything else is matplotlib's Figure
    (``savefig``, ``axes``).
    """

    def _repr_png_(self):
        return png_bytes(self)


def place(fig, margins):
    """Put the axes grid of ``fig`` at the fixed ``margins`` [in] (:class:`Margins`); returns
    them."""
    width, height = fig.get_size_inches()
    grid = fig.axes[0].get_subplotspec().get_gridspec()
    rows, cols = grid.get_geometry()
    inner_w = width - margins.left - margins.right
    inner_h = height - margins.bottom - margins.top
    axes_w = (inner_w - (cols - 1) * margins.wgap) / cols
    axes_h = (inner_h - (rows - 1) * margins.hgap) / rows
    fig.subplots_adjust(left=margins.left / width, right=1.0 - margins.right / width,
                        bottom=margins.bottom / height, top=1.0 - margins.top / height,
                        wspace=margins.wgap / axes_w, hspace=margins.hgap / axes_h)
    return margins


def _extent_in(fig, artist):
    """Width and height of ``artist`` as drawn [in], measured with a throw-away Agg renderer
    (text only: no tick of any axes is laid out)."""
    from matplotlib.backends.backend_agg import RendererAgg

    width, height = fig.get_size_inches()
    renderer = RendererAgg(width * fig.dpi, height * fig.dpi, fig.dpi)
    with rc_context(STYLE):
        box = artist.get_window_extent(renderer)
    return box.width / fig.dpi, box.height / fig.dpi


#: Room added to a measured legend [in] (text measured with Agg, drawn by the SVG viewer).
LEGEND_PAD = 0.12


def legend_room_right(fig, margins, legend, cols=1):
    """Place ``fig`` at ``margins`` with the right one widened to hold ``legend``, drawn beside
    the last column of axes (anchored at ``(1.02, 1.0)`` in axes coordinates, 2 % of the axes
    width to its right); returns the margins used."""
    legend_w, _ = _extent_in(fig, legend)
    width = fig.get_size_inches()[0]
    # the axes width depends on the right margin: solve right = 0.02 * axes_w + legend + pad
    inner = width - margins.left - (cols - 1) * margins.wgap
    room = legend_w + LEGEND_PAD
    right = (0.02 * inner / cols + room) / (1.0 + 0.02 / cols)
    return place(fig, dataclasses.replace(margins, right=max(margins.right, right)))


def legend_room_below(fig, margins, legends, gap=0.5):
    """Place ``fig`` at ``margins`` with the bottom one raised above the tallest of
    ``legends`` (figure legends at its bottom edge), ``gap`` [in] kept for the x tick and axis
    labels in between; returns the margins used."""
    tallest = max(_extent_in(fig, legend)[1] for legend in legends)
    return place(fig, dataclasses.replace(margins, bottom=tallest + LEGEND_PAD + gap))


def legend_below(fig, margins, handles, labels, fontsize, columns):
    """A figure legend below the axes in ``columns`` columns (fewer when they would not fit the
    figure's width); the figure grows by the legend's height, so the axes keep theirs. Returns
    the legend."""
    width, height = fig.get_size_inches()
    while True:
        legend = fig.legend(handles, labels, loc="lower center", fontsize=fontsize,
                            ncols=columns)
        legend_w, legend_h = _extent_in(fig, legend)
        if columns == 1 or legend_w <= width - 0.2:
            break
        legend.remove()
        columns -= 1
    fig.set_size_inches(width, height + legend_h + LEGEND_PAD)
    legend_room_below(fig, margins, [legend])
    return legend


#: Decimals of the coordinates in the SVG files [pt] (0.01 pt is far below what shows).
SVG_DECIMALS = 2

# A comment (kept as it is: matplotlib writes each text's content there) or a tag.
_SVG_PART = re.compile(r"(<!--.*?-->)|(<[^>]*>)", re.DOTALL)
# A decimal number with more than SVG_DECIMALS decimals ("1.0" and "1.1" of the XML prolog and
# DOCTYPE have fewer and are never touched; ids and colours have no decimal point).
_LONG_DECIMAL = re.compile(rf"-?\d+\.\d{{{SVG_DECIMALS + 1},}}")
# Ids matplotlib makes from a hash of the content ("p" clip paths, "m" markers, "h" hatches,
# "C<n>_<n>_" collection paths): the hash covers unrounded floats.
_HASHED_ID = re.compile(r'\bid="((?:C[0-9a-f]+_[0-9a-f]+_|[a-z]?))([0-9a-f]{10})"')


def _round_decimal(match):
    text = f"{float(match.group(0)):.{SVG_DECIMALS}f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def tidy_svg(svg):
    """SVG text made independent of the last bits of the floats it was drawn from.

    * Every number with more than :data:`SVG_DECIMALS` decimals inside a tag (path data,
      ``x``/``y``, transforms, clip rectangles, styles) is rounded to that many decimals of a
      point (0.01 pt). Text content and comments are left as they are.
    * matplotlib names clip paths, markers and hatches by a hash of their unrounded content;
      each such id is renamed, in order of appearance, to its prefix, a digest of the rounded
      SVG and a counter (``p<digest>_0``, ``m<digest>_1``, ...), and every reference to it
      (``url(#...)``, ``xlink:href="#..."``) follows. The digest keeps ids of different figures
      apart when several are inlined in one HTML page.
    """
    svg = _SVG_PART.sub(lambda m: m.group(1) or _LONG_DECIMAL.sub(_round_decimal, m.group(2)),
                        svg)
    names = {}
    for match in _HASHED_ID.finditer(svg):
        names.setdefault(match.group(1) + match.group(2), match.group(1))
    if not names:
        return svg
    alternatives = "|".join(map(re.escape, names))
    pattern = re.compile(rf'(?<=id=")({alternatives})(?=")|(?<=#)({alternatives})(?=["\)])')
    order = {old: k for k, old in enumerate(names)}
    numbered = pattern.sub(lambda m: f"{names[m[1] or m[2]]}_{order[m[1] or m[2]]}", svg)
    digest = hashlib.sha256(numbered.encode("utf-8")).hexdigest()[:8]
    return pattern.sub(lambda m: f"{names[m[1] or m[2]]}{digest}_{order[m[1] or m[2]]}", svg)


class InView(Locator):
    """The ticks of another locator that lie in the axis' view (matplotlib creates a tick
    object, four lines and two texts, for every location a locator returns, drawn or not: a log
    axis's locator returns a decade of minor ticks beyond each end)."""

    def __init__(self, locator):
        self.locator = locator

    def set_axis(self, axis):
        super().set_axis(axis)
        self.locator.set_axis(axis)

    def __call__(self):
        ticks = np.asarray(self.locator())
        if ticks.size == 0:
            return ticks
        low, high = sorted(self.axis.get_view_interval())
        transform = self.axis.get_transform()
        low_t, high_t = transform.transform([low, high])
        span = abs(high_t - low_t)
        with np.errstate(invalid="ignore", divide="ignore"):
            where = transform.transform(ticks)
        # a tolerance well above matplotlib's own (it draws the ticks at the edges)
        keep = (where >= low_t - 1e-6 * span) & (where <= high_t + 1e-6 * span)
        return ticks[keep]

    def tick_values(self, vmin, vmax):
        return self.locator.tick_values(vmin, vmax)


def _ticks_in_view(fig):
    """Wrap every axis locator of ``fig`` in :class:`InView` (once; the ticks drawn are the
    same)."""
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            for ticker in (axis.major, axis.minor):
                if not isinstance(ticker.locator, InView):
                    wrapped = InView(ticker.locator)
                    wrapped.set_axis(axis)
                    ticker.locator = wrapped


def svg_text(fig):
    """The figure as SVG text, byte-identical for the same figure (no date, fixed ids), with
    coordinates rounded to 0.01 pt and content-hash ids renamed (:func:`tidy_svg`)."""
    _ticks_in_view(fig)
    out = io.StringIO()
    with rc_context(STYLE):
        fig.savefig(out, format="svg", metadata={"Date": None, "Creator": "cas_freq"})
    return tidy_svg(out.getvalue())


def png_bytes(fig):
    """The figure as PNG bytes with fixed metadata."""
    _ticks_in_view(fig)
    out = io.BytesIO()
    with rc_context(STYLE):
        fig.savefig(out, format="png", metadata={"Software": "cas_freq"})
    return out.getvalue()


_SUPERSCRIPTS = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")
# LogFormatterSciNotation's labels: $\mathdefault{10^{3}}$, $\mathdefault{2\times10^{-2}}$
_MATHTEXT_POWER = re.compile(r"^\$\\mathdefault\{(-?)(?:([0-9.]+)\\times)?(\d+)\^\{(-?\d+)\}\}\$$")


class PowerFormatter(LogFormatterSciNotation):
    """The labels of matplotlib's log-axis formatter (the same ticks labelled, the same values)
    written as plain text, 10³ and 2×10², instead of mathtext, whose parser costs ~10 ms per
    label and figure (its cache belongs to one renderer, i.e. one savefig)."""

    def __call__(self, x, pos=None):
        label = super().__call__(x, pos)
        match = _MATHTEXT_POWER.match(label)
        if match is None:
            return label
        sign, coefficient, base, exponent = match.groups()
        power = base + exponent.translate(_SUPERSCRIPTS)
        return ("−" if sign else "") + (f"{coefficient}×{power}" if coefficient else power)


def plain_log_labels(axis):
    """Label a log ``axis`` (``ax.xaxis``) with :class:`PowerFormatter`."""
    axis.set_major_formatter(PowerFormatter())
    axis.set_minor_formatter(PowerFormatter(labelOnlyBase=False))


def rounded(values):
    """Plotted data rounded to 6 significant digits (no last-bit noise reaches the figure)."""
    return round_array(values, 6)


#: Each loop's colour in the loop figures (C2 is T, C3 the Ms and requirement marks).
LOOP_COLORS = {"current_loop": "C0", "velocity_loop": "C4", "position_loop": "C1"}


def loop_color(name):
    """The colour of loop ``name`` (a key of :data:`LOOP_COLORS`) in every loop figure."""
    return LOOP_COLORS.get(name, "C5")


def output_symbol(data):
    """The output's symbol in one variant's labels: δ (an angle), x (a linear output)."""
    return OutputWords.of(data.loaded.params).symbol
