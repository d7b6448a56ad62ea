"""The papers' contact laws: the drum's (drum paper Eq. 1) and the box's (box paper App. A).

Each law is a parameter type, its two leaves (force and Jacobian-vector product of one
contact, :mod:`granpipe.engine.contract`) and a Python-level dataclass that validates
the parameters. Contact frame: normal ``n`` from j to i, tangent ``t = e_z x n =
(-n_y, n_x)``; a wall is the j side with infinite mass, a flat wall the limit of infinite
radius (curvature ``1/r = 0``).

Drum law (docs/drum.md; drum paper Eq. 1)
    ``f = f_n n - min(gamma_t |u|, mu max(f_n, 0)) sign(u) t``,
    ``f_n = -k_n delta - gamma_n v_n`` with ``delta = r - (a_i + a_j) <= 0``,
    ``v_n = v_ij . n``, ``u = v_ij . t``. No spin; damping not scaled by mass.

Box law (docs/box.md; box paper Eqs. A1-A5)
    ``F = (kappa_n xi_n - gamma_n m_eff v_n) n + f_t t``, ``xi_n = a_i + a_j - r``,
    ``f_t = -kappa_t xi - gamma_t m_eff v_t`` truncated at ``|f_t| <= mu |F_n|``,
    with the elastic shear displacement ``xi`` (a scalar along ``t``, so it turns
    with the contact and stays in the current tangent plane) advanced as
    ``xi <- xi + v_t dt`` at each force evaluation and reset to
    ``xi = -(f_t + gamma_t m_eff v_t) / kappa_t`` when truncated (as LAMMPS
    gran/hooke/history does). ``v_t = v_ij . t - l_i w_i - l_j w_j``; torques
    ``tau_i = -l_i f_t``, ``tau_j = -l_j f_t``.

    Lever arms: the contact point sits at the middle of the overlap
    (``l_i = a_i - xi_n/2 = (r + a_i - a_j)/2``, MercuryDPM's convention) rather
    than at ``a_i = sigma_i/2`` (LAMMPS; docs/box.md). The two differ by
    ``xi_n/2 ~ 1e-4 sigma`` at the box's stiffness, but only the mid-overlap arms
    make ``l_i + l_j = r``, so that each contact exerts no net torque and angular
    momentum is conserved to round-off (an engine requirement).

Units: whatever the study's reduced units are; no unit is assumed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

from granpipe.engine.contract import (
    ContactLaw,
    checked_parameter,
    law_leaf,
    pair_force,
    pair_force_jvp,
    perturbed_force,
    perturbed_kinematics,
    truncated_spring,
    truncated_spring_jvp,
)
from granpipe.errors import ConfigError

__all__ = ["DrumLaw", "DrumParams", "BoxLaw", "BoxParams"]

# Pieces of the drum law's tangential force (piecewise smooth)
NO_FRICTION = 0  # f_n <= 0: no tangential force
VISCOUS = 1  # gamma_t |u| < mu f_n
COULOMB = 2  # capped at mu f_n


class DrumParams(NamedTuple):
    """The drum law's parameters (drum paper Eq. 1 and Table 1)."""

    k_n: float
    gamma_n: float
    gamma_t: float
    mu: float


class BoxParams(NamedTuple):
    """The box law's parameters at one kind of contact (Appendix A, Table I)."""

    kappa_n: float
    kappa_t: float
    gamma_n: float
    gamma_t: float
    mu: float


@law_leaf(pair_force, DrumParams)
def _drum_force(law, c, xi, dt):
    nx, ny = c.nx, c.ny
    vn = c.vx * nx + c.vy * ny
    u = c.vy * nx - c.vx * ny
    f_n = -law.k_n * c.delta - law.gamma_n * vn
    cap = law.mu * f_n
    cap = cap if cap > 0.0 else 0.0
    visc = law.gamma_t * abs(u)
    coulomb = visc >= cap
    mag = cap if coulomb else visc
    f_t = -mag if u > 0.0 else mag
    piece = NO_FRICTION if f_n <= 0.0 else (COULOMB if coulomb else VISCOUS)
    fx = f_n * nx - f_t * ny
    fy = f_n * ny + f_t * nx
    return fx, fy, 0.0, 0.0, 0.0, f_n, f_t, piece


@law_leaf(pair_force_jvp, DrumParams)
def _drum_jvp(law, c, f_n, f_t, piece, dt, p):
    # n turns by psi = (t . dd)/r: dn = psi t, dt = -psi n.
    nx, ny = c.nx, c.ny
    psi = c.curv * (p.ddy * nx - p.ddx * ny)
    vn = c.vx * nx + c.vy * ny
    u = c.vy * nx - c.vx * ny
    dvn = p.dvx * nx + p.dvy * ny + psi * u
    du = p.dvy * nx - p.dvx * ny - psi * vn
    dfn = -law.k_n * (p.ddx * nx + p.ddy * ny) - law.gamma_n * dvn
    dcoul = -law.mu * dfn if u > 0.0 else law.mu * dfn
    dft = -law.gamma_t * du if piece == VISCOUS else (dcoul if piece == COULOMB else 0.0)
    a = dfn - f_t * psi  # along n
    b = f_n * psi + dft  # along t
    return a * nx - b * ny, a * ny + b * nx, 0.0, 0.0, 0.0


@law_leaf(pair_force, BoxParams)
def _box_force(law, c, xi, dt):
    nx, ny, m_eff = c.nx, c.ny, c.m_eff
    overlap = -c.delta
    vn = c.vx * nx + c.vy * ny
    vt = c.vy * nx - c.vx * ny - c.lever_i * c.w_i - c.lever_j * c.w_j
    f_n = law.kappa_n * overlap - law.gamma_n * m_eff * vn
    # kappa_t = 0 keeps no elastic shear (1/kappa_t is hoisted out of the pass's loop)
    inv_kt = 1.0 / law.kappa_t if law.kappa_t > 0.0 else 0.0
    f_t, xi_new, slip = truncated_spring(
        law.kappa_t, inv_kt, xi, vt, law.gamma_t * m_eff * vt, law.mu * abs(f_n), dt
    )
    fx = f_n * nx - f_t * ny
    fy = f_n * ny + f_t * nx
    return fx, fy, -c.lever_i * f_t, -c.lever_j * f_t, xi_new, f_n, f_t, 1 if slip else 0


@law_leaf(pair_force_jvp, BoxParams)
def _box_jvp(law, c, f_n, f_t, piece, dt, p):
    # curv = 1/r for a pair (the lever arms move with r: dl_i = dl_j = dr/2), 0 for a
    # flat wall (dl_i = dr/2 with dr = n . dd; lever_j unused: a wall's spin is fixed)
    m_eff = c.m_eff
    psi, dr, dvn, dvt = perturbed_kinematics(c, p)
    dfn = -law.kappa_n * dr - law.gamma_n * m_eff * dvn
    sgn = 1.0 if f_t > 0.0 else -1.0
    sfn = 1.0 if f_n > 0.0 else -1.0
    inv_kt = 1.0 / law.kappa_t if law.kappa_t > 0.0 else 0.0
    dft, dxi_new = truncated_spring_jvp(
        law.kappa_t, inv_kt, p.dxi, dvt, law.gamma_t * m_eff * dvt, sgn * law.mu * sfn * dfn,
        piece != 1, dt,
    )  # fmt: skip
    dfx, dfy, dtau_i, dtau_j = perturbed_force(c, psi, dr, f_n, f_t, dfn, dft)
    return dfx, dfy, dtau_i, dtau_j, dxi_new


@dataclass(frozen=True)
class DrumLaw(ContactLaw):
    """Linear spring-dashpot with viscous friction capped at Coulomb (docs/drum.md).

    Parameters
    ----------
    k_n : float [force/length]
        Normal elastic coefficient (565.97 in the drum's reduced units).
    gamma_n, gamma_t : float [mass/time]
        Normal and tangential viscous coefficients (8.7308, 6.8927); NOT scaled by
        the effective mass.
    mu : float
        Friction coefficient (0.44).
    """

    k_n: float
    gamma_n: float
    gamma_t: float
    mu: float

    name = "drum"
    law_id = 0
    has_spin = False
    has_history = False
    params_type = DrumParams

    def __post_init__(self):
        checked_parameter("k_n", self.k_n, allow_zero=False)
        for name in ("gamma_n", "gamma_t", "mu"):
            checked_parameter(name, getattr(self, name))

    def params(self) -> DrumParams:
        return DrumParams(float(self.k_n), float(self.gamma_n), float(self.gamma_t), float(self.mu))

    def contact_time(self, m_eff: float) -> float:
        """Duration ``tau = pi / omega`` of a binary contact, ``omega² = k_n/m - gamma_n²/(4m²)``.

        The drum paper's Sec. II.2; ``m_eff = m_i m_j/(m_i + m_j)`` (``m_i`` against a wall).
        The force is not clipped, so the contact ends exactly when the overlap returns
        to zero, half a period of the damped oscillator after it began.
        """
        w2 = self.k_n / m_eff - self.gamma_n**2 / (4.0 * m_eff**2)
        if w2 <= 0:
            raise ConfigError("overdamped contact: no contact time")
        return math.pi / math.sqrt(w2)

    def restitution(self, m_eff: float) -> float:
        """Normal coefficient of restitution ``exp(-gamma_n tau / (2 m_eff))``."""
        return math.exp(-self.gamma_n * self.contact_time(m_eff) / (2.0 * m_eff))


@dataclass(frozen=True)
class BoxLaw(ContactLaw):
    """Linear spring-dashpot with tangential spring and Coulomb truncation (docs/box.md).

    Parameters
    ----------
    kappa_n, kappa_t : float [force/length]
        Normal and tangential stiffness (1e6, 1e4 in units of m g/sigma).
    gamma_n, gamma_t : float [1/time]
        Damping rates, multiplied by ``m_eff`` (100, 100 in units of sqrt(g/sigma)).
    mu : float
        Friction coefficient between disks (0.6).
    mu_wall : float or None
        Friction coefficient against flat walls and wall disks (default: ``mu``).
    mu_side : float or None
        Friction coefficient against the left and right flat walls only (default:
        ``mu_wall``); 0 gives frictionless side walls with a frictional bottom.
    """

    kappa_n: float
    kappa_t: float
    gamma_n: float
    gamma_t: float
    mu: float
    mu_wall: float | None = None
    mu_side: float | None = None

    name = "box"
    law_id = 1
    has_spin = True
    has_history = True
    params_type = BoxParams

    def __post_init__(self):
        checked_parameter("kappa_n", self.kappa_n, allow_zero=False)
        for name in ("kappa_t", "gamma_n", "gamma_t", "mu"):
            checked_parameter(name, getattr(self, name))
        if self.mu_wall is not None:
            checked_parameter("mu_wall", self.mu_wall)
        if self.mu_side is not None:
            checked_parameter("mu_side", self.mu_side)

    @property
    def mu_w(self) -> float:
        return self.mu if self.mu_wall is None else float(self.mu_wall)

    @property
    def mu_s(self) -> float:
        return self.mu_w if self.mu_side is None else float(self.mu_side)

    def params(self) -> BoxParams:
        """The pair law's parameters (friction ``mu``)."""
        return BoxParams(
            float(self.kappa_n),
            float(self.kappa_t),
            float(self.gamma_n),
            float(self.gamma_t),
            float(self.mu),
        )

    def wall_params(self) -> tuple:
        """The leaves' parameters at the left, right and bottom wall: the pair law with
        ``mu_side``, ``mu_side`` and ``mu_wall``."""
        p = self.params()
        side, bottom = p._replace(mu=float(self.mu_s)), p._replace(mu=float(self.mu_w))
        return (side, side, bottom)

    def contact_time(self, m_eff: float) -> float:
        """``t_c = pi (kappa_n/m_eff - gamma_n²/4)^(-1/2)`` (box paper Eq. A5)."""
        w2 = self.kappa_n / m_eff - self.gamma_n**2 / 4.0
        if w2 <= 0:
            raise ConfigError("overdamped contact: no contact time")
        return math.pi / math.sqrt(w2)

    def restitution(self, m_eff: float) -> float:
        """Normal coefficient of restitution ``exp(-gamma_n t_c / 2)``."""
        return math.exp(-self.gamma_n * self.contact_time(m_eff) / 2.0)
