"""Random placement of the mobile disks inside the drum (Sec. II.2)."""

import numpy as np
import pytest

from granpipe.drum import model
from granpipe.drum.preparation import min_gap, random_placement

PAPER = model.PAPER_PHYSICS


def test_placement_is_inside_without_overlap_and_seeded():
    d = model.diameters(PAPER)
    g = model.geometry(PAPER)
    p1 = random_placement(d, g.inner_radius, np.random.default_rng(3), gap=0.05)
    p2 = random_placement(d, g.inner_radius, np.random.default_rng(3), gap=0.05)
    np.testing.assert_array_equal(p1, p2)
    assert min_gap(p1, d) >= 0.05
    r = np.hypot(p1[:, 0], p1[:, 1]) + d / 2
    assert r.max() <= g.inner_radius - 0.05 + 1e-12
    # uniform over the drum: about half the disks in the lower half
    assert 0.4 < np.mean(p1[:, 1] < 0) < 0.6


def test_placement_refuses_an_overfull_drum():
    d = np.ones(200)
    with pytest.raises(RuntimeError, match="too full"):
        random_placement(d, 5.0, np.random.default_rng(0), max_attempts=200)
