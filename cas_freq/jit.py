"""Compiled code in cas_freq: numba's ``njit`` as the kernels use it, and the engine choice.

Every compiled kernel (the simulation loop, the second-order fit's sums, the frequency
responses of large batches) has a numpy reference it is tested against.
``CAS_FREQ_ENGINE=reference`` (or ``engine="reference"`` where a function takes it) runs the
reference instead; numba is imported only by the kernels' modules.
"""

import functools
import importlib.util
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


def compiled_for(points):
    """True where an analysis step on ``points`` array points should take its compiled kernel:
    at least :data:`COMPILED_FROM` points, the compiled engine chosen (:func:`engine_name`) and
    numba installed (else the numpy reference runs, with the same results)."""
    return (points >= COMPILED_FROM and engine_name() == "compiled"
            and _numba_installed())


@functools.cache
def _numba_installed():
    return importlib.util.find_spec("numba") is not None


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
