"""Issue 28: every code block of the README and docs/*.md runs, and shows what it prints.

Each page's blocks run in order in a folder of their own (``configs/`` and ``examples/`` of the
repository linked into it, so the pages' relative paths work as from the repository root):

- a ``cas-freq ...`` line of a shell block (fenced ```` ```bash ````/```` ```console ```` or
  indented) runs through the package's ``main`` in that folder; ``$ cas-freq ...`` lines are
  followed by an excerpt of what the command prints, and each excerpt line must appear in
  its output, in order (``...`` stands for lines left out); ``*`` in an argument is expanded
  as a shell would, an absolute ``-o``/``--csv`` path is written into the folder instead;
- a ```` ```python ```` block runs with ``exec`` in a fresh namespace; when the page follows it
  with "prints" and a ```` ```text ```` block, that is what it must print, line for line;
- a ```` ```yaml ```` block preceded by ``<!-- file: NAME -->`` is written to NAME first (a
  page's config, e.g. docs/getting-started.md's).

Not run: lines of a shell block that do not start with ``cas-freq`` (the README's set-up commands:
.ci/run runs the test command in a fresh environment, and installs the wheel that
tests/test_wheel.py checks), ``yaml`` blocks without a file name (config excerpts, the CI job
snippets of docs/cli.md and docs/howtos.md), formula blocks of docs/model.md, and a block preceded
by ``<!-- not run: REASON -->``. A block preceded by ``<!-- slow -->`` runs only in the slow-marked
test (.ci/run runs it), so that the suite stays fast; every page's other blocks run in the suite.
"""

import contextlib
import glob
import io
import os
import re
import shlex
from pathlib import Path

import pytest
from clirun import run_cli

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: The marker comment on the line before a block: ``<!-- slow -->``, ``<!-- file: x.yaml -->``,
#: ``<!-- not run: why -->``.
MARKER = re.compile(r"<!--\s*(slow|file:\s*(\S+)|not run:\s*(.+?))\s*-->")


def blocks(text):
    """The code blocks of a Markdown page: (line number, language, body, marker), the language
    "indented" for an indented block, the marker the ``<!-- ... -->`` comment above it."""
    lines, found, i = text.splitlines(), [], 0

    def marker(at):
        before = [line for line in lines[:at] if line.strip()]
        match = MARKER.fullmatch(before[-1].strip()) if before else None
        return match.group(1) if match else None

    while i < len(lines):
        fence = re.match(r"\s*```(\w*)", lines[i])
        if fence:
            end = next(j for j in range(i + 1, len(lines)) if re.fullmatch(r"\s*```\s*",
                                                                             lines[j]))
            found.append((i + 1, fence.group(1) or "text", "\n".join(lines[i + 1:end]),
                          marker(i)))
            i = end + 1
            continue
        previous = lines[i - 1] if i else ""
        if (lines[i].startswith("    ") and not previous.strip()
                and not (found and found[-1][0] > i)):
            end = i
            while end < len(lines) and (lines[end].startswith("    ") or not lines[end].strip()):
                end += 1
            # an indented line after a blank one inside a list item continues the item
            item = any(re.match(r"\s*([-*+]|\d+\.)\s", line) for line in lines[max(0, i - 3):i])
            if not item:
                body = "\n".join(line[4:] for line in lines[i:end]).strip("\n")
                found.append((i + 1, "indented", body, marker(i)))
            i = end
            continue
        i += 1
    return found


def _expected_output(text, line, blocks_of_page):
    """The ```text block a python block at ``line`` is followed by ("prints"), or None."""
    after = text.split("\n")[line:]
    for number, language, body, _ in blocks_of_page:
        if number > line:
            between = "\n".join(after[:number - line - 1])
            if language == "text" and between.strip().rstrip(":").endswith("prints") \
                    and "```" in between:
                return body
            return None
    return None


def _commands(body):
    """(argv, expected lines) of each cas-freq command of a shell block."""
    commands = []
    for line in body.splitlines():
        stripped = line.strip()
        command = stripped.removeprefix("$ ")
        if command.startswith("cas-freq ") or command == "cas-freq":
            words = shlex.split(command, comments=True)[1:]
            commands.append((words, [] if stripped.startswith("$ ") else None))
        elif commands and commands[-1][1] is not None and stripped:
            commands[-1][1].append(stripped)
    return commands


def _argv(words, folder):
    """Arguments as a shell would give them: globs expanded in ``folder``; an absolute output
    path (``-o /tmp/x``) moved into ``folder``, and an input path there read from it."""
    argv = []
    for word in words:
        if "*" in word:
            matches = sorted(glob.glob(word, root_dir=folder))
            assert matches, f"{word} matches no file"
            argv.extend(matches)
        elif word.startswith("/tmp/"):
            argv.append(str(folder / Path(word).name))
        else:
            argv.append(word)
    return argv


def _check_excerpt(expected, printed, what):
    """Each line of the excerpt ``expected`` appears in ``printed`` in order, whitespace runs
    read as one blank; ``...`` lines skip any number of lines."""
    lines = [" ".join(line.split()) for line in printed.splitlines()]
    at = 0
    for want in expected:
        if want == "...":
            continue
        want = " ".join(want.split())
        try:
            at = lines.index(want, at) + 1
        except ValueError:
            pytest.fail(f"{what}: the page shows {want!r}, which the output does not have "
                        f"(after line {at}):\n{printed}")


def _run_page(page, folder, slow):
    """Run the code blocks of ``page`` in ``folder``; the slow-marked ones too when ``slow``.
    The number of blocks run."""
    for name in ("configs", "examples"):
        (folder / name).symlink_to(ROOT / name)
    text = page.read_text(encoding="utf-8")
    found = blocks(text)
    ran = 0
    cwd = os.getcwd()
    os.chdir(folder)
    try:
        for line, language, body, marker in found:
            where = f"{page.relative_to(ROOT)}:{line}"
            if marker and marker.startswith("not run:"):
                continue
            if marker == "slow" and not slow:
                continue
            if language == "yaml" and marker and marker.startswith("file:"):
                (folder / marker.split(":", 1)[1].strip()).write_text(body + "\n",
                                                                      encoding="utf-8")
            elif language == "python":
                out = io.StringIO()
                with contextlib.redirect_stdout(out):
                    exec(compile(body, where, "exec"), {"__name__": "__main__"})
                expected = _expected_output(text, line, found)
                if expected is not None:
                    assert out.getvalue().strip() == expected.strip(), where
                ran += 1
            elif language in ("bash", "console", "sh", "shell", "indented"):
                for words, expected in _commands(body):
                    code, printed, err = run_cli(_argv(words, folder))
                    assert code in (0, 1), f"{where}: cas-freq {' '.join(words)} -> {code}: {err}"
                    if expected:
                        _check_excerpt(expected, printed, f"{where}: cas-freq {' '.join(words)}")
                    ran += 1
    finally:
        os.chdir(cwd)
    return ran


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_the_code_blocks_of_each_page_run(page, tmp_path, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    _run_page(page, tmp_path, slow=False)


#: The pages with slow-marked blocks (run again whole, as a slow block may use an earlier one's
#: output).
SLOW_PAGES = [page for page in PAGES
              if any(marker == "slow" for *_, marker in blocks(page.read_text(encoding="utf-8")))]


@pytest.mark.slow
@pytest.mark.parametrize("page", SLOW_PAGES, ids=lambda p: p.name)
def test_every_code_block_of_each_page_runs_slow_ones_included(page, tmp_path, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    _run_page(page, tmp_path, slow=True)


def test_the_block_finder_sees_each_kind_of_block_and_its_marker():
    # the tests above pass vacuously if no block is found: check the finder on a known page
    page = ("# t\n\nText:\n\n    $ cas-freq analyze\n    qt_cas / base\n\n- item\n\n"
            "    item text\n\n<!-- slow -->\n```console\n$ cas-freq tune\n```\n\n"
            "<!-- file: a.yaml -->\n\n```yaml\nname: a\n```\n\n```python\nprint(1)\n```\n\n"
            "prints\n\n```text\n1\n```\n")
    found = blocks(page)
    assert [(language, marker) for _, language, _, marker in found] == [
        ("indented", None), ("console", "slow"), ("yaml", "file: a.yaml"), ("python", None),
        ("text", None)]
    assert _commands(found[0][2]) == [(["analyze"], ["qt_cas / base"])]
    assert _expected_output(page, found[3][0], found) == "1"
    assert _commands("cas-freq sweep --set a=1:2:3   # a comment\npython -m x") == [
        (["sweep", "--set", "a=1:2:3"], None)]


def test_the_pages_have_code_that_runs():
    # every page with commands is counted: a finder that stopped seeing blocks would fail here
    runnable = {page.name for page in PAGES
                if any(language == "python" or _commands(body)
                       for _, language, body, _ in blocks(page.read_text(encoding="utf-8")))}
    assert {"README.md", "api.md", "cli.md", "getting-started.md", "howtos.md"} <= runnable


def test_an_excerpt_that_the_output_lacks_fails():
    _check_excerpt(["a", "...", "c  d"], "a\nb\nc d\n", "ok")
    with pytest.raises(pytest.fail.Exception):
        _check_excerpt(["c", "a"], "a\nb\nc\n", "out of order")
