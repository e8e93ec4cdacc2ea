"""What every report figure shares: the fixed style, the figure factory, the rounding of
plotted data and the deterministic SVG/PNG writers (only :mod:`cas_freq.plots` imports
matplotlib).

The SVG files must not depend on the last bits of floating point (which differ between CPUs),
so the plotted data are rounded to 6 significant digits (:func:`rounded`, i.e.
:func:`cas_freq.report.numbers.round_array`) before they are drawn, and :func:`svg_text` rounds
every coordinate in the SVG to 0.01 pt and renames matplotlib's content-hash ids (see
:func:`tidy_svg`).
"""

import hashlib
import io
import re

import matplotlib

matplotlib.use("Agg")

from matplotlib import rc_context  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from cas_freq.report.numbers import round_array  # noqa: E402

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


def figure(rows, cols, size, sharex=False, **kwargs):
    """A constrained-layout figure in :data:`STYLE` with a (rows, cols) array of axes."""
    with rc_context(STYLE):
        fig = Figure(figsize=size, layout="constrained")
        axes = fig.subplots(rows, cols, sharex=sharex, squeeze=False, **kwargs)
    return fig, axes


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


def svg_text(fig):
    """The figure as SVG text, byte-identical for the same figure (no date, fixed ids), with
    coordinates rounded to 0.01 pt and content-hash ids renamed (:func:`tidy_svg`)."""
    out = io.StringIO()
    with rc_context(STYLE):
        fig.savefig(out, format="svg", metadata={"Date": None, "Creator": "cas_freq"})
    return tidy_svg(out.getvalue())


def png_bytes(fig):
    """The figure as PNG bytes with fixed metadata."""
    out = io.BytesIO()
    with rc_context(STYLE):
        fig.savefig(out, format="png", metadata={"Software": "cas_freq"})
    return out.getvalue()


def rounded(values):
    """Plotted data rounded to 6 significant digits (no last-bit noise reaches the figure)."""
    return round_array(values, 6)
