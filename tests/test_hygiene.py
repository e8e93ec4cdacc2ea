"""Issue 24, test hygiene: the tests never change the machine. Headless Chromium, for the browser
check of the HTML reports, is looked for on PATH and never installed by a test (.ci/run installs
it, with .ci/install_chromium.py); without it the check skips, saying why."""

import importlib.util
import os
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
