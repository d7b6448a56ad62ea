"""Walls with prescribed motion: the rotating (and stopping) drum, the driven bottom."""

import math

import numpy as np
import pytest

from granpipe.engine import BoxLaw, DrumLaw, FlatWalls, Simulation, WallDisks
from tests.engine.conftest import DRUM_LAW, DT_DRUM
from tests.engine.geometry import ring_of_disks

BOX_LAW = BoxLaw(kappa_n=1e6, kappa_t=1e4, gamma_n=100.0, gamma_t=100.0, mu=0.6)


def test_drum_wall_disks_turn_rigidly_and_stop_at_the_switch():
    ring, radius = ring_of_disks(150, 1.3846, centre=(1.0, 2.0))
    assert radius == pytest.approx(33.057, abs=5e-4)  # docs/drum.md
    omega = -2.4417e-4 * 1000  # faster than the study so that the angle is measurable
    t_switch = 400 * DT_DRUM
    walls = WallDisks(centre=(1.0, 2.0), omega=omega, omega_after=0.0, t_switch=t_switch)
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=walls)
    pos = np.vstack([[[1.0, 2.0]], ring])
    is_wall = np.arange(151) > 0
    state = sim.new_state(pos, np.r_[0.5, np.full(150, 0.6923)], np.ones(151), is_wall=is_wall)
    sim.run(state, 250)
    th = omega * 250 * DT_DRUM
    rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    expect = (ring - [1.0, 2.0]) @ rot.T + [1.0, 2.0]
    np.testing.assert_allclose(state.positions[1:], expect, rtol=0, atol=1e-12)
    assert state.wall_angle == pytest.approx(th, rel=1e-12)
    # clockwise: velocity = omega x (r - c)
    r = state.positions[1:] - [1.0, 2.0]
    np.testing.assert_allclose(state.velocities[1:], omega * np.c_[-r[:, 1], r[:, 0]], atol=1e-12)
    sim.run(state, 250)
    assert state.wall_angle == pytest.approx(omega * t_switch, rel=1e-12)
    assert np.all(state.velocities[1:] == 0.0)
    assert state.velocities[0, 1] < 0  # the mobile disk falls meanwhile


def test_wall_rings_turn_at_their_own_rates_and_a_still_ring_stays():
    # the shear cell's walls (docs/shear.md): an inner ring at rate 1, an outer ring at 0,
    # and a third ring at -0.5 (counter-turning at half speed), one centre, no gravity
    inner, r_in = ring_of_disks(20, 1.0, centre=(0.0, 0.0))
    outer, r_out = ring_of_disks(60, 1.0, centre=(0.0, 0.0))
    third, _ = ring_of_disks(40, 1.0, centre=(0.0, 0.0))
    third = third * 0.8
    omega = 0.3
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, gravity=(0.0, 0.0), wall_disks=WallDisks(omega=omega))
    pos = np.vstack([[[0.5 * (r_in + r_out), 0.0]], inner, outer, third])
    n = len(pos)
    rate = np.r_[0.0, np.ones(20), np.zeros(60), np.full(40, -0.5)]
    vel = np.r_[[[0.0, 0.1]], np.zeros((n - 1, 2))]
    state = sim.new_state(pos, np.full(n, 0.5), np.ones(n), is_wall=np.arange(n) > 0,
                          wall_rate=rate, velocities=vel)  # fmt: skip
    sim.run(state, 300)
    for ring, rows, f in ((inner, slice(1, 21), 1.0), (outer, slice(21, 81), 0.0),
                          (third, slice(81, n), -0.5)):  # fmt: skip
        th = f * omega * 300 * DT_DRUM
        rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        np.testing.assert_allclose(state.positions[rows], ring @ rot.T, rtol=0, atol=1e-12)
        r = state.positions[rows]
        np.testing.assert_allclose(state.velocities[rows], f * omega * np.c_[-r[:, 1], r[:, 0]],
                                   atol=1e-12)  # fmt: skip
    # no gravity: the free disk between the rings moves uniformly
    np.testing.assert_allclose(state.velocities[0], [0.0, 0.1], atol=1e-15)
    np.testing.assert_allclose(state.positions[0], [0.5 * (r_in + r_out), 300 * DT_DRUM * 0.1],
                               rtol=1e-12)  # fmt: skip


@pytest.mark.parametrize("v_wall", [0.05, 0.2])
def test_disk_pressed_on_a_turning_wall_disk_is_dragged_as_eq1_predicts(v_wall):
    # A disk (m = 1, radius 0.5) rests under gravity g on a large wall disk (radius 50:
    # a disk on top of a round wall sits at an unstable equilibrium, and the lag of the
    # dragged disk behind the top, ~v_wall/gamma_t, tilts the normal; on a radius of 1
    # that bends v_x by 2 %, on 50 by 0.04 %) that turns about a far centre (R_c = 1e4,
    # so its top moves horizontally at v_wall over the test). Eq. (1):
    # f_n = m g at rest, and the tangential force on the disk is gamma_t (v_wall - v_x)
    # while below mu m g (viscous), mu m g while capped (Coulomb). Predicted:
    # Coulomb while gamma_t (v_wall - v_x) > mu g: v_x = mu g t, then
    # v_x = v_wall - (mu g / gamma_t) exp(-gamma_t (t - t_c)); viscous from the start when
    # gamma_t v_wall < mu g: v_x = v_wall (1 - exp(-gamma_t t)).
    k_n, gamma_t, mu, g = 565.97, 6.8927, 0.44, 1.0
    law = DrumLaw(k_n, 8.7308, gamma_t, mu)
    r_c = 1.0e4
    sim = Simulation(law, dt=DT_DRUM, gravity=(0.0, -g),
                     wall_disks=WallDisks(centre=(0.0, -r_c), omega=-v_wall / r_c))  # fmt: skip
    y0 = 50.5 - g / k_n  # at rest on the wall disk: k_n delta = m g
    state = sim.new_state([[0.0, y0], [0.0, 0.0]], [0.5, 50.0], [1.0, 1.0],
                          is_wall=[False, True])  # fmt: skip
    n_steps = 800
    t = np.arange(1, n_steps + 1) * DT_DRUM
    vx = np.empty(n_steps)
    for k in range(n_steps):
        sim.run(state, 1)
        vx[k] = state.velocities[0, 0]
    cap = mu * g
    t_c = max(0.0, (v_wall - cap / gamma_t) / cap)
    u_c = min(cap, gamma_t * v_wall) / gamma_t  # the slip when viscous friction takes over
    expect = np.where(t < t_c, cap * t, v_wall - u_c * np.exp(-gamma_t * (t - t_c)))
    assert (t_c > 0) == (gamma_t * v_wall > cap)
    # to the O(dt) of velocity Verlet (the half-step velocities the force sees) and the
    # wall's curvature
    np.testing.assert_allclose(vx, expect, rtol=0, atol=0.005 * v_wall)
    # no slip at the end: the disk moves with the wall, to within the decaying lag
    assert abs(vx[-1] - v_wall) < 0.01 * v_wall


def test_disk_on_plate_driven_below_one_g_follows_it_with_quasistatic_compression():
    """Gamma = 0.5: the disk stays on the plate, compressed by m (g + z_b'')/kappa_n."""
    amp, omega = 0.5, 1.0
    flat = FlatWalls(bottom=True, z0=0.0, amplitude=amp, omega=omega, phase=-math.pi / 2)
    dt = BOX_LAW.contact_time(0.5) / 50
    sim = Simulation(BOX_LAW, dt=dt, flat_walls=flat)
    z0 = flat.height(0.0)
    state = sim.new_state([[0.0, z0 + 0.5 - 1e-6]], [0.5], [1.0])
    steps = int(round(2 * math.pi / omega / dt / 16))
    worst = 0.0
    for _ in range(32):
        sim.run(state, steps)
        t = state.time
        gap = state.positions[0, 1] - flat.height(t) - 0.5
        accel = -amp * omega**2 * math.sin(omega * t - math.pi / 2)
        worst = max(worst, abs(-gap * BOX_LAW.kappa_n / (1.0 + accel) - 1))
        assert state.contacts[0] == 1
    assert worst < 0.02


def test_bottom_height_ramp_and_phase():
    flat = FlatWalls(
        bottom=True, z0=-10.0, amplitude=2.0, omega=1.0, phase=0.3, ramp_start=1.0, ramp_time=4.0
    )
    t = np.array([0.0, 1.0, 2.0, 5.0, 7.0])
    ramp = np.clip((t - 1.0) / 4.0, 0, 1)
    np.testing.assert_allclose(flat.height(t), -10 + 2 * ramp * np.sin(t + 0.3), atol=1e-15)
    h = 1e-6
    for s in (2.0, 7.0):
        fd = (flat.height(s + h) - flat.height(s - h)) / (2 * h)
        assert flat.velocity(s) == pytest.approx(fd, rel=1e-8)


def test_rising_bottom_meets_a_resting_disk_when_their_gap_closes():
    """A disk at rest without gravity, far above the bottom (more than the near-wall
    list's margin), is struck in the step where the rising bottom reaches it: the
    near-wall list is rebuilt as the bottom moves, not only when disks move."""
    a, amp, omega = 0.5, 1.0, 1.0
    flat = FlatWalls(bottom=True, z0=0.0, amplitude=amp, omega=omega, phase=-math.pi / 2)
    dt = BOX_LAW.contact_time(0.5) / 50
    sim = Simulation(BOX_LAW, dt=dt, flat_walls=flat, gravity=(0.0, 0.0), skin=0.05)
    y0 = a + 0.5 * amp  # the bottom (from -A) passes z = A/2 at omega t = 2 pi / 3
    state = sim.new_state([[3.0, y0]], [a], [1.0])
    t_hit = (2 * math.pi / 3) / omega
    n_before = int(t_hit / dt) - 1
    sim.run(state, n_before)
    assert state.velocities[0, 1] == 0.0 and state.neighbour_stats()["rebuilds"] == 1
    sim.run(state, 3)
    assert state.velocities[0, 1] > 0.0
