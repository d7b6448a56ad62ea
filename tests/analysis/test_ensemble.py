"""Streaming ensemble reduction against numpy on the concatenated replicas."""

import tracemalloc

import numpy as np
import pytest
import xarray as xr

from granpipe.analysis.ensemble import EnsembleAccumulator, batch_moments, reduce_batch_files
from granpipe.io import write_dataset


def _ragged_batches(rng, n_batches, n_time=200, max_rep=7):
    """Batches of different sizes; replicas of different record lengths (NaN-padded);
    batches of different time lengths; large offset to stress cancellation."""
    out = []
    for _ in range(n_batches):
        r = int(rng.integers(1, max_rep + 1))
        L = int(rng.integers(n_time // 2, n_time + 1))
        x = 1e6 + rng.normal(size=(r, L)) * np.linspace(1, 3, L)
        for i in range(r):
            stop = int(rng.integers(L // 3, L + 1))
            x[i, stop:] = np.nan
        out.append(x)
    return out


def _concat(batches):
    L = max(b.shape[1] for b in batches)
    return np.concatenate(
        [np.pad(b, ((0, 0), (0, L - b.shape[1])), constant_values=np.nan) for b in batches]
    )


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_streaming_equals_numpy_on_concatenation():
    rng = np.random.default_rng(1)
    batches = _ragged_batches(rng, 23)
    acc = EnsembleAccumulator()
    for b in batches:
        acc.add(b)
    x = _concat(batches)
    count = np.isfinite(x).sum(axis=0)
    np.testing.assert_array_equal(acc.count, count)
    ok = count >= 2
    np.testing.assert_allclose(acc.mean[ok], np.nanmean(x, axis=0)[ok], rtol=1e-14)
    np.testing.assert_allclose(acc.std[ok], np.nanstd(x, axis=0, ddof=1)[ok], rtol=1e-9)
    np.testing.assert_allclose(
        acc.sem[ok], np.nanstd(x, axis=0, ddof=1)[ok] / np.sqrt(count[ok]), rtol=1e-9
    )
    assert np.all(np.isnan(acc.sem[count < 2]))
    assert acc.n_replicas == x.shape[0]


def test_merge_of_two_accumulators_equals_single_pass():
    rng = np.random.default_rng(2)
    batches = _ragged_batches(rng, 10)
    whole, left, right = EnsembleAccumulator(), EnsembleAccumulator(), EnsembleAccumulator()
    for i, b in enumerate(batches):
        whole.add(b)
        (left if i % 2 else right).add(b)
    left.merge(right)
    np.testing.assert_array_equal(left.count, whole.count)
    np.testing.assert_allclose(left.mean, whole.mean, rtol=1e-14, equal_nan=True)
    np.testing.assert_allclose(left.var, whole.var, rtol=1e-9, equal_nan=True)


def test_batch_moments_all_nan_column():
    x = np.array([[1.0, np.nan], [3.0, np.nan]])
    n, m, m2 = batch_moments(x)
    np.testing.assert_array_equal(n, [2, 0])
    assert m[0] == 2.0 and np.isnan(m[1])
    assert m2[0] == 2.0 and m2[1] == 0.0


def test_batch_means_kept_and_consistent():
    rng = np.random.default_rng(3)
    batches = _ragged_batches(rng, 6)
    acc = EnsembleAccumulator(keep_batch_means=True)
    for b in batches:
        acc.add(b)
    means, counts = acc.batch_means()
    assert means.shape == (6, len(acc.count))
    ok = acc.count > 0
    pooled = np.nansum(means * counts, axis=0)[ok] / counts.sum(axis=0)[ok]
    np.testing.assert_allclose(pooled, acc.mean[ok], rtol=1e-13)


def _peak_bytes(n_batches, shape=(20, 4000)):
    rng = np.random.default_rng(0)
    acc = EnsembleAccumulator()
    tracemalloc.start()
    for _ in range(n_batches):
        # Generated inside the loop: only one batch alive at a time.
        acc.add(rng.normal(size=shape))
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def test_memory_independent_of_batch_count():
    p5, p50 = _peak_bytes(5), _peak_bytes(50)
    # One batch is 640 kB; growth with batch count would add ~29 MB.
    assert p50 < 1.1 * p5 + 100_000, (p5, p50)


def test_dataarray_time_coordinate_grows_and_is_checked():
    t = np.arange(10) * 0.5
    acc = EnsembleAccumulator()
    acc.add(xr.DataArray(np.ones((2, 6)), dims=("replica", "time"), coords={"time": t[:6]}))
    acc.add(xr.DataArray(np.zeros((10, 3)), dims=("time", "replica"), coords={"time": t}))
    np.testing.assert_array_equal(acc.time, t)
    np.testing.assert_array_equal(acc.count, [5] * 6 + [3] * 4)
    np.testing.assert_allclose(acc.mean, [0.4] * 6 + [0.0] * 4)
    with pytest.raises(ValueError, match="time coordinate"):
        acc.add(xr.DataArray(np.ones((1, 3)), dims=("replica", "time"), coords={"time": t[:3] + 1}))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_reduce_batch_files(tmp_path):
    rng = np.random.default_rng(4)
    batches = _ragged_batches(rng, 5, n_time=50)
    L = max(b.shape[1] for b in batches)
    t = np.arange(L) * 4e-3
    paths = []
    for i, b in enumerate(batches):
        n_t = b.shape[1]
        ds = xr.Dataset(
            {
                "global_speed": (
                    ("replica", "time"),
                    b,
                    {"units": "d_s/t0", "long_name": "global speed V"},
                ),
                "scalar": ("replica", b[:, 0], {"units": "1", "long_name": "not reduced"}),
            },
            coords={
                "time": ("time", t[:n_t], {"units": "t0", "long_name": "time"}),
                "time_s": ("time", t[:n_t] * 0.035, {"units": "s", "long_name": "time"}),
                "replica": ("replica", np.arange(b.shape[0]), {"units": "1", "long_name": "r"}),
            },
        )
        paths.append(write_dataset(ds, tmp_path / f"batch_{i}.nc", config_subset={"b": i}))
    out = reduce_batch_files(paths, batch_means=True)
    x = _concat(batches)
    np.testing.assert_array_equal(out["global_speed_count"].values, np.isfinite(x).sum(0))
    np.testing.assert_allclose(out["global_speed_mean"].values, np.nanmean(x, 0), rtol=1e-14)
    assert out["global_speed_sem"].attrs["units"] == "d_s/t0"
    assert out["global_speed_count"].attrs["units"] == "1"
    assert "time_s" in out.coords and out.sizes["time"] == L
    assert out["global_speed_batch_mean"].shape == (5, L)
    assert "scalar_mean" not in out
    assert out.attrs["n_replicas"] == x.shape[0]
    write_dataset(out, tmp_path / "ensemble.nc")  # every variable labelled


def test_replica_mean_sem_and_pooled_batch_mean():
    from granpipe.analysis.ensemble import pooled_batch_mean, replica_mean_sem

    rng = np.random.default_rng(5)
    x = rng.normal(2.0, 1.5, size=(4000, 3))
    m, s, c = replica_mean_sem(x)
    np.testing.assert_allclose(m, x.mean(0), rtol=1e-13)
    np.testing.assert_allclose(s, x.std(0, ddof=1) / np.sqrt(4000), rtol=1e-12)
    bm = x.reshape(200, 20, 3).mean(1)
    pm, ps, pc = pooled_batch_mean(bm, np.full(bm.shape, 20))
    np.testing.assert_allclose(pm, m, rtol=1e-13)
    np.testing.assert_array_equal(pc, 4000)
    # The batch-scatter SEM estimates the same quantity (200 batches: ~5 % noise).
    np.testing.assert_allclose(ps, s, rtol=0.2)
