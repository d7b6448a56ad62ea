"""The shear cell: packing fraction, walls and their rates, the prepared state."""

import math

import numpy as np
import pytest

from granpipe.shear import layout
from granpipe.shear.model import ShearCell, n_disks, ring
from granpipe.shear.preparation import grow, placement
from tests.shear.conftest import shear_section


@pytest.mark.parametrize("phi", [0.6, 0.82, 0.86])
def test_n_disks_fills_the_annulus_to_phi_within_one_pair(phi):
    ph = {**shear_section()["physics"], "phi": phi}
    cell = ShearCell.from_physics(ph)
    area = math.pi * (cell.r_out**2 - cell.r_in**2)
    got = float(np.sum(math.pi * cell.diameters**2 / 4)) / area
    pair = math.pi / 4 * (1 + 1.1667**2) / area
    assert abs(got - phi) <= pair / 2 + 1e-12
    assert n_disks(ph) == cell.n_mobile and cell.n_mobile % 2 == 0
    # the rings' inner envelopes: R_in + d_w/2 and R_out - d_w/2
    _, r_in = ring(ph["n_inner"], ph["d_wall"])
    assert cell.r_in == pytest.approx(r_in + ph["d_wall"] / 2)


def test_placement_has_no_contact_and_stays_in_the_annulus(tiny):
    cell = ShearCell.from_physics(tiny["physics"])
    s = tiny["preparation"]["start_scale"]
    pos = placement(cell, s, 0.05, np.random.default_rng(3))
    d = cell.diameters * s
    gap = np.hypot(*(pos[:, None] - pos[None]).transpose(2, 0, 1)) - (d[:, None] + d[None]) / 2
    np.fill_diagonal(gap, np.inf)
    assert gap.min() >= 0.05 - 1e-9
    r = np.hypot(*pos.T)
    assert np.all(r - d / 2 >= cell.r_in) and np.all(r + d / 2 <= cell.r_out)


def test_prepared_cell_is_sheared_by_the_inner_ring_only(tiny):
    """After growth and steady shear: the outer ring has not moved, the inner ring has
    turned by Ω t, the disks stay between the rings, and the mean angular velocity of the
    disks decreases outwards (a sheared, not a rigidly turning, packing)."""
    cell = ShearCell.from_physics(tiny["physics"])
    sim, state = grow(cell, tiny["preparation"], np.random.default_rng(1))
    n = cell.n_mobile
    walls = state.positions[n:]
    outer = cell.rate == 0.0
    np.testing.assert_array_equal(walls[outer], cell.walls[outer])
    t = round(tiny["preparation"]["steady_s"] / (tiny["physics"]["dt"] * tiny["physics"]["t0_s"]))
    assert state.wall_angle == pytest.approx(cell.omega * t * tiny["physics"]["dt"], rel=1e-12)
    r = np.hypot(*state.positions[:n].T)
    assert np.all((r > cell.r_in - 0.5) & (r < cell.r_out + 0.5))
    x, y = state.positions[:n].T
    vx, vy = state.velocities[:n].T
    w = (x * vy - y * vx) / r**2  # angular velocity of each disk
    inner = r < np.median(r)
    assert w[inner].mean() > w[~inner].mean()
    assert 0 < w[inner].mean() < cell.omega


def test_check_refuses_what_cannot_run(tiny):
    from granpipe.errors import ConfigError

    layout.check(tiny)
    with pytest.raises(ConfigError, match="start_scale"):
        layout.check({**tiny, "preparation": {**tiny["preparation"], "start_scale": 1.0}})
    with pytest.raises(ConfigError, match="n_outer"):
        layout.check({**tiny, "physics": {**tiny["physics"], "n_outer": 12}})
    with pytest.raises(ConfigError, match="contrast_phi"):
        layout.check({**tiny, "figures": {**tiny["figures"], "contrast_phi": 0.5}})
    with pytest.raises(ConfigError, match="aligned_before_s"):
        layout.check({**tiny, "fits": {**tiny["fits"], "aligned_before_s": 1.0}})
    # sizes are counted before anything is built: the plan, a job's memory
    for section, key, value in (("ensemble", "n_replicas", 10**9), ("physics", "n_outer", 10**10),
                                ("protocol", "record_s", 1e12)):  # fmt: skip
        with pytest.raises(ConfigError, match=f"shear.{section}.{key}"):
            layout.check({**tiny, section: {**tiny[section], key: value}})
