"""Drum geometry (Table 1), random placement, settings and file layout."""

import math

import numpy as np
import pytest

from granpipe.drum import geometry, layout
from granpipe.drum.placement import min_gap, random_placement
from granpipe.drum.settings import (
    filled,
    omega,
    point_label,
    points,
    seed_physics,
    steps,
    tiny_section,
)
from granpipe.errors import ConfigError

PAPER = geometry.PAPER_PHYSICS


def test_drum_of_table_1():
    g = geometry.geometry(PAPER)
    assert g.radius == pytest.approx(33.057, abs=5e-4)  # circumradius of the 150-gon
    # the paper's drum diameter 66.115 d_s is the circumscribed diameter of the centres
    assert 2 * g.radius == pytest.approx(66.115, abs=2e-3)
    w = geometry.wall_positions(g)
    side = np.hypot(*(w - np.roll(w, 1, axis=0)).T)
    np.testing.assert_allclose(side, 1.3846, rtol=1e-12)  # neighbours touch: no leak
    assert len(geometry.diameters(PAPER)) == 736
    m = geometry.masses(PAPER)
    assert m.min() == 1.0 and m.max() == pytest.approx(1.1667**2)
    assert (geometry.species(PAPER) == 1).sum() == 368


def test_rotation_is_clockwise():
    g = geometry.geometry(PAPER)
    w0 = geometry.wall_positions(g, 0.0)
    w1 = geometry.wall_positions(g, 0.01)
    # clockwise: the polar angle of every wall disk decreases
    da = np.angle(np.exp(1j * (np.arctan2(w1[:, 1], w1[:, 0]) - np.arctan2(w0[:, 1], w0[:, 0]))))
    np.testing.assert_allclose(da, -0.01, atol=1e-12)
    # v = Ω (y, −x) is the derivative of the clockwise motion
    v = geometry.wall_velocities(w0, 2.0)
    eps = 1e-7
    num = (geometry.wall_positions(g, 2.0 * eps) - w0) / eps
    np.testing.assert_allclose(v, num, atol=1e-5)


def test_period_and_steps_of_the_protocol():
    sec = filled({})
    ph = sec["physics"]
    assert 2 * math.pi / omega(ph) * ph["t0_s"] == pytest.approx(900.0, rel=1e-12)
    assert omega(ph) == pytest.approx(2.4417e-4, rel=1e-4)  # the paper's rad/t0
    st = steps(sec)
    assert st.dt_s == pytest.approx(4e-5, rel=1e-5)
    assert st.block == 100  # 4 ms
    assert st.pre_rotation == 62_500  # 1 degree = 2.5 s
    # paper start-up: the tangent vector starts tangent_alignment_s before t = 0;
    # settled: at the start of the rotation
    assert st.alignment == 62_500  # from the placement
    assert steps({"protocol": {"startup": "settled"}}).alignment == st.pre_rotation
    assert st.decay_rotating == 125_000  # the stop at 5 s
    assert st.onset % st.block == 0 and st.decay % st.chunk == 0


def test_tiny_drum_keeps_the_filling_fraction():
    tiny = tiny_section({})["physics"]
    assert tiny["n_wall"] == 40 and tiny["n_small"] == tiny["n_large"]
    assert geometry.filling_fraction(tiny) == pytest.approx(
        geometry.filling_fraction(PAPER), rel=0.05
    )
    for key in ("k_n", "gamma_n", "dt", "period_s", "d_wall"):
        assert tiny[key] == PAPER[key]


def test_placement_is_inside_without_overlap_and_seeded():
    d = geometry.diameters(PAPER)
    g = geometry.geometry(PAPER)
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


def test_seed_subset_excludes_sample_sizes_and_analysis():
    a = seed_physics({"ensemble": {"n_replicas": 10}, "fits": {"seed": 3}})
    b = seed_physics({"ensemble": {"n_replicas": 99}})
    # the paper start-up does not depend on the settling keys, nor on the overlap bound
    assert a == b and set(a) == {"physics", "protocol"} and "max_overlap" not in a["physics"]
    assert seed_physics({"settle": {"max_speed": 3.0}, "physics": {"max_overlap": 0.9}}) == a
    c = seed_physics({"protocol": {"block_s": 0.008}})
    assert c != a
    settled = seed_physics({"protocol": {"startup": "settled"}})
    assert set(settled) == {"physics", "settle", "protocol"}
    assert seed_physics({"protocol": {"startup": "settled"}, "settle": {"max_speed": 3}}) != settled


def test_bad_windows_and_keys_name_the_key():
    with pytest.raises(ConfigError, match="onset_zero_window_s"):
        filled({"fits": {"onset_zero_window_s": [20.0, 10.0]}})
    with pytest.raises(ConfigError, match="not_a_key"):
        filled({"physics": {"not_a_key": 1}})
    with pytest.raises(ConfigError, match="dt"):
        filled({"physics": {"dt": 0.0}})


def test_layout_batches_and_files():
    sec = {"ensemble": {"n_replicas": 5, "batch_size": 2}}
    assert layout.point_name(sec) == "N=736,period=900s,startup=paper"
    assert layout.batch_ids(sec) == ["0000", "0001", "0002"]  # whole batches: 6 replicas
    files = layout.run_files(sec)
    assert files[0] == "runs/N=736,period=900s,startup=paper/batch_0000.nc" and len(files) == 3
    assert layout.init_files(sec)[2].startswith("init/")
    grown = layout.run_files({"ensemble": {"n_replicas": 9, "batch_size": 2}})
    assert grown[:3] == files  # a larger ensemble only appends batches
    assert len(layout.figure_files()) == 12


def test_points_vary_one_key_at_a_time_from_the_reference():
    sec = {"physics": {"period_s": [900.0, 450.0, 225.0]},
           "protocol": {"startup": ["paper", "settled"]}}  # fmt: skip
    pts = points(sec)
    got = [(p["physics"]["period_s"], p["protocol"]["startup"]) for p in pts]
    assert got == [(900.0, "paper"), (450.0, "paper"), (225.0, "paper"), (900.0, "settled")]
    assert [point_label(p, sec) for p in pts] == [
        "", "[period=450s]", "[period=225s]", "[startup=settled]"
    ]  # fmt: skip
    prod = points({**sec, "design": "product"})
    assert len(prod) == 6 and len({layout.point_name(p) for p in prod}) == 6
    # a point's simulation subset does not depend on the other entries of the lists
    alone = layout.rule_params({"physics": {"period_s": 450.0}})["sim"]
    listed = layout.rule_params(sec)["sim"]
    assert alone["N=736,period=450s,startup=paper"] == listed["N=736,period=450s,startup=paper"]
    with pytest.raises(ConfigError, match="period_s"):
        filled({"physics": {"period_s": [900.0, -1.0]}})
