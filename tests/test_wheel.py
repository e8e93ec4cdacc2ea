"""The wheel carries what the main job needs (issue 28): built from a copy of the source,
installed offline into a fresh virtual environment, it runs ``cas-freq report`` and
``cas_freq.load()`` from another folder, on the shipped config it carries as package data.

The install test is slow (the installed package compiles its numba kernels afresh: 18-32 s,
~18 s of CPU here): it is marked ``slow`` (deselected by pyproject's addopts) and .ci/run
runs it explicitly.
It changes nothing outside pytest's tmp_path: the wheel is built from a copy of the source
tree (a build writes build/ and *.egg-info next to pyproject.toml), without build isolation,
network or pip's cache; the environment has no pip of its own and no system site-packages: the
test's own site-packages (numpy, numba, ...) are on its path through a .pth file, after its
own site-packages, so ``cas_freq`` can only come from the wheel; its numba cache lands in the
environment, the unit and matplotlib caches in tmp_path.
"""

import importlib.resources
import importlib.util
import os
import site
import subprocess
import sys
import sysconfig
import tomllib
import venv
from pathlib import Path

import pytest

from cas_freq.config import loader

ROOT = Path(__file__).resolve().parents[1]
#: What a build reads: the package, the configs it maps in, the metadata's files.
SOURCES = ("pyproject.toml", "README.md", "LICENSE", "cas_freq", "configs")


def test_pyproject_lists_every_package_and_maps_the_configs():
    # pyproject lists the packages (a mapped package-dir rules out find); a package missing
    # from the list would be missing from the wheel. The design page's static folders are
    # data-only packages, listed so that setuptools installs them without a deprecation.
    settings = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["tool"]
    on_disk = {".".join(init.parent.relative_to(ROOT).parts)
               for init in (ROOT / "cas_freq").rglob("__init__.py")}
    data = {"cas_freq.design.static", "cas_freq.design.static.vendor.uplot"}
    assert set(settings["setuptools"]["packages"]) == on_disk | {"cas_freq.configs"} | data
    assert settings["setuptools"]["package-dir"] == {"cas_freq.configs": "configs"}
    assert settings["setuptools"]["package-data"] == {"cas_freq.configs": ["*.yaml"],
                                                      **dict.fromkeys(data, ["*"])}
    assert {p.name for p in (ROOT / "configs").glob("*.yaml")} == {
        "qt_cas.yaml", "dc_servo.yaml", "cascade_axis.yaml", "ball_screw.yaml"}


def test_the_shipped_configs_are_package_data_when_installed_else_the_repositorys(
        tmp_path, monkeypatch):
    # a source checkout (this one): the repository's configs/, which reports name from its root
    assert loader.default_config_path() == ROOT / "configs" / "qt_cas.yaml"
    # an installed package: its package data cas_freq/configs/ (what the wheel maps there)
    installed = tmp_path / "site-packages" / "cas_freq"
    (installed / "configs").mkdir(parents=True)
    monkeypatch.setattr(importlib.resources, "files",
                        lambda package: installed if package == "cas_freq" else None)
    assert loader.default_config_path() == installed / "configs" / "qt_cas.yaml"


def _copy_sources(target):
    import shutil

    for name in SOURCES:
        source = ROOT / name
        if source.is_dir():
            shutil.copytree(source, target / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nbi",
                                                          "*.nbc"))
        else:
            shutil.copy2(source, target / name)


def _child_environment(tmp_path):
    environment = {key: value for key, value in os.environ.items()
                   if key not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    environment["CAS_FREQ_UNIT_CACHE"] = str(tmp_path / "unit-cache")  # not the user's cache
    environment["MPLCONFIGDIR"] = str(tmp_path / "matplotlib")
    environment["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")  # not the user's cache either
    environment["MPLBACKEND"] = "Agg"
    environment["PIP_NO_INDEX"] = "1"  # never the network
    environment["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    environment["PIP_NO_CACHE_DIR"] = "1"
    return environment


def _run(args, cwd, environment):
    result = subprocess.run(args, cwd=cwd, env=environment, capture_output=True, text=True,
                            timeout=600, check=False)
    assert result.returncode == 0, (args, result.stdout[-2000:], result.stderr[-2000:])
    return result


@pytest.mark.slow
def test_the_wheel_installed_offline_runs_report_and_load_from_another_folder(tmp_path):
    for module in ("setuptools", "wheel", "pip"):
        if importlib.util.find_spec(module) is None:
            pytest.skip(f"{module} is not importable: the wheel cannot be built offline "
                        f"without build isolation (pip install '.[test]' installs it)")
    environment = _child_environment(tmp_path)
    source, wheels, work = tmp_path / "source", tmp_path / "wheels", tmp_path / "work"
    for folder in (source, wheels, work):
        folder.mkdir()
    _copy_sources(source)
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
          "--no-index", "-q", "-w", str(wheels), str(source)], tmp_path, environment)
    (wheel,) = wheels.glob("cas_freq-*.whl")

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=False).create(env_dir)
    scripts = "Scripts" if os.name == "nt" else "bin"
    python = env_dir / scripts / ("python.exe" if os.name == "nt" else "python")
    purelib = Path(_run([str(python), "-c", "import sysconfig; "
                         "print(sysconfig.get_paths()['purelib'])"],
                        work, environment).stdout.strip())
    # the dependencies: this interpreter's site-packages, after the environment's own
    parents = dict.fromkeys([*site.getsitepackages(), sysconfig.get_paths()["purelib"]])
    (purelib / "_cas_freq_test_dependencies.pth").write_text(
        "".join(f"{path}\n" for path in parents if Path(path).is_dir()), encoding="utf-8")
    _run([sys.executable, "-m", "pip", "--python", str(python), "install", "--no-deps",
          "--no-index", "--no-build-isolation", "-q", str(wheel)], work, environment)

    # the package and its shipped config come from the environment, not the source tree
    where = _run([str(python), "-c",
                  "import cas_freq as cf; act = cf.load(); "
                  "print(cf.__file__); print(act.config_path); print(act.params.name)"],
                 work, environment).stdout.splitlines()
    installed = purelib / "cas_freq"
    assert Path(where[0]) == installed / "__init__.py"
    assert Path(where[1]) == installed / "configs" / "qt_cas.yaml"
    assert where[2] == "qt_cas"
    # the design page's files (cas-freq design serves them from the installed package)
    static = installed / "design" / "static"
    assert {p.relative_to(static).as_posix() for p in static.rglob("*") if p.is_file()} == {
        "index.html", "design.js", "design.css", "vendor/uplot/uPlot.iife.min.js",
        "vendor/uplot/uPlot.min.css", "vendor/uplot/LICENSE", "vendor/uplot/README.md"}

    # the main job from another folder: into -o, and by default into ./reports/qt_cas/
    cli = env_dir / scripts / ("cas-freq.exe" if os.name == "nt" else "cas-freq")
    _run([str(cli), "report", "--variant", "base", "-o", str(tmp_path / "out")], work,
         environment)
    report = (tmp_path / "out" / "report.md").read_text(encoding="utf-8")
    assert "- config: " in report and "Verdict:" in report
    _run([str(cli), "report", "--variant", "base", "-q"], work, environment)
    assert (work / "reports" / "qt_cas" / "report.md").is_file()
