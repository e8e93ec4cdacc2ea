"""A report as a list of plain blocks, rendered to Markdown or HTML by the renderers.

The content of a report is built once (:mod:`cas_freq.report.build`,
:mod:`cas_freq.report.compare`) as :class:`Heading`, :class:`Paragraph`, :class:`Bullets`,
:class:`Table` and :class:`Figure` blocks; :mod:`cas_freq.report.markdown` and
:mod:`cas_freq.report.html` only render them, so both files always say the same.
"""

import dataclasses
import math
import re


@dataclasses.dataclass(frozen=True)
class Heading:
    """A section heading; ``level`` 1 is the title."""

    level: int
    text: str

    @property
    def anchor(self):
        """Stable id for links: the text lower-cased, runs of other characters as '-'."""
        return re.sub(r"[^a-z0-9]+", "-", self.text.lower()).strip("-") or "section"


@dataclasses.dataclass(frozen=True)
class Paragraph:
    """Plain text (no markup)."""

    text: str


@dataclasses.dataclass(frozen=True)
class Bullets:
    """A list of plain-text items."""

    items: tuple


@dataclasses.dataclass(frozen=True)
class Table:
    """A table of text cells; ``caption`` is shown above it."""

    header: tuple
    rows: tuple
    caption: str = ""


@dataclasses.dataclass(frozen=True)
class Figure:
    """A figure: its SVG text and its path relative to the report's folder."""

    path: str
    caption: str
    svg: str


def number(value, digits=4, unit=""):
    """A figure as text: ``digits`` significant digits, "—" for a missing one."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, str):
        return value
    text = f"{value:.{digits}g}"
    return f"{text} {unit}" if unit else text


def difference(value, baseline, digits=4):
    """``value - baseline`` as signed text with the relative change; "" for the baseline."""
    if value is None or baseline is None:
        return "—"
    if isinstance(value, bool) or isinstance(baseline, bool):
        return "same" if value == baseline else "differs"
    delta = value - baseline
    if delta == 0:
        return "0"
    text = f"{delta:+.{digits}g}"
    if baseline != 0 and math.isfinite(baseline):
        text += f" ({100.0 * delta / abs(baseline):+.3g} %)"
    return text
