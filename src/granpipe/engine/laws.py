"""Contact laws: a force function and its Jacobian, written once per law.

Two laws, each a pair of small jitted *leaves* acting on one contact in its local
frame (normal ``n`` from j to i, tangent ``t = e_z x n = (-n_y, n_x)``), plus a
Python-level dataclass that carries the parameters and offers the same physics on
vectors for tests and studies. The pair loops in :mod:`granpipe.engine.kernels`
lift the leaves over neighbour pairs and walls (a wall is the j side with infinite
mass; a flat wall is the limit of infinite radius, curvature ``1/r = 0``).

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

import numpy as np

from granpipe._jit import njit
from granpipe.engine.contract import (
    ContactLaw,
    checked_parameter,
    law_leaf,
    pair_force,
    pair_force_jvp,
    perturbed_force,
    perturbed_kinematics,
    select,
)
from granpipe.errors import ConfigError

__all__ = [
    "DrumLaw",
    "BoxLaw",
    "drum_force",
    "drum_force_jvp",
    "box_force",
    "box_wall_force",
    "box_force_jvp",
]

# Regimes of the drum law's tangential force (piecewise smooth; see drum_force).
NO_FRICTION = 0  # f_n <= 0: no tangential force
VISCOUS = 1  # gamma_t |u| < mu f_n
COULOMB = 2  # capped at mu f_n


@njit
def drum_force(nx, ny, delta, vx, vy, k_n, gamma_n, gamma_t, mu):
    """Drum-law force on i from j for one contact (drum paper Eq. 1).

    Parameters
    ----------
    nx, ny : float
        Unit normal from j to i.
    delta : float [length]
        ``r - (a_i + a_j)`` (negative overlap; the contact exists for ``delta <= 0``).
    vx, vy : float [length/time]
        Relative velocity ``v_i - v_j``.
    k_n, gamma_n, gamma_t, mu : float
        Normal stiffness, normal and tangential viscous coefficients, friction
        coefficient.

    Returns
    -------
    fx, fy : float
        Force on i (j feels the opposite).
    f_n : float
        Normal force magnitude along ``n`` (not clipped; may be negative).
    f_t : float
        Signed tangential force along ``t``.
    regime : int
        NO_FRICTION, VISCOUS or COULOMB (which smooth piece applies).
    """
    # choices by select only: the four-lane pass runs this very function on lanes
    vn = vx * nx + vy * ny
    u = vy * nx - vx * ny
    f_n = -k_n * delta - gamma_n * vn
    cap = mu * f_n
    cap = select(cap > 0.0, cap, 0.0)
    visc = gamma_t * abs(u)
    coulomb = visc >= cap
    mag = select(coulomb, cap, visc)
    f_t = select(u > 0.0, -mag, mag)
    regime = select(f_n <= 0.0, NO_FRICTION, select(coulomb, COULOMB, VISCOUS))
    fx = f_n * nx - f_t * ny
    fy = f_n * ny + f_t * nx
    return fx, fy, f_n, f_t, regime


@njit
def drum_force_jvp(
    nx, ny, curv, vx, vy, f_n, f_t, regime, ddx, ddy, dvx, dvy, k_n, gamma_n, gamma_t, mu
):
    """Directional derivative of :func:`drum_force` (its Jacobian times a vector).

    ``dF = J_d . dd + J_v . dv`` at a contact whose forward values
    ``f_n, f_t, regime`` came from :func:`drum_force`. Exact on each smooth piece.

    Parameters
    ----------
    curv : float [1/length]
        ``1/r`` for a disk pair; ``0`` for a flat wall (its normal does not turn).
    ddx, ddy : float
        Perturbation of the relative position ``r_i - r_j``.
    dvx, dvy : float
        Perturbation of the relative velocity.

    Returns
    -------
    dfx, dfy : float
        Perturbation of the force on i.
    """
    # n turns by psi = (t . dd)/r: dn = psi t, dt = -psi n.
    psi = curv * (ddy * nx - ddx * ny)
    vn = vx * nx + vy * ny
    u = vy * nx - vx * ny
    dvn = dvx * nx + dvy * ny + psi * u
    du = dvy * nx - dvx * ny - psi * vn
    dfn = -k_n * (ddx * nx + ddy * ny) - gamma_n * dvn
    dcoul = select(u > 0.0, -mu * dfn, mu * dfn)
    dft = select(regime == VISCOUS, -gamma_t * du, select(regime == COULOMB, dcoul, 0.0))
    a = dfn - f_t * psi  # along n
    b = f_n * psi + dft  # along t
    return a * nx - b * ny, a * ny + b * nx


@njit
def box_force(
    nx,
    ny,
    overlap,
    lever_i,
    lever_j,
    vx,
    vy,
    w_i,
    w_j,
    m_eff,
    xi,
    dt,
    kappa_n,
    kappa_t,
    gamma_n,
    gamma_t,
    mu,
):
    """Box-law force for one contact (box paper Eqs. A1-A4), with shear history.

    Parameters
    ----------
    nx, ny : float
        Unit normal from j to i.
    overlap : float [length]
        ``xi_n = a_i + a_j - r`` (``a_i - h`` for a flat wall at distance ``h``).
    lever_i, lever_j : float [length]
        Distances from the centres to the contact point (mid-overlap).
    vx, vy : float
        Relative velocity ``v_i - v_j``.
    w_i, w_j : float [1/time]
        Spins (counter-clockwise positive). A wall has ``w_j`` = its own spin.
    m_eff : float [mass]
        ``m_i m_j / (m_i + m_j)``; ``m_i`` against a wall.
    xi : float [length]
        Elastic shear displacement along ``t`` before this evaluation.
    dt : float [time]
        Time step by which ``xi`` advances (0 to evaluate without advancing).

    Returns
    -------
    fx, fy : float
        Force on i.
    tau_i, tau_j : float
        Torques on i and on j.
    xi_new : float
        Updated shear displacement.
    f_n, f_t : float
        Normal and tangential force components.
    slip : bool
        True if the Coulomb truncation applied.
    """
    vn = vx * nx + vy * ny
    vt = vy * nx - vx * ny - lever_i * w_i - lever_j * w_j
    f_n = kappa_n * overlap - gamma_n * m_eff * vn
    xi_new = xi + vt * dt
    damp = gamma_t * m_eff * vt
    f_t = -kappa_t * xi_new - damp
    limit = mu * abs(f_n)
    slip = abs(f_t) > limit
    # selects only (the pair pass vectorises); kappa_t = 0 keeps no elastic shear
    capped = limit if f_t > 0.0 else -limit
    # (1/kappa_t is loop-invariant in the pair pass and hoisted out of it)
    inv_kt = 1.0 / kappa_t if kappa_t > 0.0 else 0.0
    xi_new = -(capped + damp) * inv_kt if slip else xi_new
    f_t = capped if slip else f_t
    fx = f_n * nx - f_t * ny
    fy = f_n * ny + f_t * nx
    return fx, fy, -lever_i * f_t, -lever_j * f_t, xi_new, f_n, f_t, slip


@njit
def box_wall_force(
    nx, ny, overlap, radius, vx, vy, w, mass, xi, dt, kappa_n, kappa_t, gamma_n, gamma_t, mu
):
    """:func:`box_force` against a flat wall: the wall's side infinitely heavy and not
    turning (``m_eff`` = the disk's mass, no spin), the lever arm ``radius - overlap/2``
    (the contact point mid-overlap). Same arguments and returns as :func:`box_force`,
    with ``(vx, vy)`` the disk's velocity relative to the wall and ``w`` its spin.
    """
    return box_force(
        nx,
        ny,
        overlap,
        radius - 0.5 * overlap,
        0.0,
        vx,
        vy,
        w,
        0.0,
        mass,
        xi,
        dt,
        kappa_n,
        kappa_t,
        gamma_n,
        gamma_t,
        mu,
    )


@njit
def box_force_jvp(
    nx,
    ny,
    curv,
    lever_i,
    lever_j,
    vx,
    vy,
    w_i,
    w_j,
    m_eff,
    f_n,
    f_t,
    slip,
    dt,
    ddx,
    ddy,
    dvx,
    dvy,
    dw_i,
    dw_j,
    dxi,
    kappa_n,
    kappa_t,
    gamma_n,
    gamma_t,
    mu,
):
    """Directional derivative of :func:`box_force`.

    Perturbations: relative position ``dd``, relative velocity ``dv``, spins
    ``dw_i, dw_j`` and prior history ``dxi``. ``curv = 1/r`` for a pair (the lever arms
    then move with ``r``: ``dl_i = dl_j = dr/2``) and 0 for a flat wall (``dl_i = dr/2``
    with ``dr = n . dd``; ``lever_j`` is unused there because a wall's spin is fixed).

    Returns
    -------
    dfx, dfy, dtau_i, dtau_j, dxi_new : float
    """
    psi, dr, dvn, dvt = perturbed_kinematics(
        nx, ny, curv, lever_i, lever_j, vx, vy, w_i, w_j, ddx, ddy, dvx, dvy, dw_i, dw_j
    )
    dfn = -kappa_n * dr - gamma_n * m_eff * dvn
    sgn = 1.0 if f_t > 0.0 else -1.0
    sfn = 1.0 if f_n > 0.0 else -1.0
    ddamp = gamma_t * m_eff * dvt
    if slip:
        dft = sgn * mu * sfn * dfn
        inv_kt = 1.0 / kappa_t if kappa_t > 0.0 else 0.0
        dxi_new = -(dft + ddamp) * inv_kt
    else:
        dxi_new = dxi + dvt * dt
        dft = -kappa_t * dxi_new - ddamp
    dfx, dfy, dtau_i, dtau_j = perturbed_force(
        nx, ny, psi, dr, f_n, f_t, dfn, dft, lever_i, lever_j
    )
    return dfx, dfy, dtau_i, dtau_j, dxi_new


# --------------------------------------------------------------------------- the contract


class DrumParams(NamedTuple):
    """The drum law's parameters as the contract's leaves take them."""

    k_n: float
    gamma_n: float
    gamma_t: float
    mu: float


class BoxParams(NamedTuple):
    """The box law's parameters as the contract's leaves take them."""

    kappa_n: float
    kappa_t: float
    gamma_n: float
    gamma_t: float
    mu: float


@law_leaf(pair_force, DrumParams)
def _drum_leaf(law, nx, ny, delta, lever_i, lever_j, vx, vy, w_i, w_j, m_eff, xi, dt):
    fx, fy, f_n, f_t, regime = drum_force(
        nx, ny, delta, vx, vy, law.k_n, law.gamma_n, law.gamma_t, law.mu
    )
    return fx, fy, 0.0, 0.0, 0.0, f_n, f_t, regime


@law_leaf(pair_force_jvp, DrumParams)
def _drum_leaf_jvp(
    law,
    nx,
    ny,
    curv,
    lever_i,
    lever_j,
    vx,
    vy,
    w_i,
    w_j,
    m_eff,
    f_n,
    f_t,
    piece,
    dt,
    ddx,
    ddy,
    dvx,
    dvy,
    dw_i,
    dw_j,
    dxi,
):
    dfx, dfy = drum_force_jvp(
        nx, ny, curv, vx, vy, f_n, f_t, piece, ddx, ddy, dvx, dvy,
        law.k_n, law.gamma_n, law.gamma_t, law.mu,
    )  # fmt: skip
    return dfx, dfy, 0.0, 0.0, 0.0


@law_leaf(pair_force, BoxParams)
def _box_leaf(law, nx, ny, delta, lever_i, lever_j, vx, vy, w_i, w_j, m_eff, xi, dt):
    fx, fy, ti, tj, xi_new, f_n, f_t, slip = box_force(
        nx, ny, -delta, lever_i, lever_j, vx, vy, w_i, w_j, m_eff, xi, dt,
        law.kappa_n, law.kappa_t, law.gamma_n, law.gamma_t, law.mu,
    )  # fmt: skip
    return fx, fy, ti, tj, xi_new, f_n, f_t, 1 if slip else 0


@law_leaf(pair_force_jvp, BoxParams)
def _box_leaf_jvp(
    law,
    nx,
    ny,
    curv,
    lever_i,
    lever_j,
    vx,
    vy,
    w_i,
    w_j,
    m_eff,
    f_n,
    f_t,
    piece,
    dt,
    ddx,
    ddy,
    dvx,
    dvy,
    dw_i,
    dw_j,
    dxi,
):
    return box_force_jvp(
        nx,
        ny,
        curv,
        lever_i,
        lever_j,
        vx,
        vy,
        w_i,
        w_j,
        m_eff,
        f_n,
        f_t,
        piece == 1,
        dt,
        ddx,
        ddy,
        dvx,
        dvy,
        dw_i,
        dw_j,
        dxi,
        law.kappa_n,
        law.kappa_t,
        law.gamma_n,
        law.gamma_t,
        law.mu,
    )


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

    def __post_init__(self):
        checked_parameter("k_n", self.k_n, allow_zero=False)
        for name in ("gamma_n", "gamma_t", "mu"):
            checked_parameter(name, getattr(self, name))

    def params(self) -> np.ndarray:
        """Parameter vector passed to the kernels: ``[k_n, gamma_n, gamma_t, mu]``."""
        return np.array([self.k_n, self.gamma_n, self.gamma_t, self.mu], dtype=np.float64)

    def leaf_params(self) -> DrumParams:
        """The parameters as the contract's leaves take them."""
        return DrumParams(*(float(x) for x in self.params()))

    def kernels(self):
        """The drum law's own vectorised passes (:func:`granpipe.engine.kernels.drum_kernels`)."""
        from granpipe.engine.kernels import drum_kernels

        return drum_kernels()

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

    def force(self, d, v, radius_sum):
        """Force on i for relative position ``d = r_i - r_j`` and velocity ``v = v_i - v_j``.

        Parameters
        ----------
        d, v : (2,) float64
        radius_sum : float
            ``a_i + a_j``.

        Returns
        -------
        (2,) float64 (zero when the disks do not touch).
        """
        r = math.hypot(d[0], d[1])
        if r - radius_sum > 0:
            return np.zeros(2)
        fx, fy, *_ = drum_force(d[0] / r, d[1] / r, r - radius_sum, v[0], v[1], *self.params())
        return np.array([fx, fy])

    def jacobian(self, d, v, radius_sum):
        """Jacobians ``(J_d, J_v)``, each (2, 2), of :meth:`force` (exact on each smooth piece)."""
        r = math.hypot(d[0], d[1])
        nx, ny = d[0] / r, d[1] / r
        p = self.params()
        _, _, f_n, f_t, regime = drum_force(nx, ny, r - radius_sum, v[0], v[1], *p)
        jac = np.zeros((2, 4))
        for k in range(4):
            e = np.zeros(4)
            e[k] = 1.0
            jac[:, k] = drum_force_jvp(nx, ny, 1.0 / r, v[0], v[1], f_n, f_t, regime, *e, *p)
        return jac[:, :2], jac[:, 2:]

    def wall_force(self, h, v, radius, normal):
        """Force on a disk at distance ``h`` from a flat wall of unit ``normal`` (into the box)."""
        n = np.asarray(normal, dtype=np.float64)
        if h - radius > 0:
            return np.zeros(2)
        fx, fy, *_ = drum_force(n[0], n[1], h - radius, v[0], v[1], *self.params())
        return np.array([fx, fy])

    def wall_jacobian(self, h, v, radius, normal):
        """``(J_h, J_v)``: derivative of :meth:`wall_force` w.r.t. ``h`` (2,) and ``v`` (2, 2)."""
        n = np.asarray(normal, dtype=np.float64)
        p = self.params()
        _, _, f_n, f_t, regime = drum_force(n[0], n[1], h - radius, v[0], v[1], *p)
        cols = []
        for e in np.eye(4):
            cols.append(drum_force_jvp(n[0], n[1], 0.0, v[0], v[1], f_n, f_t, regime, *e, *p))
        jac = np.array(cols).T
        # a displacement dd of the disk changes h by n . dd
        j_h = jac[:, :2] @ n
        return j_h, jac[:, 2:]


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

    def params(self) -> np.ndarray:
        """``[kappa_n, kappa_t, gamma_n, gamma_t, mu, mu_wall, mu_side]``."""
        return np.array(
            [self.kappa_n, self.kappa_t, self.gamma_n, self.gamma_t, self.mu, self.mu_w, self.mu_s],
            dtype=np.float64,
        )

    def leaf_params(self) -> BoxParams:
        """The parameters as the contract's leaves take them (pair friction ``mu``)."""
        return BoxParams(*(float(x) for x in self.params()[:5]))

    def wall_leaf_params(self) -> tuple:
        """The leaves' parameters at the left, right and bottom wall: the pair law with
        ``mu_side``, ``mu_side`` and ``mu_wall``."""
        p = self.leaf_params()
        side, bottom = p._replace(mu=float(self.mu_s)), p._replace(mu=float(self.mu_w))
        return (side, side, bottom)

    def kernels(self):
        """The box law's own passes (:func:`granpipe.engine.kernels.box_kernels`)."""
        from granpipe.engine.kernels import box_kernels

        return box_kernels()

    def contact_time(self, m_eff: float) -> float:
        """``t_c = pi (kappa_n/m_eff - gamma_n²/4)^(-1/2)`` (box paper Eq. A5)."""
        w2 = self.kappa_n / m_eff - self.gamma_n**2 / 4.0
        if w2 <= 0:
            raise ConfigError("overdamped contact: no contact time")
        return math.pi / math.sqrt(w2)

    def restitution(self, m_eff: float) -> float:
        """Normal coefficient of restitution ``exp(-gamma_n t_c / 2)``."""
        return math.exp(-self.gamma_n * self.contact_time(m_eff) / 2.0)

    def _pair_geometry(self, d, radius_i, radius_j):
        r = math.hypot(d[0], d[1])
        overlap = radius_i + radius_j - r
        lev_i = 0.5 * (r + radius_i - radius_j)
        lev_j = 0.5 * (r + radius_j - radius_i)
        return r, d[0] / r, d[1] / r, overlap, lev_i, lev_j

    def force(self, d, v, spin_i, spin_j, radius_i, radius_j, m_eff, xi=0.0, dt=0.0):
        """Force on i, torques on i and j, and the new shear displacement.

        Parameters
        ----------
        d, v : (2,) float64
            ``r_i - r_j`` and ``v_i - v_j``.
        spin_i, spin_j : float [1/time]
        radius_i, radius_j : float [length]
        m_eff : float [mass]
        xi : float [length]
            Shear displacement along ``t`` before the evaluation.
        dt : float [time]
            Step by which the history advances (0: evaluate without advancing).

        Returns
        -------
        force : (2,) float64, tau_i : float, tau_j : float, xi_new : float
        """
        r, nx, ny, overlap, lev_i, lev_j = self._pair_geometry(d, radius_i, radius_j)
        if overlap < 0:
            return np.zeros(2), 0.0, 0.0, 0.0
        fx, fy, ti, tj, xi_new, *_ = box_force(
            nx,
            ny,
            overlap,
            lev_i,
            lev_j,
            v[0],
            v[1],
            spin_i,
            spin_j,
            m_eff,
            xi,
            dt,
            *self.params()[:5],
        )
        return np.array([fx, fy]), ti, tj, xi_new

    def jacobian(self, d, v, spin_i, spin_j, radius_i, radius_j, m_eff, xi=0.0, dt=0.0):
        """Jacobian (4, 6) of ``(F_x, F_y, tau_i, tau_j)`` w.r.t. ``(d, v, w_i, w_j)``.

        At fixed prior history ``xi``; exact on each smooth piece (stick or slip).
        """
        r, nx, ny, overlap, lev_i, lev_j = self._pair_geometry(d, radius_i, radius_j)
        p = self.params()[:5]
        out = box_force(
            nx, ny, overlap, lev_i, lev_j, v[0], v[1], spin_i, spin_j, m_eff, xi, dt, *p
        )
        f_n, f_t, slip = out[5], out[6], out[7]
        jac = np.zeros((4, 6))
        for k, e in enumerate(np.eye(6)):
            jac[:, k] = box_force_jvp(
                nx,
                ny,
                1.0 / r,
                lev_i,
                lev_j,
                v[0],
                v[1],
                spin_i,
                spin_j,
                m_eff,
                f_n,
                f_t,
                slip,
                dt,
                *e,
                0.0,
                *p,
            )[:4]
        return jac

    def wall_force(self, h, v, spin, radius, mass, normal, xi=0.0, dt=0.0, mu=None):
        """Box law against a flat wall at distance ``h`` (unit ``normal`` into the box).

        The pair law with the wall's side infinitely heavy and not turning: ``m_eff = m``,
        lever arm ``a - xi_n/2`` with ``xi_n = a - h``; ``mu`` defaults to ``mu_wall``.

        Returns
        -------
        force : (2,) float64, torque : float, xi_new : float
        """
        n = np.asarray(normal, dtype=np.float64)
        overlap = radius - h
        if overlap < 0:
            return np.zeros(2), 0.0, 0.0
        p = self.params()
        mu_w = self.mu_w if mu is None else mu
        fx, fy, ti, _, xi_new, *_ = box_wall_force(
            n[0], n[1], overlap, radius, v[0], v[1], spin, mass, xi, dt, *p[:4], mu_w
        )
        return np.array([fx, fy]), ti, xi_new

    def wall_jacobian(self, h, v, spin, radius, mass, normal, xi=0.0, dt=0.0, mu=None):
        """Jacobian (3, 4) of ``(F_x, F_y, tau)`` of :meth:`wall_force` w.r.t. ``(h, v, w)``."""
        n = np.asarray(normal, dtype=np.float64)
        overlap = radius - h
        p = self.params()
        mu_w = self.mu_w if mu is None else mu
        lev = radius - 0.5 * overlap
        out = box_wall_force(
            n[0], n[1], overlap, radius, v[0], v[1], spin, mass, xi, dt, *p[:4], mu_w
        )
        f_n, f_t, slip = out[5], out[6], out[7]
        jac = np.zeros((3, 4))
        # a displacement n * dh of the disk; velocity and spin perturbations
        for k, (dd, dv, dw) in enumerate(
            [
                (n, np.zeros(2), 0.0),
                (0.0 * n, np.eye(2)[0], 0.0),
                (0.0 * n, np.eye(2)[1], 0.0),
                (0.0 * n, np.zeros(2), 1.0),
            ]
        ):
            dfx, dfy, dti, _, _ = box_force_jvp(
                n[0],
                n[1],
                0.0,
                lev,
                0.0,
                v[0],
                v[1],
                spin,
                0.0,
                mass,
                f_n,
                f_t,
                slip,
                dt,
                dd[0],
                dd[1],
                dv[0],
                dv[1],
                dw,
                0.0,
                0.0,
                p[0],
                p[1],
                p[2],
                p[3],
                mu_w,
            )
            jac[:, k] = dfx, dfy, dti
        return jac
