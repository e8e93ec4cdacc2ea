#!/usr/bin/env python3
"""Install headless Chromium for the browser check of the HTML reports, where it is missing.

Run by ``.ci/run`` before the tests (which never install anything: without Chromium the check
skips, saying why). Installs ``chromium`` with apt-get as root, and, if that fails (for example
for lack of package lists on a fresh machine), runs ``apt-get update`` and the install once
more. Exit status 0 when Chromium is on PATH afterwards, else 1 with the reason on stderr.
"""

import os
import shutil
import subprocess
import sys
import time

#: Chromium's executables, in the order looked for: the names tests/conftest.py's ``chromium``
#: fixture looks for (tests/test_hygiene.py checks that they are the same).
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


def main():
    if find_chromium() is not None:
        print(f"Chromium for the browser check: {find_chromium()}")
        return 0
    start = time.monotonic()
    path, reason = install_chromium()
    if path is None:
        print(f"Chromium not installed, the browser check will be skipped: {reason}",
              file=sys.stderr)
        return 1
    print(f"Chromium installed for the browser check in {time.monotonic() - start:.0f} s: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
