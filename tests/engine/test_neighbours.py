"""Neighbour lists give the same forces as all pairs (slow reference in reference.py)."""

import numpy as np
import pytest

from granpipe.engine import BoxLaw, FlatWalls, Simulation, WallDisks
from granpipe.engine import layout as K
from tests.engine.conftest import DRUM_LAW, DT_DRUM
from tests.engine.geometry import random_disks_in_circle, ring_of_disks
from tests.engine.reference import all_pair_forces

BOX_LAW = BoxLaw(kappa_n=1e6, kappa_t=1e4, gamma_n=100.0, gamma_t=100.0, mu=0.6, mu_side=0.2)
FLAT = FlatWalls(x_left=-6.0, x_right=6.0, bottom=True, z0=-5.5)


def dense_state(seed, shrink, n_mobile=None):
    """Bidisperse disks packed at random (overlapping by up to 1 - shrink) in a drum of wall
    disks, cut by flat walls; random velocities and spins."""
    rng = np.random.default_rng(seed)
    if n_mobile is None:
        n_mobile = 150 if shrink < 0.9 else 115
    ring, radius = ring_of_disks(40, 1.3846)
    diam = rng.choice([1.0, 1.1667], n_mobile)
    mob = random_disks_in_circle(rng, diam / 2 * shrink, radius - 0.7, max_tries=100_000)
    # keep the disks that the flat walls cut by less than 0.4 of a radius
    a = diam / 2
    keep = (mob[:, 0] - 0.6 * a > FLAT.x_left) & (mob[:, 0] + 0.6 * a < FLAT.x_right)
    keep &= mob[:, 1] - 0.6 * a > FLAT.z0
    mob, diam = mob[keep], diam[keep]
    n_mobile = len(diam)
    pos = np.vstack([mob, ring])
    radii = np.concatenate([diam / 2, np.full(40, 0.6923)])
    masses = np.concatenate([diam**2, np.ones(40)])
    is_wall = np.arange(len(radii)) >= n_mobile
    vel = np.where(is_wall[:, None], 0.0, rng.normal(0, 0.5, pos.shape))
    spins = np.where(is_wall, 0.0, rng.normal(0, 1.0, len(radii)))
    return pos, radii, masses, is_wall, vel, spins


def test_drum_law_forces_equal_all_pairs_on_random_dense_states():
    for seed in range(2):
        pos, radii, masses, is_wall, vel, _ = dense_state(seed, shrink=0.88)
        sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=0.3), flat_walls=FLAT)
        state = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall)
        ref, _ = all_pair_forces(
            DRUM_LAW,
            state.positions,
            state.velocities,
            radii,
            masses,
            is_wall,
            sim.gravity,
            flat=FLAT.__dict__,
            bottom=(FLAT.z0, 0.0),
        )
        mob = ~is_wall
        scale = np.abs(ref[mob]).max()
        np.testing.assert_allclose(state.forces[mob], ref[mob], rtol=0, atol=1e-12 * scale)
        assert state.contacts[mob].mean() > 1.2  # dense: most disks touch


def test_drum_law_forces_after_rebuilds_equal_all_pairs():
    """After a run with many list rebuilds, the stored forces (evaluated at the half-step
    velocities w = v - dt/2 F/m) equal the all-pairs forces at (r, w)."""
    pos, radii, masses, is_wall, vel, _ = dense_state(7, shrink=0.95)
    sim = Simulation(
        DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=0.3), flat_walls=FLAT, skin=0.02
    )
    state = sim.new_state(pos, radii, masses, velocities=3 * vel, is_wall=is_wall)
    sim.run(state, 400)
    assert state.neighbour_stats()["rebuilds"] > 10
    mob = ~is_wall
    w = state.velocities.copy()
    w[mob] -= 0.5 * sim.dt * state.forces[mob] / masses[mob, None]
    t = state.time
    bottom = (FLAT.height(t), FLAT.velocity(t - 0.5 * sim.dt))
    ref, _ = all_pair_forces(
        DRUM_LAW,
        state.positions,
        w,
        radii,
        masses,
        is_wall,
        sim.gravity,
        flat=FLAT.__dict__,
        bottom=bottom,
    )
    # w is reconstructed to round-off; the damping terms pass that on to the forces
    scale = np.abs(ref[mob]).max()
    np.testing.assert_allclose(state.forces[mob], ref[mob], rtol=0, atol=1e-10 * scale)


def test_box_law_forces_and_torques_equal_all_pairs():
    for seed in range(2):
        pos, radii, masses, is_wall, vel, spins = dense_state(seed, shrink=0.998)
        sim = Simulation(BOX_LAW, dt=1e-5, flat_walls=FLAT)
        state = sim.new_state(pos, radii, masses, velocities=vel, spins=spins, is_wall=is_wall)
        ref, tau = all_pair_forces(
            BOX_LAW,
            state.positions,
            state.velocities,
            radii,
            masses,
            is_wall,
            sim.gravity,
            spins=spins,
            flat=FLAT.__dict__,
            bottom=(FLAT.z0, 0.0),
        )
        mob = ~is_wall
        np.testing.assert_allclose(
            state.forces[mob], ref[mob], rtol=0, atol=1e-12 * np.abs(ref[mob]).max()
        )
        np.testing.assert_allclose(
            state.torques[mob], tau[mob], rtol=0, atol=1e-12 * np.abs(tau[mob]).max()
        )
        assert np.abs(tau[mob]).max() > 0


@pytest.mark.parametrize("law", ["drum", "box"])
def test_every_contact_is_in_the_list_after_rebuilds(law):
    pos, radii, masses, is_wall, vel, spins = dense_state(11, shrink=1.0)
    if law == "drum":
        sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=0.5), skin=0.05)
        kw = {}
    else:
        sim = Simulation(BOX_LAW, dt=1e-4, wall_disks=WallDisks(omega=0.5), skin=0.01)
        kw = {"spins": spins}
        # a converging flow packs the disks within the short run
        vel = vel - np.where(is_wall[:, None], 0.0, 2.0 * (pos - pos[~is_wall].mean(0)))
    state = sim.new_state(pos, radii, masses, velocities=4 * vel, is_wall=is_wall, **kw)
    seen = 0
    for _ in range(20):
        sim.run(state, 50)
        s = state._s
        start, pj = s["pair_start"][0], s["pair_ij"][0, 1]
        listed = {(i, int(j)) for i in range(len(radii)) for j in pj[start[i] : start[i + 1]]}
        p = state.positions
        d = np.linalg.norm(p[:, None] - p[None], axis=-1)
        touching = d <= radii[:, None] + radii[None]
        touching[np.ix_(is_wall, is_wall)] = False
        for i, j in zip(*np.nonzero(np.triu(touching, 1)), strict=True):
            assert (int(i), int(j)) in listed
            seen += 1
    assert seen > 200
    assert state.neighbour_stats()["rebuilds"] > 5


@pytest.mark.parametrize("law", ["drum", "box"])
def test_compacted_and_full_pair_passes_agree_bit_for_bit(law):
    """The law runs on all listed pairs or on the touching ones only (chosen from the
    previous step's contact fraction); both give the same state to the last bit."""
    pos, radii, masses, is_wall, vel, spins = dense_state(5, shrink=0.99)
    walls = WallDisks(omega=0.5)
    if law == "drum":
        sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=walls, flat_walls=FLAT, skin=0.2)
        kw = {}
    else:
        sim = Simulation(BOX_LAW, dt=1e-5, wall_disks=walls, flat_walls=FLAT, skin=0.2)
        kw = {"spins": spins}
    base = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall, **kw)
    sim.run(base, 20)
    if law == "drum":
        sim.random_tangent(base, np.random.default_rng(0))
    full, compact = base.copy(), base.copy()
    npairs = full._s["counters"][0, K.N_PAIRS]
    full._s["counters"][0, K.LAST_PAIR_CONTACTS] = npairs
    compact._s["counters"][0, K.LAST_PAIR_CONTACTS] = 0
    touching = full.contacts.sum() / 2
    assert 0.1 * npairs < touching < 0.9 * npairs  # both kinds of listed pairs present
    for state in (full, compact):
        sim.run(state, 1, tangent=law == "drum")
    np.testing.assert_array_equal(full._s["vec"], compact._s["vec"])
    for key in ("sca", "pair_xi"):
        np.testing.assert_array_equal(full._s[key], compact._s[key])
    np.testing.assert_array_equal(full.contacts, compact.contacts)
