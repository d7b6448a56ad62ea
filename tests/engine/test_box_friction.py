"""Box law friction: rolling without slipping, static friction below the Coulomb limit."""

import math

import numpy as np
import pytest

from granpipe.engine import BoxLaw, FlatWalls, Simulation

BOX_LAW = BoxLaw(kappa_n=1e6, kappa_t=1e4, gamma_n=100.0, gamma_t=100.0, mu=0.6)
DT = BOX_LAW.contact_time(0.5) / 50
FLOOR = FlatWalls(bottom=True, z0=0.0)
A = 0.5  # radius (sigma = 1)


def lever(state):
    """Mid-overlap lever arm of the floor contact of disk 0."""
    return 0.5 * (A + state.positions[0, 1])


def test_spinning_disk_dropped_on_floor_reaches_rolling_without_slipping():
    """Friction at the contact point exerts no torque about it, nor do gravity and the
    normal force, so L = I w - m h v_x about the contact point is conserved: from
    (v_x, w) = (0, w0) the disk ends rolling with w = w0 I/(I + m a²) = w0/3
    (I = m sigma²/8 = m a²/2) and v_x = -a w (contact point at rest)."""
    w0 = 10.0
    sim = Simulation(BOX_LAW, dt=DT, flat_walls=FLOOR)
    state = sim.new_state([[0.0, A + 0.01]], [A], [1.0], spins=[w0])
    sim.run(state, 100_000)  # 4.4 time units; sliding stops after ~2.8
    v_x, w = state.velocities[0, 0], state.spins[0]
    assert w == pytest.approx(w0 / 3, rel=1e-4)
    assert v_x == pytest.approx(-A * w0 / 3, rel=1e-4)
    slip = v_x + lever(state) * w
    assert abs(slip) < 1e-6
    # and it keeps rolling: no rolling resistance in the law
    sim.run(state, 20_000)
    assert state.velocities[0, 0] == pytest.approx(v_x, rel=1e-6)


@pytest.mark.parametrize("load_ratio", [0.9, 0.5])
def test_disk_under_tangential_load_below_coulomb_does_not_slide(load_ratio):
    """A disk that cannot turn (inertia inf) on a floor under tilted gravity: tangential
    load m g sin(theta) below mu m g cos(theta). It creeps only by the elastic shear
    m g sin(theta)/kappa_t, then stays put."""
    theta = math.atan(load_ratio * BOX_LAW.mu)
    g = (math.sin(theta), -math.cos(theta))
    sim = Simulation(BOX_LAW, dt=DT, flat_walls=FLOOR, gravity=g)
    state = sim.new_state([[0.0, A - 1e-6]], [A], [1.0], inertia=[math.inf])
    sim.run(state, 20_000)
    x1 = state.positions[0, 0]
    sim.run(state, 40_000)
    shear = math.sin(theta) / BOX_LAW.kappa_t
    assert abs(x1) < 2 * shear
    assert abs(state.positions[0, 0] - x1) < 1e-9
    assert abs(state.velocities[0, 0]) < 1e-8
    assert state.spins[0] == 0.0


def test_disk_under_tangential_load_above_coulomb_slides_at_coulomb_rate():
    """Same disk with tan(theta) = 1.2 mu slides with a = g (sin(theta) - mu cos(theta))."""
    theta = math.atan(1.2 * BOX_LAW.mu)
    g = (math.sin(theta), -math.cos(theta))
    sim = Simulation(BOX_LAW, dt=DT, flat_walls=FLOOR, gravity=g)
    state = sim.new_state([[0.0, A - 1e-6]], [A], [1.0], inertia=[math.inf])
    sim.run(state, 10_000)
    v1, t1 = state.velocities[0, 0], state.time
    sim.run(state, 40_000)
    accel = (state.velocities[0, 0] - v1) / (state.time - t1)
    assert accel == pytest.approx(math.sin(theta) - BOX_LAW.mu * math.cos(theta), rel=1e-6)


def test_disk_rolls_down_incline_without_slipping():
    """Free disk, tan(theta) = 0.5 < 3 mu: rolls with a = (2/3) g sin(theta) and the contact
    point stays at rest (the friction needed, m g sin(theta)/3, is below mu N)."""
    theta = math.atan(0.5)
    g = (math.sin(theta), -math.cos(theta))
    sim = Simulation(BOX_LAW, dt=DT, flat_walls=FLOOR, gravity=g)
    state = sim.new_state([[0.0, A - 1e-6]], [A], [1.0])
    sim.run(state, 10_000)
    v1, t1 = state.velocities[0, 0], state.time
    sim.run(state, 40_000)
    accel = (state.velocities[0, 0] - v1) / (state.time - t1)
    assert accel == pytest.approx(2 / 3 * math.sin(theta), rel=1e-4)
    slip = state.velocities[0, 0] + lever(state) * state.spins[0]
    assert abs(slip) < 1e-5 * abs(state.velocities[0, 0])
    assert np.sign(state.spins[0]) == -1  # rolling to +x turns clockwise


# --------------------------------------------- a disk held against a moving side wall
G_X, G_Y = 1.0, 0.1  # pressed against the left wall by m G_X, pulled down by m G_Y
DRIVE = 0.2  # wall amplitude A (omega = 1): wall acceleration up to 0.2 g


def _against_side_wall(shaken, torque, inertia=None):
    """A disk pressed against the left wall of a box whose plate (far below) moves as
    ``z_b = -50 - A cos t`` (at rest at t = 0), run for half a period, t = pi: the wall
    rises by 2 A. The friction a sticking contact needs, m (a_wall + G_Y) <= 0.3 m, stays
    below mu m G_X = 0.6 m."""
    walls = FlatWalls(
        x_left=0.0, bottom=True, z0=-50.0, amplitude=DRIVE, omega=1.0, phase=-math.pi / 2,
        shaken_sides=shaken, wall_torque=torque,
    )  # fmt: skip
    sim = Simulation(BOX_LAW, dt=DT, flat_walls=walls, gravity=(-G_X, -G_Y))
    kw = {} if inertia is None else {"inertia": [inertia]}
    state = sim.new_state([[A - G_X / BOX_LAW.kappa_n, 0.0]], [A], [1.0], **kw)
    sim.run(state, round(math.pi / DT))
    return state


def test_a_shaken_side_wall_carries_a_sticking_disk_and_a_still_one_holds_it():
    """A disk that cannot turn sticks to the wall: it rises with a shaken wall by the
    wall's 2 A (less the elastic shear, ~1e-5), and stays put at a still one, which
    holds the weight m G_Y < mu m G_X."""
    up = _against_side_wall(True, True, inertia=math.inf)
    assert up.positions[0, 1] == pytest.approx(2 * DRIVE, abs=1e-4)
    assert up.velocities[0, 1] == pytest.approx(0.0, abs=1e-4)  # the wall turns at t = pi
    held = _against_side_wall(False, True, inertia=math.inf)
    assert abs(held.positions[0, 1]) < 1e-4


def test_a_free_disk_rolls_on_a_shaken_wall_and_without_wall_torque_is_carried():
    """A free disk (I = m a²/2) rolls without slipping on the moving wall: from
    m y'' = f - m G_Y, I w' = -f a and y'' + a w' = a_wall, y'' = (a_wall - 2 G_Y)/3, so
    y(pi) = (2 A - G_Y pi²)/3. Without wall torque (the sigma_j = 0 reading of Eq. A4) the
    disk never turns, the contact sticks, and the disk rises with the wall by 2 A."""
    rolled = _against_side_wall(True, True)
    assert rolled.positions[0, 1] == pytest.approx((2 * DRIVE - G_Y * math.pi**2) / 3, rel=1e-3)
    assert rolled.spins[0] != 0.0
    carried = _against_side_wall(True, False)
    assert carried.spins[0] == 0.0
    assert carried.positions[0, 1] == pytest.approx(2 * DRIVE, abs=1e-4)


def test_without_wall_torque_a_spinning_disk_on_the_floor_keeps_its_spin():
    """The floor's friction still acts on the disk's centre (it is pushed along), but
    exerts no torque: the spin stays w0 exactly, where with a lever it falls to w0/3."""
    w0 = 10.0
    floor = FlatWalls(bottom=True, z0=0.0, wall_torque=False)
    sim = Simulation(BOX_LAW, dt=DT, flat_walls=floor)
    state = sim.new_state([[0.0, A + 0.01]], [A], [1.0], spins=[w0])
    sim.run(state, 20_000)
    assert state.spins[0] == w0
    assert state.velocities[0, 0] < -0.1  # the sliding contact drives the disk along -x
