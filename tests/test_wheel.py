"""The wheel carries what the main job needs (issue 28): built from a copy of the source,
installed offline into a fresh virtual environment, it runs ``cas-freq report`` and
``cas_freq.load()`` from another folder, on the shipped config it carries as package data.

Tests never install anything: ``.ci/run`` builds and installs the wheel first
(``python .ci/install_wheel.py DIR``: offline, without build isolation or pip's cache, into a
fresh environment under DIR) and runs the check of the installed package with its Python as
``CAS_FREQ_WHEEL_PYTHON``; without that variable the check skips, saying so. It is slow (the
installed package compiles its numba kernels afresh: 18-32 s, ~18 s of CPU here): it is marked
``slow`` (deselected by pyproject's addopts). Its numba cache, unit cache and matplotlib cache
land in tmp_path.
"""

import importlib.resources
import os
import subprocess
import tomllib
from pathlib import Path

import pytest

from cas_freq.config import loader

ROOT = Path(__file__).resolve().parents[1]


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


def _child_environment(tmp_path):
    environment = {key: value for key, value in os.environ.items()
                   if key not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    environment["CAS_FREQ_UNIT_CACHE"] = str(tmp_path / "unit-cache")  # not the user's cache
    environment["MPLCONFIGDIR"] = str(tmp_path / "matplotlib")
    environment["NUMBA_CACHE_DIR"] = str(tmp_path / "numba")  # not the user's cache either
    environment["MPLBACKEND"] = "Agg"
    return environment


def _run(args, cwd, environment):
    result = subprocess.run(args, cwd=cwd, env=environment, capture_output=True, text=True,
                            timeout=600, check=False)
    assert result.returncode == 0, (args, result.stdout[-2000:], result.stderr[-2000:])
    return result


#: The environment variable naming the Python of the environment the wheel is installed in.
WHEEL_PYTHON = "CAS_FREQ_WHEEL_PYTHON"


@pytest.mark.slow
def test_the_wheel_installed_offline_runs_report_and_load_from_another_folder(tmp_path):
    if not os.environ.get(WHEEL_PYTHON):
        pytest.skip(f"{WHEEL_PYTHON} is not set: .ci/run builds and installs the wheel first "
                    "(python .ci/install_wheel.py DIR); tests do not install")
    python = Path(os.environ[WHEEL_PYTHON])
    environment = _child_environment(tmp_path)
    work = tmp_path / "work"
    work.mkdir()
    purelib = Path(_run([str(python), "-c", "import sysconfig; "
                         "print(sysconfig.get_paths()['purelib'])"],
                        work, environment).stdout.strip())

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
    cli = python.parent / ("cas-freq.exe" if os.name == "nt" else "cas-freq")
    _run([str(cli), "report", "--variant", "base", "-o", str(tmp_path / "out")], work,
         environment)
    report = (tmp_path / "out" / "report.md").read_text(encoding="utf-8")
    assert "- config: " in report and "Verdict:" in report
    _run([str(cli), "report", "--variant", "base", "-q"], work, environment)
    assert (work / "reports" / "qt_cas" / "report.md").is_file()
