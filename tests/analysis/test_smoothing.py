"""Moving average (drum Eq. 2) and FFT low-pass on signals with known answers."""

import numpy as np
import pytest

from granpipe.analysis.smoothing import (
    lowpass_fft,
    lowpass_mask,
    moving_average,
    moving_average_gain,
    paper_lowpass_cutoff,
    window_half_width,
)


def test_window_half_width_paper_values():
    assert window_half_width(0.5, 4e-3) == 62  # (2*62+1)*4 ms = 0.5 s
    assert window_half_width(0.1, 4e-3) == 12  # five times narrower: 25 samples
    assert window_half_width(1e-3, 4e-3) == 0


def test_linear_signal_unchanged_and_edges_nan():
    t = np.arange(1000) * 4e-3
    y = 3.0 - 2.5 * t
    m = moving_average(y, width=0.5, dt=4e-3)
    q = 62
    assert np.all(np.isnan(m[:q])) and np.all(np.isnan(m[-q:]))
    np.testing.assert_allclose(m[q:-q], y[q:-q], rtol=0, atol=1e-12)


def test_definition_eq2_against_direct_sum():
    rng = np.random.default_rng(0)
    y = rng.normal(size=(3, 300)) + 100.0
    q = 7
    m = moving_average(y, q)
    direct = np.array([[row[i - q : i + q + 1].mean() for i in range(q, 300 - q)] for row in y])
    np.testing.assert_allclose(m[:, q:-q], direct, rtol=1e-13)


def test_sinusoid_attenuated_by_known_gain():
    dt, q = 4e-3, 62
    t = np.arange(5000) * dt
    for f in (0.3, 1.0, 1.7, 3.1):
        y = np.sin(2 * np.pi * f * t + 0.4)
        m = moving_average(y, q)
        gain = moving_average_gain(f, q, dt)
        np.testing.assert_allclose(m[q:-q], gain * y[q:-q], atol=1e-10)
    # A period equal to the window is removed entirely (first zero of the gain).
    f0 = 1.0 / ((2 * q + 1) * dt)
    assert abs(moving_average_gain(f0, q, dt)) < 1e-12


def test_shrink_edges_and_nan_locality():
    y = np.arange(10.0)
    m = moving_average(y, 2, edges="shrink")
    assert m[0] == pytest.approx(1.0)  # mean of 0, 1, 2
    assert m[9] == pytest.approx(8.0)
    y[5] = np.nan
    m = moving_average(y, 1)
    assert np.isnan(m[[0, 4, 5, 6, 9]]).all()
    np.testing.assert_allclose(m[[1, 2, 3, 7, 8]], [1, 2, 3, 7, 8])


def test_moving_average_axis():
    y = np.tile(np.arange(20.0), (4, 1)).T  # time along axis 0
    m = moving_average(y, 3, axis=0)
    np.testing.assert_allclose(m[3:-3, 2], np.arange(3.0, 17.0))


def test_lowpass_separates_slow_from_fast():
    n, dt = 8000, 4e-3
    t = np.arange(n) * dt
    T = n * dt
    slow = 0.7 * np.sin(2 * np.pi * (3 / T) * t)  # bin 3
    fast = 0.5 * np.sin(2 * np.pi * 5.0 * t)  # 5 Hz
    y = slow + fast + 2.0
    # Periodic on the record: the periodic transform is exact.
    out = lowpass_fft(y, cutoff=1.0, dt=dt, detrend="mean", boundary="periodic")
    np.testing.assert_allclose(out, slow + 2.0, atol=1e-10)
    # Default (linear detrend, reflected): close everywhere, very close inside.
    out = lowpass_fft(y, cutoff=1.0, dt=dt)
    assert np.max(np.abs(out - slow - 2.0)) < 0.15
    assert np.max(np.abs(out - slow - 2.0)[n // 10 : -n // 10]) < 0.005


def test_lowpass_trend_and_step():
    n, dt = 7500, 4e-3
    t = np.arange(n) * dt
    fast = 0.3 * np.sin(2 * np.pi * 5.0 * t)
    for slow in (1.5 * t + np.sin(2 * np.pi * 0.2 * t), np.tanh((t - 14.5) / 3.0)):
        out = lowpass_fft(slow + fast, cutoff=1.0, dt=dt)
        err = np.abs(out - slow)
        # Within ~1/cutoff of the ends any low-pass is biased by the kink; inside it is tight.
        assert err.max() < 0.25 and err[n // 10 : -n // 10].max() < 0.005
    periodic = lowpass_fft(slow + fast, cutoff=1.0, dt=dt, boundary="periodic")
    # Without the reflection the step's end-to-end mismatch rings through the record.
    assert np.abs(periodic - slow).max() > 5 * err.max()
    # A linear signal passes unchanged.
    np.testing.assert_allclose(lowpass_fft(2 - 0.5 * t, fraction=1e-4), 2 - 0.5 * t, atol=1e-12)


def test_lowpass_mask_fraction_definition():
    n = 750_000  # paper: 30 s at the 4e-5 s step
    keep = lowpass_mask(n, fraction=8e-5)
    assert keep.sum() == 31  # k = 0..30, f_k = k/(30 s) <= 1 Hz
    np.testing.assert_array_equal(keep, lowpass_mask(n, cutoff=1.0, dt=4e-5))
    assert lowpass_mask(7500, fraction=8e-5).sum() == 1  # only DC at 4 ms sampling
    assert paper_lowpass_cutoff() == pytest.approx(1.0)


def test_lowpass_rejects_nan():
    with pytest.raises(ValueError):
        lowpass_fft(np.array([1.0, np.nan, 2.0]), fraction=0.1)
