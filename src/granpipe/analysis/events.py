"""Event-aligned (event-triggered) averages: each replica shifted onto its own event.

An ensemble mean at a fixed time t averages replicas whose events (an avalanche's
start, a slip) happen at different times, and so smears them: a sharp change that
every replica makes, each at its own time t_r, becomes a ramp as wide as the spread
of the t_r. Aligning every replica on its own event first — averaging
``Y_r(t_r + τ)`` at fixed τ = t − t_r — keeps the change sharp and says what happens
*relative to the event* (the drum's λ̄ after each pile's own avalanche starts,
docs/drum.md, "Aligned on each pile's avalanche").

* :func:`first_run` — the first sample of a run of ``hold`` consecutive true samples
  (the generic part of an event detector: "above a threshold for so long").
* :func:`align_on_events` — the (replica, τ) matrix of the records shifted onto their
  events, NaN where a replica's record does not reach (or it has no event).
* :func:`event_aligned_average` — mean, standard error and count per τ of that matrix.
* :func:`align_on_many_events` — several events per replica (the shear cell's
  rearrangements): each replica's mean over its own events and their count per τ, the
  (unit, τ) means and counts that :func:`~granpipe.analysis.ensemble.pooled_batch_mean`
  pools and :func:`~granpipe.analysis.bootstrap.bootstrap_batches` resamples by replica
  (events of one replica are not independent; replicas are).

The aligned matrix is what :func:`granpipe.analysis.bootstrap.bootstrap_replicas`
resamples (each replica keeps its own event time in every resample), and its batch
means with counts (:func:`granpipe.analysis.ensemble.batch_moments`) what
:func:`~granpipe.analysis.bootstrap.bootstrap_batches` resamples. Plain numpy; nothing
here knows a study.
"""

from __future__ import annotations

import numpy as np

from .ensemble import replica_mean_sem

__all__ = ["first_run", "align_on_events", "event_aligned_average", "align_on_many_events"]


def first_run(mask: np.ndarray, hold: int, start: np.ndarray | int = 0) -> np.ndarray:
    """Index of the first sample that starts ``hold`` consecutive true samples.

    Parameters
    ----------
    mask : (..., T) bool
        E.g. ``V > threshold`` per sample; a run must lie wholly inside the record.
    hold : int >= 1
        Length of the run in samples.
    start : int or (...,) int
        Only runs that start at or after this index count (per series).

    Returns
    -------
    (...,) int64: the run's first index, −1 where there is none.
    """
    m = np.asarray(mask, dtype=bool)
    hold = int(hold)
    if hold < 1:
        raise ValueError("hold must be at least one sample")
    T = m.shape[-1]
    lead = m.shape[:-1]
    if T < hold:
        return np.full(lead, -1, dtype=np.int64)
    # c[i] = number of true samples in [i, i + hold): a window sum by cumulative sums
    c = np.concatenate([np.zeros(lead + (1,), np.int64), np.cumsum(m, -1, dtype=np.int64)], -1)
    full = (c[..., hold:] - c[..., : T - hold + 1]) == hold  # (..., T - hold + 1)
    idx = np.arange(T - hold + 1)
    s = np.asarray(start, dtype=np.int64)
    full = full & (idx >= s[..., np.newaxis])
    has = full.any(axis=-1)
    return np.where(has, np.argmax(full, axis=-1), -1).astype(np.int64)


def align_on_events(
    t: np.ndarray,
    Y: np.ndarray,
    events: np.ndarray,
    before: float,
    after: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Shift each replica's record onto its own event time.

    Parameters
    ----------
    t : (T,) float [time], uniformly spaced sample times (spacing dt)
    Y : (R, T) float, one record per replica; NaN marks a missing sample
    events : (R,) float [time], each replica's event time; NaN leaves the replica out
        (its row is all NaN)
    before, after : float [time] >= 0
        The aligned axis runs from −before to +after around the event.

    Returns
    -------
    tau : (L,) float [time], τ = k·dt for k = −round(before/dt) .. round(after/dt)
    Z : (R, L) float, Z[r, k] = Y[r, i_r + k] with i_r the sample nearest the event
        (the event is placed on the sample grid: to within dt/2); NaN where i_r + k
        falls outside the record.
    """
    t = np.asarray(t, dtype=np.float64)
    Y = np.atleast_2d(np.asarray(Y, dtype=np.float64))
    ev = np.asarray(events, dtype=np.float64).reshape(-1)
    if Y.shape != (ev.size, t.size):
        raise ValueError(f"Y must be (replicas, times) = ({ev.size}, {t.size}); got {Y.shape}")
    if before < 0 or after < 0:
        raise ValueError("before and after must be >= 0")
    if t.size < 2:
        raise ValueError("need at least two samples")
    dt = float(t[1] - t[0])
    nb, na = int(round(before / dt)), int(round(after / dt))
    k = np.arange(-nb, na + 1)
    tau = k * dt
    ok = np.isfinite(ev)
    i0 = np.where(ok, np.rint((np.where(ok, ev, t[0]) - t[0]) / dt), 0).astype(np.int64)
    idx = i0[:, np.newaxis] + k[np.newaxis, :]
    inside = ok[:, np.newaxis] & (idx >= 0) & (idx < t.size)
    Z = np.where(inside, np.take_along_axis(Y, np.clip(idx, 0, t.size - 1), axis=1), np.nan)
    return tau, Z


def event_aligned_average(
    t: np.ndarray,
    Y: np.ndarray,
    events: np.ndarray,
    before: float,
    after: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean over replicas of records aligned on their own events (:func:`align_on_events`).

    Returns
    -------
    tau : (L,) [time]
    mean, sem : (L,) [Y]; NaN where no replica (sem: fewer than two) reaches τ
    count : (L,) int, replicas contributing at each τ
    """
    tau, Z = align_on_events(t, Y, events, before, after)
    mean, sem, count = replica_mean_sem(Z)
    return tau, mean, sem, count


def align_on_many_events(
    t: np.ndarray,
    Y: np.ndarray,
    events: list[np.ndarray],
    before: float,
    after: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each replica's record aligned on each of its events, pooled per replica.

    Parameters
    ----------
    t : (T,) [time], uniformly spaced; Y : (R, T), one record per replica
    events : R arrays of event times [time] (any number, possibly none, per replica)
    before, after : as :func:`align_on_events`

    Returns
    -------
    tau : (L,) [time]
    means : (R, L) [Y], the mean over a replica's events at each τ (NaN where none reach)
    counts : (R, L) int, the number of its events that reach each τ
    """
    Y = np.atleast_2d(np.asarray(Y, dtype=np.float64))
    if len(events) != Y.shape[0]:
        raise ValueError(f"{len(events)} event lists for {Y.shape[0]} replicas")
    tau, _ = align_on_events(t, Y[:1], np.array([np.nan]), before, after)
    means = np.full((Y.shape[0], tau.size), np.nan)
    counts = np.zeros((Y.shape[0], tau.size), dtype=np.int64)
    for r, ev in enumerate(events):
        ev = np.asarray(ev, dtype=np.float64).reshape(-1)
        if ev.size == 0:
            continue
        _, Z = align_on_events(t, np.repeat(Y[r : r + 1], ev.size, axis=0), ev, before, after)
        counts[r] = np.isfinite(Z).sum(axis=0)
        with np.errstate(invalid="ignore"):
            means[r] = np.where(counts[r] > 0, np.nansum(Z, axis=0) / counts[r], np.nan)
    return tau, means, counts
