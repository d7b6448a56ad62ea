"""Crystal and random placements: geometry checks with known answers."""

import math

import numpy as np
import pytest
from scipy.spatial.distance import pdist

from granpipe.box import model, preparation


def test_spanning_crystal_rows_touch_both_walls_and_the_plate():
    pos = preparation.crystal_positions(200, 20.0, "spanning")
    assert pos.shape == (200, 2)
    assert pdist(pos).min() == pytest.approx(1.0, abs=1e-12)
    bottom = pos[np.isclose(pos[:, 1], 0.5)]
    assert len(bottom) == 20
    assert bottom[:, 0].min() == pytest.approx(0.5) and bottom[:, 0].max() == pytest.approx(19.5)
    # rows √3/2 apart, alternating 20 and 19 disks: 200 = 5 x 39 + 5 on top
    rows = np.round((pos[:, 1] - 0.5) / preparation.ROW_SPACING).astype(int)
    counts = np.bincount(rows)
    assert list(counts[:10]) == [20, 19] * 5 and counts[10] == 5


def test_inset_crystal_leaves_room_at_the_walls():
    pos = preparation.crystal_positions(100, 20.0, "inset")
    assert pos[:, 0].min() > 0.5 + 0.2 and pos[:, 0].max() < 19.5 - 0.2
    assert pdist(pos).min() == pytest.approx(1.0, abs=1e-12)
    assert preparation.crystal_row_lengths(20.0, "inset") == (19, 19)


def test_partial_top_row_is_centred():
    pos = preparation.crystal_positions(23, 6.0, "spanning")  # rows 6, 5, 6, 5 + 1
    top = pos[pos[:, 1] == pos[:, 1].max()]
    # one of the two central sites of a 6-site row (x = 2.5 or 3.5 in Lx = 6)
    assert len(top) == 1 and abs(top[0, 0] - 3.0) == pytest.approx(0.5)


def test_random_placement_has_no_overlap_and_stays_in_the_box():
    rng = np.random.default_rng(5)
    pos = preparation.random_positions(400, 20.0, 0.3, rng)
    assert pdist(pos).min() >= 1.0
    assert pos[:, 0].min() >= 0.5 and pos[:, 0].max() <= 19.5 and pos[:, 1].min() >= 0.5
    area = 400 * math.pi / 4
    assert area / (20.0 * pos[:, 1].max()) == pytest.approx(0.3, rel=0.1)
    again = preparation.random_positions(400, 20.0, 0.3, np.random.default_rng(5))
    np.testing.assert_array_equal(pos, again)


def test_time_step_is_tc_over_50_rounded_to_whole_phases():
    phys = {"kappa_n": 1e6, "gamma_n": 100.0, "steps_per_contact": 50.0, "omega": 1.0}
    t_c = model.contact_time(phys)
    assert t_c == pytest.approx(math.pi / math.sqrt(2e6 - 2500.0))
    assert model.nominal_dt(phys) == pytest.approx(4.4457e-5, rel=1e-4)
    n, dt = model.steps_per_period(phys, 64)
    assert n % 256 == 0 and n * dt == pytest.approx(2 * math.pi, rel=1e-14)
    assert 0 < model.nominal_dt(phys) - dt < 256 / 141_000 * dt
    assert 141_000 < n < 142_000


@pytest.mark.parametrize("start,ramp", [("sine", 2.0), ("bottom", 0.0), ("bottom", 1.0)])
def test_drive_starts_with_the_plate_at_rest_height(start, ramp):
    phys = {"omega": 1.0}
    d = model.drive_for(phys, {"start_phase": start, "ramp_periods": ramp}, 2.0)
    assert d.amplitude == 2.0
    assert d.height(0.0) == pytest.approx(0.0, abs=1e-15)
    # smooth: plate speed at t = 0 is small compared with Aω (finite difference)
    h = 1e-6
    assert abs(d.height(h) - d.height(0.0)) / h < 0.2 * d.amplitude * d.omega
    # the measurement starts at drive phase 2π n: plate at mid-height, moving up
    t_m = d.measurement_start(6)
    assert math.sin(d.omega * t_m + d.phase) == pytest.approx(0.0, abs=1e-12)
    assert math.cos(d.omega * t_m + d.phase) == pytest.approx(1.0)
