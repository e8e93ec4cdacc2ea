"""Render report blocks (:mod:`cas_freq.report.document`) as one self-contained HTML page.

The figures are inlined as SVG (their XML prolog and DOCTYPE removed), the style sheet is inline,
and nothing refers to the network, so the page reads the same in any browser, offline.
"""

import html
import re

from cas_freq.report.document import Bullets, Figure, Heading, Paragraph, Table

_STYLE = """
body { font-family: system-ui, -apple-system, "Segoe UI", Helvetica, Arial, sans-serif;
       margin: 2em auto; max-width: 1100px; padding: 0 1em; color: #222; line-height: 1.4; }
h1 { border-bottom: 2px solid #444; padding-bottom: .2em; }
h2 { border-bottom: 1px solid #aaa; margin-top: 2em; }
/* a table wider than the text may use the window's width, centred on the text (it scrolls in
   its own box only beyond that) */
table { border-collapse: collapse; margin: .5em 0 1.5em 0; font-size: 90%;
        display: block; width: max-content; max-width: calc(100vw - 3em); overflow-x: auto;
        position: relative; left: 50%; transform: translateX(-50%); }
caption { text-align: left; font-style: italic; padding: .3em 0; }
th, td { border: 1px solid #bbb; padding: .25em .6em; text-align: left; vertical-align: top; }
th { background: #eee; }
/* a number never breaks, nor a cell of one word (a status, a key); text wraps at its spaces
   and after the dots and underscores of long keys (<wbr>) */
.v { white-space: nowrap; }
tr:nth-child(even) td { background: #f8f8f8; }
td.PASS, td.ADVISORY-PASS { background: #d9f2d9 !important; }
td.FAIL { background: #f6d0d0 !important; font-weight: bold; }
td.ADVISORY, td.ADVISORY-FAIL { background: #fbe8c8 !important; }
figure { margin: 1em 0 2em 0; }
figure svg { max-width: 100%; height: auto; }
figcaption { font-style: italic; font-size: 90%; }
nav ul { columns: 2; }
@media print {
  body { max-width: none; margin: 0; padding: 0; }
  /* on paper a table cannot scroll: it takes the page's width, its columns share it and long
     cells wrap, in smaller type, so that no column is cut off */
  table { display: table; width: 100%; max-width: none; table-layout: fixed; overflow: visible;
          font-size: 7pt; position: static; transform: none; }
  th, td { padding: .1em .25em; overflow-wrap: anywhere; }
  .v { white-space: normal; }
  tr, figure { break-inside: avoid; }
  nav { display: none; }
}
"""

_PROLOG = re.compile(r"^\s*(<\?xml[^>]*\?>\s*)?(<!DOCTYPE[^>]*>\s*)?", re.DOTALL)
_METADATA = re.compile(r"\s*<metadata>.*?</metadata>", re.DOTALL)
_STATUSES = ("PASS", "FAIL", "ADVISORY", "ADVISORY-PASS", "ADVISORY-FAIL")


def inline_svg(svg):
    """SVG text fit to sit inside HTML: no XML prolog, no DOCTYPE, no RDF metadata block."""
    return _METADATA.sub("", _PROLOG.sub("", svg, count=1), count=1).strip()


#: Keys and other unspaced words at least this long get break opportunities after their dots
#: and underscores (``closed_loop.bandwidth_rad_s`` in a message) [characters].
LONG_WORD = 16

_WORD = re.compile(r"\S+")
_NUMBER = re.compile(r"^[-−+]?\d[\d.]*(e[-+]\d+)?\W*$", re.IGNORECASE)


def _word(word):
    """A word of a text cell as HTML: a number kept whole (Chromium breaks ``1.3e-06`` after
    its hyphen), a long key breakable after its dots and underscores."""
    text = html.escape(word)
    if _NUMBER.match(word) and "-" in word:
        return f'<span class="v">{text}</span>'
    if len(word) >= LONG_WORD:
        return re.sub(r"([._])(?=\w)", r"\1<wbr>", text)
    return text


def _cell(tag, text, css=()):
    """One ``<td>`` or ``<th>``: a short word (a number, a status) on one line, a long key
    breakable after its dots and underscores, text wrapping at its spaces (each word as
    :func:`_word` makes it)."""
    if " " not in text and len(text) < LONG_WORD:
        css, inner = (*css, "v"), html.escape(text)
    else:
        inner = _WORD.sub(lambda m: _word(m.group(0)), text)
    classes = f' class="{" ".join(css)}"' if css else ""
    return f"<{tag}{classes}>{inner}</{tag}>"


def _table(block):
    out = ["<table>"]
    if block.caption:
        out.append(f"<caption>{html.escape(block.caption)}</caption>")
    out.append("<thead><tr>" + "".join(_cell("th", str(c)) for c in block.header)
               + "</tr></thead>")
    out.append("<tbody>")
    for row in block.rows:
        cells = []
        for cell in row:
            text = str(cell)
            first = text.split(" ", 1)[0]
            cells.append(_cell("td", text, (first,) if first in _STATUSES else ()))
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def render(blocks, title):
    """One HTML page of a list of blocks; sections of level 2 are listed in a contents box."""
    body = []
    contents = [b for b in blocks if isinstance(b, Heading) and b.level == 2]
    for block in blocks:
        if isinstance(block, Heading):
            level = min(max(block.level, 1), 6)
            body.append(f'<h{level} id="{block.anchor}">{html.escape(block.text)}</h{level}>')
            if block.level == 1 and contents:
                links = "".join(f'<li><a href="#{h.anchor}">{html.escape(h.text)}</a></li>'
                                for h in contents)
                body.append(f"<nav><ul>{links}</ul></nav>")
        elif isinstance(block, Paragraph):
            body.append(f"<p>{html.escape(block.text)}</p>")
        elif isinstance(block, Bullets):
            body.append("<ul>" + "".join(f"<li>{html.escape(i)}</li>" for i in block.items)
                        + "</ul>")
        elif isinstance(block, Table):
            body.append(_table(block))
        elif isinstance(block, Figure):
            body.append(f'<figure id="fig-{html.escape(block.path)}">\n{inline_svg(block.svg)}\n'
                        f"<figcaption>{html.escape(block.caption)} "
                        f'(<a href="{html.escape(block.path)}">{html.escape(block.path)}</a>)'
                        "</figcaption></figure>")
        else:
            raise TypeError(f"html: unknown block {type(block).__name__}")
    return (
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
        "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n"
        f"<title>{html.escape(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n"
        + "\n".join(body) + "\n</body>\n</html>\n"
    )
