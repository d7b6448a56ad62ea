"""Walls with prescribed motion: the rotating (and stopping) drum, the driven bottom."""

import math

import numpy as np
import pytest

from granpipe.engine import BoxLaw, FlatWalls, Simulation, WallDisks
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
