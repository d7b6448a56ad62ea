"""Event-aligned averages: runs above a threshold, replicas shifted by known amounts."""

import numpy as np
import pytest

from granpipe.analysis.events import (
    align_on_events,
    align_on_many_events,
    event_aligned_average,
    first_run,
)


def test_first_run_finds_the_first_long_enough_run():
    m = np.array([0, 1, 1, 0, 1, 1, 1, 1, 0, 1], bool)
    assert first_run(m, 2) == 1
    assert first_run(m, 3) == 4
    assert first_run(m, 4) == 4
    assert first_run(m, 5) == -1  # never five in a row
    assert first_run(m, 1, start=8) == 9
    assert first_run(m, 2, start=2) == 4
    # a run cut by the end of the record does not count
    assert first_run(np.array([0, 0, 1, 1], bool), 3) == -1
    # vectorised, with a start per series
    M = np.stack([m, ~m])
    np.testing.assert_array_equal(first_run(M, 2, start=np.array([0, 0])), [1, -1])
    np.testing.assert_array_equal(first_run(M, 1, start=np.array([2, 2])), [2, 3])
    with pytest.raises(ValueError):
        first_run(m, 0)


def _shape(tau):
    """A sharp step with a bump after it: smeared by any misalignment."""
    return np.where(tau < 0, -1.0, 1.0) + np.exp(-(((tau - 1.0) / 0.3) ** 2))


def test_alignment_of_shifted_replicas_recovers_the_unshifted_mean():
    dt = 0.01
    t = np.arange(0.0, 30.0, dt)
    rng = np.random.default_rng(3)
    shifts = rng.integers(500, 2500, size=40) * dt  # events at 5-25 s, on the grid
    Y = np.stack([_shape(t - s) for s in shifts])
    tau, mean, sem, count = event_aligned_average(t, Y, shifts, before=4.0, after=4.0)
    assert tau[0] == pytest.approx(-4.0) and tau[-1] == pytest.approx(4.0)
    np.testing.assert_allclose(mean, _shape(tau), atol=1e-12)
    np.testing.assert_allclose(sem, 0.0, atol=1e-12)
    assert (count == 40).all()
    # the plain ensemble mean at fixed t smears the step over the spread of the events
    plain = Y.mean(0)
    i = np.searchsorted(t, np.median(shifts))
    assert abs(plain[i]) < 0.6


def test_alignment_places_off_grid_events_on_the_nearest_sample_and_counts_coverage():
    dt = 0.1
    t = np.arange(0.0, 10.0, dt)  # 100 samples, 0 .. 9.9
    Y = np.tile(t, (3, 1))
    events = np.array([2.04, 9.5, np.nan])
    tau, Z = align_on_events(t, Y, events, before=1.0, after=1.0)
    assert Z.shape == (3, 21)
    np.testing.assert_allclose(Z[0], 2.0 + tau, atol=1e-12)  # 2.04 -> sample at 2.0
    # the second record ends 0.4 s after its event; the third has no event
    np.testing.assert_allclose(Z[1, :15], 9.5 + tau[:15], atol=1e-12)
    assert np.isnan(Z[1, 15:]).all() and np.isnan(Z[2]).all()
    _, mean, _, count = event_aligned_average(t, Y, events, 1.0, 1.0)
    np.testing.assert_array_equal(count, np.r_[np.full(15, 2), np.full(6, 1)])
    np.testing.assert_allclose(mean[15:], 2.0 + tau[15:], atol=1e-12)  # replica 0 alone
    np.testing.assert_allclose(mean[:15], 0.5 * (2.0 + 9.5) + tau[:15], atol=1e-12)


def test_align_on_many_events_pools_each_replica_over_its_own_events():
    """A bump f(t − e) at each event e: every replica's mean over its events is f itself,
    the counts are its events that reach each τ (one fewer where one lies too close to the
    record's end), a replica without events is NaN with count 0."""
    t = np.arange(1000) * 0.01
    f = lambda x: np.exp(-(x**2) / 0.02)  # noqa: E731
    events = [np.array([2.0, 5.0, 9.5]), np.array([], float), np.array([3.0])]
    Y = np.stack([sum((f(t - e) for e in ev), np.zeros_like(t)) for ev in events])
    tau, means, counts = align_on_many_events(t, Y, events, 0.5, 0.8)
    assert tau[0] == pytest.approx(-0.5) and tau[-1] == pytest.approx(0.8)
    np.testing.assert_allclose(means[0], f(tau), atol=1e-12)
    np.testing.assert_allclose(means[2], f(tau), atol=1e-12)
    assert np.all(np.isnan(means[1])) and not counts[1].any()
    # the event at 9.5 s reaches τ <= 0.49 only (the record ends at 9.99 s)
    np.testing.assert_array_equal(counts[0], np.where(tau <= 0.495, 3, 2))
