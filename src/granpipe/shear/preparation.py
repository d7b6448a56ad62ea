"""A sheared cell at packing fraction φ: placement, growth of the radii, steady shear.

docs/shear.md, "Preparation":

1. **Placement** (:func:`placement`): the N disks, at ``start_scale`` of their diameters,
   on sites of concentric rings in the annulus spaced by the largest scaled diameter plus
   ``gap`` (no contact at all), each ring turned by a random angle, the disks assigned to
   a random subset of the sites in a random order: the replica's stream decides it all.
2. **Growth** (:func:`grow`): the diameters grow from ``start_scale`` to 1 in
   ``growth_stages`` equal steps, the cell still, each step relaxed for
   ``growth_s / growth_stages`` (dissipation by γ_n and γ_t only: compression by growth
   of radii, as Lubachevsky–Stillinger, without their event-driven dynamics).
3. **Steady shear**: the inner ring turns for ``steady_s`` before anything is recorded.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from .model import ShearCell

__all__ = ["placement", "grow"]


def placement(cell: ShearCell, scale: float, gap: float, rng: np.random.Generator):
    """(N, 2) [d_s]: non-overlapping centres of the disks at ``scale`` × their diameters.

    Raises RuntimeError if the rings hold fewer sites than disks (``start_scale`` too
    large for φ).
    """
    h = scale * float(cell.diameters.max()) + gap
    radii = np.arange(cell.r_in + h / 2.0, cell.r_out - h / 2.0 + 1e-12, h)
    sites = []
    for r in radii:
        k = int(2.0 * math.pi * r / h)
        th = rng.uniform(0.0, 2.0 * math.pi) + 2.0 * math.pi * np.arange(k) / k
        sites.append(r * np.column_stack([np.cos(th), np.sin(th)]))
    sites = np.vstack(sites) if sites else np.zeros((0, 2))
    n = cell.n_mobile
    if len(sites) < n:
        raise RuntimeError(f"{len(sites)} sites for {n} disks: lower 'start_scale'")
    chosen = rng.choice(len(sites), size=n, replace=False)
    return sites[chosen[rng.permutation(n)]]


def grow(cell: ShearCell, prep: Mapping, rng: np.random.Generator):
    """Place, grow and shear one replica (steps 1-3); returns ``(sim, state)``: the turning
    cell's engine and the state sheared for ``steady_s``.

    ``prep``: ``start_scale``, ``gap``, ``growth_stages``, ``growth_s``, ``steady_s``
    (seconds, t0 = ``cell.physics['t0_s']``).
    """
    dt_s = float(cell.physics["dt"]) * float(cell.physics["t0_s"])
    s0 = float(prep["start_scale"])
    stages = int(prep["growth_stages"])
    per_stage = max(1, round(float(prep["growth_s"]) / stages / dt_s))
    still = cell.simulation(turning=False)
    pos = placement(cell, s0, float(prep["gap"]), rng)
    vel = None
    for k in range(1, stages + 1):
        scale = s0 + (1.0 - s0) * k / stages
        state = cell.new_state(still, pos, vel, scale=scale)
        still.run(state, per_stage)
        pos = state.positions[: cell.n_mobile].copy()
        vel = state.velocities[: cell.n_mobile].copy()
    sim = cell.simulation()
    state = cell.new_state(sim, pos, vel)
    sim.run(state, round(float(prep["steady_s"]) / dt_s))
    return sim, state
