"""The drum model: geometry of Table 1, clockwise rotation, protocol times, the tiny drum."""

import math

import numpy as np
import pytest

from granpipe.drum import model
from granpipe.drum.layout import filled, steps
from granpipe.drum.model import omega
from granpipe.drum.protocol import tiny_section

PAPER = model.PAPER_PHYSICS


def test_drum_of_table_1():
    g = model.geometry(PAPER)
    assert g.radius == pytest.approx(33.057, abs=5e-4)  # circumradius of the 150-gon
    # the paper's drum diameter 66.115 d_s is the circumscribed diameter of the centres
    assert 2 * g.radius == pytest.approx(66.115, abs=2e-3)
    w = model.wall_positions(g)
    side = np.hypot(*(w - np.roll(w, 1, axis=0)).T)
    np.testing.assert_allclose(side, 1.3846, rtol=1e-12)  # neighbours touch: no leak
    assert len(model.diameters(PAPER)) == 736
    m = model.masses(PAPER)
    assert m.min() == 1.0 and m.max() == pytest.approx(1.1667**2)
    assert (model.species(PAPER) == 1).sum() == 368


def test_rotation_is_clockwise():
    g = model.geometry(PAPER)
    w0 = model.wall_positions(g, 0.0)
    w1 = model.wall_positions(g, 0.01)
    # clockwise: the polar angle of every wall disk decreases
    da = np.angle(np.exp(1j * (np.arctan2(w1[:, 1], w1[:, 0]) - np.arctan2(w0[:, 1], w0[:, 0]))))
    np.testing.assert_allclose(da, -0.01, atol=1e-12)
    # v = Ω (y, −x) is the derivative of the clockwise motion
    v = model.wall_velocities(w0, 2.0)
    eps = 1e-7
    num = (model.wall_positions(g, 2.0 * eps) - w0) / eps
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
    assert model.filling_fraction(tiny) == pytest.approx(model.filling_fraction(PAPER), rel=0.05)
    for key in ("k_n", "gamma_n", "dt", "period_s", "d_wall"):
        assert tiny[key] == PAPER[key]
