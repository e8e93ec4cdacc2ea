"""Where the compiled kernels are cached, and the first run's compilation messages (first runs
and read-only installs).

numba caches next to the kernels' modules; with a read-only package folder and no writable
home it found no cache folder and compiled in every process (5.8-6.6 s each). The tests run
as root, which writes anywhere, so the package folder's writability is a stand-in function
(``package_writable``); the real read-only case runs only for another user.
"""

import os
import re
import shutil
import stat
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

from cas_freq.core import jit

ROOT = Path(__file__).resolve().parents[1]
NOTE = "cas-freq: compiling the numerical kernels not in the cache yet"
SUMMARY = "cas-freq: compiled the numerical kernels in"


def read_only(_path):
    return False


def test_read_only_package_caches_in_the_users_cache_folder(tmp_path):
    environ = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    folder = jit.configure_cache(environ, package_writable=read_only)
    expected = tmp_path / "xdg" / "cas_freq" / "numba"
    assert folder == str(expected)
    assert environ[jit.CACHE_ENV] == str(expected)
    assert expected.is_dir() and stat.S_IMODE(expected.stat().st_mode) == 0o700


def test_a_users_numba_cache_dir_is_respected(tmp_path):
    environ = {jit.CACHE_ENV: str(tmp_path / "mine"), "XDG_CACHE_HOME": str(tmp_path / "xdg")}
    assert jit.configure_cache(environ, package_writable=read_only) is None
    assert environ[jit.CACHE_ENV] == str(tmp_path / "mine")
    assert not (tmp_path / "xdg").exists()


def test_a_writable_package_keeps_numbas_own_cache(tmp_path):
    environ = {"XDG_CACHE_HOME": str(tmp_path / "xdg")}
    assert jit.configure_cache(environ, package_writable=lambda path: True) is None
    assert jit.CACHE_ENV not in environ


def test_without_a_writable_home_the_cache_is_a_private_temporary_folder(tmp_path, monkeypatch):
    # a cache home below a regular file cannot be created, even by root (ENOTDIR)
    (tmp_path / "file").write_text("")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    environ = {"XDG_CACHE_HOME": str(tmp_path / "file" / "cache")}
    folder = jit.configure_cache(environ, package_writable=read_only)
    assert folder == str(tmp_path / "tmp" / f"cas_freq-numba-{os.getuid()}")


def test_a_temporary_folder_others_can_write_is_not_trusted(tmp_path, monkeypatch):
    # machine code is loaded from the cache: a folder in /tmp that another user could have
    # made (or can write) must not be used; the kernels then compile in the process
    (tmp_path / "file").write_text("")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    shared = tmp_path / f"cas_freq-numba-{os.getuid()}"
    shared.mkdir()
    shared.chmod(0o777)
    environ = {"XDG_CACHE_HOME": str(tmp_path / "file" / "cache")}
    assert jit.configure_cache(environ, package_writable=read_only) is None
    assert jit.CACHE_ENV not in environ


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0,
                    reason="root writes into a read-only folder: the stand-in tests cover it")
def test_a_really_read_only_copy_of_the_package(tmp_path):
    shutil.copytree(ROOT / "cas_freq", tmp_path / "site" / "cas_freq",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for path in (tmp_path / "site").rglob("*"):
        path.chmod(path.stat().st_mode & ~0o222)
    env = {key: value for key, value in os.environ.items()
           if key not in (jit.CACHE_ENV, "XDG_CACHE_HOME")}
    env.update(PYTHONPATH=str(tmp_path / "site"), HOME=str(tmp_path / "home"))
    out = subprocess.run([sys.executable, "-c", "import os, cas_freq.core.jit; "
                          f"print(os.environ['{jit.CACHE_ENV}'])"],
                         env=env, capture_output=True, text=True, check=True).stdout
    assert out.strip() == str(tmp_path / "home" / ".cache" / "cas_freq" / "numba")


def _run(args, cache, *, code=None):
    env = dict(os.environ, PYTHONPATH=str(ROOT), **{jit.CACHE_ENV: str(cache)})
    env.pop("CAS_FREQ_ENGINE", None)
    command = [sys.executable, "-c", code] if code else [sys.executable, "-m", "cas_freq", *args]
    return subprocess.run(command, env=env, capture_output=True, text=True, check=True).stderr


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_the_first_run_says_once_that_it_compiles_and_how_long_it_took(tmp_path):
    # the smallest command with a compiled kernel: a step fit (fit_kernel, ~5 s to compile)
    t = np.linspace(0.0, 0.2, 201)
    response = 10.0 * (1.0 - np.exp(-60.0 * t))
    np.savetxt(tmp_path / "step.csv", np.c_[t, response], delimiter=",",
               header="t [s],delta [deg]", comments="")
    args = ["fit", str(tmp_path / "step.csv"), "--step", "10deg"]
    first = _run(args, tmp_path / "cache")
    assert first.count(NOTE) == 1 and first.count(SUMMARY) == 1
    assert first.index(NOTE) < first.index(SUMMARY)
    second = _run(args, tmp_path / "cache")  # the kernels now come from the cache
    assert NOTE not in second and SUMMARY not in second
    quiet = _run([*args, "-q"], tmp_path / "quiet")  # compiles again, silently
    assert NOTE not in quiet and SUMMARY not in quiet
    assert list((tmp_path / "quiet").rglob("*.nbi"))  # (it did compile)


@pytest.mark.slow  # run by .ci/run (the suite keeps its CPU budget)
def test_the_api_tells_only_a_configured_logger(tmp_path):
    fit = ("import numpy as np; from cas_freq.simulation import fit_second_order; "
           "t = np.linspace(0, 0.2, 201); fit_second_order(t, 1 - np.exp(-60 * t), 1.0)")
    assert NOTE not in _run(None, tmp_path / "silent", code=fit)
    logged = _run(None, tmp_path / "logged",
                  code="import logging; logging.basicConfig(level=logging.INFO); " + fit)
    assert NOTE in logged


def test_without_a_home_nothing_is_created_in_the_working_folder(monkeypatch, tmp_path):
    # HOME unset and no password entry: expanduser("~") stays "~", which must not become a
    # folder "~/.cache" below the working folder
    monkeypatch.setattr(os.path, "expanduser", lambda path: path)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    assert jit.cache_candidates({"XDG_CACHE_HOME": "relative"}) == [
        tmp_path / f"cas_freq-numba-{os.getuid()}"]


def test_the_users_own_numba_functions_are_not_announced(tmp_path):
    # the listener is process-wide (registered by the first kernel declared; here directly,
    # since declaring one compiles it): a compilation of the user's code is not cas_freq's
    code = ("import logging; logging.basicConfig(level=logging.INFO); import cas_freq.core.jit; "
            "cas_freq.core.jit._listen_to_compilations(); import numba; "
            "numba.njit(lambda x: x + 1)(1)")
    assert NOTE not in _run(None, tmp_path / "cache", code=code)


def _signatures():
    """The argument types each simulation, fit and frequency-domain batch kernel has machine
    code for in this process (compiled, or loaded from numba's cache)."""
    from numba.core.registry import CPUDispatcher

    from cas_freq.analysis import response_kernel
    from cas_freq.simulation import figure_kernel, fit_kernel, kernel

    return {(module.__name__, name, signature)
            for module in (kernel, fit_kernel, figure_kernel, response_kernel)
            for name, function in vars(module).items() if isinstance(function, CPUDispatcher)
            for signature in function.overloads}


def test_the_report_has_the_envelope_workers_kernels_before_it_forks():
    # a first report compiled the kernels again in the figure workers computing the load
    # envelopes: the simulation's (~25 s of CPU each: 70 s against 19 s warm), then, once the
    # report prepared those, the frequency-domain batch's (response_kernel, in each of the two
    # workers at once); build_report now gets them all first (report.workers.prepare_kernels:
    # compiled or from the cache) and the forked workers inherit them: an envelope (2 of its
    # hinge stiffnesses) then needs no other signature
    from cas_freq.config import load_all_variants
    from cas_freq.report.workers import prepare_kernels
    from cas_freq.studies.envelope import load_envelope

    if not jit.use_compiled():
        pytest.skip("numba is not importable: nothing compiles")
    variants = load_all_variants(ROOT / "configs" / "qt_cas.yaml")
    prepare_kernels(variants)
    before = _signatures()
    loaded = next(v for v in variants if v.variant in variants[0].params.load_envelope.variants)
    load_envelope(loaded, [0.0, 10.0], loaded.params.load_envelope.step)
    assert _signatures() - before == set()
    # (the fit's kernels by the names the fit calls; the batch responses, whatever their names)
    assert {name for _, name, _ in before} >= {"advance_parallel", "start_batch",
                                               "normal_equations_of", "lm_trials", "lm_update",
                                               "refine"}
    assert any(module.endswith(".response_kernel") for module, _, _ in before)


def _compiling(seconds, cpu_seconds):
    """A compilation of a cas_freq kernel as numba announces it (its ``numba:compile`` event),
    lasting ``seconds`` [s] of which ``cpu_seconds`` [s] busy; returns the wall and CPU time
    the test measured itself around it."""
    from types import SimpleNamespace

    from numba.core import event

    kernel = SimpleNamespace(py_func=SimpleNamespace(__module__="cas_freq.simulation.kernel"))
    wall, cpu = time.perf_counter(), time.thread_time()
    with event.trigger_event("numba:compile", data={"dispatcher": kernel}):
        while time.thread_time() - cpu < cpu_seconds:
            pass
        time.sleep(max(0.0, seconds - (time.perf_counter() - wall)))
    return time.perf_counter() - wall, time.thread_time() - cpu


def test_the_cli_says_what_compiling_took_so_far_and_in_the_end(monkeypatch):
    # the first line promised "about 25 s" where a first report compiled for 85-133 s (and
    # minutes on a loaded machine): now the time is measured, said while it runs and at the end
    monkeypatch.setattr(jit, "TICK_S", 0.3, raising=False)
    jit._listen_to_compilations()
    jit.compile_summary()  # nothing left over from an earlier test
    lines = []
    jit.compile_messages(lines.append)
    try:
        wall, cpu = _compiling(1.1, 0.3)
        summary = jit.compile_summary()
    finally:
        jit.compile_messages(None)
    assert lines[0].startswith(NOTE) and "about" not in lines[0]  # no estimate
    ticks = [float(re.fullmatch(r"cas-freq: still compiling the numerical kernels "
                                r"\(([\d.]+) s so far\) \.\.\.", line).group(1))
             for line in lines[1:]]
    # every 0.3 s of compiling, at multiples of it (one decimal): 0.3, 0.6, 0.9 s when the
    # ticker is on time; at least two of them on a loaded machine, none beyond the compiling
    assert len(ticks) >= 2 and ticks == sorted(set(ticks)) and ticks[-1] <= wall
    assert all(abs(tick / 0.3 - round(tick / 0.3)) < 0.01 for tick in ticks), ticks
    said = re.fullmatch(r"cas-freq: compiled the numerical kernels in ([\d.]+) s \(CPU "
                        r"([\d.]+) s; runs that need the same kernels load them from the "
                        r"cache\)", summary)
    assert said, summary
    # the wall and CPU time the test measured around the compilation, to the 0.1 s said (the
    # rounding, 0.05 s, and the event's own overhead, well below 0.05 s)
    assert abs(float(said.group(1)) - wall) <= 0.1
    assert abs(float(said.group(2)) - cpu) <= 0.1 and cpu < wall - 0.5
    time.sleep(0.4)  # the ticker is stopped: nothing more is said
    assert len(lines) == 1 + len(ticks)


def test_the_scan_figure_and_fit_kernels_have_one_machine_code_for_any_array_layout():
    # a kernel compiled once per argument types compiled again for a strided view (the step
    # figures of a batch's first columns) or a read-only array (settled_runs' final values):
    # each now has one signature, compiled or loaded on import, which every layout converts to
    from numba.core.registry import CPUDispatcher

    from cas_freq.analysis import scan_kernel
    from cas_freq.simulation import figure_kernel, fit_kernel

    if not jit.use_compiled():
        pytest.skip("numba is not importable: nothing compiles")
    kernels = {name: function for module in (scan_kernel, figure_kernel, fit_kernel)
               for name, function in vars(module).items()
               if isinstance(function, CPUDispatcher)
               and function.targetoptions.get("inline") != "always"}
    assert len(kernels) == 18
    rng = np.random.default_rng(3)
    grid = rng.standard_normal((3, 40)) + 1j * rng.standard_normal((3, 40))
    read_only = grid.copy()
    read_only.flags.writeable = False
    results = []
    for response in (grid, np.asfortranarray(grid), read_only, np.repeat(grid, 2, axis=1)[:, ::2]):
        out = [np.empty(grid.shape) for _ in range(3)]
        scan_kernel.magnitudes(response, *out)
        results.append(out)
    for other in results[1:]:
        np.testing.assert_array_equal(np.array(other), np.array(results[0]))
    t = np.linspace(0.0, 0.04, 40)
    delta = 1.0 - np.exp(-200.0 * t) * np.ones((3, 1))
    final = np.ones(3)
    final.flags.writeable = False
    assert figure_kernel.settled_runs(delta, delta, final, 20, 0.02).all()
    flags = np.zeros((3, 41), dtype=bool)
    table = figure_kernel.step_figures_batch(t, delta, np.full(3, 40), 1.0, delta, delta,
                                             flags[:, :40], flags[:, 1:])
    assert table.shape == (3, 9)
    assert {name: len(function.signatures) for name, function in kernels.items()} == dict.fromkeys(
        kernels, 1)
