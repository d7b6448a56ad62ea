"""Windowed fits and the bootstrap: exact polynomials, vertex and zero times, fit errors
against the scatter, first crossings, bootstrap coverage and reproducibility."""

import numpy as np
import pytest

from granpipe.analysis.bootstrap import (
    bootstrap_batches,
    bootstrap_replicas,
    first_crossing,
    polyfit_window,
    vertex_times,
    zero_crossing_times,
)

T_GRID = np.arange(0.0, 6.0, 0.01)


def test_polyfit_recovers_exact_polynomial_and_ignores_nan():
    t = T_GRID
    y = 0.3 - 1.2 * (t - 2.5) + 0.7 * (t - 2.5) ** 2
    y[150] = np.nan
    coef, cov, chi2, n, t_ref = polyfit_window(t, y, (1.0, 4.0), 2, t_ref=2.5)
    np.testing.assert_allclose(coef, [0.3, -1.2, 0.7], atol=1e-10)
    assert n == 300  # 301 samples in [1, 4] minus the NaN


@pytest.mark.parametrize("weighted", [False, True])
def test_vertex_fit_error_consistent_with_scatter(weighted):
    rng = np.random.default_rng(11)
    t = T_GRID
    # The residual-scaled (unweighted) error assumes equal noise everywhere; the
    # weighted one is tested with heteroscedastic noise.
    noise = 0.05 * (1 + t / 3) if weighted else np.full(t.size, 0.08)
    Y = 5.0 + 3.0 * (t - 2.628) ** 2 + noise * rng.normal(size=(3000, t.size))
    val, err, ex = vertex_times(t, Y, (1.0, 4.0), noise if weighted else None)
    assert abs(np.mean(val) - 2.628) < 3 * np.std(val) / np.sqrt(len(val))
    ratio = np.std(val, ddof=1) / np.median(err)
    assert 0.93 < ratio < 1.07, ratio
    if weighted:  # residuals in units of the given noise
        assert np.median(ex["chi2_red"]) == pytest.approx(1.0, abs=0.05)
    else:  # the residual variance estimates the noise variance, 0.08²
        assert np.median(ex["chi2_red"]) == pytest.approx(0.08**2, rel=0.05)


def test_zero_crossing_fit_error_consistent_with_scatter():
    rng = np.random.default_rng(12)
    t = T_GRID
    Y = 0.4 * (t - 4.1) + 0.2 * rng.normal(size=(3000, t.size))
    val, err, _ = zero_crossing_times(t, Y, (3.0, 5.5))
    ratio = np.std(val, ddof=1) / np.median(err)
    assert 0.93 < ratio < 1.07, ratio
    assert abs(np.mean(val) - 4.1) < 4 * np.std(val) / np.sqrt(len(val))


def test_inflation_when_sigma_too_small():
    rng = np.random.default_rng(13)
    t = T_GRID
    Y = 0.4 * (t - 4.1) + 0.2 * rng.normal(size=(500, t.size))
    _, err_auto, ex = zero_crossing_times(t, Y, (3.0, 5.5), np.full(t.size, 0.02))
    _, err_abs, _ = zero_crossing_times(
        t, Y, (3.0, 5.5), np.full(t.size, 0.02), error_scale="absolute"
    )
    assert np.median(ex["chi2_red"]) > 50
    assert np.median(err_auto / err_abs) == pytest.approx(10.0, rel=0.1)


def test_first_crossing_of_a_single_sample_is_nan():
    assert np.isnan(first_crossing(np.array([0.8]), np.array([-1.0])))
    assert np.isnan(first_crossing(np.array([0.8]), np.ones((5, 1)))).all()


def test_first_crossing_and_directions():
    t = np.linspace(0, 10, 1001)
    y = np.sin(t)  # crossings at pi (down), 2pi (up), 3pi (down)
    assert first_crossing(t, y, (1, 10), -1) == pytest.approx(np.pi, abs=1e-4)
    assert first_crossing(t, y, (1, 10), +1) == pytest.approx(2 * np.pi, abs=1e-4)
    assert first_crossing(t, y, (4, 10), 0) == pytest.approx(2 * np.pi, abs=1e-4)
    assert np.isnan(first_crossing(t, y, (4, 6), 0))
    both = first_crossing(t, np.stack([y, -y]), (1, 10), +1)
    np.testing.assert_allclose(both, [2 * np.pi, np.pi], atol=1e-4)


def _replicas(rng, R, t, mean_vertex=2.6):
    a = rng.normal(mean_vertex, 0.3, size=(R, 1))
    return 5 + 3 * (t - a) ** 2 + 0.5 * rng.normal(size=(R, t.size))


def test_bootstrap_coverage_vertex():
    """90 % percentile CI over replicas covers the population vertex at ~90 %."""
    t = np.arange(0.0, 5.0, 0.02)
    rng = np.random.default_rng(2024)
    draws, covered = 200, 0
    for d in range(draws):
        X = _replicas(rng, 40, t)
        boot = bootstrap_replicas(
            X, lambda m: vertex_times(t, m, (1.0, 4.0))[0], n_resamples=400, seed=d
        )
        covered += boot.ci_low[0] <= 2.6 <= boot.ci_high[0]
    rate = covered / draws
    # Binomial sd at 0.9 over 200 draws is 0.021; allow 3 sd.
    assert 0.836 <= rate <= 0.964, rate


def test_bootstrap_reproducible_and_batches_of_one_equal_replicas():
    t = np.arange(0.0, 5.0, 0.02)
    X = _replicas(np.random.default_rng(0), 30, t)

    def stat(m):
        return vertex_times(t, m, (1.0, 4.0))[0]

    a = bootstrap_replicas(X, stat, n_resamples=300, seed=5)
    b = bootstrap_replicas(X, stat, n_resamples=300, seed=5, chunk=64)
    np.testing.assert_array_equal(a.samples[:64], b.samples[:64])
    c = bootstrap_batches(X, np.ones_like(X), stat, n_resamples=300, seed=5)
    np.testing.assert_allclose(c.samples, a.samples, rtol=1e-12)
    assert a.n == 30 and a.n_resamples == 300 and a.n_failed[0] == 0


def test_bootstrap_batches_width_matches_replica_bootstrap():
    t = np.arange(0.0, 5.0, 0.02)
    X = _replicas(np.random.default_rng(1), 400, t)
    stat = lambda m: vertex_times(t, m, (1.0, 4.0))[0]  # noqa: E731
    rep = bootstrap_replicas(X, stat, n_resamples=500, seed=1)
    bm = X.reshape(40, 10, -1).mean(axis=1)
    bat = bootstrap_batches(bm, np.full(bm.shape, 10), stat, n_resamples=500, seed=1)
    assert bat.std[0] == pytest.approx(rep.std[0], rel=0.25)


def test_first_crossing_with_hold_skips_noise_crossings():
    """A line through zero at t = 4 with a dip below zero after an early noise crossing at
    t = 1: without hold the first upward crossing is the noise one, with a hold of 0.5 the
    lasting one."""
    t = np.arange(0.0, 8.0, 0.01)
    y = 0.1 * (t - 4.0)
    y[(t > 1.0) & (t < 1.2)] = 0.05  # a brief excursion above zero
    assert first_crossing(t, y, (0.0, 8.0), +1) == pytest.approx(1.0, abs=0.011)
    assert first_crossing(t, y, (0.0, 8.0), +1, hold=50) == pytest.approx(4.0, abs=1e-9)
    # vectorised over series, and NaN when no crossing lasts
    Y = np.stack([y, -np.abs(y) - 0.01])
    got = first_crossing(t, Y, (0.0, 8.0), +1, hold=50)
    assert got[0] == pytest.approx(4.0) and np.isnan(got[1])
