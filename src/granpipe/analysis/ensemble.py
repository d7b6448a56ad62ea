"""Streaming reduction of replica batches to ensemble means (docs/architecture.md, "Stages").

Replicas arrive in batches shaped ``(replica, time)``; the ensemble mean, standard
error of the mean and count at each time point are accumulated one batch at a
time with the pairwise update of Chan, Golub & LeVeque (1979) — Welford's
algorithm generalised to merging two partial results — so that peak memory is
set by one batch and the time axis, never by the number of batches.

Missing samples are ``NaN``: replicas may have different record lengths (padded
with ``NaN`` inside a batch), and batches may have different time lengths (the
accumulator grows its time axis; a shorter batch contributes nothing at the later
times). Counts are therefore per time point.

For bootstrap over batch means at paper scale (70,000 replicas), the
accumulator can also keep each batch's mean and count, ``(batch, time)``; this
costs one row per batch and is off by default.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence

import numpy as np
import xarray as xr

__all__ = [
    "EnsembleAccumulator",
    "batch_moments",
    "replica_mean_sem",
    "pooled_batch_mean",
    "reduce_batch_files",
]


def batch_moments(values: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Count, mean and sum of squared deviations over axis 0, ignoring ``NaN``.

    Parameters
    ----------
    values : (replica, time) float
        One batch; ``NaN`` marks a missing sample.

    Returns
    -------
    count : (time,) int64
    mean : (time,) float64, ``NaN`` where count is 0
    m2 : (time,) float64, sum of (x - mean)**2 over the finite samples (0 where count is 0)
    """
    x = np.asarray(values, dtype=np.float64)
    if x.ndim == 1:
        x = x[np.newaxis, :]
    if x.ndim != 2:
        raise ValueError(f"a batch must be (replica, time); got shape {x.shape}")
    finite = np.isfinite(x)
    count = finite.sum(axis=0, dtype=np.int64)
    total = np.where(finite, x, 0.0).sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = total / count
    # Two-pass within the batch: the deviations are taken from the batch mean.
    dev = np.where(finite, x - mean, 0.0)
    m2 = (dev * dev).sum(axis=0)
    return count, mean, m2


def replica_mean_sem(replicas: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean, standard error and count over axis 0 of (replica, time) data, ignoring NaN.

    Returns (mean, sem, count), each (time,); sem is ``NaN`` where count < 2.
    """
    count, mean, m2 = batch_moments(replicas)
    with np.errstate(invalid="ignore", divide="ignore"):
        sem = np.where(count > 1, np.sqrt(m2 / (count - 1) / count), np.nan)
    return mean, sem, count


def pooled_batch_mean(
    batch_means: np.ndarray, batch_counts: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pooled mean of batch means, with its standard error from the batch scatter.

    Parameters
    ----------
    batch_means : (batch, time) float, NaN where a batch has no sample
    batch_counts : (batch, time) int, replicas per batch and time point

    Returns
    -------
    mean : (time,) count-weighted mean Σ c_b m_b / Σ c_b (the ensemble mean)
    sem : (time,) standard error of that mean estimated from the scatter of the
        batch means (ratio-estimator variance,
        ``nb/(nb-1) Σ c_b² (m_b − mean)² / (Σ c_b)²``; NaN with < 2 batches)
    count : (time,) total replicas
    """
    m = np.asarray(batch_means, dtype=np.float64)
    c = np.asarray(batch_counts, dtype=np.float64)
    has = (c > 0) & np.isfinite(m)
    c = np.where(has, c, 0.0)
    mz = np.where(has, m, 0.0)
    total = c.sum(axis=0)
    nb = has.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = (c * mz).sum(axis=0) / total
        dev = np.where(has, mz - mean, 0.0)
        var = nb / (nb - 1.0) * (c * c * dev * dev).sum(axis=0) / (total * total)
        sem = np.where(nb > 1, np.sqrt(var), np.nan)
    return mean, sem, total.astype(np.int64)


class EnsembleAccumulator:
    """Running mean, variance and count per time point over batches of replicas.

    Parameters
    ----------
    keep_batch_means : bool
        Also store each batch's mean and count, shape (batch, time), for
        :func:`granpipe.analysis.bootstrap.bootstrap_batches`. Memory then grows by one
        row per batch.

    Notes
    -----
    Merge rule (Chan et al. 1979) for partial results (n_a, mean_a, M2_a) and
    (n_b, mean_b, M2_b), applied per time point::

        n = n_a + n_b
        delta = mean_b - mean_a
        mean = mean_a + delta * n_b / n
        M2 = M2_a + M2_b + delta**2 * n_a * n_b / n

    The sample variance is ``M2 / (n - 1)`` and the standard error of the mean
    ``sqrt(M2 / (n - 1) / n)`` (``NaN`` for n < 2).

    Examples
    --------
    >>> acc = EnsembleAccumulator()
    >>> for batch in batches:          # each (replica, time)
    ...     acc.add(batch)
    >>> acc.mean, acc.sem, acc.count
    """

    def __init__(self, keep_batch_means: bool = False):
        self.keep_batch_means = keep_batch_means
        self._count = np.zeros(0, dtype=np.int64)
        self._mean = np.zeros(0, dtype=np.float64)
        self._m2 = np.zeros(0, dtype=np.float64)
        self._time: np.ndarray | None = None
        self._time_attrs: dict = {}
        self._batch_means: list[np.ndarray] = []
        self._batch_counts: list[np.ndarray] = []
        self.n_batches = 0
        self.n_replicas = 0

    # ------------------------------------------------------------------ input
    def add(self, batch, replica_dim: str = "replica", time_dim: str = "time"):
        """Merge one batch into the running result; returns ``self``.

        Parameters
        ----------
        batch : (replica, time) numpy array or xarray.DataArray
            A DataArray is transposed to ``(replica_dim, time_dim)``; its time
            coordinate, if any, must agree with earlier batches on their common
            length (checked), and the longest one is kept.
        """
        if isinstance(batch, xr.DataArray):
            batch = batch.transpose(replica_dim, time_dim)
            if time_dim in batch.coords:
                self._check_time(np.asarray(batch[time_dim].values), dict(batch[time_dim].attrs))
            values = batch.values
        else:
            values = np.asarray(batch)
        count, mean, m2 = batch_moments(values)
        self._merge(count, mean, m2)
        self.n_batches += 1
        self.n_replicas += 1 if np.ndim(values) == 1 else np.shape(values)[0]
        if self.keep_batch_means:
            self._batch_means.append(mean)
            self._batch_counts.append(count)
        return self

    def _check_time(self, time: np.ndarray, attrs: dict) -> None:
        if self._time is None:
            self._time, self._time_attrs = time.copy(), attrs
            return
        k = min(len(time), len(self._time))
        if not np.allclose(time[:k], self._time[:k], rtol=1e-12, atol=0.0):
            raise ValueError("batches disagree on the time coordinate")
        if len(time) > len(self._time):
            self._time = time.copy()

    def _grow(self, n: int) -> None:
        extra = n - len(self._count)
        if extra > 0:
            self._count = np.concatenate([self._count, np.zeros(extra, np.int64)])
            self._mean = np.concatenate([self._mean, np.full(extra, np.nan)])
            self._m2 = np.concatenate([self._m2, np.zeros(extra)])

    def _merge(self, n_b: np.ndarray, mean_b: np.ndarray, m2_b: np.ndarray) -> None:
        self._grow(len(n_b))
        L = len(n_b)
        n_a = self._count[:L]
        mean_a = self._mean[:L]
        n = n_a + n_b
        with np.errstate(invalid="ignore", divide="ignore"):
            frac_b = np.where(n > 0, n_b / np.maximum(n, 1), 0.0)
            delta = np.where(n_b > 0, mean_b - np.where(n_a > 0, mean_a, 0.0), 0.0)
            new_mean = np.where(
                n_a > 0,
                mean_a + delta * frac_b,
                np.where(n_b > 0, mean_b, np.nan),
            )
            new_m2 = self._m2[:L] + np.where(n_b > 0, m2_b, 0.0) + delta * delta * n_a * frac_b
        self._count[:L] = n
        self._mean[:L] = new_mean
        self._m2[:L] = np.where(n_a > 0, new_m2, np.where(n_b > 0, m2_b, 0.0))

    def merge(self, other: EnsembleAccumulator) -> EnsembleAccumulator:
        """Merge another accumulator into this one (e.g. from a parallel worker)."""
        if other._time is not None:
            self._check_time(other._time, other._time_attrs)
        self._merge(other._count, other._mean, other._m2)
        self.n_batches += other.n_batches
        self.n_replicas += other.n_replicas
        if self.keep_batch_means:
            self._batch_means.extend(other._batch_means)
            self._batch_counts.extend(other._batch_counts)
        return self

    # ----------------------------------------------------------------- output
    @property
    def count(self) -> np.ndarray:
        """(time,) int64: number of finite samples at each time point."""
        return self._count.copy()

    @property
    def mean(self) -> np.ndarray:
        """(time,) float64: ensemble mean (``NaN`` where count is 0)."""
        return self._mean.copy()

    @property
    def var(self) -> np.ndarray:
        """(time,) float64: unbiased sample variance (``NaN`` where count < 2)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self._count > 1, self._m2 / (self._count - 1), np.nan)

    @property
    def std(self) -> np.ndarray:
        """(time,) float64: sample standard deviation (ddof = 1)."""
        return np.sqrt(self.var)

    @property
    def sem(self) -> np.ndarray:
        """(time,) float64: standard error of the mean, std / sqrt(count)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.sqrt(self.var / self._count)

    @property
    def time(self) -> np.ndarray | None:
        """(time,) the longest time coordinate seen, if batches carried one."""
        return None if self._time is None else self._time.copy()

    def batch_means(self) -> tuple[np.ndarray, np.ndarray]:
        """Per-batch means and counts, each (batch, time), padded with NaN / 0.

        Only available with ``keep_batch_means=True``.
        """
        if not self.keep_batch_means:
            raise RuntimeError("construct the accumulator with keep_batch_means=True")
        L = len(self._count)
        B = len(self._batch_means)
        means = np.full((B, L), np.nan)
        counts = np.zeros((B, L), dtype=np.int64)
        for b, (m, c) in enumerate(zip(self._batch_means, self._batch_counts, strict=True)):
            means[b, : len(m)] = m
            counts[b, : len(c)] = c
        return means, counts


def _label(attrs: dict, suffix: str, what: str) -> dict:
    """Attrs for a derived variable: same units (count: '1'), long_name with a qualifier."""
    name = attrs.get("long_name", "")
    units = "1" if suffix == "count" else attrs.get("units", "1")
    return {"units": units, "long_name": f"{what} of {name}".strip() if name else what}


def reduce_batch_files(
    paths: Sequence[str | os.PathLike] | Iterable[str | os.PathLike],
    variables: Sequence[str] | None = None,
    *,
    replica_dim: str = "replica",
    time_dim: str = "time",
    batch_means: bool = False,
) -> xr.Dataset:
    """Reduce netCDF batch files to ensemble statistics, one file open at a time.

    Parameters
    ----------
    paths : sequence of paths
        Batch files (``runs/<point>/batch_<b>.nc``), each holding variables with
        dims exactly ``(replica, time)`` (in either order).
    variables : sequence of str, optional
        Which variables to reduce; default every variable whose dims are
        ``{replica, time}``.
    batch_means : bool
        Also return ``<var>_batch_mean`` and ``<var>_batch_count``, dims
        ``(batch, time)``, for bootstrap over batch means.

    Returns
    -------
    xarray.Dataset
        For each variable: ``<var>_mean`` and ``<var>_sem`` (the variable's
        units) and ``<var>_count`` (units "1"), dims ``(time,)``; the time
        coordinate and every coordinate that depends on time only (e.g. the
        drum's seconds), copied with their attributes from the longest file;
        global attrs ``n_replicas`` and ``n_batches``. Ready for
        :func:`granpipe.io.write_dataset`.
    """
    paths = [os.fspath(p) for p in paths]
    if not paths:
        raise ValueError("no batch files to reduce")
    accs: dict[str, EnsembleAccumulator] = {}
    var_attrs: dict[str, dict] = {}
    time_coords: dict[str, xr.DataArray] = {}
    longest = -1
    for path in paths:
        with xr.open_dataset(path, engine="netcdf4") as ds:
            names = variables
            if names is None:
                names = [
                    n for n, v in ds.data_vars.items() if set(v.dims) == {replica_dim, time_dim}
                ]
            n_time = ds.sizes.get(time_dim, 0)
            if n_time > longest:
                longest = n_time
                time_coords = {
                    name: c.load().copy() for name, c in ds.coords.items() if c.dims == (time_dim,)
                }
            for name in names:
                da = ds[name]
                if set(da.dims) != {replica_dim, time_dim}:
                    raise ValueError(f"{path}: {name} has dims {da.dims}, not (replica, time)")
                if name not in accs:
                    accs[name] = EnsembleAccumulator(keep_batch_means=batch_means)
                    var_attrs[name] = dict(da.attrs)
                # Loads this one variable of this one file only.
                accs[name].add(da.load(), replica_dim=replica_dim, time_dim=time_dim)
    if not accs:
        raise ValueError("no (replica, time) variables found in the batch files")
    L = max(len(a.count) for a in accs.values())
    out = xr.Dataset(coords=time_coords)
    for name, acc in accs.items():
        acc._grow(L)
        attrs = var_attrs[name]
        out[f"{name}_mean"] = (time_dim, acc.mean, _label(attrs, "mean", "ensemble mean"))
        out[f"{name}_sem"] = (
            time_dim,
            acc.sem,
            _label(attrs, "sem", "standard error of the ensemble mean"),
        )
        out[f"{name}_count"] = (time_dim, acc.count, _label(attrs, "count", "replica count"))
        if batch_means:
            means, counts = acc.batch_means()
            out[f"{name}_batch_mean"] = (
                ("batch", time_dim),
                means,
                _label(attrs, "mean", "batch mean"),
            )
            out[f"{name}_batch_count"] = (
                ("batch", time_dim),
                counts,
                _label(attrs, "count", "replica count per batch"),
            )
    if batch_means:
        out = out.assign_coords(
            batch=("batch", np.arange(len(paths)), {"units": "1", "long_name": "batch index"})
        )
    first = next(iter(accs.values()))
    out.attrs["n_replicas"] = int(first.n_replicas)
    out.attrs["n_batches"] = int(first.n_batches)
    return out
