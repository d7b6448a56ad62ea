"""The rotating drum of Maghsoodi & Luijten (2016), Sec. II.1-II.2 and Table 1.

Reduced units (the paper's Table 1): length d_s (small-disk diameter), mass of a
small disk, time t0 = sqrt(d_s/g) = 0.034975 s, so g = 1. Masses scale with the
disk area (equal height and density): m = d² in units of the small-disk mass.

The drum is n wall disks of diameter d_w on the vertices of a regular n-gon of
side d_w (neighbouring wall disks touch, so no mobile disk can leak out); the
circumradius is R = d_w / (2 sin(π/n)) (33.057 d_s for n = 150, d_w = 1.3846).
The drum turns *clockwise* at angular speed Ω (period 900 s): the wall-disk
polar angles are θ_k(t) = θ_k(0) − φ(t) with φ the rotated angle, and a wall
disk at r moves with v = Ω (y, −x) (rigid rotation, angular velocity −Ω ẑ).

A *tiny drum* (tests) is the same model with fewer wall disks (same d_w, so a
smaller R) and fewer mobile disks at about the same filling fraction:
:func:`tiny_physics`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

__all__ = [
    "T0_SECONDS",
    "DrumGeometry",
    "geometry",
    "diameters",
    "masses",
    "species",
    "wall_positions",
    "wall_velocities",
    "filling_fraction",
    "tiny_physics",
    "PAPER_PHYSICS",
    "omega",
]

T0_SECONDS = 0.034975
"""t0 = sqrt(d_s/g) for d_s = 12 mm, g = 9.81 m/s² [s] (Table 1)."""

PAPER_PHYSICS: dict = {
    "n_small": 368,
    "n_large": 368,
    "d_small": 1.0,
    "d_large": 1.1667,
    "n_wall": 150,
    "d_wall": 1.3846,
    "k_n": 565.97,
    "gamma_n": 8.7308,
    "gamma_t": 6.8927,
    "mu": 0.44,
    "g": 1.0,
    "t0_s": T0_SECONDS,
    "dt": 1.14368e-3,
    "period_s": 900.0,
    "skin": 0.3,
    "min_contacts": 2,
    "max_overlap": 1.0,
}
"""The paper's model (Table 1, Sec. II.2) in reduced units: the default ``drum.physics``."""


@dataclass(frozen=True)
class DrumGeometry:
    """Wall of the drum.

    Attributes
    ----------
    n_wall : int
        Number of wall disks n.
    d_wall : float [d_s]
        Wall-disk diameter d_w (also the polygon side).
    radius : float [d_s]
        Circumradius R = d_w / (2 sin(π/n)) of the wall-disk centres.
    inner_radius : float [d_s]
        R − d_w/2: a mobile disk of diameter d whose centre is within
        ``inner_radius − d/2`` of the axis overlaps no wall disk (the wall's inner
        envelope is closest to the axis at the wall-disk centres).
    """

    n_wall: int
    d_wall: float
    radius: float
    inner_radius: float


def geometry(physics: Mapping) -> DrumGeometry:
    """The drum wall of a ``drum.physics`` config section."""
    n = int(physics["n_wall"])
    dw = float(physics["d_wall"])
    radius = dw / (2.0 * math.sin(math.pi / n))
    return DrumGeometry(n_wall=n, d_wall=dw, radius=radius, inner_radius=radius - dw / 2.0)


def species(physics: Mapping) -> np.ndarray:
    """(N,) int8: 0 for a small disk, 1 for a large one; small disks first."""
    return np.repeat(
        np.array([0, 1], dtype=np.int8), [int(physics["n_small"]), int(physics["n_large"])]
    )


def diameters(physics: Mapping) -> np.ndarray:
    """(N,) float64 [d_s]: mobile-disk diameters d_i, small disks first."""
    return np.where(species(physics) == 0, float(physics["d_small"]), float(physics["d_large"]))


def masses(physics: Mapping) -> np.ndarray:
    """(N,) float64 [m_s]: m_i = (d_i/d_s)² (equal height and density, Table 1)."""
    d = diameters(physics) / float(physics["d_small"])
    return d * d


def wall_positions(geom: DrumGeometry, angle: float = 0.0) -> np.ndarray:
    """(n, 2) float64 [d_s]: wall-disk centres after the drum turned clockwise by ``angle``.

    Parameters
    ----------
    angle : float [rad]
        Rotated angle φ ≥ 0 (clockwise); the vertex k sits at polar angle
        2πk/n − φ.
    """
    theta = 2.0 * np.pi * np.arange(geom.n_wall) / geom.n_wall - angle
    return geom.radius * np.column_stack([np.cos(theta), np.sin(theta)])


def wall_velocities(positions: np.ndarray, omega: float) -> np.ndarray:
    """(n, 2) float64 [d_s/t0]: v = Ω (y, −x), clockwise rigid rotation at rate Ω [rad/t0]."""
    p = np.asarray(positions, dtype=np.float64)
    return omega * np.column_stack([p[:, 1], -p[:, 0]])


def filling_fraction(physics: Mapping) -> float:
    """Area of the mobile disks over the free area π(R − d_w/2)² of the drum."""
    geom = geometry(physics)
    d = diameters(physics)
    return float(np.sum(np.pi * d * d / 4.0) / (np.pi * geom.inner_radius**2))


def tiny_physics(n_wall: int = 40, physics: Mapping | None = None) -> dict:
    """A drum with ``n_wall`` wall disks and the paper's filling fraction (for tests).

    Same disks, contact law, Δt and Ω; the drum radius follows from n_wall (same
    d_w and polygon side), and the number of mobile disks from the paper's
    filling fraction, rounded to an even total split 1:1.
    """
    base = dict(PAPER_PHYSICS if physics is None else physics)
    phi = filling_fraction(base)
    tiny = {**base, "n_wall": int(n_wall)}
    inner = geometry(tiny).inner_radius
    area_pair = np.pi / 4.0 * (base["d_small"] ** 2 + base["d_large"] ** 2)
    pairs = max(1, round(phi * np.pi * inner**2 / area_pair))
    tiny["n_small"] = tiny["n_large"] = int(pairs)
    return tiny


# ------------------------------------------------------- the drum's rotation
def omega(physics: Mapping) -> float:
    """Angular speed of the drum's clockwise rotation [rad/t0], 2π t0 / period.

    ``physics.period_s`` must be one number here (a point's section, :func:`points`).
    """
    period = physics["period_s"]
    if isinstance(period, list | tuple):
        raise ConfigError("drum.physics.period_s is a list: take one point (layout.points)")
    return 2.0 * math.pi * float(physics["t0_s"]) / float(period)
