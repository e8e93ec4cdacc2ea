#!/usr/bin/env python3
"""Build the wheel offline and install it into a fresh environment, for tests/test_wheel.py.

Run by ``.ci/run`` (the tests never install anything) as ``python .ci/install_wheel.py DIR``
from the environment the tests run in; prints the path of the new environment's Python, which
``.ci/run`` gives the test as ``CAS_FREQ_WHEEL_PYTHON``.

Everything is written under DIR: the wheel is built from a copy of the source tree (a build
writes build/ and *.egg-info next to pyproject.toml), without build isolation, network or pip's
cache. The environment has no pip of its own and no system site-packages; this interpreter's
site-packages (numpy, numba, ...) are on its path through a .pth file, after its own
site-packages, so ``cas_freq`` can only come from the wheel (the editable install of the
source, a .pth hook of this interpreter's site-packages, is not run from there).
"""

import os
import shutil
import site
import subprocess
import sys
import sysconfig
import venv
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: What a build reads: the package, the configs it maps in, the metadata's files.
SOURCES = ("pyproject.toml", "README.md", "LICENSE", "cas_freq", "configs")


def copy_sources(target):
    """Copy :data:`SOURCES` into ``target``, without caches (bytecode, numba's)."""
    for name in SOURCES:
        source = ROOT / name
        if source.is_dir():
            shutil.copytree(source, target / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi",
                                                          "*.nbc"))
        else:
            shutil.copy2(source, target / name)


def _pip(*args, cwd):
    environment = {**os.environ, "PIP_NO_INDEX": "1", "PIP_NO_CACHE_DIR": "1",
                   "PIP_DISABLE_PIP_VERSION_CHECK": "1"}  # never the network, nor pip's cache
    subprocess.run([sys.executable, "-m", "pip", *args, "--no-deps", "--no-index",
                    "--no-build-isolation", "-q"], cwd=cwd, env=environment, check=True,
                   stdout=sys.stderr)


def install(folder):
    """Build the wheel and install it into ``folder``/venv; returns that environment's Python."""
    source, wheels = folder / "source", folder / "wheels"
    for path in (source, wheels):
        path.mkdir(parents=True)
    copy_sources(source)
    _pip("wheel", "-w", str(wheels), str(source), cwd=folder)
    (wheel,) = wheels.glob("cas_freq-*.whl")

    env_dir = folder / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    python = env_dir / ("Scripts/python.exe" if os.name == "nt" else "bin/python")
    purelib = Path(subprocess.run(
        [str(python), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        check=True, capture_output=True, text=True).stdout.strip())
    # the dependencies: this interpreter's site-packages, after the environment's own
    parents = dict.fromkeys([*site.getsitepackages(), sysconfig.get_paths()["purelib"]])
    (purelib / "_cas_freq_test_dependencies.pth").write_text(
        "".join(f"{path}\n" for path in parents if Path(path).is_dir()), encoding="utf-8")
    _pip("--python", str(python), "install", str(wheel), cwd=folder)
    return python


def main(argv):
    if len(argv) != 1:
        print("usage: python .ci/install_wheel.py DIR (a folder that does not exist yet)",
              file=sys.stderr)
        return 2
    folder = Path(argv[0]).resolve()
    folder.mkdir(parents=True)
    print(install(folder))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
