"""Render report blocks (:mod:`cas_freq.report.document`) as GitHub-flavoured Markdown."""

from cas_freq.report.document import Bullets, Figure, Heading, Paragraph, Table


def _cell(text):
    return str(text).replace("|", "\\|").replace("\n", " ")


def _table(block):
    lines = []
    if block.caption:
        lines += [f"*{block.caption}*", ""]
    lines.append("| " + " | ".join(_cell(c) for c in block.header) + " |")
    lines.append("|" + "|".join(" --- " for _ in block.header) + "|")
    lines += ["| " + " | ".join(_cell(c) for c in row) + " |" for row in block.rows]
    return "\n".join(lines)


def render(blocks):
    """Markdown text of a list of blocks (ends with one newline)."""
    parts = []
    for block in blocks:
        if isinstance(block, Heading):
            parts.append("#" * block.level + " " + block.text)
        elif isinstance(block, Paragraph):
            parts.append(block.text)
        elif isinstance(block, Bullets):
            parts.append("\n".join(f"- {item}" for item in block.items))
        elif isinstance(block, Table):
            parts.append(_table(block))
        elif isinstance(block, Figure):
            parts.append(f"![{_cell(block.caption)}]({block.path})\n\n*{block.caption}*")
        else:
            raise TypeError(f"markdown: unknown block {type(block).__name__}")
    return "\n\n".join(parts) + "\n"
