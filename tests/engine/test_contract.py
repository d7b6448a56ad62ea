"""The contact-law contract: every registered law through the same tests.

For each law (drum, box, static friction): its Jacobian leaf against central finite
differences of its force leaf on every smooth piece; the tangent vector against twin
trajectories on a settled pile in a turning drum and against flat walls; friction
against physics (a disk sliding on a floor decelerates at mu g in the Coulomb regime
and, below it, sticks or decays at the viscous rate; on an incline a law with static
friction holds below atan(mu) and slides above); restitution at an effective mass
other than one half; lambda against its definition, with the spin's part of the norm;
and the compiled row loop of the passes vectorised (packed square roots and divisions).
For the static-friction law also conservation (momentum, angular momentum with spin,
energy of an elastic sticking contact).
"""

import numpy as np
import pytest

from granpipe.engine import (
    BoxLaw,
    DrumLaw,
    FlatWalls,
    Simulation,
    StaticFrictionLaw,
    WallDisks,
    registered_laws,
)
from granpipe.errors import ConfigError, SimulationError
from tests.engine.conftest import DRUM_LAW, DT_DRUM
from tests.engine.geometry import random_disks_in_box

OMEGA = -2.4417e-4  # the drum of docs/drum.md, clockwise, in its reduced units

# one instance per registered law, in the drum's reduced units (the box law with
# stiffness and damping of the drum's order, so that the same time step resolves it)
LAWS = {
    "drum": DRUM_LAW,
    "box": BoxLaw(kappa_n=565.97, kappa_t=150.0, gamma_n=8.0, gamma_t=8.0, mu=0.44),
    "static_friction": StaticFrictionLaw(k_n=565.97, gamma_n=8.7308, gamma_t=6.8927, mu=0.44),
}


def test_every_registered_law_is_tested():
    assert set(registered_laws()) == set(LAWS)


def central_jacobian(f, x, h):
    cols = []
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.array(cols).T


def random_contact(rng):
    """A random touching pair: (d, v, spin_i, spin_j, a_i, a_j, m_eff, xi)."""
    a_i, a_j = rng.uniform(0.45, 0.6, 2)
    r = (a_i + a_j) * rng.uniform(0.97, 0.999)
    phi = rng.uniform(0, 2 * np.pi)
    d = r * np.array([np.cos(phi), np.sin(phi)])
    v = rng.normal(0, 0.3, 2)
    spins = rng.normal(0, 0.5, 2)
    return d, v, *spins, a_i, a_j, rng.uniform(0.3, 1.0), rng.normal(0, 2e-3)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_jacobian_leaf_matches_central_differences_on_every_piece(name):
    """``pair_jacobian`` (the law's Jacobian leaf) against central differences of ``pair``
    in all seven inputs, at contacts drawn until every smooth piece was seen."""
    law = LAWS[name]
    rng = np.random.default_rng(3)
    dt = DT_DRUM
    seen = set()
    for _ in range(400):
        d, v, wi, wj, ai, aj, m_eff, xi = random_contact(rng)
        _, piece = law.pair(d, v, wi, wj, ai, aj, m_eff, xi, dt)

        def f(x, ai=ai, aj=aj, m_eff=m_eff):
            return law.pair(x[:2], x[2:4], x[4], x[5], ai, aj, m_eff, x[6], dt)[0]

        x = np.array([*d, *v, wi, wj, xi])
        fd = central_jacobian(f, x, 1e-7)
        # a step across a switch between pieces spoils the differences: skip those
        pieces = {law.pair(x[:2] + s * e[:2], x[2:4] + s * e[2:4], x[4] + s * e[4],
                           x[5] + s * e[5], ai, aj, m_eff, x[6] + s * e[6], dt)[1]
                  for s in (1e-7, -1e-7) for e in np.eye(7)}  # fmt: skip
        if pieces != {piece}:
            continue
        jac = law.pair_jacobian(d, v, wi, wj, ai, aj, m_eff, xi, dt)
        scale = np.abs(fd).max(axis=1, keepdims=True) + 1e-12
        np.testing.assert_allclose(jac / scale, fd / scale, atol=2e-6, err_msg=f"piece {piece}")
        seen.add(piece)
    assert len(seen) >= (2 if name != "drum" else 3), seen


def twin_error(sim, settled, du, dspin, eps, steps):
    """Relative distance between (twin - base)/eps and the tangent vector after ``steps``."""
    is_wall = settled.is_wall
    r0, v0 = settled.positions.copy(), settled.velocities.copy()
    spins = settled.spins.copy() if sim.law.has_spin else None
    kw = dict(is_wall=is_wall)
    base = sim.new_state(r0, settled.radii, settled.masses, velocities=v0, spins=spins, **kw)
    history = settled.shear_history() if sim.law.has_history else None
    if history is not None:  # the loaded springs of the pile, the same for both twins
        sim.set_shear_history(base, *history)
    sim.set_tangent(base, du[:, 0], du[:, 1], dspin)
    sim.run(base, steps, tangent=True)
    s1 = None if spins is None else spins + eps * dspin
    twin = sim.new_state(
        r0 + eps * du[:, 0], settled.radii, settled.masses, velocities=v0 + eps * du[:, 1],
        spins=s1, **kw,
    )  # fmt: skip
    if history is not None:
        sim.set_shear_history(twin, *history)
    sim.run(twin, steps)
    tr, tv = base.tangent
    mob = ~is_wall
    gr = (twin.positions - base.positions) / eps
    gv = (twin.velocities - base.velocities) / eps
    gw = (twin.spins - base.spins) / eps
    tw = base.tangent_spin
    err = ((gr - tr)[mob] ** 2).sum() + ((gv - tv)[mob] ** 2).sum() + ((gw - tw)[mob] ** 2).sum()
    ref = (tr[mob] ** 2).sum() + (tv[mob] ** 2).sum() + (tw[mob] ** 2).sum()
    return np.sqrt(err / ref)


@pytest.fixture(scope="module")
def piles(settled_drum_pile):
    """Per law: (simulation of the turning drum, a pile settled under it)."""
    sim0, settled = settled_drum_pile
    out = {}
    for name, law in LAWS.items():
        sim = Simulation(law, dt=DT_DRUM, wall_disks=WallDisks(omega=OMEGA))
        spins = np.zeros(settled.n) if law.has_spin else None
        state = sim.new_state(
            settled.positions, settled.radii, settled.masses, spins=spins, is_wall=settled.is_wall
        )
        sim.run(state, 3000)  # settle the history and spins of this law
        out[name] = (sim, state)
    return out


@pytest.mark.parametrize("name", sorted(LAWS))
def test_twin_trajectory_agrees_with_the_tangent_vector(piles, name):
    """(state(eps du0) - state)/eps against the tangent vector after
    2,000 steps on a settled pile in the turning drum: relative error O(eps) (positions,
    velocities and, with spin, spins; the shear histories' perturbations drive them)."""
    sim, settled = piles[name]
    rng = np.random.default_rng(11)
    mob = ~settled.is_wall
    du = np.where(mob[:, None, None], rng.uniform(-1, 1, (settled.n, 2, 2)), 0.0)
    dspin = np.where(mob, rng.uniform(-1, 1, settled.n), 0.0) if sim.law.has_spin else None
    e5 = twin_error(sim, settled, du, dspin, 1e-5, 2000)
    e6 = twin_error(sim, settled, du, dspin, 1e-6, 2000)
    assert e6 < 1e-5
    assert 5 < e5 / e6 < 20


@pytest.mark.parametrize("name", sorted(LAWS))
def test_local_lyapunov_counts_each_disks_spin_perturbation(piles, name):
    """A record of stride 1 equals ``lambda = (1/2dt) ln(|du(t)|²_S / |du(t - dt)|²_S)``
    computed by hand, S the mobile disks with at least two contacts and, for laws with
    spin, ``|du_i|² = |dr_i|² + |dv_i|² + (a_i domega_i)²`` (the spin's perturbation as a
    velocity at the rim). For those laws the value without the spin's part is also
    computed and must differ: the test sees a dropped or misplaced spin term."""
    sim, settled = piles[name]
    state = settled.copy()
    rng = np.random.default_rng(4)
    mob = state.mobile
    du = np.where(mob[:, None, None], rng.uniform(-1, 1, (state.n, 2, 2)), 0.0)
    dspin = np.where(mob, rng.uniform(-20, 20, state.n), 0.0) if sim.law.has_spin else None
    sim.set_tangent(state, du[:, 0], du[:, 1], dspin)

    def norms(st, spin=True):
        tr, tv = st.tangent
        q = (tr**2).sum(axis=1) + (tv**2).sum(axis=1)
        return q + (st.radii * st.tangent_spin) ** 2 if spin and sim.law.has_spin else q

    prev, prev_bare = norms(state), norms(state, spin=False)
    for _ in range(40):
        rec = sim.run(state, 1, stride=1, tangent=True)
        s = mob & (state.contacts >= 2)
        q, bare = norms(state), norms(state, spin=False)
        lam = 0.5 * np.log(q[s].sum() / prev[s].sum()) / sim.dt
        assert rec.lyapunov_count[0] == 1
        assert rec.local_lyapunov[0] == pytest.approx(lam, rel=1e-12, abs=1e-9)
        if sim.law.has_spin:
            lam_bare = 0.5 * np.log(bare[s].sum() / prev_bare[s].sum()) / sim.dt
            assert abs(lam_bare - lam) > 1e-6
        prev, prev_bare = q, bare


@pytest.mark.parametrize("name", [n for n, law in sorted(LAWS.items()) if law.has_history])
def test_a_state_rebuilt_with_its_shear_history_continues_as_the_saved_one(piles, name):
    """Positions, velocities, spins and shear histories are the whole state: a copy made
    from them follows the original for 1,000 steps to round-off, and one made without
    the histories does not."""
    sim, pile = piles[name]
    saved = pile.copy()
    sim.refresh(saved)  # forces at full-step velocities, as a new state evaluates them
    pairs, xi = saved.shear_history()
    assert len(xi) > saved.n // 2  # a loaded pile: most contacts hold a spring

    def rebuilt(with_history):
        state = sim.new_state(
            saved.positions, saved.radii, saved.masses, velocities=saved.velocities,
            spins=saved.spins, is_wall=saved.is_wall, time=saved.time,
        )  # fmt: skip
        if with_history:
            sim.set_shear_history(state, pairs, xi)
        return state

    copy, forgetful = rebuilt(True), rebuilt(False)
    np.testing.assert_allclose(copy.forces, saved.forces, rtol=0, atol=1e-12)
    for st in (saved, copy, forgetful):
        sim.run(st, 1000)
    mob = ~saved.is_wall
    scale = np.abs(saved.velocities[mob]).max()
    err = np.abs(copy.velocities - saved.velocities)[mob].max() / scale
    lost = np.abs(forgetful.velocities - saved.velocities)[mob].max() / scale
    assert err < 1e-10, err
    assert lost > 1e3 * max(err, 1e-14), lost
    with pytest.raises(ConfigError, match="not within contact range"):
        sim.set_shear_history(copy, [[0, saved.n - 1]], [1e-3])


def free_pair(law, dt, v=(0.4, 0.05), spins=(0.3, -1.0)):
    sim = Simulation(law, dt=dt, gravity=(0.0, 0.0))
    pos = np.array([[0.0, 0.0], [1.01, 0.2]])
    vel = np.array([v, [-v[0], 0.0]])
    return sim, sim.new_state(pos, np.full(2, 0.5), np.array([1.0, 1.3]), velocities=vel,
                              spins=np.array(spins))  # fmt: skip


def momenta(st):
    m = st.masses
    r, v = st.positions, st.velocities
    inertia = 0.5 * m * st.radii**2
    p = (m[:, None] * v).sum(0)
    ang = (m * (r[:, 0] * v[:, 1] - r[:, 1] * v[:, 0])).sum() + (inertia * st.spins).sum()
    return p, ang


def test_static_friction_conserves_momentum_and_angular_momentum_to_round_off():
    """A free colliding pair with spin, damping and sliding: linear and angular momentum
    (about the origin, spin included) are conserved by the discrete map to round-off,
    because the contact point sits mid-overlap (l_i + l_j = r)."""
    law = StaticFrictionLaw(k_n=565.97, gamma_n=8.7308, gamma_t=6.8927, mu=0.44)
    sim, st = free_pair(law, DT_DRUM)
    p0, l0 = momenta(st)
    for _ in range(10):
        sim.run(st, 300)
        p, ang = momenta(st)
        np.testing.assert_allclose(p, p0, rtol=0, atol=1e-14)
        assert abs(ang - l0) < 1e-13 * (1 + abs(l0))
    assert not np.allclose(st.spins, [0.3, -1.0])  # the contact did turn the disks


def contact_energy(law, st):
    """Kinetic energy plus the normal and tangential springs' energy."""
    d = st.positions[0] - st.positions[1]
    overlap = max(0.0, 1.0 - np.hypot(*d))
    xi = st._s["pair_xi"][0, 0] if overlap > 0 else 0.0
    return st.kinetic_energy() + 0.5 * law.k_n * overlap**2 + 0.5 * law.k_tangential * xi**2


def test_static_friction_elastic_sticking_contact_conserves_energy_to_order_dt2():
    """No damping and a friction coefficient that never lets the contact slide: the energy
    (kinetic, translational and rotational, plus both springs) is conserved up to the
    integrator's O(dt²) error, measured by halving dt."""
    law = StaticFrictionLaw(k_n=565.97, gamma_n=0.0, gamma_t=0.0, mu=50.0)
    errs = []
    for dt in (2e-3, 1e-3):
        sim, st = free_pair(law, dt, v=(0.15, 0.0))
        e0 = contact_energy(law, st)
        worst, touched = 0.0, False
        for _ in range(int(0.4 / dt)):
            sim.run(st, 1)
            apart = np.hypot(*(st.positions[0] - st.positions[1])) > 1.0
            if touched and apart:
                break  # the history of an opened contact is dropped: stop at the opening
            touched = touched or not apart
            worst = max(worst, abs(contact_energy(law, st) - e0))
        assert touched
        errs.append(worst / e0)
    assert errs[1] < 1e-3
    assert 3.0 < errs[0] / errs[1] < 5.0


def test_static_friction_default_tangential_stiffness_matches_periods():
    """k_t = k_n/3 gives a sticking contact the normal period: measured on a disk that
    rocks on a fixed wall disk, against the normal oscillation of the same contact."""
    law = StaticFrictionLaw(k_n=565.97, gamma_n=0.0, gamma_t=0.0, mu=50.0)  # default k_t
    # normal: m_eff = m against a wall disk, omega_n² = k_n/m; the sticking contact's
    # tangential mode, 3 k_t/m (rolling disk, I = m a²/2), has it when k_t = k_n/3
    m = 1.0
    w_n = np.sqrt(law.k_n / m)
    # measured: a disk resting under gravity on a fixed wall disk (at its equilibrium
    # overlap), kicked tangentially; its spring's history oscillates at w_t (the rolling
    # mode leaves the history alone)
    dt = 1e-4
    sim = Simulation(law, dt=dt)
    pos = np.array([[0.0, 1.0 - m / law.k_n], [0.0, 0.0]])
    st = sim.new_state(pos, np.full(2, 0.5), np.array([m, 1.0]), is_wall=np.array([False, True]),
                       velocities=np.array([[1e-3, 0.0], [0.0, 0.0]]))  # fmt: skip
    xs = []
    for _ in range(20_000):
        sim.run(st, 1)
        xs.append(st._s["pair_xi"][0, 0])
    xs = np.array(xs) - np.mean(xs)
    k = np.flatnonzero(np.sign(xs[1:]) != np.sign(xs[:-1]))
    t_cross = (k + xs[k] / (xs[k] - xs[k + 1])) * dt  # linear interpolation
    period = 2 * np.mean(np.diff(t_cross))
    assert period == pytest.approx(2 * np.pi / w_n, rel=0.01)


def test_bad_coefficients_and_a_drum_law_state_are_refused():

    with pytest.raises(ConfigError, match="k_t must be > 0"):
        StaticFrictionLaw(k_n=1.0, gamma_n=0.0, gamma_t=0.0, mu=0.4, k_t=0.0)
    with pytest.raises(ConfigError, match="mu must be >= 0"):
        StaticFrictionLaw(k_n=1.0, gamma_n=0.0, gamma_t=0.0, mu=float("nan"))
    law = LAWS["static_friction"]
    sim_d = Simulation(DrumLaw(k_n=1.0, gamma_n=0.0, gamma_t=0.0, mu=0.0), dt=1e-3)
    st = sim_d.new_state(np.zeros((1, 2)), [0.5], [1.0])
    with pytest.raises(ConfigError, match="different contact law"):
        Simulation(law, dt=1e-3).run(st, 1)


def test_profiling_the_passes_leaves_the_state_where_it_was(piles):
    """``Simulation.profile_passes`` times every pass on a copy of the state:
    the state itself then runs bit for bit as an untouched copy does."""
    sim, pile = piles["static_friction"]
    state, twin = pile.copy(), pile.copy()
    t = sim.profile_passes(state, repeats=1, nrep=3)
    assert t["n_pairs"] == int(np.ravel(state.neighbour_stats()["pairs"])[0])
    assert t["n_particles"] == state.n
    names = {
        f"{p}.{m}" for p in ("gather", "law", "scatter", "kicks") for m in ("forward", "tangent")
    } | {"rebuild"}
    assert names <= set(t) and all(t[k] > 0 for k in names)
    for st in (state, twin):
        sim.run(st, 200)
    np.testing.assert_array_equal(state.positions, twin.positions)
    np.testing.assert_array_equal(state.shear_history()[1], twin.shear_history()[1])


# ----------------------------------------------------------------- flat walls
BOX_WALLS = FlatWalls(x_left=0.0, x_right=8.0, bottom=True, z0=0.0)


@pytest.fixture(scope="module")
def boxes():
    """Per law: (simulation of a box with side walls and a floor, a pile of 40 disks
    settled in it over 34 t0)."""
    rng = np.random.default_rng(5)
    n = 40
    radii = np.full(n, 0.5)
    pos = random_disks_in_box(rng, radii, (0.0, 0.0), (8.0, 12.0))
    out = {}
    for name, law in LAWS.items():
        sim = Simulation(law, dt=DT_DRUM, flat_walls=BOX_WALLS)
        spins = np.zeros(n) if law.has_spin else None
        state = sim.new_state(pos, radii, np.ones(n), spins=spins)
        sim.run(state, 30000)
        out[name] = (sim, state)
    return out


@pytest.mark.parametrize("name", sorted(LAWS))
def test_twin_trajectory_agrees_with_the_tangent_vector_against_flat_walls(boxes, name):
    """The tangent vector against twin trajectories of a pile
    resting on a floor between two side walls, 200 steps: relative error O(eps), so the
    wall contacts (with their shear histories under the box and static-friction laws)
    are linearised exactly. (Over longer times the pile's contacts switch pieces: at
    rest, many sit at the Coulomb bound.)"""
    sim, pile = boxes[name]
    walls = (pile.positions[:, 1] < 0.51).sum() + (pile.positions[:, 0] < 0.51).sum()
    walls += (pile.positions[:, 0] > 7.49).sum()
    assert walls >= 8  # disks on the floor and against the side walls
    rng = np.random.default_rng(7)
    du = rng.uniform(-1, 1, (pile.n, 2, 2))
    dspin = rng.uniform(-1, 1, pile.n) if sim.law.has_spin else None
    e5 = twin_error(sim, pile, du, dspin, 1e-5, 200)
    e6 = twin_error(sim, pile, du, dspin, 1e-6, 200)
    assert e5 < 1e-4 and e6 < 1e-5, (e5, e6)
    assert 8.0 < e5 / e6 < 12.0, (e5, e6)


def test_a_disk_driven_into_a_flat_wall_names_the_wall():
    sim = Simulation(LAWS["static_friction"], dt=DT_DRUM, gravity=(0.0, 0.0),
                     flat_walls=FlatWalls(x_left=0.0, bottom=False))  # fmt: skip
    st = sim.new_state([[0.6, 5.0]], [0.5], [1.0], velocities=[[-50.0, 0.0]], spins=[0.0])
    with pytest.raises(SimulationError, match="overlap") as err:
        sim.run(st, 200)
    assert err.value.context.get("other") == "left wall"


# ----------------------------------------------------------------- friction and restitution
FLOOR = FlatWalls(bottom=True, z0=0.0)


def _on_floor(law, vx, gravity=(0.0, -1.0)):
    """One disk (radius 1/2, mass 1, not turning) resting on the floor at its equilibrium
    overlap, sliding at ``vx``; ``gravity`` may be tilted (an incline)."""
    sim = Simulation(law, dt=DT_DRUM, flat_walls=FLOOR, gravity=gravity)
    spins = [0.0] if law.has_spin else None
    k = law.params()[0]  # k_n or kappa_n: the first parameter of every law here
    state = sim.new_state([[0.0, 0.5 + gravity[1] / k]], [0.5], [1.0], velocities=[[vx, 0.0]],
                          spins=spins, inertia=[np.inf])  # fmt: skip
    return sim, state


def _velocity_series(sim, state, steps, every):
    out = []
    for _ in range(steps // every):
        sim.run(state, every)
        out.append((state.time, state.velocities[0, 0]))
    return np.array(out)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_a_disk_sliding_on_a_floor_decelerates_at_mu_g(name):
    """Coulomb regime: |f_t| = mu m g, so v_x falls linearly at mu g (exactly, once the
    normal force is the weight), for every law."""
    law = LAWS[name]
    sim, state = _on_floor(law, 2.0)
    series = _velocity_series(sim, state, 3000, 100)
    t, v = series[:, 0], series[:, 1]
    sliding = (v > 0.3) & (t > 0.05)
    slope = np.polyfit(t[sliding], v[sliding], 1)[0]
    assert slope == pytest.approx(-law.params().mu * 1.0, rel=1e-6)


def test_below_the_cap_the_drum_law_slows_at_its_viscous_rate():
    """Drum paper Eq. 1 below the Coulomb cap: f_t = -gamma_t u, so the half-step
    velocity of the discrete map shrinks by (1 - dt gamma_t/m) per step, and the
    full-step velocity with it."""
    law = LAWS["drum"]
    u_cap = law.mu / law.gamma_t  # mu m g / gamma_t: the speed below which it is viscous
    sim, state = _on_floor(law, 0.5 * u_cap)
    sim.run(state, 10)
    v0 = state.velocities[0, 0]
    sim.run(state, 200)
    assert state.velocities[0, 0] / v0 == pytest.approx(
        (1 - DT_DRUM * law.gamma_t) ** 200, rel=1e-9
    )


@pytest.mark.parametrize("name", [n for n, law in sorted(LAWS.items()) if law.has_history])
def test_below_the_cap_a_law_with_static_friction_sticks(name):
    """A spring law below the cap sticks: the disk stops within the elastic creep of its
    tangential spring and stays put."""
    law = LAWS[name]
    sim, state = _on_floor(law, 0.5 * law.params().mu)
    x0 = state.positions[0, 0]
    sim.run(state, 20_000)
    x1 = state.positions[0, 0]
    sim.run(state, 5_000)
    assert abs(state.velocities[0, 0]) < 1e-9
    assert state.positions[0, 0] == pytest.approx(x1, abs=1e-12)
    assert 0.0 < x1 - x0 < 1.0  # it slid a little, then held


@pytest.mark.parametrize("name", sorted(LAWS))
@pytest.mark.parametrize("ratio", [0.8, 1.25])
def test_on_an_incline(name, ratio):
    """Gravity tilted by theta with tan(theta) = ratio * mu: above atan(mu) every law
    slides down at g (sin(theta) - mu cos(theta)); below it a law with static friction
    holds, and the drum law (viscous friction only) creeps at its terminal speed
    m g sin(theta) / gamma_t."""
    law = LAWS[name]
    mu = law.params().mu
    theta = np.arctan(ratio * mu)
    g = (np.sin(theta), -np.cos(theta))
    sim, state = _on_floor(law, 0.0, gravity=g)
    series = _velocity_series(sim, state, 6000, 100)
    t, v = series[:, 0], series[:, 1]
    late = t > t[-1] / 2
    if ratio > 1:
        slope = np.polyfit(t[late], v[late], 1)[0]
        assert slope == pytest.approx(np.sin(theta) - mu * np.cos(theta), rel=1e-6)
    elif law.has_history:
        assert np.abs(v[late]).max() < 1e-6  # held (the drum law creeps at ~0.05)
    else:
        np.testing.assert_allclose(v[late], np.sin(theta) / law.gamma_t, rtol=1e-6)


@pytest.mark.parametrize("name", sorted(LAWS))
def test_restitution_at_an_effective_mass_other_than_one_half(name):
    """Head-on collision of masses 1 and 3 (m_eff = 3/4): the normal coefficient of
    restitution of the linear spring-dashpot m_eff x'' + c x' + k x = 0,
    e = exp(-beta pi / sqrt(k/m_eff - beta²)), beta = c / (2 m_eff), with c = gamma_n
    (drum and static friction: damping not scaled by mass) or gamma_n m_eff (box), to
    the integrator's error at a hundredth of the study's step (as test_collisions.py)."""
    law = LAWS[name]
    p = law.params()
    k, gamma_n = p[0], (p.gamma_n if hasattr(p, "gamma_n") else p[2])
    m1, m2 = 1.0, 3.0
    m_eff = m1 * m2 / (m1 + m2)
    c = gamma_n * m_eff if name == "box" else gamma_n
    beta = c / (2 * m_eff)
    e = np.exp(-beta * np.pi / np.sqrt(k / m_eff - beta**2))
    dt = DT_DRUM / 100
    sim = Simulation(law, dt=dt, gravity=(0.0, 0.0))
    spins = np.zeros(2) if law.has_spin else None
    v_in = 0.3
    state = sim.new_state([[0.0, 0.0], [1.0 + 2 * dt * v_in, 0.0]], [0.5, 0.5], [m1, m2],
                          velocities=[[v_in, 0.0], [0.0, 0.0]], spins=spins)  # fmt: skip
    sim.run(state, int(0.5 / dt))
    v_out = state.velocities[1, 0] - state.velocities[0, 0]
    assert v_out / v_in == pytest.approx(e, rel=1e-3)
    # the value a law that dropped the factor 2 m_eff (exact at m_eff = 1/2) would give
    dropped = np.exp(-c * np.pi / np.sqrt(k / m_eff - c**2))
    assert abs(dropped / e - 1) > 0.01


# ----------------------------------------------------------------- speed cannot be lost silently
@pytest.mark.parametrize("name", sorted(LAWS))
@pytest.mark.parametrize("mode", ["forward", "tangent"])
def test_the_law_rows_compile_to_packed_square_roots_and_divisions(name, mode):
    """The law's row loop of every registered law, forward and with the tangent vector,
    vectorises: its assembly holds packed square roots and divisions (``sqrtpd``,
    ``divpd``, or their AVX forms). Compiled afresh with the project's JIT options
    (numba does not keep the assembly of cached code)."""
    import numba

    from granpipe._jit import JIT_OPTIONS
    from granpipe.engine import passes as P
    from granpipe.engine.layout import NB

    fn = numba.njit(**{**JIT_OPTIONS, "cache": False})(P.law_rows.py_func)
    cap = 16
    a = np.zeros(cap)
    marker = P.TANGENT if mode == "tangent" else P.FORWARD
    fn(LAWS[name].params(), marker, np.zeros((NB, cap)), a, a, a, a, a, a,
       np.zeros(cap, np.int64), np.zeros(cap, np.int8), cap, 0.0)  # fmt: skip
    asm = fn.inspect_asm(fn.signatures[0])
    assert "sqrtpd" in asm and "divpd" in asm


def test_law_leaves_compile_with_the_project_jit_options():
    """The leaves are overloads registered with the project's options (numpy's error
    model: without it a division by zero raises, and its check blocks vectorisation)."""
    from numba.core.registry import cpu_target

    from granpipe._jit import JIT_OPTIONS
    from granpipe.engine.contract import pair_force, pair_force_jvp

    for generic in (pair_force, pair_force_jvp):
        templates = cpu_target.typing_context.resolve_value_type(generic).templates
        assert len(templates) == len(LAWS)
        for template in templates:
            options = template._jit_options
            assert {k: options[k] for k in JIT_OPTIONS} == JIT_OPTIONS, options
