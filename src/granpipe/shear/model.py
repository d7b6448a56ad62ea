"""The sheared annular (Couette) cell of the drum paper's Ref. [20] (Banigan et al. 2013)
under the drum paper's "same force model" (docs/shear.md, "The cell": every value and
choice). Two rings of touching wall disks of the drum's size about one centre, the inner
turning counter-clockwise at Ω = ``wall_speed`` / R_in (rate 1), the outer still (rate 0);
1:1 bidisperse disks of Table 1 (m = d² m_s) at packing fraction φ of the annulus between
the rings' inner envelopes; Eq. (1) with Table 1's coefficients and Δt; no gravity.
Reduced units: d_s, m_s, t0 = 0.034975 s (the drum's); λ in 1/t0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..engine import DrumLaw, Simulation, WallDisks

__all__ = ["ShearCell", "ring", "n_disks"]


def ring_radius(n: int, d_wall: float) -> float:
    """Circumradius R = d_w / (2 sin(π/n)) [d_s] of ``n`` touching wall disks of diameter
    ``d_wall`` on a regular n-gon."""
    return d_wall / (2.0 * math.sin(math.pi / n))


def ring(n: int, d_wall: float) -> tuple[np.ndarray, float]:
    """Centres (n, 2) [d_s] of ``n`` touching wall disks of diameter ``d_wall`` on a regular
    n-gon about the origin, and its circumradius (:func:`ring_radius`) [d_s]."""
    radius = ring_radius(n, d_wall)
    th = 2.0 * np.pi * np.arange(n) / n
    return radius * np.column_stack([np.cos(th), np.sin(th)]), radius


def annulus(physics: Mapping) -> tuple[float, float]:
    """(r_in, r_out) [d_s]: the rings' inner envelopes, R_in + d_w/2 and R_out − d_w/2."""
    dw = float(physics["d_wall"])
    r_in, r_out = (ring_radius(int(physics[k]), dw) for k in ("n_inner", "n_outer"))
    return r_in + dw / 2.0, r_out - dw / 2.0


def n_disks(physics: Mapping) -> int:
    """Number of mobile disks N (even: half small, half large) that fills the annulus to
    the packing fraction ``phi`` (rounded to the nearest pair)."""
    r_in, r_out = annulus(physics)
    pair = math.pi / 4.0 * (float(physics["d_small"]) ** 2 + float(physics["d_large"]) ** 2)
    return 2 * max(1, round(float(physics["phi"]) * math.pi * (r_out**2 - r_in**2) / pair))


@dataclass
class ShearCell:
    """Disks, walls and engine of a ``shear.physics`` section at one φ.

    Attributes
    ----------
    physics : the section (``phi`` one number)
    diameters : (N,) [d_s], small disks first; masses : (N,) [m_s]
    walls : (n_inner + n_outer, 2) [d_s], inner ring first; rate : (n_walls,) 1 or 0
    r_in, r_out : [d_s], the annulus between the rings' inner envelopes
    omega : [rad/t0], the inner ring's angular velocity
    """

    physics: dict
    diameters: np.ndarray
    masses: np.ndarray
    walls: np.ndarray
    rate: np.ndarray
    r_in: float
    r_out: float
    omega: float

    @classmethod
    def from_physics(cls, physics: Mapping) -> ShearCell:
        ph = dict(physics)
        dw = float(ph["d_wall"])
        inner, big_r_in = ring(int(ph["n_inner"]), dw)
        outer, _ = ring(int(ph["n_outer"]), dw)
        n = n_disks(ph)
        d = np.repeat([float(ph["d_small"]), float(ph["d_large"])], n // 2)
        r_in, r_out = annulus(ph)
        rate = np.r_[np.ones(len(inner)), np.zeros(len(outer))]
        omega = float(ph["wall_speed"]) / big_r_in
        return cls(ph, d, d * d / float(ph["d_small"]) ** 2, np.vstack([inner, outer]), rate,
                   r_in, r_out, omega)  # fmt: skip

    @property
    def n_mobile(self) -> int:
        return len(self.diameters)

    def simulation(self, turning: bool = True) -> Simulation:
        """The engine: Eq. (1), no gravity, the inner ring turning at Ω (or still)."""
        ph = self.physics
        law = DrumLaw(ph["k_n"], ph["gamma_n"], ph["gamma_t"], ph["mu"])
        walls = WallDisks(omega=self.omega if turning else 0.0)
        return Simulation(law, float(ph["dt"]), gravity=(0.0, 0.0), wall_disks=walls,
                          skin=float(ph["skin"]), parallel=False,
                          max_overlap=float(ph["max_overlap"]))  # fmt: skip

    def new_state(self, sim: Simulation, positions, velocities=None, scale: float = 1.0,
                  wall_angle: float = 0.0):  # fmt: skip
        """An engine state: the mobile disks (N, 2) with diameters × ``scale`` (the
        preparation grows them to 1), then the walls, the inner ring turned by
        ``wall_angle`` [rad] (it is where it was when a saved state was taken)."""
        n, n_w = self.n_mobile, len(self.walls)
        c, s = math.cos(wall_angle), math.sin(wall_angle)
        walls = self.walls.copy()
        inner = self.rate == 1.0
        walls[inner] = self.walls[inner] @ np.array([[c, s], [-s, c]])
        pos = np.concatenate([np.asarray(positions, np.float64), walls])
        vel = np.zeros((n + n_w, 2))
        if velocities is not None:
            vel[:n] = velocities
        radii = np.r_[self.diameters * scale, np.full(n_w, float(self.physics["d_wall"]))] / 2
        return sim.new_state(pos, radii, np.r_[self.masses, np.ones(n_w)], velocities=vel,
                             is_wall=np.arange(n + n_w) >= n,
                             wall_rate=np.r_[np.zeros(n), self.rate])  # fmt: skip
