"""numba's ``njit`` as cas_freq compiles its kernels: cached on disk, numpy's error model."""

from numba import njit


def cached_jit(**options):
    """``numba.njit`` with ``cache=True``; without a cache if no cache directory is usable.

    ``error_model="numpy"``: a division by zero gives inf or nan, as in the numpy code each
    kernel mirrors, instead of raising.
    """

    def decorate(function):
        try:
            return njit(cache=True, error_model="numpy", **options)(function)
        except RuntimeError:  # numba: "cannot cache function ...: no locator available"
            return njit(cache=False, error_model="numpy", **options)(function)

    return decorate
