"""Drum fits on synthetic ensembles with a known vertex and known zeros: the pipeline, the
onset vertex, sign changes, automatic windows and lags."""

import tracemalloc

import numpy as np
import pytest

from granpipe.analysis.bootstrap import (
    FitResult,
)
from granpipe.drum.fits import (
    PAPER_VALUES,
    drum_fits,
    lag,
    load_units,
    minimum_times,
    reduce_runs,
    sign_change_times,
    vertex_time,
    zero_crossing_time,
)
from granpipe.drum.layout import filled

from .conftest import synthetic_runs

FITS = {**filled({})["fits"], "bootstrap_resamples": 300}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    return synthetic_runs(tmp_path_factory.mktemp("runs"))


@pytest.fixture(scope="module")
def fitted(runs):
    ens = reduce_runs(runs)
    units = load_units(runs, "replica")
    results, curves = drum_fits(ens, units, FITS)
    return ens, {r.quantity: r for r in results}, curves


def test_ensemble_matches_numpy_over_all_replicas(runs):
    import xarray as xr

    ens = reduce_runs(runs)
    allv = np.concatenate([xr.open_dataset(p)["lambda_onset"].values for p in runs])
    np.testing.assert_allclose(ens["lambda_onset_mean"].values, allv.mean(0), rtol=1e-12)
    np.testing.assert_allclose(
        ens["lambda_onset_sem"].values, allv.std(0, ddof=1) / np.sqrt(len(allv)), rtol=1e-10
    )
    assert ens.attrs["n_replicas"] == 12 and ens.attrs["n_batches"] == 3
    assert (ens["speed_decay_count"].values == 12).all()
    assert ens["seconds_onset"].attrs["units"] == "s"


def test_flagged_replicas_are_left_out(tmp_path):
    import xarray as xr

    paths = synthetic_runs(tmp_path, n_batches=1, batch_size=4)
    ds = xr.open_dataset(paths[0]).load()
    ds["continuous"].values[1] = 0
    ds["settled"].values[2] = 0
    ds.to_netcdf(tmp_path / "flagged.nc")
    ens = reduce_runs([tmp_path / "flagged.nc"])
    assert ens.attrs["n_replicas"] == 2 and ens.attrs["n_excluded"] == 2
    expected = ds["speed_onset"].values[[0, 3]].mean(0)
    np.testing.assert_allclose(ens["speed_onset_mean"].values, expected, rtol=1e-12)
    kept = reduce_runs([tmp_path / "flagged.nc"], exclude_flagged=False)
    assert kept.attrs["n_replicas"] == 4


def test_known_vertex_zeros_and_lags_are_recovered(fitted):
    _, r, _ = fitted
    truth = {
        "onset_time": 3.0,
        "onset_sign_change_time": 12.0,
        "onset_lag": 9.0,
        "decay_sign_change_time": 8.0,
        "decay_lag": 8.0 - 5.0,
    }
    for name, value in truth.items():
        for suffix in ("", "_auto"):
            res = r[name + suffix]
            # within ~4 standard errors, by the fit error and by the bootstrap interval
            # (a 95 % interval spans ~3.9 sigma); coverage itself is tested in tests/analysis
            assert abs(res.value - value) < 4 * res.fit_error + 0.02, (name + suffix, res)
            assert abs(res.value - value) < 2 * (res.ci_high - res.ci_low), (name + suffix, res)
            assert res.ci_low < res.value < res.ci_high
            assert res.n == 12 and res.unit == "s"
    # The automatic windows are centred where the data say (vertex 3, zeros 12 and 8).
    assert abs(np.mean(r["onset_time_auto"].window) - 3.0) < 0.3
    assert abs(np.mean(r["onset_sign_change_time_auto"].window) - 12.0) < 1.0
    # lambda-bar crossings carry a bootstrap CI but no fit error
    lb = r["onset_lambda_bar_zero_time"]
    assert np.isnan(lb.fit_error) and abs(lb.value - 12.0) < 2 * (lb.ci_high - lb.ci_low)


def test_decay_lag_refers_to_the_stop_time(fitted):
    ens, r, _ = fitted
    stop = ens.attrs["stop_time_s"]
    assert stop == pytest.approx(5.0, abs=1e-4)
    d = r["decay_sign_change_time"]
    assert r["decay_lag"].value == pytest.approx(d.value - stop)


def test_batch_means_bootstrap_agrees_with_replicas(runs, fitted):
    ens, r, _ = fitted
    units = load_units(runs, "batch")
    assert units["onset"].speed.shape[0] == 3 and units["onset"].counts.max() == 4
    results, _ = drum_fits(ens, units, {**FITS, "auto_windows": False})
    rb = {x.quantity: x for x in results}
    # same central values (same ensemble), intervals from 3 batch means instead of 12 replicas
    assert rb["onset_time"].value == pytest.approx(r["onset_time"].value)
    assert np.isfinite(rb["onset_time"].ci_low)


def test_smoothed_curves_follow_the_line(fitted):
    ens, _, curves = fitted
    t = ens["seconds_onset"].values
    inside = (t > 2) & (t < 23)
    for name in ("lambda_bar_onset", "lambda_lowpass_onset"):
        y = curves[name].values[inside]
        assert np.nanmax(np.abs(y - 0.02 * (t[inside] - 12.0))) < 0.05, name
    fit = curves["fit_lambda_onset_config"].values
    assert np.isfinite(fit[(t > 10.1) & (t < 19.9)]).all() and np.isnan(fit[t < 9.9]).all()


def test_paper_values_are_the_papers():
    assert PAPER_VALUES["onset_time"] == 2.628
    assert PAPER_VALUES["onset_sign_change_time"] == 14.5
    assert PAPER_VALUES["decay_sign_change_time"] == 8.13
    assert PAPER_VALUES["onset_lag"] == pytest.approx(11.872)


def test_ensemble_memory_does_not_grow_with_batches(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    few = synthetic_runs(tmp_path / "a", n_batches=2, batch_size=2)
    many = synthetic_runs(tmp_path / "b", n_batches=12, batch_size=2)
    peaks = []
    for paths in (few, many):
        reduce_runs(paths)  # warm imports and caches
        tracemalloc.start()
        reduce_runs(paths)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
    assert peaks[1] < 1.3 * peaks[0], peaks


def test_heavy_tailed_lambda_unweighted_fit_is_unbiased(tmp_path):
    """Skewed per-replica noise (like per-step λ): OLS finds the zero, 1/SEM² weights do not."""
    import xarray as xr

    paths = synthetic_runs(tmp_path, n_batches=2, batch_size=4, noise=0.0, seed=5)
    rng = np.random.default_rng(11)
    skewed = []
    for p in paths:
        ds = xr.open_dataset(p).load()
        x = ds["lambda_decay"].values
        # mean-zero, right-skewed noise (skewness 2): small SEM where the draws are low
        ds["lambda_decay"].values = x + 1.5 * (rng.exponential(1.0, x.shape) - 1.0)
        skewed.append(p.with_name("skewed_" + p.name))
        ds.to_netcdf(skewed[-1])
    paths = skewed
    ens = reduce_runs(paths)
    units = load_units(paths)
    cfg = {**FITS, "auto_windows": False, "bootstrap_resamples": 100}
    ols = {r.quantity: r for r in drum_fits(ens, units, cfg)[0]}["decay_sign_change_time"]
    wls = {r.quantity: r for r in drum_fits(ens, units, {**cfg, "weighted": True})[0]}[
        "decay_sign_change_time"
    ]
    assert abs(ols.value - 8.0) < 4 * ols.fit_error
    # the weighted fit's level at 8 s is pulled low (true level 0), moving the zero by seconds
    assert ols.coefficients[0] > -0.1 and wls.coefficients[0] < -0.3
    # ... so far that its zero leaves the window (refused) or lands seconds away
    assert np.isnan(wls.value) or abs(wls.value - 8.0) > 1.0


def test_a_downward_parabola_is_refused_as_an_onset(tmp_path):
    """V with a maximum at 3 s: the vertex fit is no minimum, in the full sample and in
    every resample; the row is empty and says why, and no onset lag is formed."""
    import xarray as xr

    paths = synthetic_runs(tmp_path, n_batches=2, batch_size=4)
    flipped = []
    for p in paths:
        ds = xr.open_dataset(p).load()
        ds["speed_onset"].values = 1.0 - ds["speed_onset"].values
        flipped.append(p.with_name("flipped_" + p.name))
        ds.to_netcdf(flipped[-1])
    ens = reduce_runs(flipped)
    results, _ = drum_fits(ens, load_units(flipped), {**FITS, "bootstrap_resamples": 200})
    r = {x.quantity: x for x in results}
    for suffix in ("", "_auto"):
        on = r["onset_time" + suffix]
        assert np.isnan(on.value) and on.note, on
        assert np.isnan(r["onset_lag" + suffix].value)
        assert r["onset_curvature" + suffix].value < -5 * r["onset_curvature" + suffix].fit_error
        assert r["onset_valid_fraction" + suffix].value < 0.05
    # the sign change does not depend on the onset and is still found
    assert abs(r["onset_sign_change_time"].value - 12.0) < 1.0


def test_a_lambda_that_turns_positive_before_the_onset_is_measured_as_a_lead(fitted, tmp_path):
    """λ crossing zero at 12 s (after the V minimum at 3 s): the first crossing after the
    start-up is that crossing, with the lag of the other rows. λ crossing at 4 s with the
    V minimum at 8 s: no crossing after the minimum, and the first crossing gives a
    negative lag, 4 - 8 = -4 s, inside its interval."""
    _, r, _ = fitted
    first = r["onset_lambda_bar_first_zero_time"]
    assert first.value == r["onset_lambda_bar_zero_time"].value
    assert r["onset_lag_lambda_bar_first"].value == r["onset_lag_lambda_bar"].value
    paths = synthetic_runs(tmp_path, n_batches=2, batch_size=4, vertex=8.0, zero_on=4.0)
    results, _ = drum_fits(
        reduce_runs(paths), load_units(paths), {**FITS, "bootstrap_resamples": 200}
    )
    lead = {x.quantity: x for x in results}
    assert np.isnan(lead["onset_lambda_bar_zero_time"].value)
    first, lag_first = lead["onset_lambda_bar_first_zero_time"], lead["onset_lag_lambda_bar_first"]
    assert abs(first.value - 4.0) < 1.0 and first.ci_low < 4.0 < first.ci_high, first
    assert abs(lag_first.value + 4.0) < 1.0 and lag_first.ci_high < 0.0, lag_first


def test_onset_minimum_accepted_in_almost_every_resample(fitted):
    _, r, _ = fitted
    for suffix in ("", "_auto"):
        assert r["onset_valid_fraction" + suffix].value >= 0.95
        c2 = r["onset_curvature" + suffix]
        assert c2.value == pytest.approx(0.01, abs=4 * c2.fit_error) and c2.value > 0


def test_startup_excess_measures_the_early_decay(tmp_path):
    """A flat, noisy V with (and without) a decay from 0.2 above it over the first 0.3 s:
    the early mean exceeds the minimum's neighbourhood by many standard errors (or not)."""
    import xarray as xr

    paths = synthetic_runs(tmp_path, n_batches=2, batch_size=4)
    flat, decayed = [], []
    for p in paths:
        ds = xr.open_dataset(p).load()
        t = ds["seconds_onset"].values
        ds["speed_onset"].values = ds["speed_onset"].values - 0.01 * (t - 3.0) ** 2
        flat.append(p.with_name("flat_" + p.name))
        ds.to_netcdf(flat[-1])
        ds["speed_onset"].values = ds["speed_onset"].values + 0.2 * np.exp(-t / 0.3)
        decayed.append(p.with_name("decayed_" + p.name))
        ds.to_netcdf(decayed[-1])
    for files, decays in ((decayed, True), (flat, False)):
        ens = reduce_runs(files)
        r = {x.quantity: x for x in drum_fits(ens, load_units(files), FITS)[0]}
        sigma = r["onset_startup_excess_sigma"].value
        assert (sigma > 10) if decays else (sigma < 3), sigma


T_GRID = np.arange(0.0, 6.0, 0.01)


def test_vertex_and_zero_exact():
    t = T_GRID
    V = 5.0 + 3.0 * (t - 2.628) ** 2
    r = vertex_time(t, V, (1.0, 4.0))
    assert r.value == pytest.approx(2.628, abs=1e-10)
    assert r.fit_error < 1e-8 and r.window == (1.0, 4.0)
    lam = 0.8 * (t - 4.5)
    z = zero_crossing_time(t, lam, (3.0, 5.5), quantity="q", unit="t0")
    assert z.value == pytest.approx(4.5, abs=1e-12) and z.unit == "t0" and z.quantity == "q"


def test_auto_windows():
    rng = np.random.default_rng(3)
    t = np.arange(0, 30, 0.004)
    V = 10 + 2 * (t - 2.628) ** 2 + 0.01 * rng.normal(size=t.size)
    r = vertex_time(t, V, "auto", half_width=1.5, search=(0.5, 6.0), smooth_q=10)
    assert r.window[0] == pytest.approx(2.628 - 1.5, abs=0.05)
    assert r.value == pytest.approx(2.628, abs=5 * r.fit_error + 1e-3)
    lam = np.tanh((t - 14.5) / 4) + 0.2 * rng.normal(size=t.size)
    z = zero_crossing_time(t, lam, "auto", half_width=2.0, search=(5, 25), smooth_q=62, direction=1)
    assert z.value == pytest.approx(14.5, abs=4 * z.fit_error)
    assert abs(0.5 * (z.window[0] + z.window[1]) - 14.5) < 0.3
    assert "auto" in z.method


def test_lag_combines_errors():
    a = FitResult("sign_change_time", 14.5, 0.2, "s", n=10)
    b = FitResult("onset_time", 2.6, 0.05, "s")
    d = lag(a, b)
    assert d.value == pytest.approx(11.9) and d.fit_error == pytest.approx(np.hypot(0.2, 0.05))
    assert lag(a, 5.0).fit_error == 0.2


def test_minimum_refuses_a_maximum_and_a_vertex_outside_the_window():
    """Only an upward parabola with its vertex inside the window is an onset (a minimum)."""
    t = T_GRID
    rng = np.random.default_rng(3)
    noise = 0.01 * rng.standard_normal(t.size)
    up = 0.2 + 0.05 * (t - 2.6) ** 2 + noise
    down = 0.2 - 0.05 * (t - 2.6) ** 2 + noise
    rising = 0.2 + 0.05 * (t - 0.2) ** 2 + noise  # vertex at 0.2 s, window 1-4 s
    Y = np.stack([up, down, rising])
    value, err, c2, c2_err, reason, _ = minimum_times(t, Y, (1.0, 4.0))
    assert list(reason) == [0, 2, 3]
    assert value[0] == pytest.approx(2.6, abs=5 * err[0]) and np.isnan(value[1:]).all()
    # the curvature is reported with its error either way, and its sign is significant
    assert c2[0] == pytest.approx(0.05, abs=5 * c2_err[0]) and c2[1] < -10 * c2_err[1]
    refused = vertex_time(t, down, (1.0, 4.0), require_minimum=True)
    assert np.isnan(refused.value) and "maximum" in refused.note
    plain = vertex_time(t, down, (1.0, 4.0))
    assert plain.value == pytest.approx(2.6, abs=0.05) and plain.note == ""


def test_sign_change_refuses_an_extrapolated_zero_and_the_wrong_direction():
    t = T_GRID
    rising = 0.5 * (t - 4.5)
    Y = np.stack([rising, -rising, 0.5 * (t - 0.2)])
    value, err, reason, _ = sign_change_times(t, Y, (3.0, 5.5), direction=+1)
    assert list(reason) == [0, 2, 3]
    assert value[0] == pytest.approx(4.5) and np.isnan(value[1:]).all()
    v_any, _, r_any, _ = sign_change_times(t, Y, (3.0, 5.5), direction=0)
    assert list(r_any) == [0, 0, 3] and v_any[1] == pytest.approx(4.5)
