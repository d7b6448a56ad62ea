"""Fitted quantities with fit errors and bootstrap intervals: windowed polynomial fits
of ensemble means, their vertex and zero times, and the percentile bootstrap.

Every fitted time carries

* a **fit error** — delta-method propagation of the covariance of the
  polynomial coefficients (weighted by the SEMs of the ensemble mean when
  given; see ``error_scale``). The ensemble mean at neighbouring times is
  correlated (the same replicas contribute everywhere), which no per-point
  weighting captures, so this is a model-based error, and
* a **bootstrap confidence interval** — resample replicas (or batches) with
  replacement, recompute the ensemble mean, refit; percentile interval. This one
  respects the correlation in time and is the honest one.

Fits are vectorised: ``Y`` may be (..., time); all series are fitted at once by
batched normal equations in the scaled variable u = (t − t_ref)/h (well
conditioned for the low degrees used here). Per-series weights (zero outside the
window or at NaN samples) let every resample carry its own window, which is
how automatic window modes run inside the bootstrap.

The drum's onset, sign-change and lag fits (Maghsoodi & Luijten 2016, Sec. III) are
built on these in :mod:`granpipe.drum.fits`.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from .smoothing import moving_average

__all__ = [
    "FitResult",
    "BootstrapResult",
    "polyfit_window",
    "vertex_times",
    "zero_crossing_times",
    "first_crossing",
    "argmin_time",
    "resample_counts",
    "bootstrap_replicas",
    "bootstrap_batches",
]


# --------------------------------------------------------------------- results
@dataclass(frozen=True)
class FitResult:
    """A fitted quantity with its fit error and (optionally) a bootstrap CI.

    Attributes
    ----------
    quantity : str
        Name in the paper's words (``onset_time``, ``sign_change_time``, ``lag``).
    value, fit_error : float [unit]
    unit : str
    ci_low, ci_high : float [unit]
        Percentile bootstrap interval at ``ci_level`` (``NaN`` if not computed).
    n : int or None
        Number of replicas behind the ensemble mean.
    n_resamples : int
        Bootstrap resamples used (0 if none); ``n_failed`` of them gave no value.
    window : (float, float) or None
        Fit window actually used (t_lo, t_hi).
    coefficients, covariance : arrays or None
        Polynomial coefficients in ascending powers of (t − t_ref) and their
        covariance (already scaled as described by ``error_scale``).
    chi2_red : float
        Reduced χ² of the fit (weighted residuals when SEMs were given).
    note : str
        Why ``value`` is NaN when a fit was refused (e.g. a vertex that is a maximum),
        else empty.
    """

    quantity: str
    value: float
    fit_error: float
    unit: str = ""
    ci_low: float = math.nan
    ci_high: float = math.nan
    ci_level: float = math.nan
    n: int | None = None
    n_resamples: int = 0
    n_failed: int = 0
    window: tuple[float, float] | None = None
    t_ref: float = 0.0
    coefficients: np.ndarray | None = field(default=None, repr=False)
    covariance: np.ndarray | None = field(default=None, repr=False)
    chi2_red: float = math.nan
    method: str = ""
    note: str = ""

    def with_ci(self, boot: BootstrapResult, column: int = 0) -> FitResult:
        """A copy carrying the bootstrap interval of ``boot`` (column ``column``)."""
        return dataclasses.replace(
            self,
            ci_low=float(np.atleast_1d(boot.ci_low)[column]),
            ci_high=float(np.atleast_1d(boot.ci_high)[column]),
            ci_level=boot.level,
            n_resamples=boot.n_resamples,
            n_failed=int(np.atleast_1d(boot.n_failed)[column]),
            n=boot.n if self.n is None else self.n,
        )

    def to_row(self, study: str, paper_value: float | None = None) -> dict:
        """A ``summary.csv`` row (:func:`granpipe.analysis.summary.summary_row`)."""
        from .summary import summary_row

        return summary_row(
            study, self.quantity, self.value, self.unit,
            fit_error=self.fit_error, ci_low=self.ci_low, ci_high=self.ci_high, n=self.n,
            paper_value=paper_value,
        )  # fmt: skip


@dataclass(frozen=True)
class BootstrapResult:
    """Bootstrap replicates of a statistic and their percentile interval.

    ``samples`` is (n_resamples, k); ``ci_low``/``ci_high``/``n_failed`` are (k,);
    ``n`` is the number of resampled units (replicas or batches).
    """

    samples: np.ndarray
    ci_low: np.ndarray
    ci_high: np.ndarray
    level: float
    n_resamples: int
    n: int
    n_failed: np.ndarray
    seed: int | None = None

    @property
    def std(self) -> np.ndarray:
        """(k,) bootstrap standard deviation of the statistic (NaN resamples ignored)."""
        return np.nanstd(self.samples, axis=0, ddof=1)


# ------------------------------------------------------------------ core fits
def _weights(t, Y, window, sigma):
    """Per-series weights (..., T): 1/σ² (or 1) inside the window at finite samples."""
    t = np.asarray(t, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    lo = np.asarray(window[0], dtype=np.float64)[..., np.newaxis]
    hi = np.asarray(window[1], dtype=np.float64)[..., np.newaxis]
    inside = (t >= lo) & (t <= hi)
    w = np.where(inside & np.isfinite(Y), 1.0, 0.0)
    if sigma is not None:
        s = np.asarray(sigma, dtype=np.float64)
        good = np.isfinite(s) & (s > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            w = w * np.where(good, 1.0 / (s * s), 0.0)
    return w


def polyfit_window(
    t: np.ndarray,
    Y: np.ndarray,
    window,
    deg: int,
    sigma: np.ndarray | None = None,
    *,
    t_ref: float | None = None,
    error_scale: str = "auto",
):
    """Weighted least-squares polynomial fits of many series on a window at once.

    Parameters
    ----------
    t : (T,) float [time]
    Y : (..., T) float; NaN samples are ignored.
    window : (t_lo, t_hi), each a float or an array broadcastable to Y.shape[:-1]
        Closed interval of t used by each series (per-series windows allowed).
    deg : int
        Polynomial degree (1: line, 2: parabola).
    sigma : (T,) or (..., T) float, optional
        Standard errors of Y (e.g. SEM of the ensemble mean); weights 1/σ².
    t_ref : float, optional
        Expansion point; default the centre of the (first) window.
    error_scale : {"auto", "absolute", "residual"}
        How the coefficient covariance is scaled. ``"residual"``: (AᵀWA)⁻¹ · χ²/(n−p)
        (the usual unweighted least-squares error). ``"absolute"``: (AᵀWA)⁻¹,
        trusting σ. ``"auto"`` (default): ``"residual"`` without σ; with σ,
        absolute but inflated by χ²_red when χ²_red > 1 (the model or the σ is
        then shown to be wrong; the Particle Data Group's scale factor).

    Returns
    -------
    coef : (..., deg+1) ascending powers of (t − t_ref)
    cov : (..., deg+1, deg+1)
    chi2_red : (...,)
    n_points : (...,) int
    t_ref : float
    """
    t = np.asarray(t, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    p = deg + 1
    w = _weights(t, Y, window, sigma)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN per-series windows
        lo = np.nanmin(np.ravel(window[0]))
        hi = np.nanmax(np.ravel(window[1]))
        if t_ref is None:
            t_ref = float(np.nanmedian(0.5 * (np.ravel(window[0]) + np.ravel(window[1]))))
    if not np.isfinite(t_ref):
        t_ref = float(np.mean(t))
    h = 0.5 * (hi - lo) if np.isfinite(hi - lo) and hi > lo else 1.0
    u = (t - t_ref) / h
    A = u[:, np.newaxis] ** np.arange(p)  # (T, p)
    Yz = np.where(w > 0, Y, 0.0)
    G = np.einsum("...t,ti,tj->...ij", w, A, A)
    rhs = np.einsum("...t,ti,...t->...i", w, A, Yz)
    n_points = (w > 0).sum(axis=-1)
    ok = n_points >= p
    eye = np.broadcast_to(np.eye(p), G.shape)
    G_safe = np.where(ok[..., np.newaxis, np.newaxis], G, eye)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            Ginv = np.linalg.inv(G_safe)
        except np.linalg.LinAlgError:
            Ginv = np.linalg.pinv(G_safe)
        coef_u = np.einsum("...ij,...j->...i", Ginv, rhs)
        resid = np.where(w > 0, Y - np.einsum("ti,...i->...t", A, coef_u), 0.0)
        chi2 = (w * resid * resid).sum(axis=-1)
        dof = n_points - p
        chi2_red = np.where(dof > 0, chi2 / np.maximum(dof, 1), np.nan)
    if error_scale == "auto":
        factor = chi2_red if sigma is None else np.where(chi2_red > 1.0, chi2_red, 1.0)
    elif error_scale == "residual":
        factor = chi2_red
    elif error_scale == "absolute":
        factor = np.ones_like(chi2_red)
    else:
        raise ValueError("error_scale must be 'auto', 'absolute' or 'residual'")
    cov_u = Ginv * np.asarray(factor)[..., np.newaxis, np.newaxis]
    # Back from u = (t - t_ref)/h to powers of (t - t_ref).
    scale = h ** -np.arange(p, dtype=np.float64)
    coef = coef_u * scale
    cov = cov_u * scale[:, np.newaxis] * scale[np.newaxis, :]
    coef = np.where(ok[..., np.newaxis], coef, np.nan)
    cov = np.where(ok[..., np.newaxis, np.newaxis], cov, np.nan)
    return coef, cov, chi2_red, n_points, float(t_ref)


def _quad_form(g, cov):
    with np.errstate(invalid="ignore"):
        return np.sqrt(np.einsum("...i,...ij,...j->...", g, cov, g))


def vertex_times(t, Y, window, sigma=None, *, t_ref=None, error_scale="auto"):
    """Vertex time −c₁/(2c₂) of quadratic fits on a window, vectorised.

    Returns ``(value, fit_error, extras)`` with value and fit_error (...,) [time]
    and extras a dict (coef, cov, chi2_red, n_points, t_ref). The error is
    the delta method: ∂t*/∂c₁ = −1/(2c₂), ∂t*/∂c₂ = c₁/(2c₂²). A fit with
    c₂ ≤ 0 (a maximum) still returns its vertex; check ``coef[..., 2]``.
    """
    coef, cov, chi2_red, n_points, t_ref = polyfit_window(
        t, Y, window, 2, sigma, t_ref=t_ref, error_scale=error_scale
    )
    c1, c2 = coef[..., 1], coef[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        value = t_ref - c1 / (2.0 * c2)
        g = np.stack([np.zeros_like(c1), -1.0 / (2.0 * c2), c1 / (2.0 * c2 * c2)], axis=-1)
    err = _quad_form(g, cov)
    return value, err, dict(coef=coef, cov=cov, chi2_red=chi2_red, n_points=n_points, t_ref=t_ref)


def zero_crossing_times(t, Y, window, sigma=None, *, t_ref=None, error_scale="auto"):
    """Zero −c₀/c₁ of linear fits on a window, vectorised.

    Returns ``(value, fit_error, extras)`` as :func:`vertex_times`; the error
    uses ∂t*/∂c₀ = −1/c₁, ∂t*/∂c₁ = c₀/c₁².
    """
    coef, cov, chi2_red, n_points, t_ref = polyfit_window(
        t, Y, window, 1, sigma, t_ref=t_ref, error_scale=error_scale
    )
    c0, c1 = coef[..., 0], coef[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        value = t_ref - c0 / c1
        g = np.stack([-1.0 / c1, c0 / (c1 * c1)], axis=-1)
    err = _quad_form(g, cov)
    return value, err, dict(coef=coef, cov=cov, chi2_red=chi2_red, n_points=n_points, t_ref=t_ref)


# -------------------------------------------------------------- auto windows
def first_crossing(t, Y, search=None, direction: int = 0, hold: int = 0) -> np.ndarray:
    """Time of the first zero crossing of each series in ``search``, vectorised.

    Parameters
    ----------
    t : (T,) ; Y : (..., T), e.g. λ̄ (NaN samples never bracket a crossing)
    search : (t_lo, t_hi), optional; each bound a float or an array (..., 1)
    direction : +1 (− to +), −1 (+ to −) or 0 (either)
    hold : int
        Count a crossing only if the series keeps its new sign (and stays finite) over
        the next ``hold`` samples, all inside the search range: a noisy curve crosses
        zero many times before it changes sign for good.

    Returns (...,) the linearly interpolated crossing time, NaN if none (or fewer than two
    samples).
    """
    t = np.asarray(t, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    if t.size < 2:  # one sample brackets no crossing
        return np.full(Y.shape[:-1], np.nan)
    if search is None:
        inside = np.ones_like(t, dtype=bool)
    else:  # bounds may be arrays (..., 1), one search range per series
        inside = (t >= np.asarray(search[0])) & (t <= np.asarray(search[1]))
    inside = np.broadcast_to(inside, Y.shape)
    y0, y1 = Y[..., :-1], Y[..., 1:]
    ok = inside[..., :-1] & inside[..., 1:] & np.isfinite(y0) & np.isfinite(y1)
    up = (y0 < 0) & (y1 >= 0)
    down = (y0 > 0) & (y1 <= 0)
    if direction > 0:
        cross = ok & up
    elif direction < 0:
        cross = ok & down
    else:
        cross = ok & (up | down)
    if hold > 0:
        with np.errstate(invalid="ignore"):
            pos = inside & (Y >= 0)
            neg = inside & (Y <= 0)

        def persists(good):
            # the samples i+1 .. i+hold are all good: a window count of the bad ones
            bad = np.concatenate([np.zeros(Y.shape[:-1] + (1,)), np.cumsum(~good, -1)], -1)
            n = Y.shape[-1]
            end = np.minimum(np.arange(1, n) + hold, n)
            counts = bad[..., end] - bad[..., 1:n]
            return (counts == 0) & (np.arange(1, n) + hold <= n)

        keep = np.where(up, persists(pos), persists(neg))
        cross = cross & keep
    has = cross.any(axis=-1)
    i = np.argmax(cross, axis=-1)
    a = np.take_along_axis(y0, i[..., np.newaxis], -1)[..., 0]
    b = np.take_along_axis(y1, i[..., np.newaxis], -1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        tc = t[i] + (t[i + 1] - t[i]) * a / (a - b)
    return np.where(has, tc, np.nan)


def argmin_time(t, Y, search, smooth_q):
    """Time of the smallest value of each series within ``search`` after a
    (2·smooth_q+1)-point moving average, vectorised over (..., T); NaN if none."""
    t = np.asarray(t, dtype=np.float64)
    Ys = moving_average(Y, smooth_q) if smooth_q else np.asarray(Y, dtype=np.float64)
    inside = np.ones_like(t, dtype=bool) if search is None else (t >= search[0]) & (t <= search[1])
    Z = np.where(inside & np.isfinite(Ys), Ys, np.inf)
    i = np.argmin(Z, axis=-1)
    best = np.take_along_axis(Z, i[..., np.newaxis], -1)[..., 0]
    return np.where(np.isfinite(best), t[i], np.nan)


# ------------------------------------------------------------------ bootstrap
def resample_counts(n: int, n_resamples: int, rng: np.random.Generator) -> np.ndarray:
    """(n_resamples, n) float64: how often each unit is drawn in each resample.

    Drawing n units with replacement is one multinomial(n, 1/n) draw per resample.
    """
    return rng.multinomial(n, np.full(n, 1.0 / n), size=n_resamples).astype(np.float64)


def _bootstrap_core(statistic, sums, counts, n_units, n_resamples, level, seed, chunk):
    rng = np.random.default_rng(seed)
    out = []
    for start in range(0, n_resamples, chunk):
        b = min(chunk, n_resamples - start)
        W = resample_counts(n_units, b, rng)
        means = []
        for s, c in zip(sums, counts, strict=True):
            with np.errstate(invalid="ignore", divide="ignore"):
                means.append((W @ s) / (W @ c))
        stat = np.asarray(statistic(*means), dtype=np.float64)
        out.append(stat.reshape(b, -1))
    samples = np.concatenate(out, axis=0)
    alpha = 0.5 * (1.0 - level)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        lo = np.nanquantile(samples, alpha, axis=0)
        hi = np.nanquantile(samples, 1.0 - alpha, axis=0)
    n_failed = np.isnan(samples).sum(axis=0)
    if np.any(n_failed > 0.05 * n_resamples):
        warnings.warn(
            f"{int(n_failed.max())} of {n_resamples} bootstrap resamples gave no value",
            RuntimeWarning,
            stacklevel=3,
        )
    return BootstrapResult(
        samples,
        lo,
        hi,
        level,
        n_resamples,
        n_units,
        n_failed,
        seed if isinstance(seed, int) else None,
    )


def _as_list(x):
    if isinstance(x, np.ndarray):
        return [x]
    return list(x)


def bootstrap_replicas(
    replicas: np.ndarray | Sequence[np.ndarray],
    statistic: Callable[..., np.ndarray],
    *,
    n_resamples: int = 1000,
    level: float = 0.90,
    seed: int | np.random.SeedSequence | None = None,
    chunk: int = 250,
) -> BootstrapResult:
    """Percentile bootstrap over replicas of a statistic of the ensemble mean.

    Parameters
    ----------
    replicas : (R, T) array, or a sequence of them sharing the replica axis
        (e.g. V and λ of the same runs: resampled *jointly*, so that a
        statistic combining them, like the lag, keeps their correlation).
        NaN marks a missing sample; means are NaN-aware.
    statistic : callable
        ``statistic(mean_1, mean_2, ...)`` with each mean (b, T) for a chunk of b
        resamples, returning (b,) or (b, k). Vectorise it
        (:func:`vertex_times`, :func:`zero_crossing_times`).
    n_resamples, level : int, float
        Number of resamples; two-sided percentile interval level (0.90 → 5 %, 95 %).
    seed : int or SeedSequence
        Seed for ``numpy.random.default_rng``: same seed, same interval.
    chunk : int
        Resamples per chunk; memory is O(chunk · T) per variable.

    Notes
    -----
    Each resample's mean is ``(W @ X) / (W @ finite(X))`` with W the (b, R)
    multinomial counts: one matrix product per chunk (1000 resamples of
    100 × 5000 replicas take well under a second).
    """
    reps = [np.asarray(r, dtype=np.float64) for r in _as_list(replicas)]
    R = reps[0].shape[0]
    if any(r.shape[0] != R for r in reps):
        raise ValueError("all replica arrays must share the replica axis")
    sums = [np.where(np.isfinite(r), r, 0.0) for r in reps]
    counts = [np.isfinite(r).astype(np.float64) for r in reps]
    return _bootstrap_core(statistic, sums, counts, R, n_resamples, level, seed, chunk)


def bootstrap_batches(
    batch_means: np.ndarray | Sequence[np.ndarray],
    batch_counts: np.ndarray | Sequence[np.ndarray],
    statistic: Callable[..., np.ndarray],
    *,
    n_resamples: int = 1000,
    level: float = 0.90,
    seed: int | np.random.SeedSequence | None = None,
    chunk: int = 250,
) -> BootstrapResult:
    """Percentile bootstrap over batches (paper scale: 70,000 replicas in batches).

    Batches are independent groups of replicas; resampling whole batches and
    pooling their means with their counts (Σ w_b c_b m_b / Σ w_b c_b) resamples
    the ensemble mean without reading any replica again. Needs a few tens of
    batches at least. Parameters as :func:`bootstrap_replicas`, with
    ``batch_means`` (nb, T) and ``batch_counts`` (nb, T) (one per variable, or
    one counts array shared by all).
    """
    means = [np.asarray(m, dtype=np.float64) for m in _as_list(batch_means)]
    counts = [np.asarray(c, dtype=np.float64) for c in _as_list(batch_counts)]
    if len(counts) == 1 and len(means) > 1:
        counts = counts * len(means)
    sums, cnts = [], []
    for m, c in zip(means, counts, strict=True):
        has = np.isfinite(m) & (c > 0)
        sums.append(np.where(has, m * c, 0.0))
        cnts.append(np.where(has, c, 0.0))
    return _bootstrap_core(
        statistic, sums, cnts, means[0].shape[0], n_resamples, level, seed, chunk
    )
