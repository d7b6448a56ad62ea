"""Threshold interpolation on a Γ grid."""

import numpy as np
import pytest

from granpipe.analysis.box import BOUNCING_THRESHOLD, CONVECTION_THRESHOLD
from granpipe.analysis.thresholds import threshold_crossing, threshold_from_flags


def test_exact_on_linear_measure_any_grid():
    rng = np.random.default_rng(0)
    for _ in range(20):
        g = np.sort(rng.uniform(0.8, 4.0, size=9))
        g[0], g[-1] = 0.8, 4.0
        s_c = 0.7 * (g - 2.345) + CONVECTION_THRESHOLD  # crosses sigma at 2.345
        th = threshold_crossing(g[::-1], s_c[::-1], CONVECTION_THRESHOLD)  # unsorted input
        assert th.value == pytest.approx(2.345, abs=1e-12)
        assert th.low < 2.345 <= th.high and th.status == "crossed" and th.n_crossings == 1


def test_log_scale_exact_on_exponential_measure():
    g = np.linspace(0.8, 3.0, 12)
    s_b = BOUNCING_THRESHOLD * np.exp(4.0 * (g - 1.13))
    th = threshold_crossing(g, s_b, BOUNCING_THRESHOLD, scale="log")
    assert th.value == pytest.approx(1.13, abs=1e-12)
    lin = threshold_crossing(g, s_b, BOUNCING_THRESHOLD)
    assert lin.value != pytest.approx(1.13, abs=1e-3)  # linear interpolation is biased here


def test_band_gives_interval():
    g = np.linspace(1.0, 3.0, 11)
    m = g - 1.0
    th = threshold_crossing(g, m, 1.0, measure_low=m - 0.1, measure_high=m + 0.1)
    assert (th.ci_low, th.value, th.ci_high) == pytest.approx((1.9, 2.0, 2.1))


def test_outside_grid_and_nonmonotonic():
    g = np.array([1.0, 1.5, 2.0, 2.5])
    below = threshold_crossing(g, [2.0, 3, 4, 5], 1.0)
    assert below.status == "below_grid" and np.isnan(below.value) and below.high == 1.0
    above = threshold_crossing(g, [0.1, 0.2, 0.3, 0.4], 1.0)
    assert above.status == "above_grid" and above.low == 2.5 and np.isnan(above.high)
    wiggly = threshold_crossing(np.arange(6.0), [0, 2, 0, 0, 2, 3], 1.0)
    assert wiggly.n_crossings == 2 and wiggly.value == pytest.approx(0.5)
    last = threshold_crossing(np.arange(6.0), [0, 2, 0, 0, 2, 3], 1.0, which="last")
    assert last.value == pytest.approx(3.5)


def test_flags_bracket():
    th = threshold_from_flags([1.0, 1.2, 1.4, 1.6], [False, False, True, True])
    assert (th.low, th.value, th.high) == pytest.approx((1.2, 1.3, 1.4))
    assert (th.ci_low, th.ci_high) == (1.2, 1.4)
    assert threshold_from_flags([1.0, 2.0], [False, False]).status == "above_grid"
