"""Numba's on-disk cache of the compiled kernels: keyed on every kernel's source, and warm or not.

The kernels (``@njit(cache=True)`` functions of the package's modules) are compiled on their
first call and cached on disk. The first run on a machine therefore spends about
:data:`COMPILE_SECONDS` compiling before its first step; :func:`announce_compiles` says so,
once, when a kernel really compiles (Numba's ``numba:compile`` event, which fires only after
the disk cache missed), and says nothing when the cache is warm. ``pbvs-pin compile`` does the
same compile as an explicit step, right after installing (:mod:`pbvs_pin.cli`).

**The cache key.** Importing this module (the package's ``__init__`` does, before any other
module) keys the cache. Numba checks a cached kernel against its own source file only, but the
fused control step compiles into itself kernels of other modules (``inline="always"``): after
an edit of one of those, a warm cache would run the old code. :func:`use_keyed_cache`
therefore places the cache in a
folder named by :func:`cache_key`, a hash of every module that declares a kernel, Numba's
version and Python's: any edit of any kernel's source makes a new, cold cache. The folder is
under ``NUMBA_CACHE_DIR`` when it is set, else under the user's cache folder
(``$XDG_CACHE_HOME`` or ``~/.cache``, then ``pbvs_pin/numba``).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import platform
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TextIO

from numba.core import event

PACKAGE = Path(__file__).resolve().parent
"""The installed package's folder."""


def kernel_modules(package: Path = PACKAGE) -> list[Path]:
    """The package's source files that declare a compiled kernel, in path order."""
    return sorted(
        path for path in package.rglob("*.py") if "@njit" in path.read_text(encoding="utf-8")
    )


def cache_key(package: Path = PACKAGE) -> str:
    """16 hex digits hashing every kernel module's path and text and Numba's and Python's versions.

    It changes whenever any compiled code can.
    """
    import numba

    digest = hashlib.sha256(f"{numba.__version__} {platform.python_version()}".encode())
    for path in kernel_modules(package):
        digest.update(str(path.relative_to(package)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_root() -> Path:
    """The folder under which the keyed caches live."""
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        return Path(given)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "pbvs_pin" / "numba"


def use_keyed_cache() -> Path:
    """Point Numba's cache at ``cache_root() / cache_key()``; return that folder."""
    from numba.core import config

    folder = cache_root() / cache_key()
    config.CACHE_DIR = str(folder)
    return folder


KEYED_CACHE = use_keyed_cache()
"""The folder of this package's compiled kernels (set when the module is imported)."""

COMPILE_SECONDS = 45
"""Measured cold compile time of a run's kernels on a shared 2-core machine [s]."""

COMPILE_NOTICE = (
    f"compiling the control kernels (once, about {COMPILE_SECONDS} s; "
    "`pbvs-pin compile` does it ahead of a run)"
)
"""What :func:`announce_compiles` prints when a kernel compiles."""


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


class CompileAnnouncer(event.Listener):
    """Prints :data:`COMPILE_NOTICE` at the first compile of one of the package's kernels.

    A listener of Numba's ``numba:compile`` event, which Numba raises only when it compiles
    (after its disk cache missed), never when it loads a cached kernel.

    Args:
        stream: Where the notice goes (stderr when None).
        enabled: Print the notice (else only :attr:`compiled` is kept).

    Attributes:
        compiled: How many of the package's kernels compiled while it listened.
    """

    def __init__(self, stream: TextIO | None = None, enabled: bool = True) -> None:
        self.stream, self.enabled, self.compiled = stream, enabled, 0

    def on_start(self, compile_event: object) -> None:
        """A compile starts: announce it if it is the package's first."""
        function = getattr(compile_event.data["dispatcher"], "py_func", None)
        if not getattr(function, "__module__", "").startswith(PACKAGE.name):
            return
        self.compiled += 1
        if self.compiled == 1 and self.enabled:
            print(COMPILE_NOTICE, file=self.stream or sys.stderr, flush=True)

    def on_end(self, compile_event: object) -> None:
        """A compile ended (nothing to do)."""


@contextlib.contextmanager
def announce_compiles(
    enabled: bool = True, stream: TextIO | None = None
) -> Iterator[CompileAnnouncer]:
    """Within the block, print :data:`COMPILE_NOTICE` once if a package kernel compiles.

    Args:
        enabled: Print the notice; False only counts the compiles.
        stream: Where the notice goes (stderr when None).

    Yields:
        The listener: its ``compiled`` counts the package's kernels compiled in the block.
    """
    announcer = CompileAnnouncer(stream, enabled)
    with event.install_listener("numba:compile", announcer):
        yield announcer
