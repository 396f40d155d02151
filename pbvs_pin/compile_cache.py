"""Whether Numba's on-disk cache already holds the compiled control kernels.

The kernels (``@njit(cache=True)`` functions of the package's modules) are compiled on their
first call and cached on disk, next to the modules (``__pycache__``) or under
``NUMBA_CACHE_DIR``. The first run on a machine therefore spends about
:data:`COMPILE_SECONDS` compiling before its first step; :func:`compile_notice` says so, once,
and says nothing when the cache is warm. ``pbvs-pin compile`` does
the same compile as an explicit step, right after installing (:mod:`pbvs_pin.cli`).
"""

from __future__ import annotations

import sys
from typing import TextIO

COMPILE_SECONDS = 25
"""Measured cold compile time of a run's kernels on a shared 2-core machine [s]."""

COMPILE_NOTICE = (
    f"compiling the control kernels (once, about {COMPILE_SECONDS} s; "
    "`pbvs-pin compile` does it ahead of a run)"
)
"""What :func:`compile_notice` prints before a cold compile."""


def cached_kernels() -> list:
    """The Numba dispatchers of the imported pbvs_pin modules that are cached on disk.

    Only modules already imported are searched (a run imports every module it calls). Kernels
    declared ``inline="always"`` are inlined into their callers and may never get a
    cache entry of their own, so they are left out.
    """
    from numba.core.caching import FunctionCache
    from numba.core.registry import CPUDispatcher

    kernels = []
    modules = [m for n, m in list(sys.modules.items()) if n.startswith("pbvs_pin.") and m]
    for module in modules:
        for value in vars(module).values():
            if (
                isinstance(value, CPUDispatcher)
                and value.__module__ == module.__name__
                and isinstance(value._cache, FunctionCache)
                and value.targetoptions.get("inline", "never") == "never"
            ):
                kernels.append(value)
    return kernels


def kernels_cached() -> bool:
    """Whether every kernel of :func:`cached_kernels` has a valid on-disk cache index.

    A valid index matches the kernel's current source file (Numba's own stamp check); a
    kernel edited since it was cached counts as not cached. When Numba's cache internals
    cannot be read, the answer is True (better no notice than a wrong one).
    """
    try:
        return all(kernel._cache._cache_file._load_index() for kernel in cached_kernels())
    except (AttributeError, OSError):  # a Numba without these internals
        return True


def compile_notice(stream: TextIO | None = None) -> bool:
    """Print :data:`COMPILE_NOTICE` on ``stream`` (stderr) if the kernels are not cached yet.

    Returns:
        Whether the notice was printed.
    """
    if kernels_cached():
        return False
    print(COMPILE_NOTICE, file=stream or sys.stderr, flush=True)
    return True
