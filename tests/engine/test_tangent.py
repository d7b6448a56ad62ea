"""Tangent dynamics of the drum law: twin trajectories, the local Lyapunov exponent, rattlers."""

import numpy as np
import pytest

from granpipe.engine import FlatWalls, Simulation, WallDisks
from granpipe.engine import layout as K
from tests.engine.conftest import DRUM_LAW, DT_DRUM

OMEGA = -2.4417e-4  # drum of docs/drum.md, clockwise


def twin_error(sim, r0, v0, radii, masses, is_wall, du, eps, steps):
    """Relative distance between (twin - base)/eps and the tangent vector after ``steps``."""
    base = sim.new_state(r0, radii, masses, velocities=v0, is_wall=is_wall)
    sim.set_tangent(base, du[:, 0], du[:, 1])
    sim.run(base, steps, tangent=True)
    twin = sim.new_state(
        r0 + eps * du[:, 0], radii, masses, velocities=v0 + eps * du[:, 1], is_wall=is_wall
    )
    sim.run(twin, steps)
    tr, tv = base.tangent
    mob = ~is_wall
    gr = (twin.positions - base.positions) / eps
    gv = (twin.velocities - base.velocities) / eps
    err = np.sqrt(((gr - tr)[mob] ** 2).sum() + ((gv - tv)[mob] ** 2).sum())
    return err / np.sqrt((tr[mob] ** 2).sum() + (tv[mob] ** 2).sum())


def test_twin_trajectory_agrees_with_tangent_vector(settled_drum_pile):
    """(state(eps du0) - state)/eps matches the tangent after 2,000 steps, error O(eps).

    Dense settled 30-disk pile in a drum turning at the study's rate. With eps = 1e-6 the
    relative error is ~1e-6; it scales linearly with eps (absolute agreement O(eps²)),
    so the tangent map is the derivative of the discrete map. (Below eps ~ 1e-7 round-off
    of the twin difference dominates.)
    """
    sim0, settled = settled_drum_pile
    sim = sim0.replace(wall_disks=WallDisks(omega=OMEGA))
    is_wall = settled.is_wall
    rng = np.random.default_rng(5)
    du = np.where(is_wall[:, None, None], 0.0, rng.uniform(-1, 1, (len(is_wall), 2, 2)))
    args = (
        settled.positions.copy(),
        settled.velocities.copy(),
        settled.radii,
        settled.masses,
        is_wall,
        du,
    )
    e5 = twin_error(sim, *args, 1e-5, 2000)
    e6 = twin_error(sim, *args, 1e-6, 2000)
    assert e6 < 1e-5
    assert 5 < e5 / e6 < 20


def test_tangent_is_chunk_independent_and_scale_exact(settled_drum_pile):
    """Renormalisation by powers of two leaves the scaled tangent vector unchanged."""
    sim, settled = settled_drum_pile
    rng = np.random.default_rng(2)
    a = settled.copy()
    sim.random_tangent(a, rng)
    b = a.copy()
    # b starts huge: it is renormalised during the run, a is not
    b._s["vec"][:, K.T_POS : K.T_FRC + 1] *= 2.0**300
    b._s["sca"][:, K.T_PREV] *= 2.0**600
    b._s["counters"][:, K.LOG2_SCALE] = -300
    sim.run(a, 1000, tangent=True)
    for _ in range(4):
        sim.run(b, 250, tangent=True)
    assert b.tangent_log2_scale != -300
    np.testing.assert_array_equal(a.tangent[0], b.tangent[0])
    np.testing.assert_array_equal(a.tangent[1], b.tangent[1])
    np.testing.assert_array_equal(a.positions, b.positions)


def test_local_lyapunov_definition(settled_drum_pile):
    """Record of stride 1 equals lambda computed by hand from the tangent vector.

    ``lambda(t) = (1/dt) ln(|du(t)|_S / |du(t - dt)|_S)``, both norms over the disks S with
    at least two contacts (walls count) at step t. A fast disk thrown into the pile makes
    S change from step to step.
    """
    sim0, settled = settled_drum_pile
    sim = sim0.replace(wall_disks=WallDisks(omega=OMEGA))
    state = settled.copy()
    state.velocities[0] = [3.0, -2.0]  # a disk crossing the pile: contacts change
    sim.refresh(state)
    sim.random_tangent(state, np.random.default_rng(3), fraction=0.5)
    mob = state.mobile
    prev = np.concatenate(state.tangent, axis=1)
    changed = 0
    last_s = None
    for _ in range(300):
        rec = sim.run(state, 1, stride=1, tangent=True)
        du = np.concatenate(state.tangent, axis=1)
        s = mob & (state.contacts >= 2)
        num = (du[s] ** 2).sum()
        den = (prev[s] ** 2).sum()
        lam = 0.5 * np.log(num / den) / sim.dt
        assert rec.lyapunov_count[0] == 1
        assert rec.local_lyapunov[0] == pytest.approx(lam, rel=1e-12, abs=1e-9)
        if last_s is not None and np.any(s != last_s):
            changed += 1
        last_s = s
        prev = du
    assert changed > 0


def test_rattlers_are_excluded_and_lambda_matches_damped_well():
    """Rattlers (< 2 contacts) never enter lambda; a disk held in a corner gives the analytic rate.

    Disk 0 is pressed into the corner of the left and bottom walls by tilted gravity (2
    wall contacts: in S); disk 1 falls freely (0 contacts: a rattler). A perturbation of
    disk 1 alone leaves lambda undefined at every step. A horizontal perturbation of disk
    0 is a damped oscillator ``m x'' = -k_n x - (gamma_n + gamma_t) x'`` (left wall normal,
    bottom wall viscous friction), whose envelope decays at ``(gamma_n + gamma_t)/(2m)``:
    the mean of lambda over many periods tends to minus that rate, whatever disk 1 does.
    """
    walls = FlatWalls(x_left=0.0, bottom=True, z0=0.0)
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, flat_walls=walls, gravity=(-0.5, -1.0))
    state = sim.new_state([[0.499, 0.499], [5e3, 5e3]], [0.5, 0.5], [1.0, 1.0])
    sim.run(state, 10_000)  # settle into the corner (disk 1 stays far away)
    sim.set_tangent(state, [[0.0, 0.0], [1.0, 0.0]], [[0.0, 0.0], [0.0, 1.0]])
    rec = sim.run(state, 10, stride=10, tangent=True)
    assert state.contacts.tolist() == [2, 0]
    assert rec.lyapunov_count[0] == 0 and np.isnan(rec.local_lyapunov[0])

    n = 50_000
    sim.set_tangent(state, [[1.0, 0.0], [1.0, 0.0]], [[0.0, 0.0], [0.0, 1.0]])
    rec = sim.run(state, n, stride=n, tangent=True)
    assert rec.lyapunov_count[0] == n
    rate = (DRUM_LAW.gamma_n + DRUM_LAW.gamma_t) / 2.0
    assert rec.local_lyapunov[0] == pytest.approx(-rate, rel=0.01)
    assert state.tangent_log2_scale < -200  # renormalised along the way
