"""Hygiene. The tests never change the machine: headless Chromium, for the browser check of the
HTML reports, is looked for on PATH and never installed by a test (.ci/run installs it, with
.ci/install_chromium.py); without it the check skips, saying why. And nothing a user reads (the
README, the docs, the configs, the package's docstrings and messages) cites the project's
internal issue numbers, which a user cannot look up."""

import ast
import importlib.util
import os
import re
import subprocess
from pathlib import Path

import conftest
import pytest

INSTALLER = Path(__file__).resolve().parents[1] / ".ci" / "install_chromium.py"


def test_a_missing_chromium_skips_the_check_and_installs_nothing(monkeypatch):
    # as root on a machine with apt-get, where the fixture used to run `apt-get install`
    def ran(*args, **kwargs):
        raise AssertionError(f"a test ran {args[0] if args else kwargs.get('args')}")

    monkeypatch.setattr(conftest.shutil, "which",
                        lambda name: "/usr/bin/apt-get" if name == "apt-get" else None)
    monkeypatch.setattr(os, "geteuid", lambda: 0)
    monkeypatch.setattr(subprocess, "run", ran)
    monkeypatch.setattr(subprocess, "Popen", ran)
    with pytest.raises(pytest.skip.Exception,
                       match="Chromium is not installed .* .ci/install_chromium.py"):
        conftest.chromium_or_skip()


def test_the_installer_looks_for_the_executables_the_tests_use():
    spec = importlib.util.spec_from_file_location("install_chromium", INSTALLER)
    installer = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(installer)  # defines only; installs nothing (not run as a script)
    assert installer.CHROMIUM_NAMES == conftest.CHROMIUM_NAMES


# ---- what the user reads names no internal issue ---------------------------------------------

#: A reference to an issue of the project's tracker, which a user cannot look up: "issue 26",
#: "issues 14 and 15", "issue #5", "the issue's figure", "a later issue".
ISSUE_REFERENCE = re.compile(r"\bissues?\s*(?:#\s*)?\d+|\b(?:the|this|that|a later) issue\b",
                             re.IGNORECASE)
ROOT = Path(__file__).resolve().parents[1]


def _package_strings(path):
    """(line, text) of every string literal of a module: its docstrings, messages, help."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            yield node.lineno, node.value


def _user_texts():
    """(where, text) of what a user reads: README.md, the docs' pages and notebooks, the shipped
    configs' comments, and every string of the package (docstrings, messages, CLI help)."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md")),
             *sorted((ROOT / "docs").rglob("*.ipynb")), *sorted((ROOT / "configs").glob("*.yaml"))]
    for page in pages:
        for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
            yield f"{page.relative_to(ROOT)}:{number}", line
    for module in sorted((ROOT / "cas_freq").rglob("*.py")):
        for number, text in _package_strings(module):
            yield f"{module.relative_to(ROOT)}:{number}", text


def test_no_user_facing_text_cites_an_internal_issue():
    found = [f"{where}: {match.group(0)!r}" for where, text in _user_texts()
             for match in ISSUE_REFERENCE.finditer(text)]
    assert found == [], "\n".join(found)


def test_the_issue_pattern_finds_the_references_it_is_meant_for():
    for text in ("(sampled loops are issue 26's)", "## Drive architectures (issue 25)",
                 "Issue 30's cases", "issues 14 and 15", "issue #5", "as the issue states",
                 "a later issue"):
        assert ISSUE_REFERENCE.search(text), text
    for text in ("a tissue", "issued on 2026-11-25", "the drive's issues of noise"):
        assert not ISSUE_REFERENCE.search(text), text
