"""Slow, obviously-correct references for the engine's fast kernels (STYLE.md, stumpy).

* :func:`drum_eq1` — the drum paper's Eq. 1 written out in numpy, independently of the
  engine's leaf.
* :func:`all_pair_forces` — forces by looping over all pairs and walls in Python.
* :func:`contact_ode` — a binary contact integrated as an ODE to tolerance 1e-12
  (scipy DOP853), the continuous-time answer the discrete engine must converge to.
* :func:`step_by_step_collision` — drives the engine one step at a time through a
  collision and measures the outgoing velocity and the contact duration.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp


def drum_eq1(law, n, overlap, v):
    """Force on i of drum paper Eq. 1 for a contact of unit normal ``n`` (from j to i),
    overlap ``overlap`` (> 0 in contact) and relative velocity ``v = v_i - v_j``:
    ``f_n = k_n overlap - gamma_n v.n`` along n, ``-min(gamma_t |u|, mu max(f_n, 0))
    sign(u)`` along ``t = (-n_y, n_x)`` with ``u = v.t``. ``law``: the DrumLaw."""
    n = np.asarray(n, float)
    t = np.array([-n[1], n[0]])
    f_n = law.k_n * overlap - law.gamma_n * (v @ n)
    u = v @ t
    f_t = -min(law.gamma_t * abs(u), law.mu * max(f_n, 0.0)) * np.sign(u)
    return f_n * n + f_t * t


def all_pair_forces(
    law,
    positions,
    velocities,
    radii,
    masses,
    is_wall,
    gravity,
    spins=None,
    flat=None,
    bottom=(0.0, 0.0),
):
    """Forces (and torques) on every disk from all pairs and flat walls, in plain Python,
    one contact at a time through the law's leaf (:meth:`ContactLaw.pair`,
    :meth:`ContactLaw.wall_pair`): the sum over pairs and walls the passes make.

    ``flat``: dict with optional keys ``x_left``, ``x_right``, ``bottom`` (True); ``bottom``
    = (z_b, v_b). Shear histories are taken as zero (a fresh evaluation).
    """
    n = len(radii)
    f = np.zeros((n, 2))
    tau = np.zeros(n)
    spins = np.zeros(n) if spins is None else spins
    for i in range(n):
        if not is_wall[i]:
            f[i] = masses[i] * np.asarray(gravity)
    for i in range(n):
        for j in range(i + 1, n):
            if is_wall[i] and is_wall[j]:
                continue
            d = positions[i] - positions[j]
            v = velocities[i] - velocities[j]
            mi = math.inf if is_wall[i] else masses[i]
            mj = math.inf if is_wall[j] else masses[j]
            m_eff = 1.0 / (1.0 / mi + 1.0 / mj)
            out, _ = law.pair(d, v, spins[i], spins[j], radii[i], radii[j], m_eff)
            f[i] += out[:2]
            f[j] -= out[:2]
            tau[i] += out[2]
            tau[j] += out[3]
    if flat:
        walls = []
        if flat.get("x_left") is not None:
            walls.append((np.array([1.0, 0.0]), lambda p: p[0] - flat["x_left"], np.zeros(2), 0))
        if flat.get("x_right") is not None:
            walls.append((np.array([-1.0, 0.0]), lambda p: flat["x_right"] - p[0], np.zeros(2), 1))
        if flat.get("bottom"):
            walls.append(
                (np.array([0.0, 1.0]), lambda p: p[1] - bottom[0], np.array([0.0, bottom[1]]), 2)
            )
        for i in range(n):
            if is_wall[i]:
                continue
            for normal, dist, vwall, w in walls:
                h = dist(positions[i])
                v = velocities[i] - vwall
                out, _, _ = law.wall_pair(h, v, spins[i], radii[i], masses[i], normal, wall=w)
                f[i] += out[:2]
                tau[i] += out[2]
    return f, tau


def contact_ode(force, d0, v0, m_eff, contact_distance, t_max):
    """Integrate ``m_eff d'' = force(d, d')`` from first touch until separation.

    Parameters
    ----------
    force : callable (d, v) -> (2,) force on i for relative position and velocity
    d0 : (2,) relative position at first touch (``|d0|`` or the wall distance equals
        ``contact_distance``)
    v0 : (2,) relative velocity at first touch
    contact_distance : callable d -> signed gap (> 0 apart), used as the exit event

    Returns
    -------
    duration : float, v_out : (2,), d_out : (2,)
    """

    def rhs(_, y):
        return np.concatenate([y[2:], force(y[:2], y[2:]) / m_eff])

    def gap(_, y):
        return contact_distance(y[:2])

    gap.terminal = True
    gap.direction = 1
    # start just inside the contact so the exit event is not the entry
    y0 = np.concatenate([d0, v0])
    eps = 1e-9
    y0[:2] += v0 * eps
    sol = solve_ivp(rhs, (eps, t_max), y0, method="DOP853", rtol=1e-12, atol=1e-14, events=gap)
    assert sol.t_events[0].size == 1, "contact did not end"
    t_end = sol.t_events[0][0]
    y_end = sol.y_events[0][0]
    return t_end, y_end[2:], y_end[:2]


def step_by_step_collision(sim, state, mover=0, other=None, max_steps=10**6):
    """Step the engine through one collision of disk ``mover``.

    Returns a dict: ``duration`` (steps in contact x dt), ``v_in``/``v_out`` (relative
    velocity of mover w.r.t. ``other`` (None: absolute) before the first and after the
    last contact step), ``d_in``/``d_out`` relative positions at those steps, ``spin_out``.
    """

    def rel(arr):
        a = np.array(arr[mover])
        return a - (np.array(arr[other]) if other is not None else 0.0)

    steps = 0
    v_in = rel(state.velocities)
    d_in = rel(state.positions)
    while state.contacts[mover] == 0:
        v_in = rel(state.velocities)
        d_in = rel(state.positions)
        sim.run(state, 1)
        steps += 1
        assert steps < max_steps, "no contact"
    in_contact = 0
    while state.contacts[mover] > 0:
        in_contact += 1
        sim.run(state, 1)
        steps += 1
        assert steps < max_steps, "contact does not end"
    return {
        "duration": in_contact * sim.dt,
        "v_in": v_in,
        "d_in": d_in,
        "v_out": rel(state.velocities),
        "d_out": rel(state.positions),
        "spin_out": np.array(state.spins[mover]) if state.spins is not None else None,
    }


__all__ = ["drum_eq1", "all_pair_forces", "contact_ode", "step_by_step_collision"]
