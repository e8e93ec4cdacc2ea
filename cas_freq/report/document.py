"""A report as a list of plain blocks, rendered to Markdown or HTML by the renderers.

The content of a report is built once (:mod:`cas_freq.report.build`,
:mod:`cas_freq.report.compare`) as :class:`Heading`, :class:`Paragraph`, :class:`Bullets`,
:class:`Table` and :class:`Figure` blocks; :mod:`cas_freq.report.markdown` and
:mod:`cas_freq.report.html` only render them, so both files always say the same. Figures are
formatted with :func:`cas_freq.core.numbers.number` (a stated precision, 0 for numerically
zero, "—" for absent).
"""

import dataclasses
import re

from cas_freq.core.numbers import difference, number  # noqa: F401  (re-exported)


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
