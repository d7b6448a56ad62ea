"""Does a score predict an event? ROC curves, their area, and precision at a set's size.

Used to test whether the Lyapunov vector predicts *when* and *where* a packing
rearranges (Banigan et al., Nature Phys. 9, 288 (2013), the drum paper's Ref. [20];
docs/shear.md, "Predicting rearrangements"):

* *when* — a score per moment (the finite-time maximal exponent over a short window
  ending there, :func:`trailing_mean`) against a label (an event follows within a
  horizon, :func:`event_follows`): :func:`roc_curve` and :func:`roc_auc`, pooled over
  replicas, with :func:`bootstrap_auc` resampling whole replicas (moments of one
  replica are not independent);
* *where* — a score per disk (|δu_i| before the event) against the set of disks that
  rearrange: :func:`precision_at_size` (the fraction of the set among the highest
  scores, as many as the set holds; a random score gives the set's share of the disks
  on average) and :func:`roc_auc` over the disks, both for several scores of one event
  at once by :func:`locate` (the shear cell's rearrangements, the drum's avalanche
  onsets).

The area under the ROC curve is the Mann–Whitney probability that a positive scores
above a negative (ties count one half): 0.5 for a score unrelated to the label, 1 for
a perfect one. Plain numpy and scipy; nothing here knows a study.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.stats import rankdata

from .bootstrap import BootstrapResult, resample_counts

__all__ = ["roc_curve", "roc_auc", "bootstrap_auc", "precision_at_size", "locate",
           "trailing_mean", "event_follows"]  # fmt: skip


def _finite(scores, labels):
    s = np.asarray(scores, dtype=np.float64).ravel()
    y = np.asarray(labels, dtype=bool).ravel()
    if s.shape != y.shape:
        raise ValueError("scores and labels must have the same size")
    ok = np.isfinite(s)
    return s[ok], y[ok]


def roc_curve(scores: np.ndarray, labels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The ROC curve of ``scores`` (n,) predicting ``labels`` (n,) bool (NaN scores
    left out): (false-positive rate, true-positive rate), each (m + 1,) from (0, 0) to
    (1, 1), one point per distinct score threshold from the highest down. NaN arrays
    when either class is empty."""
    s, y = _finite(scores, labels)
    n1, n0 = int(y.sum()), int((~y).sum())
    if n1 == 0 or n0 == 0:
        return np.array([np.nan]), np.array([np.nan])
    order = np.argsort(-s, kind="stable")
    s, y = s[order], y[order]
    last = np.r_[np.flatnonzero(np.diff(s)), len(s) - 1]  # the last of each tied run
    tp = np.cumsum(y)[last]
    fp = (last + 1) - tp
    return np.r_[0.0, fp / n0], np.r_[0.0, tp / n1]


def roc_auc(scores: np.ndarray, labels: np.ndarray) -> float:
    """Area under the ROC curve (Mann–Whitney U / (n₁ n₀), ties one half); NaN when
    either class is empty. NaN scores are left out."""
    s, y = _finite(scores, labels)
    n1, n0 = int(y.sum()), int((~y).sum())
    if n1 == 0 or n0 == 0:
        return math.nan
    ranks = rankdata(s)
    return float((ranks[y].sum() - n1 * (n1 + 1) / 2.0) / (n1 * n0))


def _pair_counts(scores, labels):
    """Per pair of units (r, s): U[r, s] = #(positive of r above negative of s) + ½ ties,
    and the positives P[r] and negatives N[s] of each unit."""
    units = [_finite(s, y) for s, y in zip(scores, labels, strict=True)]
    neg = [np.sort(s[~y]) for s, y in units]
    R = len(units)
    U = np.zeros((R, R))
    for r, (s, y) in enumerate(units):
        pos = s[y]
        for q in range(R):
            below = np.searchsorted(neg[q], pos, side="left")
            tied = np.searchsorted(neg[q], pos, side="right") - below
            U[r, q] = below.sum() + 0.5 * tied.sum()
    P = np.array([y.sum() for _, y in units], dtype=np.float64)
    N = np.array([(~y).sum() for _, y in units], dtype=np.float64)
    return U, P, N


def bootstrap_auc(scores: Sequence[np.ndarray], labels: Sequence[np.ndarray], *,
                  n_resamples: int = 1000, level: float = 0.95,
                  seed: int | None = None) -> tuple[float, BootstrapResult]:  # fmt: skip
    """The pooled ROC area of several units (replicas: ``scores[r]``, ``labels[r]``)
    and its percentile bootstrap over units.

    Each resample draws the units with replacement and pools their moments: with c_r
    the draws of unit r, AUC = Σ_rs c_r c_s U_rs / (Σ c_r P_r · Σ c_s N_s), exactly the
    area of the pooled resample, from the pair counts U_rs of :func:`_pair_counts`
    (one sort per unit, then a matrix product per resample).

    Returns (the pooled area of all units, the bootstrap of it).
    """
    U, P, N = _pair_counts(scores, labels)
    value = float(U.sum() / (P.sum() * N.sum())) if P.sum() and N.sum() else math.nan
    W = resample_counts(len(P), int(n_resamples), np.random.default_rng(seed))
    with np.errstate(invalid="ignore", divide="ignore"):
        samples = np.einsum("br,rs,bs->b", W, U, W) / ((W @ P) * (W @ N))
    samples = samples[:, None]
    a = 0.5 * (1.0 - level)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        lo, hi = np.nanquantile(samples, a, axis=0), np.nanquantile(samples, 1.0 - a, axis=0)
    failed = np.isnan(samples).sum(axis=0)
    return value, BootstrapResult(samples, lo, hi, level, int(n_resamples), len(P), failed,
                                  seed)  # fmt: skip


def precision_at_size(scores: np.ndarray, members: np.ndarray) -> float:
    """Of the disks with the highest ``scores`` (n,), as many as ``members`` (n,) bool
    holds (ties broken by index), the fraction that are members; NaN for no member. A
    score unrelated to membership gives the members' share on average, a perfect
    one 1."""
    s = np.asarray(scores, dtype=np.float64)
    m = np.asarray(members, dtype=bool)
    k = int(m.sum())
    if k == 0:
        return math.nan
    top = np.argsort(-np.where(np.isfinite(s), s, -np.inf), kind="stable")[:k]
    return float(m[top].mean())


def locate(scores: Mapping[str, np.ndarray], members: np.ndarray) -> dict[str, float] | None:
    """How well each score says *where* one event happens.

    Parameters
    ----------
    scores : name -> (n,) float, one score per disk (NaN left out of the area)
    members : (n,) bool, the disks of the event (the positives)

    Returns
    -------
    ``{"precision_<name>", "auc_<name>"}`` for every score (:func:`precision_at_size`,
    :func:`roc_auc`), ``"precision_random"`` (the members' share of the disks: a random
    choice's expected precision) and ``"event_size"`` (the members); None when the
    event has no member.
    """
    m = np.asarray(members, dtype=bool)
    if not m.any():
        return None
    out = {f"precision_{k}": precision_at_size(s, m) for k, s in scores.items()}
    out["precision_random"] = float(m.mean())
    out.update({f"auc_{k}": roc_auc(s, m) for k, s in scores.items()})
    out["event_size"] = int(m.sum())
    return out


def trailing_mean(series: np.ndarray, window: int) -> np.ndarray:
    """(..., S) mean of the last ``window`` (>= 1) samples ending at each sample
    (``series`` (..., S)); NaN for the first ``window`` − 1 samples."""
    x = np.asarray(series, dtype=np.float64)
    w = int(window)
    if w < 1:
        raise ValueError("window must be at least one sample")
    c = np.concatenate([np.zeros(x.shape[:-1] + (1,)), np.cumsum(x, axis=-1)], axis=-1)
    out = np.full(x.shape, np.nan)
    out[..., w - 1 :] = (c[..., w:] - c[..., :-w]) / w
    return out


def event_follows(n_samples: int, events: np.ndarray, horizon: int) -> np.ndarray:
    """(S,) bool: an event (indices ``events``) at a sample in (k, k + ``horizon``]."""
    follows = np.zeros(int(n_samples) + int(horizon) + 1, dtype=np.int64)
    for e in np.asarray(events, dtype=np.int64):
        lo = max(int(e) - int(horizon), 0)  # k >= e − horizon and k < e
        follows[lo] += 1
        follows[int(e)] -= 1
    return np.cumsum(follows)[: int(n_samples)] > 0
