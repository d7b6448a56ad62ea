"""Segmented log-log regression and Arrhenius fits on synthetic data with known answers."""

import numpy as np
import pytest

from granpipe.analysis.regression import (
    arrhenius_by_region,
    arrhenius_fit,
    loglog_segmented,
    segmented_fit,
    select_segments,
    zero_count_upper_bound,
)

X = np.linspace(-1.0, 3.0, 20)


def one_break(x):
    return 0.5 + 1.0 * x + 1.5 * np.maximum(x - 1.2, 0.0)


def two_breaks(x):
    return 0.5 + 0.5 * x + 2.0 * np.maximum(x - 0.5, 0.0) - 1.5 * np.maximum(x - 2.0, 0.0)


def _covered(ci, truth):
    ci = np.atleast_2d(ci)
    return (ci[:, 0] <= truth) & (truth <= ci[:, 1])


def test_exact_data_recovered():
    r = segmented_fit(X, one_break(X), 1)
    assert r.breakpoints[0] == pytest.approx(1.2, abs=2e-3)
    np.testing.assert_allclose(r.slopes, [1.0, 2.5], atol=1e-3)
    np.testing.assert_allclose(r.predict(X), one_break(X), atol=5e-3)
    r = segmented_fit(X, two_breaks(X), 2)
    np.testing.assert_allclose(r.breakpoints, [0.5, 2.0], atol=5e-3)
    np.testing.assert_allclose(r.slopes, [0.5, 2.5, 1.0], atol=1e-2)


@pytest.mark.parametrize(
    ("k", "model", "psi", "slopes", "noise", "draws"),
    [
        (1, one_break, [1.2], [1.0, 2.5], 0.1, 300),
        (2, two_breaks, [0.5, 2.0], [0.5, 2.5, 1.0], 0.05, 40),
        pytest.param(
            2, two_breaks, [0.5, 2.0], [0.5, 2.5, 1.0], 0.05, 300, marks=pytest.mark.validate
        ),
    ],
)
def test_profile_intervals_cover_truth(k, model, psi, slopes, noise, draws):
    """Nominal 90 % profile intervals; measured 0.89-0.90 over 2000 draws (one break)."""
    rng = np.random.default_rng(100 + k)
    cov_psi, cov_slope, errs = np.zeros(k), np.zeros(k + 1), []
    for _ in range(draws):
        r = segmented_fit(X, model(X) + noise * rng.normal(size=X.size), k)
        cov_psi += _covered(r.breakpoint_ci, psi)
        cov_slope += _covered(r.slope_ci, slopes)
        errs.append(r.breakpoints - psi)
    # Unbiased breakpoints, and coverage within ~3 binomial sd of 0.9.
    errs = np.array(errs)
    assert np.all(np.abs(errs.mean(0)) < 3 * errs.std(0) / np.sqrt(draws))
    tol = 3 * np.sqrt(0.09 / draws)
    for rate in np.r_[cov_psi, cov_slope] / draws:
        assert 0.9 - tol <= rate <= min(1.0, 0.9 + tol), (cov_psi / draws, cov_slope / draws)


def test_delta_method_se_matches_scatter():
    rng = np.random.default_rng(7)
    psi, se = [], []
    for _ in range(150):
        r = segmented_fit(X, one_break(X) + 0.1 * rng.normal(size=X.size), 1, ci_method="wald")
        psi.append(r.breakpoints[0])
        se.append(r.breakpoint_se[0])
    assert np.std(psi) == pytest.approx(np.mean(se), rel=0.25)


def test_bootstrap_method_reproducible_and_covering():
    rng = np.random.default_rng(8)
    y = one_break(X) + 0.1 * rng.normal(size=X.size)
    a = segmented_fit(X, y, 1, ci_method="bootstrap", n_resamples=300, seed=3)
    b = segmented_fit(X, y, 1, ci_method="bootstrap", n_resamples=300, seed=3)
    np.testing.assert_array_equal(a.breakpoint_ci, b.breakpoint_ci)
    assert a.n_resamples == 300 and a.bootstrap_breakpoints.shape == (300, 1)
    prof = segmented_fit(X, y, 1)
    # Both intervals describe the same uncertainty: comparable widths.
    w_boot = np.diff(a.breakpoint_ci[0])[0]
    w_prof = np.diff(prof.breakpoint_ci[0])[0]
    assert 0.5 < w_boot / w_prof < 2.0


def test_bic_selection():
    rng = np.random.default_rng(9)
    for k, model in ((0, lambda x: 0.3 + 0.8 * x), (1, one_break), (2, two_breaks)):
        hits = 0
        for _ in range(10):
            best, fits = select_segments(X, model(X) + 0.05 * rng.normal(size=X.size))
            hits += best == k
            assert set(fits) == {0, 1, 2}
        assert hits >= 8, (k, hits)


def test_loglog_power_law_regions():
    K_m = np.geomspace(0.5, 20.0, 18)
    # T* ~ K^1 below K = 3.3, ~ K^2.2 above, continuous, 3 % noise.
    T = np.where(K_m < 3.3, K_m, 3.3 * (K_m / 3.3) ** 2.2) * 1e-3
    T = T * np.exp(0.03 * np.random.default_rng(10).normal(size=K_m.size))
    fit, bic = loglog_segmented(K_m, T, T_g_sem=0.03 * T)
    assert fit.n_breakpoints == 1 and set(bic) == {0, 1, 2}
    bp, bp_ci = fit.exp_breakpoints()
    # Sampling sd of ln(breakpoint) here is 0.025 (500 draws); coverage is tested above.
    assert abs(fit.breakpoints[0] - np.log(3.3)) < 0.08
    assert bp_ci[0, 0] < bp[0] < bp_ci[0, 1] and bp[0] == pytest.approx(3.3, rel=0.15)
    np.testing.assert_allclose(fit.slopes, [1.0, 2.2], atol=0.1)
    fit2, _ = loglog_segmented(K_m, T, 2)
    assert fit2.n_breakpoints == 2


# ------------------------------------------------------------------ Arrhenius
K_GRID = np.array([1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0])
TRIALS = np.full(K_GRID.size, 60_000)  # e.g. 200 periods x 300 bulk particles


@pytest.mark.parametrize("method", ["wls", "poisson"])
@pytest.mark.parametrize("cluster", [1, 3])
def test_arrhenius_recovers_barrier_with_covering_intervals(method, cluster):
    """cluster=3: slips come in threes (overdispersed); the dispersion factor copes."""
    rng = np.random.default_rng(20 + cluster)
    p = 0.5 * np.exp(-7.0 / K_GRID)
    draws, covered, E = 200, 0, []
    for _ in range(draws):
        k = cluster * rng.binomial(TRIALS // cluster, p)
        r = arrhenius_fit(K_GRID, n_slips=k, n_trials=TRIALS, method=method)
        covered += r.E_b_ci[0] <= 7.0 <= r.E_b_ci[1]
        E.append(r.E_b)
    assert abs(np.mean(E) - 7.0) < 3 * np.std(E) / np.sqrt(draws)
    rate = covered / draws
    # Measured 0.92-0.935 over 400 draws: slightly conservative (max(1, chi2) and t).
    assert 0.9 - 3 * np.sqrt(0.09 / draws) <= rate <= 0.99, rate


def test_arrhenius_with_sem_and_exact_line():
    p = 2.0 * np.exp(-130.0 / K_GRID * 0.1)
    r = arrhenius_fit(K_GRID, p, p_s_sem=0.01 * p)
    assert r.E_b == pytest.approx(13.0, rel=1e-10) and r.log_A == pytest.approx(np.log(2.0))
    assert r.scale == 1.0 and r.E_b_se == pytest.approx(0.01 / np.sqrt(
        np.sum((1 / K_GRID - np.mean(1 / K_GRID)) ** 2)), rel=1e-9)  # fmt: skip
    np.testing.assert_allclose(r.predict(K_GRID), p, rtol=1e-10)


def test_zero_counts_give_upper_bounds_not_logs():
    assert zero_count_upper_bound(1000, 0.95) == pytest.approx(1 - 0.05 ** (1 / 1000))
    assert (1 - zero_count_upper_bound(60_000)) ** 60_000 == pytest.approx(0.05)
    K = np.array([0.4, 0.6, 1.5, 2.0, 3.0, 4.0])
    n = np.full(K.size, 60_000)
    k = np.array([0, 0, 280, 1800, 5900, 10500])
    r = arrhenius_fit(K, n_slips=k, n_trials=n)
    assert r.n_points == 4 and np.isfinite(r.E_b)
    np.testing.assert_allclose(r.zero_K_m, [0.4, 0.6])
    np.testing.assert_allclose(r.zero_upper, zero_count_upper_bound(60_000))
    assert r.zero_consistent.all()
    # The likelihood fit uses the zeros directly and agrees.
    g = arrhenius_fit(K, n_slips=k, n_trials=n, method="poisson")
    assert g.n_points == 6 and g.E_b == pytest.approx(r.E_b, abs=3 * r.E_b_se)
    # A region with no slip at all (crystal A1): no barrier, only bounds.
    z = arrhenius_fit(K[:2], n_slips=k[:2], n_trials=n[:2])
    assert np.isnan(z.E_b) and len(z.zero_upper) == 2


def test_arrhenius_by_region():
    K = np.array([0.5, 0.8, 1.2, 1.6, 2.0, 2.6, 3.4, 4.5, 6.0, 8.0])
    p = np.where(K <= 1.0, 0.0, np.where(K <= 3.0, 1e12 * np.exp(-40 / K), 0.5 * np.exp(-7 / K)))
    n = np.full(K.size, 10**7)
    fits = arrhenius_by_region(K, [1.0, 3.0], p_s=p, n_trials=n, p_s_sem=0.02 * p + 1e-30)
    assert set(fits) == {"A1", "A2", "B"}
    assert np.isnan(fits["A1"].E_b) and len(fits["A1"].zero_K_m) == 2
    assert fits["A2"].E_b == pytest.approx(40.0, rel=1e-6)
    assert fits["B"].E_b == pytest.approx(7.0, rel=1e-6)
