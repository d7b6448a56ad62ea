"""The shear cell's measures: the Delaunay network on a constructed T1 swap, a rigidly
turned random annulus (no change) and one disk moved into a void (changes near it only);
the event detector on synthetic change series; C(|δu|, |v|) on synthetic fields."""

import math

import numpy as np
import pytest

from granpipe.analysis.lyapunov import lyapunov_vector_magnitude, speed_lyapunov_correlation
from granpipe.shear.measures import (
    bulk_hexatic_order,
    contact_number,
    contact_pairs,
    edge_change_counts,
    elastic_measures,
    neighbour_edges,
    network_changes,
    rearrangement_events,
    stress_release_events,
)

R_IN, R_OUT = 5.0, 11.0  # the annulus' walls [d_s]


def _with_walls(mobile_pos, mobile_radii, r_in=R_IN, r_out=R_OUT):
    """Mobile disks followed by two rings of wall disks (radius 0.5) on the walls' circles."""
    rings = []
    for r in (r_in - 0.5, r_out + 0.5):
        k = int(2 * math.pi * r)  # about one disk per d_s
        phi = 2 * math.pi * np.arange(k) / k
        rings.append(r * np.column_stack([np.cos(phi), np.sin(phi)]))
    walls = np.concatenate(rings)
    pos = np.concatenate([mobile_pos, walls])
    radii = np.concatenate([mobile_radii, np.full(len(walls), 0.5)])
    mobile = np.arange(len(pos)) < len(mobile_pos)
    return pos, radii, mobile


def _random_annulus(n=150, seed=7):
    """Random sequential addition of n bidisperse disks: n/3 of a = 0.7 placed first (the
    large disks first, or the annulus is too full for the last ones), then a = 0.5."""
    rng = np.random.default_rng(seed)
    radii = np.where(np.arange(n) < n // 3, 0.7, 0.5)
    pos = np.zeros((0, 2))
    for a in radii:
        for _ in range(100_000):
            r = math.sqrt(rng.uniform((R_IN + a) ** 2, (R_OUT - a) ** 2))
            phi = rng.uniform(0, 2 * math.pi)
            x = np.array([r * math.cos(phi), r * math.sin(phi)])
            if np.all(np.hypot(*(pos - x).T) >= a + radii[: len(pos)]):
                pos = np.vstack([pos, x])
                break
        else:
            raise RuntimeError("annulus too full for random sequential addition")
    return _with_walls(pos, radii)


def _rotated(pos, angle):
    c, s = math.cos(angle), math.sin(angle)
    return pos @ np.array([[c, s], [-s, c]])


def _ends(codes, n):
    return [tuple(int(x) for x in divmod(int(c), n)) for c in codes]


def test_t1_swap_loses_the_short_diagonal_and_gains_the_other():
    # rhombus: 0-1 the short diagonal (1.0) and 2-3 the long one (1.8) in A, swapped in B
    a = np.array([[0, 0.5], [0, -0.5], [-0.9, 0], [0.9, 0]])
    b = np.array([[0, 0.9], [0, -0.9], [-0.5, 0], [0.5, 0]])
    pos_a, radii, mobile = _with_walls(a, np.full(4, 0.5), r_in=5.0, r_out=7.0)
    pos_b = _with_walls(b, np.full(4, 0.5), r_in=5.0, r_out=7.0)[0]
    ea, eb = neighbour_edges(pos_a, radii, mobile), neighbour_edges(pos_b, radii, mobile)
    n = len(pos_a)
    assert ea.dtype == np.int64 and np.all(np.diff(ea) > 0)
    assert len(ea) == 5 and len(eb) == 5  # the four sides and the short diagonal
    assert network_changes(ea, eb) == 2
    assert _ends(np.setdiff1d(ea, eb), n) == [(0, 1)]
    assert _ends(np.setdiff1d(eb, ea), n) == [(2, 3)]
    assert rearrangement_events(np.array([0, 0, 0, 2, 0, 0]), 2, 2).tolist() == [3]


def test_rigid_rotation_changes_nothing():
    pos, radii, mobile = _random_annulus()
    e0 = neighbour_edges(pos, radii, mobile)
    assert len(e0) > 150  # a connected-enough network, not an empty one
    n = len(pos)
    assert all(i < 150 and j < 150 for i, j in _ends(e0, n))  # no wall disk in an edge
    series = [0]
    for angle in (0.1, 0.7, 1.3, 2.9, 4.4):
        series.append(network_changes(e0, neighbour_edges(_rotated(pos, angle), radii, mobile)))
    assert series == [0] * 6
    assert rearrangement_events(np.array(series), 1, 0).size == 0


def test_walls_fill_the_hole_and_the_cutoff_drops_long_edges():
    pos, radii, mobile = _random_annulus()
    n = len(pos)
    kept, every = neighbour_edges(pos, radii, mobile), neighbour_edges(pos, radii, mobile, np.inf)
    i, j = np.divmod(kept, n)
    assert np.all(np.hypot(*(pos[i] - pos[j]).T) < 1.5 * (radii[i] + radii[j]))
    assert np.all(np.isin(kept, every)) and len(every) > len(kept)  # some edges dropped
    i, j = np.divmod(every, n)
    assert np.hypot(*(pos[i] - pos[j]).T).max() < 3.0  # no chord across the hole
    # without the wall points the hole's chords (up to ~2 R_IN) would be edges
    bare = neighbour_edges(pos[mobile], radii[mobile], mobile[mobile], np.inf)
    i, j = np.divmod(bare, 150)
    assert np.hypot(*(pos[i] - pos[j]).T).max() > 2 * R_IN


def test_a_disk_moved_into_a_void_changes_edges_near_it_only():
    pos, radii, mobile = _random_annulus()
    e0 = neighbour_edges(pos, radii, mobile)
    rng = np.random.default_rng(3)
    m = 100  # a small disk
    old = pos[m].copy()
    others = np.delete(np.arange(len(pos)), m)
    for _ in range(10_000):  # a free spot 0.6-1.5 d_s away: a neighbouring void
        r, phi = rng.uniform(0.6, 1.5), rng.uniform(0, 2 * math.pi)
        new = old + r * np.array([math.cos(phi), math.sin(phi)])
        free = np.all(np.hypot(*(pos[others] - new).T) >= radii[others] + radii[m])
        if free and R_IN + 0.5 <= np.hypot(*new) <= R_OUT - 0.5:
            break
    else:
        pytest.fail("no void next to the disk")
    moved = pos.copy()
    moved[m] = new
    e1 = neighbour_edges(moved, radii, mobile)
    changed = np.setxor1d(e0, e1)
    assert network_changes(e0, e1) == changed.size > 0
    assert any(m in ends for ends in _ends(changed, len(pos)))
    for i, j in _ends(changed, len(pos)):  # both ends near the disk's old or new place
        for k in (i, j):
            assert min(np.hypot(*(pos[k] - old)), np.hypot(*(pos[k] - new))) <= 2.5


def test_events_count_a_burst_once_and_need_a_full_quiet_spell():
    ch = np.array([0, 0, 0, 0, 3, 0, 4, 0, 0, 0, 0, 5, 5, 0])
    assert rearrangement_events(ch, 2, 3).tolist() == [4, 11]  # 6 and 12 follow too soon
    assert rearrangement_events(ch, 2, 0).tolist() == [4, 6, 11, 12]
    assert rearrangement_events(ch, 5, 3).tolist() == [11]  # below threshold is quiet
    # a burst at k = 1 < quiet: the record's start is not a quiet spell
    assert rearrangement_events(np.array([0, 3, 0, 0, 0, 0, 2]), 2, 2).tolist() == [6]
    assert rearrangement_events(np.array([0, 1, 1, 0, 2]), 2, 3).tolist() == [4]
    assert rearrangement_events(np.zeros(0, int), 1, 2).size == 0
    with pytest.raises(ValueError):
        rearrangement_events(ch, 0, 3)
    with pytest.raises(ValueError):
        rearrangement_events(ch, 2, -1)


def _field(n=2000, walls=20, seed=11):
    rng = np.random.default_rng(seed)
    speed = rng.uniform(0.0, 5.0, n)
    phi = rng.uniform(0, 2 * math.pi, n)
    v = speed[:, None] * np.column_stack([np.cos(phi), np.sin(phi)])
    v = np.concatenate([v, np.zeros((walls, 2))])
    mobile = np.arange(n + walls) < n
    return rng, speed, v, mobile


def test_speed_lyapunov_correlation_on_synthetic_fields():
    rng, speed, v, mobile = _field()
    n, nw = len(speed), len(v) - len(speed)
    zero = np.zeros_like(v)
    # |δu| = 3|v|: δr = 2v, δv = √5 v turned by 90°
    dv = math.sqrt(5) * v[:, ::-1] * [1, -1]
    assert np.allclose(lyapunov_vector_magnitude(2 * v, dv), 3 * np.hypot(*v.T))
    assert speed_lyapunov_correlation(v, 2 * v, dv, mobile) == pytest.approx(1.0, abs=1e-12)
    # |δu| = 10 − |v| (decreasing, linear)
    dr = np.zeros_like(v)
    dr[:n, 0] = 10.0 - speed
    assert speed_lyapunov_correlation(v, zero, dr, mobile) == pytest.approx(-1.0, abs=1e-12)
    # independent magnitudes
    indep = np.concatenate([rng.uniform(0, 5, (n, 2)), np.zeros((nw, 2))])
    c = speed_lyapunov_correlation(v, indep, zero, mobile)
    assert abs(c) < 0.15
    # wall disks are ignored, however large their values
    v2, ind2, tv2 = v.copy(), indep.copy(), zero.copy()
    v2[n:], ind2[n:], tv2[n:] = 1e6, -3e7, 1e5
    assert speed_lyapunov_correlation(v2, ind2, tv2, mobile) == c
    # too few mobile disks, or no spread
    two = np.zeros(len(v), bool)
    two[:2] = True
    assert math.isnan(speed_lyapunov_correlation(v, 2 * v, dv, two))
    assert math.isnan(speed_lyapunov_correlation(v, np.ones_like(v), zero, mobile))


# ------------------------------------------------------------- jamming measures
def _hexagon(spacing=0.98):
    """A disk and its six neighbours at ``spacing`` (radii 0.5: all seven overlap)."""
    th = np.pi / 3 * np.arange(6)
    return np.vstack([[0, 0], spacing * np.column_stack([np.cos(th), np.sin(th)])])


def test_contact_number_and_rattlers_of_a_constructed_packing():
    hexa = _hexagon() + [0.0, 8.0]
    ring = hexa[1]  # the neighbour at 0 degrees
    lone = [-8.0, 0.0]  # no contact
    single = ring + [0.98, 0.0]  # touches that neighbour only
    pos, radii, mobile = _with_walls(np.vstack([hexa, lone, single]), np.full(9, 0.5))
    c = contact_pairs(pos, radii, mobile)
    assert len(c.i) == 12 + 1  # six spokes, six rim contacts, the single one
    assert np.allclose(c.overlap, 0.02)
    z, rattler = contact_number(c, mobile, 3)
    assert np.flatnonzero(rattler).tolist() == [7, 8]
    assert z == pytest.approx((6 + 6 * 3) / 7)
    z2, rattler2 = contact_number(c, mobile, 2)  # the frictional reading
    assert np.flatnonzero(rattler2).tolist() == [7, 8]
    # removal is iterative: a disk held by a rattler only is not held
    chain = np.vstack([hexa, single, single + [0.98, 0.0]])
    pos, radii, mobile = _with_walls(chain, np.full(9, 0.5))
    z, rattler = contact_number(contact_pairs(pos, radii, mobile), mobile, 2)
    assert np.flatnonzero(rattler).tolist() == [7, 8]
    # nothing held: z = 0
    apart = np.array([[7.0, 0.0], [0.0, 8.0]])
    pos, radii, mobile = _with_walls(apart, np.full(2, 0.5))
    assert contact_number(contact_pairs(pos, radii, mobile), mobile, 3)[0] == 0.0


def test_wall_contacts_count_and_walls_never_touch_each_other():
    ring_r = R_OUT + 0.5  # the outer ring's centres (radius 0.5)
    disk = np.array([[ring_r - 0.98, 0.0]])  # pressed on the wall disk at angle 0
    pos, radii, mobile = _with_walls(disk, np.full(1, 0.5))
    c = contact_pairs(pos, radii, mobile)
    assert len(c.i) == 1 and c.i[0] == 0 and not mobile[c.j[0]]
    assert np.allclose(pos[c.j[0]], [ring_r, 0.0])


def test_elastic_measures_of_one_pressed_disk():
    k_n, delta = 500.0, 0.02
    ring_r = R_OUT + 0.5
    pos, radii, mobile = _with_walls(np.array([[ring_r - 1 + delta, 0.0]]), np.full(1, 0.5))
    n_in = int(2 * math.pi * (R_IN - 0.5))
    inner = np.r_[False, np.arange(len(pos) - 1) < n_in]
    outer = ~mobile & ~inner
    el = elastic_measures(contact_pairs(pos, radii, mobile), pos, k_n, inner, outer, R_OUT)
    assert el["energy"] == pytest.approx(0.5 * k_n * delta**2)
    assert el["pressure"] == pytest.approx(k_n * delta / (2 * math.pi * R_OUT))
    assert el["torque"] == 0.0 and el["overlap"] == pytest.approx(delta)
    # a disk pressed on an inner wall disk at (R, 0) from the direction at angle a to
    # the radial one pushes it along -u: torque about the centre -f R sin(a)
    big_r, a = 4.5, math.radians(60)
    u = np.array([math.cos(a), math.sin(a)])
    pos = np.array([[big_r, 0.0] + (1 - delta) * u, [big_r, 0.0], [-R_OUT - 0.5, 0.0]])
    mobile = np.array([True, False, False])
    inner, outer = np.array([False, True, False]), np.array([False, False, True])
    el = elastic_measures(contact_pairs(pos, np.full(3, 0.5), mobile), pos, k_n, inner, outer,
                          R_OUT)  # fmt: skip
    assert el["torque"] == pytest.approx(-k_n * delta * big_r * math.sin(a))
    assert el["pressure"] == 0.0


def test_hexatic_order_of_a_crystal_and_of_random_points():
    a = 1.0
    i, j = np.meshgrid(np.arange(-14, 15), np.arange(-14, 15))
    lattice = np.column_stack([a * (i + 0.5 * j).ravel(), a * math.sqrt(3) / 2 * j.ravel()])
    assert bulk_hexatic_order(lattice, 2.0, 10.0, 1.0) == pytest.approx(1.0, abs=1e-6)
    rng = np.random.default_rng(0)
    r = np.sqrt(rng.uniform(2.0**2, 10.0**2, 900))
    th = rng.uniform(0, 2 * math.pi, 900)
    random = np.column_stack([r * np.cos(th), r * np.sin(th)])
    assert bulk_hexatic_order(random, 2.0, 10.0, 1.0) < 0.45
    assert math.isnan(bulk_hexatic_order(random, 2.0, 3.0, 1.0))  # no bulk


def test_stress_release_detector_finds_a_constructed_energy_drop():
    rng = np.random.default_rng(1)
    energy = 10.0 + 0.01 * rng.standard_normal(200) + np.linspace(0, 2, 200)  # loading
    energy[120:] -= 3.0  # a release of 30 % between samples 119 and 120
    assert stress_release_events(energy, 0.1, 5).tolist() == [120]
    energy[60:] -= 3.0  # and one at 60
    assert stress_release_events(energy, 0.1, 5).tolist() == [60, 120]
    assert stress_release_events(energy, 0.5, 5).size == 0  # smaller than half the median
    with pytest.raises(ValueError, match="positive"):
        stress_release_events(energy, 0.0, 5)


def test_edge_change_counts_of_a_t1_swap():
    a = np.array([[0, 0.5], [0, -0.5], [-0.9, 0], [0.9, 0]])
    b = np.array([[0, 0.9], [0, -0.9], [-0.5, 0], [0.5, 0]])
    pos_a, radii, mobile = _with_walls(a, np.full(4, 0.5), r_in=5.0, r_out=7.0)
    pos_b = _with_walls(b, np.full(4, 0.5), r_in=5.0, r_out=7.0)[0]
    n = len(pos_a)
    counts = edge_change_counts(neighbour_edges(pos_a, radii, mobile),
                                neighbour_edges(pos_b, radii, mobile), n)  # fmt: skip
    assert counts[:4].tolist() == [1, 1, 1, 1] and counts[4:].sum() == 0
