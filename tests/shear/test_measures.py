"""The shear cell's measures: the Delaunay network on a constructed T1 swap, a rigidly
turned random annulus (no change) and one disk moved into a void (changes near it only);
the event detector on synthetic change series; C(|δu|, |v|) on synthetic fields."""

import math

import numpy as np
import pytest

from granpipe.analysis.lyapunov import lyapunov_vector_magnitude, speed_lyapunov_correlation
from granpipe.shear.measures import (
    neighbour_edges,
    network_changes,
    rearrangement_events,
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
