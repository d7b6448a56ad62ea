"""Binary collisions converge to the continuous-time contact as the step shrinks.

Analytic values (both laws are linear spring-dashpots in the normal direction, and the
force is not clipped, so a contact lasts exactly half a period of the damped oscillator
``m x'' + c x' + k x = 0``):

* drum law (docs/drum.md): ``omega² = k_n/m_ij - gamma_n²/(4 m_ij²)``, ``tau = pi/omega``,
  ``e = exp(-gamma_n tau / (2 m_ij))``;
* box law (docs/box.md): ``omega² = kappa_n/m_eff - gamma_n²/4``, ``t_c = pi/omega``,
  ``e = exp(-gamma_n t_c / 2)``,

with ``m_ij = m_i m_j/(m_i + m_j)`` (``m_i`` against a wall, whose mass is infinite).
Oblique drum-law contacts couple normal and tangential motion (the normal turns, and
friction switches between viscous and Coulomb), so there the reference is the contact
ODE of Eq. 1 written out independently of the engine (``reference.drum_eq1``),
integrated to 1e-12 (``reference.contact_ode``); for the box law the normal motion
does not depend on the tangential force, and the turn of the normal during a contact of
2e-3 time units is below 1e-5 rad, so the closed form is the reference there too.

Criterion: at the study's step / 100 the restitution and contact time agree
to 1e-3 relative; the step-size error shrinks from the study's step to step / 100.
"""

import math

import numpy as np
import pytest

from granpipe.engine import BoxLaw, DrumLaw, FlatWalls, Simulation
from tests.engine.reference import contact_ode, drum_eq1, step_by_step_collision

DRUM = DrumLaw(k_n=565.97, gamma_n=8.7308, gamma_t=6.8927, mu=0.44)
DT_DRUM = 1.14368e-3
BOX = BoxLaw(kappa_n=1e6, kappa_t=1e4, gamma_n=100.0, gamma_t=100.0, mu=0.6)
DT_BOX = BOX.contact_time(0.5) / 50
A_SMALL, A_LARGE, A_WALL = 0.5, 0.58335, 0.6923
M_LARGE = 1.1667**2

# direction of approach (unit) and tangential fraction of the impact velocity
HEAD_ON = 0.0
OBLIQUE = 0.4

FLAT = {
    "left": (np.array([1.0, 0.0]), FlatWalls(x_left=0.0, bottom=False)),
    "right": (np.array([-1.0, 0.0]), FlatWalls(x_right=0.0, bottom=False)),
    "bottom": (np.array([0.0, 1.0]), FlatWalls(bottom=True, z0=0.0)),
}


def approach(normal, speed, tangential):
    """Relative velocity hitting a surface with outward ``normal`` (pointing at the mover)."""
    t = np.array([-normal[1], normal[0]])
    return -speed * normal + tangential * speed * t


def pair_collision(law, dt, a_i, a_j, m_i, m_j, tangential, wall_j=False, angle=0.7):
    """Disk i hits disk j (or a fixed wall disk j); returns the engine's collision record."""
    n = np.array([math.cos(angle), math.sin(angle)])
    v_rel = approach(n, 1.0, tangential)
    s = a_i + a_j
    pre = 3 * dt
    d0 = n * s - v_rel * pre  # touches after `pre`
    if wall_j:
        pos = [d0, [0.0, 0.0]]
        vel = [v_rel, [0.0, 0.0]]
    else:
        mt = m_i + m_j
        pos = [d0 * m_j / mt, -d0 * m_i / mt]
        vel = [v_rel * m_j / mt, -v_rel * m_i / mt]
    sim = Simulation(law, dt=dt, gravity=(0.0, 0.0))
    state = sim.new_state(pos, [a_i, a_j], [m_i, m_j], velocities=vel, is_wall=[False, wall_j])
    out = step_by_step_collision(sim, state, 0, 1)
    out["n_in"] = n
    out["touch"] = (n * s, v_rel)
    return out


def flat_collision(law, dt, wall, a_i, m_i, tangential):
    normal, walls = FLAT[wall]
    v = approach(normal, 1.0, tangential)
    pre = 3 * dt
    d0 = normal * a_i - v * pre
    sim = Simulation(law, dt=dt, gravity=(0.0, 0.0), flat_walls=walls)
    state = sim.new_state([d0], [a_i], [m_i], velocities=[v])
    out = step_by_step_collision(sim, state, 0, None)
    out["n_in"] = normal
    out["touch"] = (normal * a_i, v)
    return out


def normal_restitution(out, normal_out):
    return -(out["v_out"] @ normal_out) / (out["v_in"] @ out["n_in"])


def relerr(x, ref):
    return abs(x / ref - 1.0)


# ----------------------------------------------------------------------------- drum law

DRUM_PAIRS = {
    "small-small": (A_SMALL, A_SMALL, 1.0, M_LARGE * 0 + 1.0, False),
    "small-large": (A_SMALL, A_LARGE, 1.0, M_LARGE, False),
    "small-walldisk": (A_SMALL, A_WALL, 1.0, math.inf, True),
}


@pytest.mark.parametrize("kind", list(DRUM_PAIRS))
def test_drum_pair_head_on_converges_to_analytic(kind):
    a_i, a_j, m_i, m_j, wall = DRUM_PAIRS[kind]
    m_ij = m_i if wall else m_i * m_j / (m_i + m_j)
    errs = []
    for f in (1, 100):
        out = pair_collision(
            DRUM, DT_DRUM / f, a_i, a_j, m_i, m_j if not wall else 1.0, HEAD_ON, wall_j=wall
        )
        e = normal_restitution(out, out["n_in"])
        errs.append(
            (relerr(e, DRUM.restitution(m_ij)), relerr(out["duration"], DRUM.contact_time(m_ij)))
        )
    assert errs[1][0] < 1e-3 and errs[1][1] < 1e-3, errs
    assert errs[1][0] < errs[0][0] and errs[1][1] < errs[0][1], errs


@pytest.mark.parametrize("kind", list(DRUM_PAIRS))
def test_drum_pair_oblique_converges_to_contact_ode(kind):
    a_i, a_j, m_i, m_j, wall = DRUM_PAIRS[kind]
    m_ij = m_i if wall else m_i * m_j / (m_i + m_j)
    s = a_i + a_j
    out = pair_collision(
        DRUM, DT_DRUM / 100, a_i, a_j, m_i, 1.0 if wall else m_j, OBLIQUE, wall_j=wall
    )
    d0, v0 = out["touch"]

    def eq1(law):
        return lambda d, v: drum_eq1(law, d / np.hypot(*d), s - np.hypot(*d), v)

    t_ref, v_ref, _ = contact_ode(eq1(DRUM), d0, v0, m_ij, lambda d: np.hypot(*d) - s, 1.0)
    assert relerr(out["duration"], t_ref) < 1e-3
    assert np.linalg.norm(out["v_out"] - v_ref) / np.linalg.norm(v0) < 1e-3
    # friction changed the outcome by far more than the tolerance: an engine without it
    # (or with another cap) would miss the reference
    frictionless = DrumLaw(k_n=DRUM.k_n, gamma_n=DRUM.gamma_n, gamma_t=0.0, mu=0.0)
    _, v_free, _ = contact_ode(eq1(frictionless), d0, v0, m_ij, lambda d: np.hypot(*d) - s, 1.0)
    assert np.linalg.norm(v_ref - v_free) > 0.05 * np.linalg.norm(v0)


@pytest.mark.parametrize("wall", list(FLAT))
@pytest.mark.parametrize("tangential", [HEAD_ON, OBLIQUE])
def test_drum_flat_wall_converges(wall, tangential):
    normal = FLAT[wall][0]
    out = flat_collision(DRUM, DT_DRUM / 100, wall, A_SMALL, 1.0, tangential)
    d0, v0 = out["touch"]
    t_ref, v_ref, _ = contact_ode(
        lambda d, v: drum_eq1(DRUM, normal, A_SMALL - d @ normal, v),
        d0,
        v0,
        1.0,
        lambda d: d @ normal - A_SMALL,
        1.0,
    )
    # the flat wall's normal motion is exactly the closed form
    assert t_ref == pytest.approx(DRUM.contact_time(1.0), rel=1e-7)
    assert v_ref @ normal == pytest.approx(DRUM.restitution(1.0), rel=1e-7)
    assert relerr(out["duration"], t_ref) < 1e-3
    assert relerr(normal_restitution(out, normal), DRUM.restitution(1.0)) < 1e-3
    assert np.linalg.norm(out["v_out"] - v_ref) / np.linalg.norm(v0) < 1e-3


# ----------------------------------------------------------------------------- box law

BOX_PAIRS = {
    "pair": (A_SMALL, A_SMALL, 1.0, 1.0, False),
    "walldisk": (A_SMALL, A_WALL, 1.0, math.inf, True),
}


@pytest.mark.parametrize("kind", list(BOX_PAIRS))
@pytest.mark.parametrize("tangential", [HEAD_ON, OBLIQUE])
def test_box_pair_converges_to_analytic(kind, tangential):
    a_i, a_j, m_i, m_j, wall = BOX_PAIRS[kind]
    m_eff = m_i if wall else m_i * m_j / (m_i + m_j)
    errs = []
    for f in (1, 100):
        out = pair_collision(
            BOX, DT_BOX / f, a_i, a_j, m_i, 1.0 if wall else m_j, tangential, wall_j=wall
        )
        n_out = out["d_out"] / np.linalg.norm(out["d_out"])
        e = normal_restitution(out, n_out)
        errs.append(
            (relerr(e, BOX.restitution(m_eff)), relerr(out["duration"], BOX.contact_time(m_eff)))
        )
    assert errs[1][0] < 1e-3 and errs[1][1] < 1e-3, errs
    assert errs[1][0] < errs[0][0], errs


@pytest.mark.parametrize("wall", list(FLAT))
@pytest.mark.parametrize("tangential", [HEAD_ON, OBLIQUE])
def test_box_flat_wall_converges_to_analytic(wall, tangential):
    normal = FLAT[wall][0]
    errs = []
    for f in (1, 100):
        out = flat_collision(BOX, DT_BOX / f, wall, A_SMALL, 1.0, tangential)
        errs.append(
            (
                relerr(normal_restitution(out, normal), BOX.restitution(1.0)),
                relerr(out["duration"], BOX.contact_time(1.0)),
            )
        )
    assert errs[1][0] < 1e-3 and errs[1][1] < 1e-3, errs
    assert errs[1][0] < errs[0][0], errs


def _max_head_on_overlap(sim, speed):
    """Largest overlap [d_s] of a small disk striking a fixed one head-on at ``speed``
    (a disk landing on a pile that does not give way)."""
    pos = np.array([[-0.5 - 1e-3, 0.0], [0.5 + 1e-3, 0.0]])
    vel = np.array([[speed, 0.0], [0.0, 0.0]])
    state = sim.new_state(pos, np.full(2, A_SMALL), np.ones(2), velocities=vel,
                          is_wall=np.array([False, True]))  # fmt: skip
    deepest = 0.0
    for _ in range(int(0.2 / sim.dt)):  # the contact ends after ~0.14 t0
        sim.run(state, 1)
        gap = abs(state.positions[1, 0] - state.positions[0, 0]) - 2 * A_SMALL
        deepest = max(deepest, -gap)
    return deepest


def test_overlap_bound_passes_a_deep_impact_and_stops_a_disk_passing_through():
    """The drum's falling disks strike the pile at ~9 d_s/t0: a head-on impact at that
    speed on a disk that does not give way overlaps by the damped oscillator's amplitude,
    more than half the radius - physical, passed by the bound 1 and refused by the bound
    0.5. At 25 d_s/t0 the centre would cross the other disk's rim: refused, naming the
    pair."""
    from granpipe.errors import SimulationError

    dt = DT_DRUM / 10
    deep = Simulation(DRUM, dt, gravity=(0.0, 0.0), max_overlap=1.0)
    m = 1.0  # against a disk of infinite mass
    w0 = math.sqrt(DRUM.k_n / m)
    zeta = DRUM.gamma_n / (2.0 * math.sqrt(DRUM.k_n * m))
    wd = w0 * math.sqrt(1.0 - zeta**2)
    t_max = math.atan2(wd, zeta * w0) / wd  # the overlap rate vanishes here
    amplitude = 9.0 / wd * math.exp(-zeta * w0 * t_max) * math.sin(wd * t_max)
    got = _max_head_on_overlap(deep, 9.0)
    assert got == pytest.approx(amplitude, rel=2e-3)
    assert 0.5 * A_SMALL < got < A_SMALL
    with pytest.raises(SimulationError, match="overlap deeper"):
        _max_head_on_overlap(deep.replace(max_overlap=0.5), 9.0)
    with pytest.raises(SimulationError, match="overlap deeper") as err:
        _max_head_on_overlap(deep, 25.0)
    assert "particle=0" in str(err.value) and "other=1" in str(err.value)
