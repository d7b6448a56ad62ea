"""Continuum models of the tapped column: long-wave PDE (Eq. 35) and BSR integro-PDE (Eq. 45).

Both use the paper's *hybrid* treatment (Section 4): the free top boundary φ(t) is taken
from the discrete solution (top surface y_N + r of the column, Eqs. 19–27), the elastic
force is zero for material above it, and the moving bottom carries no gravity (it is a
prescribed Dirichlet boundary, y(0, t) = y0(t), u(0, t) = ẏ0(t), Eqs. 39, 46).

Long-wave model (L-W). Lagrangian label z ∈ [0, S], S = 2Nr (Eq. 29); y(z, t) is the
height of the material point labelled z. Eq. (35) with σ = tanh(α·), α = 1/h, χ(0) = 1/2:

    y_tt = −g + (K h²/m) [ (A₊/3) y_zz − (h/3)(B y_z + e α A₊ y_tz) y_zz
                           + h² ( (A₋/36) y_zzzz + 2 r α y_z² y_zz + e α B y_z y_zz y_tz
                                  + (1/6) e α A₊ y_zz y_tzz ) ]

with A₊ = 2.5, A₋ = 6.5, B = −1/h (Eq. 38 evaluated; the text's A₋ = 13.5 contradicts it,
and Eq. 37 flips the overall sign — docs/column.md). We use (35)'s sign.

*Why a regularization.* Linearized about the undeformed column (y_z = 1), Eq. (35) gives
ω² = c²k²(1 − γ h² k²) with c² = (K h²/m) C(1), C(p) = A₊/3 − (h B/3) p + 2 r α h² p², and
γ = A₋/(36 C(1)): every wavenumber k > 1/(h√γ) grows exponentially (the "bad Boussinesq"
sign of the long-wave expansion), so (35) is ill-posed and no grid finer than
Δz ≈ 2h√γ can converge. We use the standard consistent regularization of the dispersive
term (the "improved Boussinesq" substitution y_zzzz ≈ y_ttzz/c², exact to the order of
the expansion): (1 − γ h² ∂_zz) y_tt = (rest of Eq. 35). Its dispersion relation
ω² = c²k²/(1 + γh²k²) is bounded, so explicit RK4 is stable for Δt < 2.8 h√γ/c
independently of Δz, and the spatial discretization (second-order central differences)
converges at second order under refinement. The paper's grid (Δt = Δz = 0.01,
explicit central differences on Eq. 37) violates the CFL bound c Δt/Δz ≤ 1 by a factor
c ≈ 6.4e2 cm/s × 1 = 640 for its own parameters.

Boundary conditions: y(0, t) = y0(t), y_t(0, t) = ẏ0(t); stress-free top y_z(S, t) = 1
(ghost node), Neumann for the regularizing operator. Density from Eq. (41),
ρ_t + (y_t ρ)_z = 0, ρ(z, 0) = m/(2r) (Eq. 42), finite volumes with minmod MUSCL.

BSR model. Eulerian height z ∈ [0, Z]; velocity u(z, t) (Eq. 45):

    u_t + u u_z = −g − (K/m) ∫_{−h}^{h} Θ(y, z) [1 − e σ(u(z + y) − u(z))] (2r − |y|) dy,
    Θ(y, z) = exp(−((z + y) − b)² / (2 c²)) / (c √(2π)),   b = 7h, c = 3h,

(Eq. 44 normalizes with b where c is meant — docs/column.md), u(z, 0) = 0, u(0, t) = ẏ0(t). Finite
volumes: Godunov flux for Burgers with minmod MUSCL, SSP-RK3, CFL 0.4; the kernel integral
by the trapezoid rule on the grid (h/Δz must be an integer), exact σ (σ(0) = 0 sits at the
node y = 0, where the integrand jumps, so the rule stays second order). Density from
Eq. (48). Material positions follow dX/dt = u(X, t) (Lagrangian tracers, clamped at the
floor), to compare with the discrete particles.

*A second regularization.* The term (1/6) e α A₊ h² y_zz y_tzz of Eq. (35) is a viscosity
proportional to y_zz: negative wherever y_zz < 0, which makes the model ill-posed there
too (growth ∝ |y_zz|, unbounded under refinement). By default we keep only its
dissipative part, max(y_zz, 0) (option ``viscosity``); with the printed form the figure-1
problem blows up at Δz = h/64. The time step follows the fastest rate of the linearized,
regularized equation at every step, because Q (the y_zz coefficient) and the viscosity grow
like 1/Δz² next to the velocity jumps of the floor (Eq. 3).

*What Eq. (45) as printed implies.* The kernel is even in y and positive, so the integral
is a downward body force independent of the compression: (K/m) h² Θ ≈ 5 g at z = b for
the figure-1 parameters, on top of gravity. Nothing in (45) can hold a column up; the
material falls onto the floor within a fraction of a second. We integrate it faithfully
until all tracers rest on the floor, and report it (the comparison number says so).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from scipy.linalg import solve_banded

from .._jit import njit
from .params import ColumnParams

__all__ = [
    "LongWaveCoefficients",
    "longwave_coefficients",
    "longwave_equilibrium",
    "solve_longwave",
    "solve_bsr",
    "bsr_kernel_force",
    "floor_state",
    "floor_position",
]


# --------------------------------------------------------------------------- shared
def floor_state(p: ColumnParams, t: float, tap_start: float, in_tap: bool):
    """y0, ẏ0, ÿ0 at time t (Eqs. 2–3); ``in_tap`` selects the branch explicitly."""
    if in_tap:
        s = p.omega * (t - tap_start)
        return p.a * math.sin(s), p.a * p.omega * math.cos(s), -p.a * p.omega**2 * math.sin(s)
    return 0.0, 0.0, 0.0


def floor_position(p: ColumnParams, t):
    """y0(t) of Eq. (2) for any t (array or scalar) [length]."""
    t = np.asarray(t, dtype=np.float64)
    phase = np.mod(t, p.T)
    inside = (phase > 0) & (phase <= p.tap_duration) if p.a > 0 else np.zeros_like(t, bool)
    return np.where(inside, p.a * np.sin(p.omega * phase), 0.0)


def _segments(p: ColumnParams, t_end: float):
    """(start, end, in_tap, tap_start) of the drive's smooth pieces on [0, t_end]."""
    out = []
    k = 0
    tau = p.tap_duration if p.a > 0 else 0.0
    while k * p.T < t_end - 1e-12:
        t0 = k * p.T
        if tau > 0:
            out.append((t0, min(t0 + tau, t_end), True, t0))
        if t0 + tau < t_end:
            out.append((t0 + tau, min((k + 1) * p.T, t_end), False, t0))
        k += 1
    return [s for s in out if s[1] - s[0] > 1e-12]


class _TopBoundary:
    """φ(t): the free top boundary of the hybrid treatment; +inf if absent.

    The discrete column's top surface y_N + r moves the continuum's top: φ(t) =
    top0 + (φ_d(t) − φ_d(0)), with top0 the continuum's own initial top. (Its rest
    height differs from the discrete one: with the paper's coefficients the L-W column
    is ~5× stiffer and sags 0.5 cm instead of 2.75 cm for N = 10, so the discrete top
    itself would cut 2 cm of material loose at t = 0.)
    """

    def __init__(self, top, top0=0.0):
        if top is None:
            self.t = None
        else:
            self.t = np.asarray(top[0], dtype=np.float64)
            self.y = np.asarray(top[1], dtype=np.float64) - float(top[1][0]) + float(top0)

    def __call__(self, t):
        if self.t is None:
            return np.inf
        return float(np.interp(t, self.t, self.y))


# --------------------------------------------------------------------------- long wave
@dataclasses.dataclass(frozen=True)
class LongWaveCoefficients:
    """Coefficients of Eq. (35) with σ_α, χ(0) (Eqs. 36–38).

    Attributes: ``A_plus``, ``A_minus``, ``B`` [1/length], ``alpha`` [1/length], ``chi0``,
    ``C1`` (= C(1), linear wave coefficient about y_z = 1), ``gamma`` (regularization,
    A₋/(36 C(1))), ``c`` [length/time] (linear wave speed h sqrt(K C(1)/m)).
    """

    A_plus: float
    A_minus: float
    B: float
    alpha: float
    chi0: float
    C1: float
    gamma: float
    c: float


def longwave_coefficients(p: ColumnParams, alpha: float | None = None, chi0: float = 0.5):
    """A₊, A₋, B of Eq. (38) for σ = tanh(α s): A± = 3χ(0) + 6rα ∓ 16r³α³, B = α(1 − 8r²α²).

    With the paper's α = 1/h and χ(0) = 1/2: A₊ = 2.5, A₋ = 6.5, B = −1/h.
    """
    h, r = p.h, p.r
    alpha = 1.0 / h if alpha is None else float(alpha)
    Ap = 3 * chi0 + 6 * r * alpha - 16 * r**3 * alpha**3
    Am = 3 * chi0 + 6 * r * alpha + 16 * r**3 * alpha**3
    B = alpha * (1 - 8 * r**2 * alpha**2)
    C1 = Ap / 3 - h * B / 3 + 2 * r * alpha * h**2
    gamma = Am / (36 * C1)
    c = h * math.sqrt(p.K * C1 / p.m)
    return LongWaveCoefficients(Ap, Am, B, alpha, chi0, C1, gamma, c)


@njit
def _lw_rhs(
    y,
    v,
    dz,
    Kh2m,
    h,
    r,
    alpha,
    e,
    Ap,
    B,
    g,
    gamma,
    a_bottom,
    top_dirichlet,
    a_top,
    dissipative,
    out,
):
    """Acceleration y_tt of the regularized Eq. (35) at every node (node 0 = bottom).

    Solves (1 − γh² D2) a = R(y, v) with a_0 = ÿ0 (Dirichlet) and at the top either
    a_J = ``a_top`` (the top point follows the discrete column: hybrid treatment) or the
    stress-free surface y_z = 1 (ghost node) with a_{J+1} = a_{J−1}.
    """
    J = y.size - 1
    gh2 = gamma * h * h / (dz * dz)
    l = np.empty(J + 1)
    d = np.empty(J + 1)
    u = np.empty(J + 1)
    b = np.empty(J + 1)
    for j in range(1, J + 1):
        if j < J:
            yp, vp = y[j + 1], v[j + 1]
        else:  # stress-free top: y_z = 1, y_tz = 0 (even reflection of y − z and v)
            yp, vp = y[J - 1] + 2.0 * dz, v[J - 1]
        ym, vm = y[j - 1], v[j - 1]
        yz = (yp - ym) / (2.0 * dz)
        yzz = (yp - 2.0 * y[j] + ym) / (dz * dz)
        vz = (vp - vm) / (2.0 * dz)
        vzz = (vp - 2.0 * v[j] + vm) / (dz * dz)
        R = (Ap / 3.0) * yzz - (h / 3.0) * (B * yz + e * alpha * Ap * vz) * yzz
        # viscous term (1/6) e α A₊ y_zz y_tzz: a negative viscosity where y_zz < 0 (ill-posed);
        # the "dissipative" form keeps its positive part only
        visc = max(yzz, 0.0) if dissipative else yzz
        R += (
            h
            * h
            * (
                2.0 * r * alpha * yz * yz * yzz
                + e * alpha * B * yz * yzz * vz
                + (e * alpha * Ap / 6.0) * visc * vzz
            )
        )
        l[j] = -gh2
        d[j] = 1.0 + 2.0 * gh2
        u[j] = -gh2
        b[j] = -g + Kh2m * R
    if top_dirichlet:
        l[J] = 0.0
        d[J] = 1.0
        u[J] = 0.0
        b[J] = a_top
    else:
        l[J] = -2.0 * gh2  # Neumann: a_{J+1} = a_{J−1}
        u[J] = 0.0
    b[1] -= l[1] * a_bottom
    for j in range(2, J + 1):
        w = l[j] / d[j - 1]
        d[j] -= w * u[j - 1]
        b[j] -= w * b[j - 1]
    out[J] = b[J] / d[J]
    for j in range(J - 1, 0, -1):
        out[j] = (b[j] - u[j] * out[j + 1]) / d[j]
    out[0] = a_bottom


@njit
def _minmod(a, b):
    if a * b <= 0.0:
        return 0.0
    return a if abs(a) < abs(b) else b


@njit
def _transport_rate(rho, vel_face, dz, rho_bottom, wall_bottom, out):
    """−∂z(vel ρ) by finite volumes, minmod MUSCL upwind; faces i+1/2 for i = −1..n−1.

    ``vel_face`` (n+1,) holds velocities at faces 1/2 − 1 .. n − 1/2 (face 0 = bottom edge).
    Bottom: inflow value ``rho_bottom`` or a wall (zero flux); top: zero-gradient outflow.
    """
    n = rho.size
    flux = np.empty(n + 1)
    for f in range(n + 1):
        vf = vel_face[f]
        if f == 0:
            if wall_bottom:
                flux[f] = 0.0
            else:
                flux[f] = vf * (rho_bottom if vf > 0.0 else rho[0])
            continue
        i = f - 1  # left cell
        if vf >= 0.0:
            sl = _minmod(rho[i] - rho[i - 1], rho[i + 1] - rho[i]) if 0 < i < n - 1 else 0.0
            flux[f] = vf * (rho[i] + 0.5 * sl)
        else:
            k = i + 1
            if k < n:
                sl = _minmod(rho[k] - rho[k - 1], rho[k + 1] - rho[k]) if k < n - 1 else 0.0
                flux[f] = vf * (rho[k] - 0.5 * sl)
            else:
                flux[f] = vf * rho[i]
    for i in range(n):
        out[i] = -(flux[i + 1] - flux[i]) / dz


def longwave_equilibrium(p: ColumnParams, z: np.ndarray, coeffs: LongWaveCoefficients):
    """Static solution of the discretized Eq. (35) with y(0) = 0 and y_z(S) = 1 (Newton).

    Returns (J+1,) float64 [length]; the residual of the discrete equations is ~1e-13 g.
    """
    dz = z[1] - z[0]
    J = z.size - 1
    h, r, al = p.h, p.r, coeffs.alpha
    Kh2m = p.K * h * h / p.m

    def Cf(q):
        return coeffs.A_plus / 3 - h * coeffs.B * q / 3 + 2 * r * al * h * h * q * q

    def dCf(q):
        return -h * coeffs.B / 3 + 4 * r * al * h * h * q

    y = z.astype(np.float64).copy()
    for _ in range(60):
        yp = np.append(y[2:], y[J - 1] + 2 * dz)
        ym = y[:-1]
        yz = (yp - ym) / (2 * dz)
        yzz = (yp - 2 * y[1:] + ym) / dz**2
        R = -p.g + Kh2m * Cf(yz) * yzz
        dR_dp = Kh2m * (dCf(yz) * yzz / (2 * dz) + Cf(yz) / dz**2)
        dR_dm = Kh2m * (-dCf(yz) * yzz / (2 * dz) + Cf(yz) / dz**2)
        dR_d0 = Kh2m * (-2 * Cf(yz) / dz**2)
        # top row: y_{J+1} = y_{J−1} + 2dz, so the two neighbour derivatives add on y_{J−1}
        dR_dm[-1] += dR_dp[-1]
        dR_dp[-1] = 0.0
        ab = np.zeros((3, J))
        ab[0, 1:] = dR_dp[:-1]
        ab[1, :] = dR_d0
        ab[2, :-1] = dR_dm[1:]
        dy = solve_banded((1, 1), ab, -R)
        y[1:] += dy
        if np.max(np.abs(dy)) < 1e-14 * max(1.0, float(z[-1])):
            break
    return y


def solve_longwave(
    p: ColumnParams,
    t_end: float,
    *,
    dz: float,
    dt: float | None = None,
    cfl: float = 0.5,
    top=None,
    initial: str = "equilibrium",
    record_dt: float | None = None,
    forcing=None,
    exact=None,
    alpha: float | None = None,
    viscosity: str = "dissipative",
) -> dict:
    """Integrate the regularized long-wave model (Eq. 35) with RK4.

    Parameters
    ----------
    p : ColumnParams (the discrete column's parameters; S = 2Nr)
    t_end : float [time]
    dz : float [length], label spacing; S/dz is rounded to an integer number of cells
    dt : float [time], optional; default cfl·h√γ/c (stable for cfl < 2.8, any dz), also
        limited by the density transport CFL in the run
    top : (t (n,), y_top (n,), v_top (n,)), optional; the free top boundary from the
        discrete solution (hybrid treatment, Section 4): the continuum's top point z = S
        follows it (Dirichlet), shifted by the difference of rest heights; without it the
        top is a stress-free surface
    initial : ``"equilibrium"`` (static solution of the same discrete equations) or
        ``"undeformed"`` (y(z, 0) = z, the paper's Eq. 39)
    record_dt : float [time], optional output interval (default: every 0.01 T, ≥ dt)
    viscosity : ``"dissipative"`` (default: y_zz⁺ in the y_zz y_tzz term) or
        ``"as_printed"`` (the viscosity is negative wherever y_zz < 0; the figure-1 problem
        then blows up under refinement, at Δz = h/64 after 0.21 s)
    forcing : callable (z, t) -> (J+1,) extra acceleration (manufactured-solution tests)
    exact : callable (z, t) -> (y, v), optional Dirichlet data at z = 0 and initial state
        (manufactured-solution tests)

    Returns
    -------
    dict: ``z`` (J+1,), ``t`` (n,), ``y``/``v`` (n, J+1) [length, length/time], ``rho``
    (n, J) [mass/length] from Eq. (41) at cell centres ``z_cell``, ``coeffs``, ``dt``.
    """
    co = longwave_coefficients(p, alpha)
    S = 2 * p.N * p.r
    J = max(2, int(round(S / dz)))
    z = np.linspace(0.0, S, J + 1)
    dz = z[1] - z[0]
    if dt is None:
        dt = cfl * p.h * math.sqrt(co.gamma) / co.c
    if exact is not None:
        y, v = (np.array(a, dtype=np.float64) for a in exact(z, 0.0))
    elif initial == "equilibrium":
        y = longwave_equilibrium(p, z, co)
        v = np.zeros_like(y)
    elif initial == "undeformed":
        y = z.copy()
        v = np.zeros_like(y)
    else:
        raise ValueError(f"initial must be 'equilibrium' or 'undeformed', got {initial!r}")
    if top is not None:
        # the top point follows the discrete column's top (y_N + r), shifted by the
        # difference of rest heights (with the paper's coefficients the L-W column is ~5x
        # stiffer than the chain and sags 0.5 cm instead of 2.75 cm for N = 10)
        top_t = np.asarray(top[0], dtype=np.float64)
        top_y = np.asarray(top[1], dtype=np.float64) - float(top[1][0]) + float(y[-1])
        top_v = np.asarray(top[2], dtype=np.float64)
        top_a = np.gradient(top_v, top_t)
    rho = np.full(J, p.m / (2 * p.r))
    Kh2m = p.K * p.h**2 / p.m
    record_dt = record_dt or max(0.01 * p.T, dt)
    n_rec = int(math.floor(t_end / record_dt + 1e-9)) + 1
    out_t = np.arange(n_rec) * record_dt
    out_y = np.full((n_rec, J + 1), np.nan)
    out_v = np.full((n_rec, J + 1), np.nan)
    out_r = np.full((n_rec, J), np.nan)
    acc = np.empty(J + 1)
    drho = np.empty(J)

    def bottom(t, seg):
        if exact is not None:
            yb, vb = exact(np.zeros(1), t)
            return float(yb[0]), float(vb[0]), None
        return floor_state(p, t, seg[3], seg[2])

    def _max_rate(yy, vv):
        # Bound of the fastest rate of the regularized Eq. (35) linearized about the current
        # state: R = Q y_zz + ν y_tzz + β y_tz + ... with (1 + γh²k²) on the left gives
        # ω ≤ sqrt(K|Q|/(mγ)), viscous rate ≤ ν/(γh²), first-order rate ≤ |β|/(2h√γ).
        # Q and ν grow like 1/dz² where the floor's velocity jumps (Eq. 3), so the step
        # follows them.
        yz = np.gradient(yy, dz)
        vz = np.gradient(vv, dz)
        yzz = np.zeros_like(yy)
        vzz = np.zeros_like(vv)
        yzz[1:-1] = (yy[2:] - 2 * yy[1:-1] + yy[:-2]) / dz**2
        vzz[1:-1] = (vv[2:] - 2 * vv[1:-1] + vv[:-2]) / dz**2
        ea = p.e * co.alpha
        Q = co.A_plus / 3 - p.h / 3 * (co.B * yz + ea * co.A_plus * vz)
        Q = Q + p.h**2 * (
            2 * p.r * co.alpha * yz**2 + ea * co.B * yz * vz + ea * co.A_plus / 6 * vzz
        )
        wave = math.sqrt(p.K * max(float(np.max(np.abs(Q))), co.C1) / (p.m * co.gamma))
        nu = Kh2m * p.h**2 * ea * co.A_plus / 6 * float(np.max(np.abs(yzz)))
        beta = Kh2m * float(
            np.max(np.abs(yzz * (p.h / 3 * ea * co.A_plus - p.h**2 * ea * co.B * yz)))
        )
        return wave + nu / (co.gamma * p.h**2) + beta / (2 * p.h * math.sqrt(co.gamma))

    def top_state(t):
        return (
            float(np.interp(t, top_t, top_y)),
            float(np.interp(t, top_t, top_v)),
            float(np.interp(t, top_t, top_a)),
        )

    def set_ends(t, seg, yy, vv):
        yb, vb, _ = bottom(t, seg)
        yy[0], vv[0] = yb, vb
        if top is not None:
            yy[-1], vv[-1], _ = top_state(t)

    def deriv(t, yy, vv, rr, seg):
        yb, vb, ab = bottom(t, seg)
        yy = yy.copy()
        vv = vv.copy()
        set_ends(t, seg, yy, vv)
        if ab is None:  # manufactured: bottom acceleration from the exact solution
            eps = 1e-6 * max(dt, 1e-12)
            ab = (bottom(t + eps, seg)[1] - bottom(t - eps, seg)[1]) / (2 * eps)
        a_top = top_state(t)[2] if top is not None else 0.0
        _lw_rhs(
            yy,
            vv,
            dz,
            Kh2m,
            p.h,
            p.r,
            co.alpha,
            p.e,
            co.A_plus,
            co.B,
            p.g,
            co.gamma,
            ab,
            top is not None,
            a_top,
            viscosity == "dissipative",
            acc,
        )
        a = acc.copy()
        if forcing is not None:
            f = np.asarray(forcing(z, t), dtype=np.float64)
            # the regularizing operator acts on the forcing too
            a[1:] += _apply_inverse(f, dz, co.gamma * p.h**2, z.size)[1:]
        vface = np.empty(J + 1)
        vface[:] = vv  # cell i spans nodes i..i+1; faces are the nodes
        _transport_rate(rr, vface, dz, p.m / (2 * p.r), False, drho)
        return vv, a, drho.copy()

    segs = _segments(p, t_end) if exact is None else [(0.0, t_end, False, 0.0)]
    # a velocity 1000 times the wave speed is a numerical blow-up, not physics
    v_blowup = 1e3 * (co.c + p.a * p.omega + float(np.max(np.abs(v))))
    i_rec = 0
    t = 0.0
    for seg in segs:
        t = seg[0]
        while True:
            while i_rec < n_rec and out_t[i_rec] <= t + 1e-9 * dt:
                set_ends(t, seg, y, v)
                out_y[i_rec], out_v[i_rec], out_r[i_rec] = y, v, rho
                i_rec += 1
            if seg[1] - t <= 1e-9 * dt:
                break
            stop = seg[1]
            if i_rec < n_rec and out_t[i_rec] < stop:
                stop = out_t[i_rec]
            while stop - t > 1e-9 * dt:
                hs = min(dt, stop - t, cfl / _max_rate(y, v))
                vmax = max(float(np.max(np.abs(v))), 1e-30)
                hs = min(hs, 0.8 * dz / vmax)
                k1 = deriv(t, y, v, rho, seg)
                k2 = deriv(
                    t + hs / 2, y + hs / 2 * k1[0], v + hs / 2 * k1[1], rho + hs / 2 * k1[2], seg
                )
                k3 = deriv(
                    t + hs / 2, y + hs / 2 * k2[0], v + hs / 2 * k2[1], rho + hs / 2 * k2[2], seg
                )
                k4 = deriv(t + hs, y + hs * k3[0], v + hs * k3[1], rho + hs * k3[2], seg)
                y = y + hs / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
                v = v + hs / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
                rho = rho + hs / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2])
                t += hs
                set_ends(t, seg, y, v)
                if not np.all(np.isfinite(y)) or np.max(np.abs(v)) > v_blowup:
                    from ..errors import SimulationError

                    raise SimulationError(
                        "column long-wave: solution blew up", time=t, dz=dz, dt=dt
                    )
    return {
        "z": z,
        "z_cell": 0.5 * (z[1:] + z[:-1]),
        "t": out_t[:i_rec],
        "y": out_y[:i_rec],
        "v": out_v[:i_rec],
        "rho": out_r[:i_rec],
        "coeffs": co,
        "dt": dt,
    }


def _apply_inverse(f, dz, gh2_len2, n):
    """(1 − γh²D2)^{-1} f with f_0 fixed (Dirichlet 0) and Neumann top; returns (n,)."""
    J = n - 1
    gh2 = gh2_len2 / dz**2
    ab = np.zeros((3, J))
    ab[0, 1:] = -gh2
    ab[1, :] = 1 + 2 * gh2
    ab[2, :-1] = -gh2
    ab[2, -2] = -2 * gh2  # Neumann row J: coefficient of a_{J-1}
    out = np.zeros(n)
    out[1:] = solve_banded((1, 1), ab, f[1:])
    return out


# --------------------------------------------------------------------------- BSR
@njit
def _bsr_force(u, u_bottom, dz, H, z_cell, K_m, h, r, e, b, c, g, phi, out):
    """Source of Eq. (45) at cell centres: −g − (K/m) ∫Θ[1 − eσ(Δu)](2r − |y|)dy.

    The integral is the trapezoid rule on the nodes y = kΔz, |k| ≤ H = h/Δz; u beyond the
    bottom is the floor's velocity, beyond the top the last cell's. Zero elastic force
    above the free top φ.
    """
    n = u.size
    norm = 1.0 / (c * math.sqrt(2.0 * math.pi))
    for i in range(n):
        zi = z_cell[i]
        if zi > phi:
            out[i] = -g
            continue
        s = 0.0
        for k in range(-H, H + 1):
            yk = k * dz
            j = i + k
            if j < 0:
                uj = u_bottom
            elif j >= n:
                uj = u[n - 1]
            else:
                uj = u[j]
            du = uj - u[i]
            sg = 1.0 if du > 0.0 else (-1.0 if du < 0.0 else 0.0)
            th = norm * math.exp(-((zi + yk - b) ** 2) / (2.0 * c * c))
            w = 0.5 if (k == -H or k == H) else 1.0
            s += w * th * (1.0 - e * sg) * (2.0 * r - abs(yk))
        out[i] = -g - K_m * s * dz


@njit
def _burgers_rate(u, u_bottom, dz, out):
    """−∂z(u²/2) by Godunov's flux with minmod MUSCL; bottom ghost u_bottom, top outflow."""
    n = u.size
    flux = np.empty(n + 1)
    for f in range(n + 1):
        # left state
        # Dirichlet bottom: ghost cell 2 u_b − u_0 (the face value is u_b to second order)
        ghost = 2.0 * u_bottom - u[0]
        if f == 0:
            uL = u_bottom
        else:
            i = f - 1
            lo = u[i - 1] if i > 0 else ghost
            hi = u[i + 1] if i < n - 1 else u[i]
            uL = u[i] + 0.5 * _minmod(u[i] - lo, hi - u[i])
        if f == n:
            uR = uL
        else:
            k = f
            lo = u[k - 1] if k > 0 else ghost
            hi = u[k + 1] if k < n - 1 else u[k]
            uR = u[k] - 0.5 * _minmod(u[k] - lo, hi - u[k])
        if uL <= uR:
            if uL > 0.0:
                flux[f] = 0.5 * uL * uL
            elif uR < 0.0:
                flux[f] = 0.5 * uR * uR
            else:
                flux[f] = 0.0
        else:
            flux[f] = 0.5 * max(uL * uL, uR * uR)
    for i in range(n):
        out[i] = -(flux[i + 1] - flux[i]) / dz


def bsr_kernel_force(p: ColumnParams, z_cell, u, dz, u_bottom=0.0, phi=np.inf, b=None, c=None):
    """The right-hand side of Eq. (45) at cell centres (see :func:`_bsr_force`)."""
    H = int(round(p.h / dz))
    out = np.empty_like(np.asarray(u, dtype=np.float64))
    _bsr_force(
        np.asarray(u, dtype=np.float64),
        u_bottom,
        dz,
        H,
        np.asarray(z_cell, float),
        p.K / p.m,
        p.h,
        p.r,
        p.e,
        7 * p.h if b is None else b,
        3 * p.h if c is None else c,
        p.g,
        phi,
        out,
    )
    return out


def solve_bsr(
    p: ColumnParams,
    t_end: float,
    *,
    dz: float,
    height: float | None = None,
    cfl: float = 0.4,
    top=None,
    tracers=None,
    record_dt: float | None = None,
    forcing=None,
    exact=None,
    stop_when_collapsed: bool = True,
    kernel: bool = True,
) -> dict:
    """Integrate the BSR model (Eqs. 45–48) with SSP-RK3 finite volumes.

    Parameters
    ----------
    p : ColumnParams
    t_end : float [time]
    dz : float [length]; h/dz must be an integer (trapezoid nodes on the grid)
    height : float [length], top of the Eulerian domain (default S + 4h)
    top : (t, y_top[, v_top]), optional; free top φ(t) from the discrete solution (hybrid):
        no elastic force above φ(t) = S + (y_top(t) − y_top(0))
    tracers : (n_tr,) initial heights of material points followed by dX/dt = u(X, t)
        (default: the discrete equilibrium positions of the N particles)
    forcing, exact : manufactured-solution hooks, ``forcing(z, t)`` is added to the
        source, ``exact(z, t)`` gives u (initial and bottom data)
    kernel : bool; ``False`` drops the integral of Eq. (45) (transport-only checks)
    stop_when_collapsed : stop once every tracer rests on the floor (the model has no force
        that can lift it again without a tap moving the floor; positions then stay put)

    Returns
    -------
    dict: ``z`` (n,) cell centres, ``t``, ``u`` (n_t, n) [length/time], ``rho`` (n_t, n)
    [mass/length], ``tracers`` (n_t, n_tr) [length], ``collapse_time`` [time] or NaN.
    """
    from .params import equilibrium_positions

    S = 2 * p.N * p.r
    Z = S + 4 * p.h if height is None else float(height)
    H = int(round(p.h / dz))
    if H < 1 or abs(H * dz - p.h) > 1e-9 * p.h:
        raise ValueError(f"BSR: h/dz must be an integer, got h = {p.h}, dz = {dz}")
    n = int(round(Z / dz))
    zc = (np.arange(n) + 0.5) * dz
    phi = _TopBoundary(top, S)
    b, c = 7 * p.h, 3 * p.h
    u = np.zeros(n) if exact is None else np.array(exact(zc, 0.0), dtype=np.float64)
    rho = np.where(zc < S, p.m / (2 * p.r), 0.0)
    X = np.asarray(equilibrium_positions(p) if tracers is None else tracers, dtype=np.float64)
    X = X.copy()
    record_dt = record_dt or 0.01 * p.T
    n_rec = int(math.floor(t_end / record_dt + 1e-9)) + 1
    out_t = np.arange(n_rec) * record_dt
    out_u = np.full((n_rec, n), np.nan)
    out_r = np.full((n_rec, n), np.nan)
    out_x = np.full((n_rec, X.size), np.nan)
    src = np.empty(n)
    adv = np.empty(n)
    drho = np.empty(n)
    collapse_time = np.nan

    def bottom(t, seg):
        if exact is not None:
            return float(np.asarray(exact(np.zeros(1), t))[0]), 0.0
        yb, vb, _ = floor_state(p, t, seg[3], seg[2])
        return vb, yb

    def rate(t, uu, rr, seg):
        ub, _ = bottom(t, seg)
        _burgers_rate(uu, ub, dz, adv)
        _bsr_force(
            uu, ub, dz, H, zc, p.K / p.m if kernel else 0.0, p.h, p.r, p.e, b, c, p.g, phi(t), src
        )
        du = adv + src
        if forcing is not None:
            du = du + np.asarray(forcing(zc, t), dtype=np.float64)
        vface = np.empty(n + 1)
        vface[0] = ub
        vface[1:-1] = 0.5 * (uu[1:] + uu[:-1])
        vface[-1] = uu[-1]
        # the floor is a wall for the material (Eq. 48 with zero flux through z = 0)
        _transport_rate(rr, vface, dz, 0.0, True, drho)
        return du, drho.copy()

    def u_at(x, uu, ub):
        return np.interp(x, np.concatenate([[0.0], zc]), np.concatenate([[ub], uu]))

    segs = _segments(p, t_end) if exact is None else [(0.0, t_end, False, 0.0)]
    i_rec = 0
    t = 0.0
    done = False
    for seg in segs:
        if done:
            break
        t = seg[0]
        while True:
            while i_rec < n_rec and out_t[i_rec] <= t + 1e-12:
                out_u[i_rec], out_r[i_rec], out_x[i_rec] = u, rho, X
                i_rec += 1
            if seg[1] - t <= 1e-12 * max(1.0, t):
                break
            stop = seg[1]
            if i_rec < n_rec and out_t[i_rec] < stop:
                stop = out_t[i_rec]
            while stop - t > 1e-12 * max(1.0, t):
                ub, yb = bottom(t, seg)
                umax = max(float(np.max(np.abs(u))), abs(ub), 1e-12)
                hs = min(cfl * dz / umax, stop - t)
                # SSP-RK3 (Shu–Osher); tracers with the same stages
                k1u, k1r = rate(t, u, rho, seg)
                x1 = X + hs * u_at(X, u, ub)
                u1 = u + hs * k1u
                r1 = rho + hs * k1r
                ub1, _ = bottom(t + hs, seg)
                k2u, k2r = rate(t + hs, u1, r1, seg)
                x2 = 0.75 * X + 0.25 * (x1 + hs * u_at(x1, u1, ub1))
                u2 = 0.75 * u + 0.25 * (u1 + hs * k2u)
                r2 = 0.75 * rho + 0.25 * (r1 + hs * k2r)
                ubh, _ = bottom(t + hs / 2, seg)
                k3u, k3r = rate(t + hs / 2, u2, r2, seg)
                X = X / 3 + 2 / 3 * (x2 + hs * u_at(x2, u2, ubh))
                u = u / 3 + 2 / 3 * (u2 + hs * k3u)
                rho = rho / 3 + 2 / 3 * (r2 + hs * k3r)
                t += hs
                _, yb = bottom(t, seg)
                X = np.maximum(X, yb)  # the floor is impermeable to material points
                if not np.all(np.isfinite(u)):
                    from ..errors import SimulationError

                    raise SimulationError("column BSR: non-finite solution", time=t, dz=dz)
                if stop_when_collapsed and exact is None and np.all(X <= yb + 1e-12):
                    collapse_time = t
                    done = True
                    break
            if done:
                break
    if done:
        # collapsed: material rests on the floor from here on (recorded as such)
        while i_rec < n_rec:
            out_x[i_rec] = floor_position(p, out_t[i_rec])
            i_rec += 1
    return {
        "z": zc,
        "t": out_t[:i_rec],
        "u": out_u[:i_rec],
        "rho": out_r[:i_rec],
        "tracers": out_x[:i_rec],
        "collapse_time": collapse_time,
    }
