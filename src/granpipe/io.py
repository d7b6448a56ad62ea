"""netCDF in and out, provenance, atomic writes (docs/architecture.md, "Files and provenance").

Every data variable and coordinate written by granpipe carries ``units`` and
``long_name``; every file carries global attributes naming the granpipe version,
the git commit, the config subset it depends on (YAML text) and its hash, the
seeds used, and the creation time. Files are written to a temporary name in the
target folder and renamed into place, so a killed job never leaves a partial file
under the final name.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import glob
import os
import subprocess
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path

import numpy as np
import xarray as xr
import yaml

from . import __version__
from .errors import RunFileError
from .seeds import physics_hash

__all__ = [
    "git_commit",
    "provenance_attrs",
    "check_labels",
    "atomic_path",
    "write_dataset",
    "read_dataset",
    "write_text",
    "config_from_attrs",
    "config_hash",
    "expect_attrs",
    "check_run_files",
    "RunFileError",
]

_ENGINE = "netcdf4"


def git_commit() -> str:
    """The git commit of the granpipe source tree, or ``"unknown"``."""
    env = os.environ.get("GRANPIPE_GIT_COMMIT")
    if env:
        return env
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        )
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=here,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
        return out.stdout.strip() + ("-dirty" if dirty else "")
    except (OSError, subprocess.SubprocessError):
        return "unknown"


def provenance_attrs(
    config_subset: Mapping | None = None,
    seeds: Sequence[int] | int | None = None,
    **extra,
) -> dict:
    """Global attributes (docs/architecture.md) for a file computed from ``config_subset``.

    Parameters
    ----------
    config_subset : mapping, optional
        The exact configuration the file depends on; stored as YAML text together
        with the hash used for seeding (:func:`granpipe.seeds.physics_hash`).
    seeds : int or sequence of int, optional
        Seeds of the replicas in the file.
    extra : str, int or float
        More attributes (study, stage, point, ...).
    """
    subset = dict(config_subset or {})
    attrs = {
        "granpipe_version": __version__,
        "git_commit": git_commit(),
        "config_yaml": yaml.safe_dump(_plain(subset), sort_keys=True),
        "config_hash": config_hash(subset),
        "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "Conventions": "CF-1.8",
    }
    if seeds is not None:
        seeds = [int(s) for s in np.atleast_1d(seeds)]
        # netCDF attributes hold no 64-bit unsigned ints portably; store as text.
        attrs["seeds"] = " ".join(str(s) for s in seeds)
    for key, value in extra.items():
        attrs[key] = value if isinstance(value, (str, int, float)) else str(value)
    return attrs


def config_hash(config_subset: Mapping) -> str:
    """The ``config_hash`` attribute a file computed from ``config_subset`` carries."""
    return physics_hash(_plain(dict(config_subset)))


def expect_attrs(ds: xr.Dataset, path: str | os.PathLike, **want) -> None:
    """Check that ``ds`` (read from ``path``) carries the attributes ``want`` (compared as
    text, so 0.6 and "0.6" agree); RunFileError names the file, the key and both values."""
    for key, value in want.items():
        have = ds.attrs.get(key)
        if have is None or str(have) != str(value):
            raise RunFileError(
                f"{path} is not the expected input: attribute {key} = {have!r}, expected {value!r}"
            )


def _plain(obj):
    """Convert numpy scalars/arrays and tuples inside a mapping into YAML-safe builtins."""
    if isinstance(obj, Mapping):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def config_from_attrs(ds: xr.Dataset) -> dict:
    """The config subset stored in a file's ``config_yaml`` attribute."""
    return yaml.safe_load(ds.attrs.get("config_yaml", "{}")) or {}


def check_labels(ds: xr.Dataset) -> None:
    """Raise ``ValueError`` if a variable or coordinate lacks ``units`` or ``long_name``."""
    missing = []
    for name, var in {**ds.data_vars, **ds.coords}.items():
        for attr in ("units", "long_name"):
            if attr not in var.attrs:
                missing.append(f"{name}.{attr}")
    if missing:
        raise ValueError(
            "netCDF variables must carry units and long_name; missing: " + ", ".join(missing)
        )


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success.

    On any exception (or if the process dies) the final name is never created or
    touched; the temporary file is removed where possible, and one left by a killed
    earlier attempt at the same path is removed when the next attempt starts.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    # temporary files of an earlier attempt at this same file that was killed (SIGKILL
    # skips the cleanup below); the workflow never writes one file from two jobs at once
    for stale in path.parent.glob(f".{glob.escape(path.name)}.*.tmp"):
        stale.unlink(missing_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(fd)
    tmp = Path(tmp)
    try:
        yield tmp
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        _fault_injection_pause()
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def _fault_injection_pause() -> None:
    """Sleep ``GRANPIPE_FAULT_DELAY_RENAME`` seconds between write and rename.

    A fault-injection hook for the workflow tests: it holds a finished temporary file
    in place long enough for a test to SIGKILL the job mid-write. Unset in normal runs.
    """
    delay = os.environ.get("GRANPIPE_FAULT_DELAY_RENAME")
    if delay:
        import time

        time.sleep(float(delay))


def write_dataset(
    ds: xr.Dataset,
    path: str | os.PathLike,
    *,
    config_subset: Mapping | None = None,
    seeds: Sequence[int] | int | None = None,
    **extra_attrs,
) -> Path:
    """Write ``ds`` to netCDF-4 at ``path`` atomically, with provenance attributes.

    Every variable and coordinate must carry ``units`` and ``long_name``
    (:func:`check_labels`). Data variables are zlib-compressed losslessly.
    """
    check_labels(ds)
    ds = ds.copy()
    ds.attrs = {**ds.attrs, **provenance_attrs(config_subset, seeds, **extra_attrs)}
    encoding = {
        name: {"zlib": True, "complevel": 4}
        for name, var in ds.data_vars.items()
        if var.dtype.kind in "fiub"
    }
    with atomic_path(path) as tmp:
        ds.to_netcdf(tmp, engine=_ENGINE, format="NETCDF4", encoding=encoding)
    return Path(path)


def read_dataset(path: str | os.PathLike) -> xr.Dataset:
    """Read a netCDF file fully into memory and close it.

    Raises
    ------
    RunFileError
        naming the file, if it is missing or not a readable netCDF file.
    """
    try:
        with xr.open_dataset(path, engine=_ENGINE) as ds:
            return ds.load()
    except (OSError, ValueError, RuntimeError) as exc:
        raise RunFileError(f"cannot read {path}: {exc}") from exc


def _batch_of(path: Path) -> int | None:
    stem = path.stem
    if stem.startswith("batch_") and stem[6:].isdigit():
        return int(stem[6:])
    return None


def check_run_files(
    paths: Sequence[str | os.PathLike], *, study: str, stage: str = "runs"
) -> list[dict]:
    """Check that run files belong together before they are reduced; return their labels.

    Every file must be readable, written by ``study``'s stage ``stage``, with the same
    config hash (the same point and physics) as the first; a file named ``batch_<b>.nc``
    must hold batch ``b``; no replica index may appear twice across the files.

    Returns
    -------
    list of ``{"path", "batch", "replicas", "config_hash"}``, one per file.

    Raises
    ------
    RunFileError
        naming the offending file (and the other file, for a duplicate or a mismatch).
    """
    out: list[dict] = []
    seen: dict[int, str] = {}
    for p in map(Path, paths):
        try:
            with xr.open_dataset(p, engine=_ENGINE) as ds:
                attrs = dict(ds.attrs)
                replicas = [int(r) for r in ds["replica"].values] if "replica" in ds else []
        except (OSError, ValueError, RuntimeError) as exc:
            raise RunFileError(f"cannot read {p}: {exc}") from exc
        for key, want in (("study", study), ("stage", stage)):
            if attrs.get(key) != want:
                raise RunFileError(
                    f"{p} is not a {study} {stage} file ({key} = {attrs.get(key)!r})"
                )
        if out and attrs.get("config_hash") != out[0]["config_hash"]:
            raise RunFileError(
                f"{p} was computed with another configuration (config hash "
                f"{str(attrs.get('config_hash'))[:12]}) than {out[0]['path']} "
                f"({out[0]['config_hash'][:12]}): another point or changed physics"
            )
        named = _batch_of(p)
        batch = attrs.get("batch")
        if named is not None and batch is not None and int(batch) != named:
            raise RunFileError(f"{p} holds batch {batch}, not batch {named} as its name says")
        for r in replicas:
            if r in seen:
                raise RunFileError(f"replica {r} appears twice: in {seen[r]} and in {p}")
            seen[r] = str(p)
        out.append(
            {"path": str(p), "batch": batch, "replicas": replicas,
             "config_hash": str(attrs.get("config_hash"))}
        )  # fmt: skip
    return out


def write_text(text: str, path: str | os.PathLike) -> Path:
    """Write a text file (CSV, YAML) atomically."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)
    return Path(path)
