"""Initial states of the drum: random placement of the mobile disks (Sec. II.2) and the
paper start-up's free fall."""

import numpy as np
import pytest

from granpipe.drum import model
from granpipe.drum.layout import steps
from granpipe.drum.model import DrumModel
from granpipe.drum.preparation import fall, min_gap, random_placement
from granpipe.drum.protocol import tiny_section

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


def test_a_disk_released_at_the_top_falls_freely_with_no_cap(tiny):
    """Paper start-up: a disk released at rest near the top of the turning drum has, after
    0.15 s and before it touches anything, the free-fall speed sqrt(2 g h) of its drop h
    (velocity Verlet is exact under constant gravity) - far above the settled start-up's
    speed cap."""
    sec = tiny_section({}, pre_rotation_deg=0.06, tangent_alignment_s=0.0)  # 0.15 s
    sec["physics"].update(n_small=1, n_large=1)  # the second disk rests out of the way
    st = steps(sec)
    drum = DrumModel.from_physics(sec["physics"])
    top = drum.geom.inner_radius - 0.6
    start = fall(drum, st, np.array([[0.0, top], [5.0, -5.0]]))
    g = float(sec["physics"]["g"])
    drop = top - start.positions[0, 1]
    v = start.velocities[0]
    assert drop > 5.0 and abs(v[0]) < 1e-12
    assert np.hypot(*v) == pytest.approx(np.sqrt(2.0 * g * drop), rel=1e-9)
    assert np.hypot(*v) > 2.0 * sec["settle"]["max_speed"]
    assert start.n_steps == st.pre_rotation and start.settled
