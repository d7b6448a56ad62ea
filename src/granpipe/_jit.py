"""JIT options, defined once, and an on-disk cache that notices every edit.

Every hot kernel is a module-level function decorated with :func:`njit` (or
:func:`pnjit` for drivers that use ``prange``). ``cache=True`` lets the many short
processes Snakemake starts reuse compiled code from ``__pycache__``; ``fastmath`` is
off because it breaks NaN checks and bit-for-bit reproducibility.

**Stale caches.** numba stamps a cached function with a hash of *its own* source file
only, so editing a function in another file that it calls (a contact law called by
the pair pass, an intrinsic of ``simd.py``) would leave the old machine code in use.
:class:`SourceTreeCacheLocator` stamps every function of the jitted sources
(:data:`JIT_SOURCES`) with one hash of all of them: an edit to any of them recompiles
every kernel in the next process. It is registered first among numba's locators when
this module is imported, which every kernel module does before defining a kernel.
"""

from __future__ import annotations

import functools
import hashlib
import os
from pathlib import Path

import llvmlite.binding as llvm
import numba
from numba.core import caching

__all__ = ["JIT_OPTIONS", "JIT_SOURCES", "njit", "njit_inline", "pnjit", "SourceTreeCacheLocator"]

PACKAGE = Path(__file__).resolve().parent

JIT_SOURCES = ("_jit.py", "engine/**/*.py", "column/discrete.py", "column/continuum.py")
"""The files, relative to the package, whose code jitted kernels compile or call."""


def _jit_files() -> list[Path]:
    files = set()
    for pattern in JIT_SOURCES:
        files.update(PACKAGE.glob(pattern))
    return sorted(p for p in files if p.is_file())


@functools.cache
def _tree_hash(stamps: tuple) -> bytes:
    h = hashlib.sha256()
    for name, _, _ in stamps:
        h.update(name.encode())
        h.update(Path(name).read_bytes())
    return h.digest()


def source_tree_stamp() -> bytes:
    """SHA-256 over the names and contents of :data:`JIT_SOURCES` (re-read when a file's
    modification time or size changes)."""
    stamps = tuple((str(p), *_stat(p)) for p in _jit_files())
    return _tree_hash(stamps)


def _stat(path: Path) -> tuple:
    st = os.stat(path)
    return st.st_mtime_ns, st.st_size


class SourceTreeCacheLocator(caching.InTreeCacheLocator):
    """numba's in-tree cache (``__pycache__`` beside the source, or ``NUMBA_CACHE_DIR``
    when set) for the package's jitted sources, stamped with :func:`source_tree_stamp`
    instead of the one file's hash."""

    def __init__(self, py_func, py_file):
        super().__init__(py_func, py_file)
        if numba.config.CACHE_DIR:
            sub = self.get_suitable_cache_subpath(py_file)
            self._cache_path = os.path.join(numba.config.CACHE_DIR, sub)

    def get_source_stamp(self):
        return source_tree_stamp()

    @classmethod
    def from_function(cls, py_func, py_file):
        path = Path(py_file).resolve()
        if path not in _jit_files():
            return None
        return super().from_function(py_func, py_file)


if SourceTreeCacheLocator not in caching.CacheImpl._locator_classes:
    caching.CacheImpl._locator_classes.insert(0, SourceTreeCacheLocator)

JIT_OPTIONS = {"cache": True, "fastmath": False, "nogil": True, "error_model": "numpy"}
"""``error_model="numpy"``: a division by zero gives inf instead of raising, so the
``1/r`` of the pair loops does not block LLVM's vectoriser (with numba's default model
the drum law's rows ran at 6.4 ns per pair instead of 0.77)."""

# LLVM's loop vectoriser gives up on a loop whose arrays it cannot prove apart when that
# would take more than 128 run-time overlap checks (LLVM's default). The law's rows under
# tangent dynamics of a law with spin and history read and write some thirty rows of the
# pair buffer (numba cannot tell LLVM they do not alias) and need about 300: allow them.
# The checks run once per loop, before thousands of pairs.
llvm.set_option("granpipe", "-vectorize-memory-check-threshold=1024")

njit = numba.njit(**JIT_OPTIONS)
"""Decorator for serial kernels: ``@njit``."""

njit_inline = numba.njit(inline="always", **JIT_OPTIONS)
"""Decorator for small helpers called in a step loop, inlined by numba into their callers
(``@njit_inline``): as plain calls the column's chain ran 5-25 % slower and the engine's
row loops 1-5 % (docs/engine_performance.md, round 13)."""

pnjit = numba.njit(parallel=True, **JIT_OPTIONS)
"""Decorator for drivers that run independent work under ``prange``: ``@pnjit``."""
