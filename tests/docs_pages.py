"""The documentation pages (README.md, docs/*.md) as the tests read them."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def doc_section(page, heading):
    """The text of a Markdown page under the heading `heading`, up to the next heading of the
    same or a higher level.

    Parameters
    ----------
    page : str
        The page's path relative to the repository root, e.g. ``"docs/api.md"``.
    heading : str
        The heading's text without its ``#`` marks; the page's title (``# ...``) is the whole page.

    Returns
    -------
    str
        The section's text, its heading line excluded.
    """
    text = (ROOT / page).read_text(encoding="utf-8")
    match = re.search(rf"^(#+) {re.escape(heading)}\n", text, flags=re.M)
    if match is None:
        raise AssertionError(f"{page} has no heading {heading!r}")
    level = len(match.group(1))
    rest = text[match.end():]
    end = re.search(rf"^#{{1,{level}}} ", rest, flags=re.M)
    return rest if end is None else rest[:end.start()]
