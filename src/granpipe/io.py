"""netCDF in and out, provenance, atomic writes (docs/architecture.md, "Files and provenance").

Every data variable and coordinate written by granpipe carries ``units`` and
``long_name``; every file carries global attributes naming the granpipe version,
the git commit, the config subset it depends on (YAML text) and its hash, the
seeds used, and the creation time. Files are written to a temporary name in the
target folder, read back, made readable as the umask allows, and renamed into place,
so a killed job or a full disk never leaves a partial file under the final name; a
write that fails names the file and the operating system's reason
(:class:`~granpipe.errors.WriteError`).

A stage reads only the files it was asked for: :func:`expect_input` and
:func:`check_run_files` compare each input's recorded study, stage, point and config
hash with the ones the stage derives from its own ``--params``
(:class:`~granpipe.errors.RunFileError` names the file and both values).
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import errno as _errno
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
from .errors import RunFileError, WriteError
from .seeds import physics_hash

__all__ = [
    "git_commit",
    "provenance_attrs",
    "check_labels",
    "atomic_path",
    "write_dataset",
    "read_dataset",
    "open_input",
    "write_text",
    "config_from_attrs",
    "config_hash",
    "expect_input",
    "check_run_files",
    "RunFileError",
    "WriteError",
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


# ------------------------------------------------------------------------ writing
def _os_reason(exc: OSError) -> str:
    """``No space left on device (ENOSPC)``: the OS error's text and symbolic name."""
    name = _errno.errorcode.get(exc.errno or 0)
    text = exc.strerror or str(exc)
    return f"{text} ({name})" if name else text


def _umask() -> int:
    """The process's umask (read without changing it where Linux allows)."""
    with contextlib.suppress(OSError, ValueError):
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path in the target's folder; rename it onto ``path`` on success.

    On any exception (or if the process dies) the final name is never created or
    touched; the temporary file is removed where possible, and one left by a killed
    earlier attempt at the same path is removed when the next attempt starts. The file
    gets the permissions an ordinary ``open`` would give it (0666 less the umask), not
    the private 0600 of a temporary file. An operating-system error while creating,
    writing or renaming it (a full disk, a file-size limit, a folder without write
    permission) raises :class:`~granpipe.errors.WriteError` naming ``path`` and the
    reason.
    """
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        # temporary files of an earlier attempt at this same file that was killed (SIGKILL
        # skips the cleanup below); the workflow never writes one file from two jobs at once
        for stale in path.parent.glob(f".{glob.escape(path.name)}.*.tmp"):
            stale.unlink(missing_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise WriteError(f"cannot write {path}: {_os_reason(exc)}") from None
    tmp = Path(tmp)
    try:
        try:
            yield tmp
            with open(tmp, "rb") as fh:
                os.fsync(fh.fileno())
            os.chmod(tmp, 0o666 & ~_umask())
            _fault_injection_pause()
            os.replace(tmp, path)
        except OSError as exc:
            raise WriteError(f"cannot write {path}: {_os_reason(exc)}") from None
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


def _netcdf_bytes(ds: xr.Dataset, encoding: Mapping) -> memoryview:
    """The netCDF-4 file of ``ds`` built in memory (written to disk by Python, whose
    errors carry the operating system's reason, where the netCDF library's do not)."""
    import netCDF4

    nc = netCDF4.Dataset("granpipe.nc", "w", memory=1, format="NETCDF4")
    try:
        ds.dump_to_store(xr.backends.NetCDF4DataStore(nc), encoding=encoding)
    except BaseException:
        nc.close()
        raise
    return nc.close()


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
    (:func:`check_labels`). Data variables are zlib-compressed losslessly. The file is
    read back before it takes its final name: one that does not hold what was written
    raises :class:`~granpipe.errors.WriteError`, and the final name is never touched.
    """
    check_labels(ds)
    ds = ds.copy()
    ds.attrs = {**ds.attrs, **provenance_attrs(config_subset, seeds, **extra_attrs)}
    encoding = {
        name: {"zlib": True, "complevel": 4}
        for name, var in ds.data_vars.items()
        if var.dtype.kind in "fiub"
    }
    data = _netcdf_bytes(ds, encoding)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(data)
        try:
            with xr.open_dataset(tmp, engine=_ENGINE) as back:
                same = back.load().drop_attrs().equals(ds.drop_attrs())
        except (OSError, ValueError, RuntimeError) as exc:
            raise WriteError(f"cannot write {path}: it does not read back ({exc})") from None
        if not same:
            raise WriteError(f"cannot write {path}: it does not read back as written")
    return Path(path)


def write_text(text: str, path: str | os.PathLike) -> Path:
    """Write a text file (CSV, YAML) atomically; it is read back before its rename."""
    with atomic_path(path) as tmp:
        Path(tmp).write_text(text)
        if Path(tmp).read_text() != text:
            raise WriteError(f"cannot write {path}: it does not read back as written")
    return Path(path)


# ------------------------------------------------------------------------ reading
def _unreadable(path, exc: BaseException) -> RunFileError:
    """The one message for an input that cannot be read: its name, the reason, and, for
    a file that exists but is not a readable netCDF file, what to do."""
    if isinstance(exc, OSError) and exc.errno and exc.errno > 0:
        return RunFileError(f"cannot read {path}: {_os_reason(exc)}")
    reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
    return RunFileError(
        f"cannot read {path}: {reason}. The file is damaged (truncated or overwritten) or not "
        "a granpipe file: remove it and rerun, and the workflow computes it again, "
        "bit-identically"
    )


@contextlib.contextmanager
def open_input(path: str | os.PathLike) -> Iterator[xr.Dataset]:
    """Open a netCDF input lazily; a file that cannot be opened or whose data cannot be
    read raises :class:`~granpipe.errors.RunFileError` naming it and what to do."""
    try:
        ds = xr.open_dataset(path, engine=_ENGINE)
    except (OSError, ValueError, RuntimeError) as exc:
        raise _unreadable(path, exc) from None
    with ds:
        try:
            yield ds
        except (OSError, RuntimeError) as exc:  # a damaged chunk met while reading data
            raise _unreadable(path, exc) from None


def read_dataset(path: str | os.PathLike) -> xr.Dataset:
    """Read a netCDF file fully into memory and close it.

    Raises
    ------
    RunFileError
        naming the file, if it is missing or not a readable netCDF file.
    """
    with open_input(path) as ds:
        return ds.load()


def expect_input(
    ds: xr.Dataset | Mapping,
    path: str | os.PathLike,
    *,
    study: str,
    stage: str,
    point: str | None = None,
    config_hash: str | None = None,
    variables: Sequence[str] = (),
    **want,
) -> None:
    """Check that the file ``path`` (its dataset or attributes ``ds``) is the input the
    stage was asked for: written by ``study``'s stage ``stage``, for ``point`` and from
    the config subset whose hash is ``config_hash`` (each as the stage derives it from its
    own ``--params``; ``None``: not checked), with the attributes ``want`` (compared as
    text, so 0.6 and "0.6" agree) and the ``variables`` the stage reads (``ds`` a
    dataset; a file an earlier granpipe wrote may lack one: the rule is named to recompute
    it).

    Raises
    ------
    RunFileError
        naming the file, the attribute, the value it holds and the value expected.
    """
    attrs = ds.attrs if isinstance(ds, xr.Dataset) else ds
    for key, value in (("study", study), ("stage", stage)):
        if attrs.get(key) != value:
            raise RunFileError(
                f"{path} is not a {study} {stage} file (it says study = "
                f"{attrs.get('study')!r}, stage = {attrs.get('stage')!r})"
            )
    if point is not None and str(attrs.get("point")) != str(point):
        raise RunFileError(
            f"{path} belongs to point {attrs.get('point')!r}, not to {point!r}, the point this "
            "stage was asked for"
        )
    for key, value in want.items():
        have = attrs.get(key)
        if have is None or str(have) != str(value):
            raise RunFileError(
                f"{path} is not the expected input: attribute {key} = {have!r}, expected {value!r}"
            )
    if config_hash is not None and attrs.get("config_hash") != config_hash:
        what = f" of point {point!r}" if point is not None else ""
        raise RunFileError(
            f"{path} was computed from another configuration (config hash "
            f"{str(attrs.get('config_hash'))[:12]}) than the one this stage was asked for"
            f"{what} ({config_hash[:12]}): another point's file, or one computed before the "
            "physics changed"
        )
    missing = [v for v in variables if v not in ds.variables] if variables else []
    if missing:
        raise RunFileError(
            f"{path} holds no {', '.join(map(repr, missing))}: it was written by an earlier "
            f"granpipe ({attrs.get('granpipe_version', 'unknown version')}) whose {study} "
            f"{stage} stage did not record it; recompute it: snakemake --forcerun "
            f"{study}_{stage} (or delete the file)"
        )


def _batch_of(path: Path) -> int | None:
    stem = path.stem
    if stem.startswith("batch_") and stem[6:].isdigit():
        return int(stem[6:])
    return None


def check_run_files(
    paths: Sequence[str | os.PathLike],
    *,
    study: str,
    config_hash: str,
    point: str | None = None,
    stage: str = "runs",
    variables: Sequence[str] = (),
    **want,
) -> list[dict]:
    """Check that run files are the ones a stage was asked for before it reduces them;
    return their labels.

    Every file must be readable, written by ``study``'s stage ``stage`` for ``point``
    (if given) from the config subset whose hash is ``config_hash`` (both as the stage
    derives them from its own ``--params``, never from another input); a file named
    ``batch_<b>.nc`` must hold batch ``b``; no replica index may appear twice across
    the files; further attributes ``want`` and the ``variables`` the stage reads as in
    :func:`expect_input`. One file open at a time.

    Returns
    -------
    list of ``{"path", "batch", "replicas", "config_hash"}``, one per file.

    Raises
    ------
    RunFileError
        naming the offending file (and the other file, for a duplicate).
    """
    out: list[dict] = []
    seen: dict[int, str] = {}
    for p in map(Path, paths):
        with open_input(p) as ds:
            attrs = dict(ds.attrs)
            replicas = [int(r) for r in ds["replica"].values] if "replica" in ds else []
            expect_input(ds, p, study=study, stage=stage, point=point, config_hash=config_hash,
                         variables=variables, **want)  # fmt: skip
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
