"""Shared fixtures: temporary config files, the shipped config's raw data, and headless Chromium
(installed here when missing and possible)."""

import copy
import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from cas_freq.config import default_config_path, read_config_file


@pytest.fixture(scope="session")
def shipped_config_path():
    """Path of the shipped ``configs/qt_cas.yaml``."""
    path = default_config_path()
    assert path.is_file(), path
    return path


@pytest.fixture(scope="session")
def _shipped_raw_once(shipped_config_path):
    return read_config_file(shipped_config_path)


@pytest.fixture
def shipped_raw(_shipped_raw_once):
    """The shipped config as plain YAML data (a fresh deep copy: tests may mutate it)."""
    return copy.deepcopy(_shipped_raw_once)


@pytest.fixture
def write_config(tmp_path):
    """``write_config(text_or_dict, name="config.yaml") -> Path``: a config file in tmp_path.

    A string is written as it is (for YAML syntax tests); a dict is dumped with ``yaml.safe_dump``
    (non-finite floats come out as ``.nan``/``.inf``, as a user would write them).
    """

    def write(content, name="config.yaml"):
        path = Path(tmp_path) / name
        if not isinstance(content, str):
            content = yaml.safe_dump(content, sort_keys=False)
        path.write_text(content, encoding="utf-8")
        return path

    return write


# ---- headless Chromium, for the browser check of the HTML reports -------------------------------

#: Chromium's executables, in the order looked for.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")

#: Longest wait for one apt-get run [s] (installing Chromium on a fresh Debian machine took 14 s
#: here; a slow mirror can take minutes).
APT_TIMEOUT_S = 900

#: The Debian package of the browser (its chromium-driver is not needed: the check drives the
#: browser from its command line).
CHROMIUM_PACKAGE = "chromium"


def find_chromium():
    """Path of a Chromium executable on PATH, or None."""
    return next(filter(None, (shutil.which(name) for name in CHROMIUM_NAMES)), None)


def _apt_get(apt, *args):
    """Run ``apt-get ARGS`` non-interactively; (succeeded, last line of its output)."""
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    try:
        done = subprocess.run([apt, "-o", "DPkg::Lock::Timeout=120", *args], env=env,
                              capture_output=True, text=True, timeout=APT_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return False, f"apt-get {args[0]} timed out after {APT_TIMEOUT_S} s"
    lines = (done.stderr.strip() or done.stdout.strip()).splitlines()
    return done.returncode == 0, lines[-1] if lines else f"exit status {done.returncode}"


def install_chromium():
    """Install Chromium with apt-get where it is missing and this process can.

    Runs ``apt-get install -y --no-install-recommends chromium`` as root, and, if that fails
    (for example for lack of package lists on a fresh machine), ``apt-get update`` and the
    install once more.

    Returns
    -------
    tuple of (str or None, str)
        The executable's path, or None and why it cannot be had: not root, no apt-get, or the
        last line of apt-get's error.
    """
    found = find_chromium()
    if found:
        return found, ""
    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        return None, "not root, so apt-get cannot install it"
    apt = shutil.which("apt-get")
    if apt is None:
        return None, "no apt-get on this machine to install it"
    install = ("install", "-y", "--no-install-recommends", CHROMIUM_PACKAGE)
    ok, last = _apt_get(apt, *install)
    if not ok:
        updated, update_last = _apt_get(apt, "update")
        if not updated:
            return None, f"apt-get install failed ({last}); apt-get update failed: {update_last}"
        ok, last = _apt_get(apt, *install)
    if not ok:
        return None, f"apt-get install {CHROMIUM_PACKAGE} failed: {last}"
    found = find_chromium()
    if found is None:
        return None, (f"apt-get installed {CHROMIUM_PACKAGE} but none of "
                      f"{', '.join(CHROMIUM_NAMES)} is on PATH")
    return found, ""


@pytest.fixture(scope="session")
def chromium():
    """Path of headless-capable Chromium, installed by :func:`install_chromium` when missing;
    the test is skipped, saying why, only when it cannot be installed."""
    path, reason = install_chromium()
    if path is None:
        pytest.skip(f"headless-browser check: Chromium is not installed and cannot be: {reason}")
    return path
