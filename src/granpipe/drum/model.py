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

from ..engine import DrumLaw, Simulation, StaticFrictionLaw, WallDisks
from ..errors import ConfigError

__all__ = [
    "T0_SECONDS",
    "DrumGeometry",
    "DrumModel",
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


@dataclass
class DrumModel:
    """Disks, wall and engine of a section (reduced units throughout).

    Attributes
    ----------
    physics : the ``drum.physics`` section
    geom : DrumGeometry
    diameters : (N,) float64 [d_s]; masses : (N,) float64 [m_s]
    n_mobile : int
    walls0 : (n, 2) float64 [d_s], wall-disk centres at rotation angle 0
    """

    physics: dict
    geom: DrumGeometry
    diameters: np.ndarray
    masses: np.ndarray
    n_mobile: int
    walls0: np.ndarray

    @classmethod
    def from_physics(cls, physics: Mapping) -> DrumModel:
        """The model of a filled ``drum.physics`` section (a plain copy is kept)."""
        ph = {k: list(v) if isinstance(v, list | tuple) else v for k, v in physics.items()}
        geom = geometry(ph)
        d = diameters(ph)
        return cls(ph, geom, d, masses(ph), len(d), wall_positions(geom))

    @property
    def omega(self) -> float:
        """Angular speed of the drum's clockwise rotation [rad/t0]."""
        return omega(self.physics)

    @property
    def static(self) -> bool:
        """Static friction (``physics.friction: static``): spins and shear histories."""
        return self.physics["friction"] == "static"

    def simulation(self, omega_clockwise: float) -> Simulation:
        """The engine with the drum turning clockwise at ``omega_clockwise`` [rad/t0],
        under the point's friction law: the paper's Eq. (1) (viscous) or the
        static-friction law (:class:`~granpipe.engine.StaticFrictionLaw`)."""
        ph = self.physics
        if self.static:
            law = StaticFrictionLaw(ph["k_n"], ph["gamma_n"], ph["gamma_t"], ph["mu"],
                                    k_t=ph["k_t"])  # fmt: skip
        else:
            law = DrumLaw(ph["k_n"], ph["gamma_n"], ph["gamma_t"], ph["mu"])
        # The engine counts angles counter-clockwise: clockwise rotation is omega < 0.
        walls = WallDisks(centre=(0.0, 0.0), omega=-float(omega_clockwise))
        return Simulation(
            law, float(ph["dt"]), gravity=(0.0, -float(ph["g"])), wall_disks=walls,
            skin=float(ph["skin"]), parallel=False, max_overlap=float(ph["max_overlap"]),
        )  # fmt: skip

    def new_state(self, sim: Simulation, positions, velocities, t: float = 0.0,
                  wall_angle: float = 0.0, spins=None, shear=None):  # fmt: skip
        """An engine state: mobile disks (N, 2) then the wall disks, the drum turned
        clockwise by ``wall_angle`` [rad] from its position at placement; under static
        friction with the mobile disks' ``spins`` (N,) [rad/t0] (default at rest) and the
        shear histories ``shear = (pairs, xi)`` of :meth:`Start.shear` (default none)."""
        n_w = self.geom.n_wall
        walls = wall_positions(self.geom, wall_angle) if wall_angle else self.walls0
        pos = np.concatenate([np.asarray(positions, np.float64), walls])
        vel = np.concatenate([np.asarray(velocities, np.float64), np.zeros((n_w, 2))])
        radii = np.concatenate([self.diameters, np.full(n_w, self.geom.d_wall)]) / 2.0
        masses = np.concatenate([self.masses, np.ones(n_w)])
        is_wall = np.concatenate([np.zeros(self.n_mobile, bool), np.ones(n_w, bool)])
        spin = None
        if self.static:
            spin = np.zeros(len(pos))
            if spins is not None:
                spin[: self.n_mobile] = spins
        state = sim.new_state(pos, radii, masses, velocities=vel, spins=spin, is_wall=is_wall,
                              time=t)  # fmt: skip
        if shear is not None and len(shear[1]):
            sim.set_shear_history(state, *shear)
        return state

    def start_arrays(self, state) -> dict:
        """What the init file keeps of an engine state to continue it: positions and
        velocities of the mobile disks, and under static friction their spins and the
        shear histories (:meth:`~granpipe.engine.State.shear_history`)."""
        n = self.n_mobile
        out = {
            "positions": state.positions[:n].copy(),
            "velocities": state.velocities[:n].copy(),
        }
        if self.static:
            out["spins"] = state.spins[:n].copy()
            out["shear"] = state.shear_history()
        return out

    def rigid_speed(self, state, omega: float) -> float:
        """Ω sqrt(Σ_i |r_i|²): V of the mobile disks turning rigidly with the drum [d_s/t0]."""
        p = state.positions[: self.n_mobile]
        return float(omega * math.sqrt(float(np.sum(p * p))))

    def rms_speed(self, global_speed):
        """V/sqrt(N): rms speed per mobile disk [d_s/t0]."""
        return np.asarray(global_speed) / math.sqrt(self.n_mobile)
