"""Short text and HTML views of the API's results, for a terminal and a notebook.

A result class lists its headline figures in ``_summary()`` as ``(title, rows)``: rows of
``(dotted key, value)`` where the key is one of :data:`cas_freq.core.figures.FIGURES` (its label,
display unit and factor come from that table) or of ``(label, value, unit)`` for anything else.
:class:`Summary` turns that into ``__repr__`` (the title and a few rows on one line each) and
``_repr_html_`` (a small table, which Jupyter shows for a cell's last value). Never an array.

Imports only the standard library and :mod:`cas_freq.core.figures`.
"""

import html
import math

from cas_freq.core.figures import FIGURES, loop_label

#: Most rows ``__repr__`` prints (the HTML table shows every row).
REPR_ROWS = 6


def _text(value):
    """A value as shown: 4 significant digits, "—" for a figure that does not exist."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float | int):
        return f"{value:.4g}"
    return str(value)


def row(entry):
    """``(label, value text, unit)`` of one summary row: ``(key, value)`` with a key of
    :data:`~cas_freq.core.figures.FIGURES` (value in its JSON unit, shown scaled), or
    ``(label, value, unit)``."""
    if len(entry) == 3:
        label, value, unit = entry
        return label, _text(value), unit
    key, value = entry
    figure = FIGURES[key]
    if isinstance(value, float | int) and not isinstance(value, bool):
        value = value * figure.scale
    loop = f"{loop_label(figure.loop)}: " if figure.loop else ""
    return loop + figure.label, _text(value), figure.shown_unit


def table_rows(result, group, names):
    """Summary rows ``(label, value, unit)`` of the attributes ``names`` of ``result``, with
    the labels and units of the figures ``group.name`` of :data:`~cas_freq.core.figures.FIGURES`
    (of no particular loop: a loop's figures without its name)."""
    rows = []
    for name in names:
        figure = FIGURES[f"{group}.{name}"]
        rows.append((figure.label, figure.shown(getattr(result, name)), figure.shown_unit))
    return rows


class Summary:
    """Mixin: ``__repr__`` and ``_repr_html_`` from the class's ``_summary()``.

    Dataclasses using it are declared with ``repr=False`` (else the dataclass's own repr, which
    prints every array, replaces this one).
    """

    def _summary(self):  # pragma: no cover - each result defines it
        raise NotImplementedError

    def __repr__(self):
        title, rows = self._summary()
        lines = [f"{type(self).__name__}: {title}"]
        for label, value, unit in map(row, rows[:REPR_ROWS]):
            lines.append(f"  {label}: {value}" + (f" {unit}" if unit and value != "—" else ""))
        if len(rows) > REPR_ROWS:
            lines.append(f"  ... {len(rows) - REPR_ROWS} more (every row in its notebook table)")
        return "\n".join(lines)

    def _repr_html_(self):
        title, rows = self._summary()
        body = "".join(
            f"<tr><td style='text-align:left'>{html.escape(label)}</td>"
            f"<td style='text-align:right'>{html.escape(value)}</td>"
            f"<td style='text-align:left'>{html.escape(unit)}</td></tr>"
            for label, value, unit in map(row, rows))
        return (f"<table><caption style='text-align:left'><b>{html.escape(type(self).__name__)}"
                f"</b>: {html.escape(title)}</caption>"
                "<tr><th>figure</th><th>value</th><th>unit</th></tr>"
                f"{body}</table>")


def spread(key, values):
    """A summary row ``(label, text, unit)`` of a figure over many variants: its smallest and
    largest value and the count where it does not exist (NaN), in the figure's display unit."""
    import numpy as np

    figure = FIGURES[key]
    values = np.asarray(values, dtype=float) * figure.scale
    finite = values[np.isfinite(values)]
    text = f"{finite.min():.4g} .. {finite.max():.4g}" if finite.size else "—"
    missing = values.size - finite.size
    if missing:
        text += f" ({missing} without)"
    loop = f"{loop_label(figure.loop)}: " if figure.loop else ""
    return loop + figure.label, text, figure.shown_unit
