"""The box model of docs/box.md / Appendix A in numbers: contact law, time step, drive.

Reduced units throughout: σ = m = g = 1, t0 = sqrt(σ/g). Every disk has diameter 1,
mass 1 and moment of inertia I = mσ²/8; the box has flat walls at ``x = 0``, ``x = Lx``
and a bottom plate at ``z_b(t) = z0 + A r(t) sin(ωt + φ)`` (Eq. 1 with a phase ``φ``
and amplitude ramp ``r(t)``; the paper's ``-Lz/2`` is our ``z0``).

Time step (Eq. A5 and Appendix A):
``t_c = π (κ_n/m_eff - γ_n²/4)^(-1/2)`` with ``m_eff = m/2`` for two disks
(≈ 2.2229e-3 t0 for Table I), ``Δt = t_c / 50`` (≈ 4.4458e-5 t0, ≈ 141,300 steps per
period at ω = 1). The runs use :func:`steps_per_period`: Δt rounded *down* so that one
period is a whole number of steps divisible by ``4 N_k``; then every sampling phase,
and the quarter period of the ``bottom`` start, falls exactly on a step (Δt shrinks by
less than 4 N_k / 141,333: 0.18 % at N_k = 64).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from ..engine import FlatWalls
from ..engine.laws import BoxLaw

__all__ = [
    "DIAMETER",
    "MASS",
    "INERTIA",
    "G",
    "contact_time",
    "nominal_dt",
    "steps_per_period",
    "box_law",
    "Drive",
    "drive_for",
    "flat_walls",
]

DIAMETER = 1.0
MASS = 1.0
INERTIA = MASS * DIAMETER**2 / 8.0
G = 1.0


def contact_time(physics: Mapping) -> float:
    """``t_c`` of Eq. (A5) for two disks (``m_eff = m/2``) [t0]."""
    m_eff = MASS / 2.0
    w2 = float(physics["kappa_n"]) / m_eff - float(physics["gamma_n"]) ** 2 / 4.0
    if w2 <= 0:
        raise ValueError("overdamped contact: Eq. (A5) has no contact time")
    return math.pi / math.sqrt(w2)


def min_steps_per_contact(physics: Mapping) -> float:
    """The smallest ``steps_per_contact`` at which the explicit (velocity-Verlet) step is
    stable on a normal contact: ω0 Δt < 2 with ω0 = sqrt(κ_n / m_eff) and
    Δt = t_c / steps_per_contact, i.e. steps_per_contact > ω0 t_c / 2 (π/2 undamped)."""
    w0 = math.sqrt(float(physics["kappa_n"]) / (MASS / 2.0))
    return w0 * contact_time(physics) / 2.0


def nominal_dt(physics: Mapping) -> float:
    """``Δt = t_c / steps_per_contact`` [t0] (used for preparation)."""
    return contact_time(physics) / float(physics["steps_per_contact"])


def steps_per_period(physics: Mapping, phases_per_period: int) -> tuple[int, float]:
    """Steps per drive period and the matching Δt [t0].

    The smallest multiple of ``4 N_k`` not below ``T / Δt_nominal``, ``T = 2π/ω``.
    """
    period = 2.0 * math.pi / float(physics["omega"])
    unit = 4 * int(phases_per_period)
    n = unit * math.ceil(period / nominal_dt(physics) / unit)
    return n, period / n


def box_law(physics: Mapping) -> BoxLaw:
    """The engine's box law with Table I parameters and the wall friction of ``physics``."""
    return BoxLaw(
        kappa_n=float(physics["kappa_n"]),
        kappa_t=float(physics["kappa_t"]),
        gamma_n=float(physics["gamma_n"]),
        gamma_t=float(physics["gamma_t"]),
        mu=float(physics["mu"]),
        mu_wall=float(physics["mu_bottom"]),
        mu_side=float(physics["mu_side_walls"]),
    )


@dataclass(frozen=True)
class Drive:
    """Plate motion ``z_b(t) = z0 + A r(t) sin(ωt + φ)``, ``r(t) = min(t/t_ramp, 1)``.

    Attributes
    ----------
    amplitude : float [σ]
        ``A = Γ g/ω²``.
    omega : float [1/t0]
    phase : float [rad]
        ``φ``: 0 for ``start_phase = sine`` (Eq. 1), ``-π/2`` for ``bottom``.
    ramp_time : float [t0]
    z0 : float [σ]
        Mean plate height; chosen so that ``z_b(0) = 0`` (the prepared bed rests at 0).
    """

    amplitude: float
    omega: float
    phase: float
    ramp_time: float
    z0: float

    @property
    def period(self) -> float:
        return 2.0 * math.pi / self.omega

    def height(self, t: float) -> float:
        r = 1.0 if self.ramp_time <= 0 else min(max(t / self.ramp_time, 0.0), 1.0)
        return self.z0 + self.amplitude * r * math.sin(self.omega * t + self.phase)

    def measurement_start(self, transient_periods: int) -> float:
        """Time at which drive phase ``ωt + φ`` reaches ``2π n_transient`` [t0].

        Measured cycle ``j`` starts at phase ``2π(n_transient + j)``, i.e. with the plate at
        mid-height moving up, the cycle start of Eq. (1).
        """
        return (2.0 * math.pi * transient_periods - self.phase) / self.omega


def drive_for(physics: Mapping, protocol: Mapping, gamma: float) -> Drive:
    """The drive of a point: ``A = Γ g/ω²``, phase from ``start_phase``, ramp in periods."""
    omega = float(physics["omega"])
    amplitude = float(gamma) * G / omega**2
    phase = {"sine": 0.0, "bottom": -0.5 * math.pi}[protocol["start_phase"]]
    ramp_time = float(protocol["ramp_periods"]) * 2.0 * math.pi / omega
    # z_b(0) = z0 + A r(0) sin φ = 0 (r(0) = 0 with a ramp)
    z0 = 0.0 if ramp_time > 0 else -amplitude * math.sin(phase)
    return Drive(amplitude, omega, phase, ramp_time, z0)


def flat_walls(physics: Mapping, drive: Drive | None = None) -> FlatWalls:
    """The box's walls: side walls at ``x = 0`` and ``Lx``, the plate moving with ``drive``
    (at rest at ``z = 0`` without one). ``physics.side_walls = shaken`` moves the side
    walls with the plate (the whole box is driven, Sec. II), ``still`` keeps them still;
    ``physics.wall_torque = none`` takes the torque of the walls' friction away (the
    ``σ_j = 0`` reading of Eq. A4). docs/box.md, "Which walls move"."""
    common = {
        "x_left": 0.0,
        "x_right": float(physics["Lx"]),
        "bottom": True,
        "shaken_sides": physics.get("side_walls", "shaken") == "shaken",
        "wall_torque": physics.get("wall_torque", "lever") == "lever",
    }
    if drive is None:
        return FlatWalls(**common, z0=0.0)
    return FlatWalls(
        **common,
        z0=drive.z0,
        amplitude=drive.amplitude,
        omega=drive.omega,
        phase=drive.phase,
        ramp_start=0.0,
        ramp_time=drive.ramp_time,
    )


def kinetic_energy(v, w) -> float:
    """Translational + rotational kinetic energy [mgσ] of disks with velocities ``v``
    (N, 2) and spins ``w`` (N,)."""
    return 0.5 * MASS * float((v * v).sum()) + 0.5 * INERTIA * float((w * w).sum())
