"""Shared systems for the engine tests: a settled 30-disk pile in a small drum."""

import numpy as np
import pytest

from granpipe.engine import DrumLaw, Simulation, WallDisks
from tests.engine.geometry import random_disks_in_circle, ring_of_disks

DRUM_LAW = DrumLaw(k_n=565.97, gamma_n=8.7308, gamma_t=6.8927, mu=0.44)
DT_DRUM = 1.14368e-3
D_SMALL, D_LARGE, D_WALL = 1.0, 1.1667, 1.3846


def small_drum(n_mobile=30, n_wall=24, seed=0):
    """A small drum: ``n_wall`` wall disks on a ring, ``n_mobile`` bidisperse disks inside.

    Returns positions, radii, masses, is_wall (mobile disks first) and the ring radius.
    """
    rng = np.random.default_rng(seed)
    ring, radius = ring_of_disks(n_wall, D_WALL)
    diam = np.where(np.arange(n_mobile) % 2 == 0, D_SMALL, D_LARGE)
    mob = random_disks_in_circle(rng, diam / 2, radius - D_WALL / 2)
    pos = np.vstack([mob, ring])
    radii = np.concatenate([diam / 2, np.full(n_wall, D_WALL / 2)])
    masses = np.concatenate([diam**2, np.ones(n_wall)])
    is_wall = np.arange(n_mobile + n_wall) >= n_mobile
    return pos, radii, masses, is_wall, radius


def settle(sim, state, max_steps=200_000, chunk=5_000, ke_tol=1e-8):
    """Run until the kinetic energy per mobile disk is below ``ke_tol``."""
    n_mob = int(state.mobile.sum())
    for _ in range(max_steps // chunk):
        sim.run(state, chunk)
        if state.kinetic_energy() / n_mob < ke_tol:
            return state
    raise RuntimeError("pile did not settle")


@pytest.fixture(scope="session")
def settled_drum_pile():
    """(sim, state): 30 disks settled under gravity in a resting 24-disk drum."""
    pos, radii, masses, is_wall, _ = small_drum()
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=0.0))
    state = sim.new_state(pos, radii, masses, is_wall=is_wall)
    settle(sim, state)
    return sim, state
