"""granpipe: granular-dynamics studies (drum, column, box) as a Snakemake workflow.

The library is organised as docs/architecture.md describes: ``engine`` (jitted 2D DEM kernels),
one package per study (``drum``, ``column``, ``box``), ``analysis`` (ensemble
reduction, fits, bootstrap), ``io`` (netCDF with provenance, atomic writes),
``figures`` (one function per figure), ``config`` and ``seeds``.
"""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("granpipe")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0+unknown"

__all__ = ["__version__"]
