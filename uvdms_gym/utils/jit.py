"""The project's numba entry point: ``njit`` with the disk cache when numba has somewhere to write it."""

from __future__ import annotations

import logging
from collections.abc import Callable

import numba

_LOG = logging.getLogger(__name__)


def jit(fn: Callable) -> Callable:
    """``numba.njit(cache=True)``, or without the disk cache if numba's cache location is not writable.

    numba picks the cache directory when the function is decorated but writes to it only after the first
    compilation, so an unusable location would fail inside the first call; it is probed here with numba's own
    check (create the directory, write a temporary file). On failure the kernel compiles in every process.
    Kernels are compiled without fastmath: no reassociation and no fused multiply-add, so a kernel that
    transcribes a float expression gives the same bits as Python or numpy evaluating it.
    """
    try:
        disp = numba.njit(cache=True)(fn)
        disp._cache._impl.locator.ensure_cache_path()
    except (RuntimeError, OSError) as exc:  # "cannot cache function ...: no locator available", read-only dir
        _LOG.warning("numba disk cache unavailable (%s); %s compiles in every process", exc, fn.__name__)
        return numba.njit(fn)
    except AttributeError:  # numba internals moved: keep caching, numba reports problems itself
        pass
    return disp
