"""JIT options, defined once (STYLE.md: "JIT options defined in one place").

Every hot kernel is a module-level function decorated with :func:`njit` (or
:func:`pnjit` for drivers that use ``prange``). ``cache=True`` lets the many short
processes Snakemake starts reuse compiled code from ``__pycache__``; ``fastmath`` is
off because it breaks NaN checks and bit-for-bit reproducibility.
"""

import numba

JIT_OPTIONS = {"cache": True, "fastmath": False, "nogil": True, "error_model": "numpy"}

njit = numba.njit(**JIT_OPTIONS)
"""Decorator for serial kernels: ``@njit``."""

pnjit = numba.njit(parallel=True, **JIT_OPTIONS)
"""Decorator for drivers that run independent work under ``prange``: ``@pnjit``."""
