"""Static-friction drum law: the drum's disks with spin and a Cundall–Strack spring.

The drum paper's next step ("we will incorporate static friction", Sec. III): the
drum's normal law (its Eq. 1, ``k_n``, ``gamma_n``, damping not scaled by mass), disks
that turn (``I = m d²/8``), and a tangential spring with history truncated at Coulomb
plus the drum's tangential dashpot (Cundall & Strack 1979, as LAMMPS' ``gran/hooke/
history``)::

    f_n  = -k_n delta - gamma_n v_n                 (delta = r - a_i - a_j <= 0)
    u    = v_ij . t - l_i w_i - l_j w_j            (slip velocity at the contact point)
    xi'  = xi + u dt,   f_t* = -k_t xi' - gamma_t u
    |f_t*| <= mu max(f_n, 0):   f_t = f_t*          (stick)
    otherwise:                  f_t = mu max(f_n, 0) sign(f_t*),
                                xi' = -(f_t + gamma_t u) / k_t   (slip; spring reset)
    F_i = f_n n + f_t t,   tau_i = -l_i f_t,   tau_j = -l_j f_t

with lever arms to the middle of the overlap (``l_i + l_j = r``, so that a contact
exerts no net torque and angular momentum is conserved to round-off). The history is
a scalar along ``t``: it turns with the contact. A contact that opens forgets it.

``k_t = k_n/3`` by default: the stiffness at which a sticking contact oscillates
tangentially with the period of the normal oscillation. For disks (``I = m a²/2``, lever
``l ~ a``, so ``l²/I = 2/m``) the contact point's tangential coordinate obeys
``xi'' = -k_t (1/m_i + l_i²/I_i + 1/m_j + l_j²/I_j) xi``, i.e. ``6 k_t/m`` for two equal
disks and ``3 k_t/m`` against a wall disk, against ``2 k_n/m`` and ``k_n/m`` normally:
the periods match at ``k_t/k_n = 1/3`` in both cases. The usual ``2/7`` is the same
condition for spheres (``I = 2/5 m a²``); on disks it would make the tangential period
``sqrt(7/6)`` times the normal one. Details: ``docs/drum.md``, "Static friction".
Everything here is in the drum's reduced units (``d_s``, ``m_s``, ``t0 = sqrt(d_s/g)``).

Tangent dynamics: :func:`_jvp` is the exact derivative on each smooth piece (stick,
slip, no friction) with respect to the relative position and velocity, both spins and
the prior history, so the tangent pass linearises everything the step updates.
"""

from __future__ import annotations

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

__all__ = ["StaticFrictionLaw", "StaticFrictionParams", "K_T_OVER_K_N"]

K_T_OVER_K_N = 1.0 / 3.0
"""Default ratio of the tangential to the normal stiffness (docs/drum.md, "Static friction")."""

# smooth pieces of the law
NO_FRICTION = 0  # f_n <= 0: no tangential force, the spring relaxes to the dashpot
STICK = 1
SLIP = 2


class StaticFrictionParams(NamedTuple):
    """The kernels' parameters of :class:`StaticFrictionLaw` (reduced units)."""

    k_n: float
    gamma_n: float
    k_t: float
    gamma_t: float
    mu: float


@law_leaf(pair_force, StaticFrictionParams)
def _force(law, c, xi, dt):
    nx, ny = c.nx, c.ny
    vn = c.vx * nx + c.vy * ny
    u = c.vy * nx - c.vx * ny - c.lever_i * c.w_i - c.lever_j * c.w_j
    f_n = -law.k_n * c.delta - law.gamma_n * vn
    cap = law.mu * f_n
    cap = cap if cap > 0.0 else 0.0
    # 1/k_t is hoisted out of the pass's loop
    f_t, xi_new, slip = truncated_spring(law.k_t, 1.0 / law.k_t, xi, u, law.gamma_t * u, cap, dt)
    piece = NO_FRICTION if f_n <= 0.0 else (SLIP if slip else STICK)
    fx = f_n * nx - f_t * ny
    fy = f_n * ny + f_t * nx
    return fx, fy, -c.lever_i * f_t, -c.lever_j * f_t, xi_new, f_n, f_t, piece


@law_leaf(pair_force_jvp, StaticFrictionParams)
def _jvp(law, c, f_n, f_t, piece, dt, p):
    psi, dr, dvn, du = perturbed_kinematics(c, p)
    dfn = -law.k_n * dr - law.gamma_n * dvn
    dft_capped = (law.mu * dfn if f_t > 0.0 else -law.mu * dfn) if piece == SLIP else 0.0
    dft, dxi_new = truncated_spring_jvp(
        law.k_t, 1.0 / law.k_t, p.dxi, du, law.gamma_t * du, dft_capped, piece == STICK, dt
    )
    dfx, dfy, dtau_i, dtau_j = perturbed_force(c, psi, dr, f_n, f_t, dfn, dft)
    return dfx, dfy, dtau_i, dtau_j, dxi_new


@dataclass(frozen=True)
class StaticFrictionLaw(ContactLaw):
    """The drum law with spin and static friction (module docstring; docs/drum.md).

    Parameters
    ----------
    k_n : float [force/length]
        Normal elastic coefficient (the drum's 565.97).
    gamma_n, gamma_t : float [mass/time]
        Normal and tangential viscous coefficients (8.7308, 6.8927), not scaled by mass.
    mu : float
        Friction coefficient (0.44).
    k_t : float or None [force/length]
        Tangential spring; default ``k_n/3`` (equal normal and tangential periods).
    """

    k_n: float
    gamma_n: float
    gamma_t: float
    mu: float
    k_t: float | None = None

    name = "static_friction"
    law_id = 2
    has_spin = True
    has_history = True
    params_type = StaticFrictionParams

    def __post_init__(self):
        checked_parameter("k_n", self.k_n, allow_zero=False)
        for name in ("gamma_n", "gamma_t", "mu"):
            checked_parameter(name, getattr(self, name))
        if self.k_t is not None:
            checked_parameter("k_t", self.k_t, allow_zero=False)

    @property
    def k_tangential(self) -> float:
        return K_T_OVER_K_N * self.k_n if self.k_t is None else float(self.k_t)

    def params(self) -> StaticFrictionParams:
        return StaticFrictionParams(
            float(self.k_n),
            float(self.gamma_n),
            self.k_tangential,
            float(self.gamma_t),
            float(self.mu),
        )
