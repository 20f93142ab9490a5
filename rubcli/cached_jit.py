"""numba's ``njit`` with its on-disk cache wherever numba can keep one.

Every compiled function of rubcli is cached (``cache=True``): the first process on a
machine compiles, later ones load the machine code. numba keeps that cache in the
``__pycache__`` beside the source, else in the user's cache dir (``~/.cache/numba``, or
``NUMBA_CACHE_DIR``). When it can write neither (a system-wide install run by a user
without a writable home), numba refuses to make a cached function at all. ``njit`` then
compiles the function uncached (again in every process) and warns once, naming the remedy.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from typing import Any

import numba

_warned = [False]


def njit(**flags: Any) -> Callable[[Callable[..., Any]], Any]:
    """``numba.njit(cache=True, **flags)``; uncached, with a warning, where numba has no
    writable cache dir."""
    cached = numba.njit(cache=True, **flags)

    def decorate(func: Callable[..., Any]) -> Any:
        try:
            return cached(func)
        except RuntimeError as exc:  # numba: "cannot cache function ...: no locator"
            if "no locator available" not in str(exc):
                raise
        if not _warned[0]:
            _warned[0] = True
            warnings.warn(
                "rubcli: numba can write no cache (the package's __pycache__ and the user "
                "cache dir are read-only): the kernels are compiled uncached, in every run; "
                "set NUMBA_CACHE_DIR to a writable dir to keep them",
                RuntimeWarning,
                stacklevel=2,
            )
        return numba.njit(cache=False, **flags)(func)

    return decorate
