"""Conservation laws: energy without dissipation, momenta without walls or gravity."""

import numpy as np
import pytest

from granpipe.engine import BoxLaw, DrumLaw, FlatWalls, Simulation, WallDisks
from granpipe.engine import layout as K
from tests.engine.conftest import DRUM_LAW, DT_DRUM, small_drum
from tests.engine.geometry import random_disks_in_box

BOX_LAW = BoxLaw(kappa_n=1e6, kappa_t=1e4, gamma_n=100.0, gamma_t=100.0, mu=0.6)
DT_BOX = BOX_LAW.contact_time(0.5) / 50


def elastic_energy(state, k_n, flat=None):
    """Sum of 1/2 k_n overlap² over disk pairs (not wall-wall) and flat walls."""
    pos, rad, wall = state.positions, state.radii, state.is_wall
    d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
    ov = np.clip(rad[:, None] + rad[None] - d, 0, None)
    ov[np.tril_indices(len(rad))] = 0
    ov[np.ix_(wall, wall)] = 0
    e = 0.5 * k_n * (ov**2).sum()
    if flat is not None:
        mob = ~wall
        x, y, a = pos[mob, 0], pos[mob, 1], rad[mob]
        for gap in (x - flat.x_left, flat.x_right - x, y - flat.z0):
            e += 0.5 * k_n * (np.clip(a - gap, 0, None) ** 2).sum()
    return e


def total_energy(state, k_n, gravity, flat=None):
    mob = state.mobile
    potential = -(state.masses[mob] * (state.positions[mob] @ np.asarray(gravity))).sum()
    return state.kinetic_energy() + potential + elastic_energy(state, k_n, flat)


@pytest.mark.parametrize(("step_fraction", "tolerance"), [(1, 2e-3), (4, 1e-4)])
def test_drum_law_energy_conserved_without_dissipation(step_fraction, tolerance):
    """gamma_n = gamma_t = mu = 0: E = kinetic + gravity + 1/2 k_n overlap² over 1e5 steps.

    30 disks (a dense gas: ~7 contacts at any time) bouncing in a resting drum of 24 wall
    disks under g = 0.3. Velocity Verlet has no shadow energy across the kink of the
    contact force at touch, so E wanders: max |E/E0 - 1| = 4.5e-4, 5.4e-4, 7.7e-4 at the
    study's step (85 steps per contact) and 2.8e-5, 2.2e-5, 1.4e-5 at a quarter of it
    (three seeds): the error is the integrator's and shrinks faster than dt².
    """
    law = DrumLaw(k_n=DRUM_LAW.k_n, gamma_n=0.0, gamma_t=0.0, mu=0.0)
    pos, radii, masses, is_wall, _ = small_drum(seed=1)
    rng = np.random.default_rng(1)
    vel = np.where(is_wall[:, None], 0.0, rng.normal(0, 1.0, pos.shape))
    sim = Simulation(law, dt=DT_DRUM / step_fraction, gravity=(0.0, -0.3), wall_disks=WallDisks())
    state = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall)
    e0 = total_energy(state, law.k_n, sim.gravity)
    dev = []
    for _ in range(100):
        sim.run(state, 1000)
        dev.append(total_energy(state, law.k_n, sim.gravity) / e0 - 1)
    assert state.neighbour_stats()["mean_contacts"] > 5  # collisions happen
    assert np.max(np.abs(dev)) < tolerance


@pytest.mark.parametrize(("step_fraction", "tolerance"), [(1, 5e-4), (4, 3e-5)])
def test_box_law_energy_conserved_without_dissipation(step_fraction, tolerance):
    """gamma_n = gamma_t = mu = 0 (tangential force truncated to zero): translational +
    rotational kinetic + gravity + elastic energy over 1e5 steps, 30 disks in the box.

    max |E/E0 - 1| = 1.5e-4, 3.4e-5, 1.2e-4 at t_c/50 and 9.4e-6, 2.9e-6, 9.9e-6 at t_c/200
    (three seeds).
    """
    law = BoxLaw(kappa_n=1e6, kappa_t=1e4, gamma_n=0.0, gamma_t=0.0, mu=0.0)
    flat = FlatWalls(x_left=0.0, x_right=6.0, bottom=True, z0=0.0)
    rng = np.random.default_rng(4)
    n = 30
    pos = random_disks_in_box(rng, np.full(n, 0.5), (0, 0), (6, 12))
    sim = Simulation(law, dt=DT_BOX / step_fraction, flat_walls=flat)
    vel = rng.normal(0, 3.0, (n, 2))
    state = sim.new_state(
        pos, np.full(n, 0.5), np.ones(n), velocities=vel, spins=rng.normal(0, 1, n)
    )
    e0 = total_energy(state, law.kappa_n, sim.gravity, flat)
    spins0 = state.spins.copy()
    dev = []
    for _ in range(20):
        sim.run(state, 5000)
        dev.append(total_energy(state, law.kappa_n, sim.gravity, flat) / e0 - 1)
    assert state.neighbour_stats()["mean_contacts"] > 0.1
    assert np.max(np.abs(dev)) < tolerance
    np.testing.assert_array_equal(state.spins, spins0)  # no friction, no torque


def cluster(law, seed):
    """40 disks at random (some overlapping), thrown together, no walls."""
    rng = np.random.default_rng(seed)
    n = 40
    radii = rng.choice([0.5, 0.58335], n)
    # soft drum-law disks may start overlapping; stiff box-law disks must not
    shrink = 1.0 if isinstance(law, BoxLaw) else 0.95
    pos = random_disks_in_box(rng, radii * shrink, (0, 0), (9.5, 9.5))
    # converging flow: the cluster collapses and rebounds
    vel = -(pos - pos.mean(0)) + rng.normal(0, 0.3, (n, 2))
    sim = Simulation(law, dt=DT_BOX if isinstance(law, BoxLaw) else DT_DRUM, gravity=(0, 0))
    kwargs = {"spins": rng.normal(0, 2.0, n)} if isinstance(law, BoxLaw) else {}
    state = sim.new_state(pos, radii, (2 * radii) ** 2, velocities=vel, **kwargs)
    return sim, state


def momenta(state):
    m = state.masses
    p = (m[:, None] * state.velocities).sum(0)
    r, v = state.positions, state.velocities
    orbital = (m * (r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0])).sum()
    inertia = np.zeros_like(m)
    inv_i = state._s["sca"][0, K.INV_INERTIA]
    inertia[inv_i > 0] = 1.0 / inv_i[inv_i > 0]
    return p, orbital + (inertia * state.spins).sum(), (m * np.abs(v).sum(1)).sum()


@pytest.mark.parametrize("law", [DRUM_LAW, BOX_LAW], ids=["drum", "box"])
def test_momentum_conserved_to_round_off(law):
    """No walls, no gravity, full dissipation and friction: P (and L for the box law)
    change only by round-off: 1e-16 of sum m|v| (P) and 4e-14 of sum m|v| max|r| (L)
    measured, over 2,000 (drum law) and 40,000 steps (box law)."""
    sim, state = cluster(law, seed=3)
    p0, l0, scale = momenta(state)
    spins0 = state.spins.copy()
    sim.run(state, 2000 if isinstance(law, DrumLaw) else 40_000)
    p1, l1, _ = momenta(state)
    # drum: a dense cluster; box: ~200 binary collisions (contacts last 50 steps)
    assert state.neighbour_stats()["mean_contacts"] > (5 if isinstance(law, DrumLaw) else 0.1)
    assert np.abs(p1 - p0).max() < 1e-12 * scale
    if isinstance(law, BoxLaw):
        r_scale = scale * np.abs(state.positions).max()
        assert abs(l1 - l0) < 1e-12 * r_scale
        assert np.abs(state.spins - spins0).max() > 0.1  # friction turned the disks
