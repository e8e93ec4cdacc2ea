"""Issue 28: the README is a short front page (what cas_freq is, set-up, an example, the three main
jobs, links), and the manual it used to be lives in docs/*.md, pages a MkDocs site can use as
they are. These tests keep it so: the README's length, the two set-up commands, every page
titled and listed in docs/index.md, and every relative link pointing at a file that exists."""

import importlib.util
import re
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "docs").glob("*.md"))
#: Pages the docs site generates when it is built (docs/_hooks/reference.py's and the gallery's
#: index): links to them are links within the site, not to files of the repository.
GENERATED = {"reference/config.md", "reference/cli.md", "readme.md", "generated/gallery/index.md"}
#: A Markdown link or image: [text](target) or ![alt](target), target up to a space or ")".
LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")


def _relative_links(path):
    """The link targets of a Markdown file that are neither URLs nor in-page anchors."""
    text = path.read_text(encoding="utf-8")
    targets = [t for t in LINK.findall(text) if not re.match(r"[a-z][a-z0-9+.-]*:|#", t)]
    return [t.split("#", 1)[0] for t in targets]


def test_the_readme_is_at_most_250_lines():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, f"README.md has {len(lines)} lines; move detail to docs/"


def test_the_readme_gives_the_two_set_up_commands_and_the_three_main_jobs():
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    setup = text.split("\n## Set-up", 1)[1].split("\n## ", 1)[0]
    commands = [line.strip() for line in setup.splitlines() if line.startswith("    ")]
    assert commands == [
        "python3 -m venv .venv && . .venv/bin/activate && pip install -e . && cas-freq report",
        'python3 -m venv .venv && . .venv/bin/activate && pip install -e ".[test]" '
        "&& python -m pytest -q"]
    jobs = text.split("\n## The three main jobs\n", 1)[1].split("\n## ", 1)[0]
    for job in ("report", "verify", "compare"):
        assert f"- **{job}**: `cas-freq {job}" in jobs, job


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_each_docs_page_starts_with_its_title_and_is_listed_in_the_index(page):
    assert re.match(r"# \S", page.read_text(encoding="utf-8")), f"{page.name}: no '# title' line"
    if page.name != "index.md":
        assert page.name in _relative_links(ROOT / "docs" / "index.md"), page.name
        assert f"docs/{page.name}" in _relative_links(ROOT / "README.md"), page.name


@pytest.mark.parametrize("path", [ROOT / "README.md", *PAGES], ids=lambda p: p.name)
def test_every_relative_link_points_to_an_existing_file(path):
    links = _relative_links(path)
    generated = {ROOT / "docs" / page for page in GENERATED}
    missing = [t for t in links
               if t and not (path.parent / t).exists() and (path.parent / t) not in generated]
    assert not missing, f"{path.relative_to(ROOT)} links to missing files: {missing}"


def test_the_link_finder_sees_links_and_skips_urls_and_anchors(tmp_path):
    # the test above passes vacuously if no link is found: check the finder on a known page
    page = tmp_path / "p.md"
    page.write_text("[a](x.md) ![b](img/y.png) [c](https://e.org) [d](#top) [e](z.md#sec)\n"
                    "`code` [f](mailto:a@b.c)\n", encoding="utf-8")
    assert _relative_links(page) == ["x.md", "img/y.png", "z.md"]
    assert "docs/model.md" in _relative_links(ROOT / "README.md")


def test_the_generated_pages_are_those_the_docs_hook_writes():
    # GENERATED above must not excuse a link to a page that nothing writes
    hooks = importlib.util.spec_from_file_location("reference", ROOT / "docs/_hooks/reference.py")
    reference = importlib.util.module_from_spec(hooks)
    hooks.loader.exec_module(reference)
    assert GENERATED == {*reference.PAGES, "generated/gallery/index.md"}
    # read as MkDocs reads it, with PyYAML's full Loader (its warning filter is a python tag)
    site = yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=yaml.Loader)
    (plugin,) = [p["gallery"] for p in site["plugins"] if isinstance(p, dict) and "gallery" in p]
    assert plugin["gallery_dirs"] == "docs/generated/gallery"
