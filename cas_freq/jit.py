"""Compiled code in cas_freq: numba's ``njit`` as the kernels use it, and the engine choice.

Every compiled kernel has a numpy reference it is tested against: the simulation loop
(:mod:`cas_freq.simulation.kernel`), the second-order fit's sums
(:mod:`cas_freq.simulation.fit_kernel`), and, for large batches only (:data:`COMPILED_FROM`),
the analysis' grid responses and scans (:mod:`cas_freq.analysis.response_kernel`,
:mod:`cas_freq.analysis.scan_kernel`). ``CAS_FREQ_ENGINE=reference`` (or ``engine="reference"``
where a function takes it) runs the references instead, as does a machine without numba; numba
is imported only by the kernels' modules.
"""

import functools
import os

from cas_freq.exceptions import ConfigError

#: Environment variable choosing the engine: ``compiled`` (default) or ``reference``.
ENGINE_ENV = "CAS_FREQ_ENGINE"
#: Engines: the numba kernels and the numpy references.
ENGINES = ("compiled", "reference")
#: Array size (points) from which the frequency-domain analysis uses its compiled kernels:
#: below it numpy is about as fast, and a single analysis needs no numba.
COMPILED_FROM = 65_536


def engine_name(requested=None):
    """The engine to use: ``requested``, else ``$CAS_FREQ_ENGINE``, else compiled.

    Parameters
    ----------
    requested : {"compiled", "reference"} or None
        The caller's choice.

    Returns
    -------
    str
        ``"compiled"`` or ``"reference"``.

    Raises
    ------
    ConfigError
        For another name (naming where it came from).
    """
    source = "engine"
    if requested is None:
        requested = os.environ.get(ENGINE_ENV, "").strip().lower() or "compiled"
        source = ENGINE_ENV
    if requested not in ENGINES:
        raise ConfigError(f"{source}: expected one of {', '.join(ENGINES)}, got {requested!r}")
    return requested


def use_compiled():
    """True where the compiled kernels should run: the compiled engine chosen
    (:func:`engine_name`) and numba importable (else the numpy references run, with the same
    results)."""
    return engine_name() == "compiled" and _numba_installed()


def compiled_for(points):
    """:func:`use_compiled`, for an analysis step on ``points`` array points: only from
    :data:`COMPILED_FROM` points."""
    return points >= COMPILED_FROM and use_compiled()


@functools.cache
def _numba_installed():
    """numba imports (an installed numba can fail to, e.g. against a newer numpy)."""
    try:
        import numba  # noqa: F401
    except Exception:  # noqa: BLE001  (any failure to import means: no compiled kernels)
        return False
    return True


def cached_jit(**options):
    """``numba.njit`` with ``cache=True``; without a cache if no cache directory is usable.

    ``error_model="numpy"``: a division by zero gives inf or nan, as in the numpy code each
    kernel mirrors, instead of raising.
    """
    from numba import njit

    def decorate(function):
        try:
            return njit(cache=True, error_model="numpy", **options)(function)
        except RuntimeError:  # numba: "cannot cache function ...: no locator available"
            return njit(cache=False, error_model="numpy", **options)(function)

    return decorate
