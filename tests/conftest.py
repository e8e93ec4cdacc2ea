"""Shared fixtures: temporary config files, the shipped config's raw data, and headless Chromium
(found on PATH; never installed here: tests do not change the machine)."""

import copy
import shutil
from pathlib import Path

import pytest
import yaml

from cas_freq.config import default_config_path, read_config_file


@pytest.fixture(scope="session", autouse=True)
def _no_compile_messages_in_process():
    """The CLI's first-compilation lines (cas_freq.core.jit) silenced for commands run in this
    process: whether a test's command compiles depends on the order the tests ran in and on
    numba's cache, and many tests check stderr exactly. tests/test_jit_cache.py checks the
    messages in processes of their own."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("cas_freq.cli._say", lambda text: None)
        yield


#: Sessions of this many tests or more get the simulation kernels first (the whole suite has
#: ~2,200).
WARM_UP_FROM = 200


@pytest.fixture(scope="session", autouse=True)
def _kernels_prepared_first(_no_compile_messages_in_process, request):
    """The numba kernels, which serve every shipped config's variants, loaded (or compiled
    where numba's cache has none) at the session's start, before any test runs them: the
    simulation's (:func:`~cas_freq.simulation.simulator.prepare_kernels`) and the
    frequency-domain batch's (:func:`~cas_freq.report.workers.prepare_frequency_kernels`),
    each compiled in a thread of its own, not deep in pytest's call stack (see their
    docstrings). With a warm cache this loads the machine code, about 1 s. A session of fewer
    than :data:`WARM_UP_FROM` tests (one file, one test) compiles only what it runs.
    """
    if len(request.session.items) >= WARM_UP_FROM:
        from cas_freq.config import load_variant
        from cas_freq.report.workers import prepare_frequency_kernels
        from cas_freq.simulation.simulator import prepare_kernels

        # the kernels take the architecture, sampling and load as data: one variant (with
        # continuous controllers, which the frequency-domain kernels evaluate) serves them all
        params = load_variant(default_config_path()).params
        prepare_kernels(params)
        prepare_frequency_kernels(params)
    yield


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


@pytest.fixture(params=["reference", "compiled"])
def engine(request, monkeypatch):
    """Both paths of the grid scans (margins and crossings tests): numpy, and the numba
    kernels forced on small arrays."""
    monkeypatch.setenv("CAS_FREQ_ENGINE", request.param)
    if request.param == "compiled":
        from cas_freq.core.jit import use_compiled

        monkeypatch.setattr("cas_freq.core.jit.COMPILED_FROM", 0)
        if not use_compiled():
            pytest.skip("numba is not importable: the compiled path cannot run")
    return request.param


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

#: Chromium's executables, in the order looked for (the names .ci/install_chromium.py installs
#: and checks for).
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium():
    """Path of a Chromium executable on PATH, or None."""
    return next(filter(None, (shutil.which(name) for name in CHROMIUM_NAMES)), None)


def chromium_or_skip():
    """Path of Chromium, or skip the calling test saying why. Never installs it: tests do not
    change the machine (``.ci/run`` installs it first, with .ci/install_chromium.py)."""
    path = find_chromium()
    if path is None:
        pytest.skip(f"headless-browser check: Chromium is not installed (none of "
                    f"{', '.join(CHROMIUM_NAMES)} on PATH); `python .ci/install_chromium.py` "
                    "installs it (as root, with apt-get)")
    return path


@pytest.fixture(scope="session")
def chromium():
    """Path of headless-capable Chromium; the test is skipped, saying why, where it is
    missing (:func:`chromium_or_skip`)."""
    return chromium_or_skip()
