"""Continuum models of the tapped column in chain units: long wave, BSR (Eq. 45), derived BSR.

Chain units (docs/column.md, "Chain units"): lengths in the spacing h = 2r of touching
particles, time in sqrt(m/K), mass in m. A column then has four numbers, N, e,
G = mg/(Kh) and the tap (a/h, ω sqrt(m/K), T sqrt(K/m)); :func:`dimensionless` maps any
column onto them, and every solver here takes a column in chain units, so the same column
given in cgs or in SI yields the same solution to round-off.

Long-wave model (L-W), derived from the middle equation of Eq. (24). With the label z of a
material point (particle i has label i − 1/2, the floor 0, the top surface N) and
y(z, t) its height, the force across the contact between labels z ∓ 1/2 is
Φ = [1 − e σ(W)] C χ(C), C = 1 − (y(z + 1/2) − y(z − 1/2)), W its rate. Taylor expansion
of the central differences in h (Eqs. 32–34) gives, to O(h²),

    y_tt = −G − ∂_z Φ − (1/24) ∂_z³ Φ,  C = 1 − y_z − y_zzz/24,  W = y_tz + y_tzzz/24,

and on every region where σ and χ are constant (Φ linear in C) the O(h²) terms add up to
(1/12) ∂_z² of the leading force: y_tt = −G − ∂_z Φ₀ + (1/12) ∂_z²(−∂_z Φ₀),
Φ₀ = [1 − e σ(y_tz)] (1 − y_z)⁺. Linearised, ω² = k² − k⁴/12: the chain's
4 sin²(k/2) to O(k⁴), with sound speed 1 (h sqrt(K/m)). We solve its standard well-posed
form (the "improved Boussinesq" substitution, exact to this order)

    (1 − (1/12) ∂_z²) y_tt = −G − ∂_z { [1 − e σ(y_tz)] (1 − y_z)⁺ },

with σ(W) = tanh(W/w_σ) (``sigma_width``) and the exact step χ. Where it differs from
Eqs. (35)–(38): the paper expands the smoothed σ_α, χ_α about zero argument with α = 1/h,
so αh = 1 terms enter at every order and the truncation is not an expansion in h; its
σ'(0) multiplies a velocity in y_tz but a length in r σ'(0), so Eq. (35) is not
dimensionally consistent (2rσ'(0) y_z² y_zz carries an extra length², e σ'(0) y_tz an
extra 1/velocity), and its linear coefficient C(1) = A₊/3 − hB/3 + 2rαh² (χ(0) = 1/2: a
half-open contact) is 5.17 in cgs and 1.17 in SI for the Fig. 2 column against 1 here; its
dispersive coefficient A₋/36 = 0.18 (relative 0.154 in SI) against 1/12 here; its y_z², y_tz
nonlinearities come from the smoothing and are absent here (the only nonlinearities are the
hysteresis 1 ∓ e and the opening of contacts). :func:`longwave_coefficients` keeps the
printed coefficients to report that.

Discretization: nodes z_j = jΔz, forces on half nodes (conservative), second-order
differences; the regularizing operator bounds the wave frequency by sqrt(12(1 + e)) and
the viscous rate of the smooth σ by 12 e C_max/w_σ independently of Δz, so explicit RK4
steps follow those bounds and end on the floor's switches (Eq. 3). Bottom: y(0, t) = y0(t)
(Eq. 39; the chain's floor contact is a half-length spring of the same K, so the chain
sits lower by G N/2 at rest than the continuum, a boundary effect of O(h)). Top: free
(Φ = 0 above the top node, half a cell of mass) or the paper's hybrid treatment
(Section 4): the top node follows the discrete column's top surface y_N + r, shifted by
the difference of rest heights. Density: in labels, ρ = (m/h)/y_z exactly (Eq. 41 in
Lagrangian form).

BSR model (Eq. 45 as printed), Eulerian height z, velocity u(z, t):

    u_t + u u_z = −g − (K/m) ∫_{−h}^{h} Θ(y, z) [1 − e σ(u(z + y) − u(z))] (2r − |y|) dy,
    Θ(y, z) = exp(−((z + y) − b)² / (2 c²)) / (c √(2π)),   b = 7h, c = 3h,

(Eq. 44 normalizes with b where c is meant — docs/column.md), u(z, 0) = 0, u(0, t) = ẏ0(t).
Finite volumes: Godunov flux for Burgers with minmod MUSCL, SSP-RK3, CFL 0.4; the kernel
integral by the trapezoid rule on the grid (h/Δz must be an integer), exact σ. Density from
Eq. (48). Material positions follow dX/dt = u(X, t) (tracers clamped at the floor), to
compare with the discrete particles. Hybrid top: no elastic force above φ(t), the discrete
top surface shifted to start at S = 2Nr; free top: φ = ∞.

*What Eq. (45) as printed implies.* The kernel is even in y and positive, so the integral
is a downward body force independent of the compression: (K/m) h² Θ ≈ 5 g at z = b for
the figure-1 parameters, on top of gravity. Nothing in (45) can hold a column up; the
material falls onto the floor within a fraction of a second. We integrate it faithfully
until all tracers rest on the floor, and report it.

Derived BSR (:func:`solve_bsr_derived`): the force law of Eq. (24) on the abutting
neighbours, the material one particle mass above and below, a kernel odd in y acting on
the compression; it has the chain's rest state. Formulation and numerics: docs/column.md,
"BSR derived from the force law".
"""

from __future__ import annotations

import dataclasses
import math
from typing import NamedTuple

import numpy as np

from .._jit import njit, njit_inline
from .discrete import floor_motion, rk4_combine, rk4_stage
from .model import ColumnParams

__all__ = [
    "LongWaveCoefficients",
    "longwave_coefficients",
    "longwave_equilibrium",
    "solve_longwave",
    "solve_bsr",
    "bsr_kernel_force",
    "solve_bsr_derived",
    "bsr_bond_weights",
    "bsr_rest_map",
    "bsr_rest_state",
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


class FloorDrive(NamedTuple):
    """The floor's taps (Eqs. 2–3), in the units of the column given: y0(t) = ``a``
    sin(``omega`` (t − kT)) for kT < t ≤ kT + ``duration``, y0 = 0 for the rest of each
    period ``T``; ``a`` [length], ``omega`` [1/time], ``T`` and ``duration`` [time]."""

    a: float
    omega: float
    T: float
    duration: float


def floor_drive(p: ColumnParams) -> FloorDrive:
    """The taps of the column ``p`` as a :class:`FloorDrive`."""
    return FloorDrive(p.a, p.omega, p.T, p.tap_duration)


class DiscreteTop(NamedTuple):
    """The discrete column's top that a hybrid continuum top follows, sampled at the times
    ``t`` (n,) [sqrt(m/K)]: the height ``y`` [h] of the point the continuum follows (each
    solver states which), its velocity ``v`` [h sqrt(K/m)] and acceleration ``a``
    [h K/m], each (n,), chain units. A free top passes placeholders of two samples."""

    t: np.ndarray
    y: np.ndarray
    v: np.ndarray
    a: np.ndarray


# --------------------------------------------------------------------------- chain units
@dataclasses.dataclass(frozen=True)
class ChainScales:
    """The chain's own units (docs/column.md, "Chain units").

    Attributes: ``length`` h = 2r, ``time`` sqrt(m/K), ``mass`` m; ``velocity`` is
    h sqrt(K/m), the long-wave sound speed of the chain.
    """

    length: float
    time: float
    mass: float

    @property
    def velocity(self) -> float:
        return self.length / self.time


def chain_scales(p: ColumnParams) -> ChainScales:
    """h, sqrt(m/K), m of a column given in any consistent unit system."""
    return ChainScales(p.h, math.sqrt(p.m / p.K), p.m)


def dimensionless(p: ColumnParams) -> ColumnParams:
    """The same column in chain units: m = K = 1, h = 1 (r = 1/2).

    g becomes G = m g/(K h) = 𝔐/h, a becomes a/h, ω becomes ω sqrt(m/K) and T becomes
    T sqrt(K/m); e and N are already numbers. A column given in cgs and the same column
    given in SI map to the same dimensionless column up to round-off.
    """
    s = chain_scales(p)
    return ColumnParams(
        N=p.N,
        m=1.0,
        r=0.5,
        g=p.g * s.time**2 / s.length,
        K=1.0,
        e=p.e,
        a=p.a / s.length,
        omega=p.omega * s.time,
        T=p.T / s.time,
    )


def _require_dimensionless(q: ColumnParams, who: str) -> None:
    if not (q.m == 1.0 and q.K == 1.0 and q.r == 0.5):
        raise ValueError(f"{who}: give the column in chain units (continuum.dimensionless(p))")


# --------------------------------------------------------------------------- long wave
@dataclasses.dataclass(frozen=True)
class LongWaveCoefficients:
    """Coefficients of Eq. (35) as printed, with σ_α, χ(0) (Eqs. 36–38).

    Kept to show what the printed equation implies: its linear wave coefficient
    C(1) = A₊/3 − hB/3 + 2rαh² carries a term with an extra length², so its value and
    the wave speed h sqrt(K C(1)/m) depend on the unit system (docs/column.md). The
    derived model that is solved (:func:`solve_longwave`) does not use them.

    Attributes: ``A_plus``, ``A_minus``, ``B`` [1/length], ``alpha`` [1/length], ``chi0``,
    ``C1``, ``gamma`` (A₋/(36 C(1))), ``c`` [length/time] (h sqrt(K C(1)/m)).
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


LW_GAMMA = 1.0 / 12.0
"""Dispersive coefficient of the derived long-wave model, in units of h² (ω² = 4 sin²(k/2))."""


class LongWave(NamedTuple):
    """The derived long-wave model on its nodes z_j = j ``dz`` [h], chain units: gravity
    ``G`` = mg/(Kh), restitution ``e``, the width ``w_sigma`` of σ(W) = tanh(W/w_σ)
    [h sqrt(K/m)], and ``hybrid``: the top node follows the discrete top (else it is
    free)."""

    dz: float
    G: float
    e: float
    w_sigma: float
    hybrid: bool


class LongWaveWork(NamedTuple):
    """Scratch of :func:`_lw_accel` on J + 1 nodes: the forces ``phi`` (J,) [K h] on the
    half nodes and the regularizing operator's tridiagonal system, its sub-diagonal
    ``lower``, diagonal ``diag``, super-diagonal ``upper`` and right-hand side ``rhs``,
    each (J + 1,)."""

    phi: np.ndarray
    lower: np.ndarray
    diag: np.ndarray
    upper: np.ndarray
    rhs: np.ndarray


@njit
def _lw_accel(Y, V, lw, a_bottom, a_top, work, out):
    """Y_ττ of the derived long-wave model at every node, in chain units.

    (1 − D2/12) Y_ττ = −G − ∂_Z Φ,  Φ = [1 − e tanh(W/w_σ)] C⁺,  C = 1 − Y_Z, W = Y_τZ,
    with Φ on the half nodes, the bottom node prescribed (a_0 = ``a_bottom``) and the top
    node either prescribed (``lw.hybrid``: a_J = ``a_top``) or free: Φ = 0 above it, half
    a cell of mass, and Neumann data for the regularizing operator.

    Y, V, out : (J + 1,) heights [h], velocities [h sqrt(K/m)], accelerations [h K/m];
    lw : LongWave; work : LongWaveWork.
    """
    dz, G, e, w_sigma = lw.dz, lw.G, lw.e, lw.w_sigma
    phi, l, d, u, b = work.phi, work.lower, work.diag, work.upper, work.rhs
    J = Y.size - 1
    for j in range(J):
        C = 1.0 - (Y[j + 1] - Y[j]) / dz
        if C > 0.0:
            W = (V[j + 1] - V[j]) / dz
            phi[j] = (1.0 - e * math.tanh(W / w_sigma)) * C
        else:
            phi[j] = 0.0
    g2 = LW_GAMMA / (dz * dz)
    for j in range(1, J):
        l[j] = -g2
        d[j] = 1.0 + 2.0 * g2
        u[j] = -g2
        b[j] = -G - (phi[j] - phi[j - 1]) / dz
    if lw.hybrid:
        l[J] = 0.0
        d[J] = 1.0
        b[J] = a_top
    else:
        l[J] = -2.0 * g2
        d[J] = 1.0 + 2.0 * g2
        b[J] = -G + phi[J - 1] / (0.5 * dz)
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


@njit_inline
def _floor_at(t, drive, tap_start, in_tap):
    """y0, ẏ0, ÿ0 of the :class:`FloorDrive` at time t, in the tap that starts at
    ``tap_start`` (``in_tap``) or between taps (the chain's :func:`floor_motion`)."""
    return floor_motion(t, tap_start, in_tap, drive.a, drive.omega)


@njit_inline
def _lw_set_ends(t, Y, V, drive, tap_start, in_tap, hybrid, top):
    """Sets the bottom node on the floor and, if ``hybrid``, the top node on the
    :class:`DiscreteTop` at time t; returns the floor's acceleration."""
    y0, v0, a0 = _floor_at(t, drive, tap_start, in_tap)
    Y[0] = y0
    V[0] = v0
    if hybrid:
        Y[-1] = np.interp(t, top.t, top.y)
        V[-1] = np.interp(t, top.t, top.v)
    return a0


@njit
def _drive_segment(t, drive, eps):
    """(tap start, in_tap, end) of the floor's smooth piece that contains time t."""
    kk = math.floor((t + eps) / drive.T)
    ts = kk * drive.T
    in_tap = drive.a > 0.0 and t + eps < ts + drive.duration
    return ts, in_tap, (ts + drive.duration if in_tap else (kk + 1) * drive.T)


@njit
def _next_stop(seg_end, t_end, rec_t, i_rec):
    """End of the next run of steps: the segment's end, t_end or the next record."""
    stop = min(seg_end, t_end)
    if i_rec < rec_t.size and rec_t[i_rec] < stop:
        stop = rec_t[i_rec]
    return stop


@njit_inline
def _blown_up(Y, V, vmax0):
    """True if a position is not finite or a speed exceeds 1000 × the initial largest
    speed ``vmax0`` (the explicit step has lost stability)."""
    bad = False
    for j in range(Y.size):
        if not (math.isfinite(Y[j]) and abs(V[j]) < 1e3 * vmax0):
            bad = True
    return bad


@njit
def _max_compression(Y, spacing):
    """Largest compression 1 − (Y[j+1] − Y[j])/spacing of neighbouring nodes (≥ 0)."""
    cmax = 0.0
    for j in range(Y.size - 1):
        cmax = max(cmax, 1.0 - (Y[j + 1] - Y[j]) / spacing)
    return cmax


@njit_inline
def _top_accel(t, hybrid, top):
    """The discrete top's acceleration at time t if ``hybrid``, else 0."""
    return np.interp(t, top.t, top.a) if hybrid else 0.0


@njit
def _lw_run(Y, V, lw, drive, top, t_end, cfl, rec_t, out_y, out_v):
    """RK4 in time for :func:`_lw_accel`; the step follows the fastest linear rate.

    The regularized operator bounds the wave frequency by sqrt(12(1 + e)) and the rate of
    the viscosity that the smooth σ implies, e C/w_σ · k²/(1 + k²/12), by 12 e C_max/w_σ,
    independently of dz. Steps end exactly at the floor's switches (t = kT, kT + π/ω) and
    at record times.

    Y, V : (J + 1,) the state, advanced in place; lw : LongWave; drive : FloorDrive;
    top : DiscreteTop (used if ``lw.hybrid``); t_end [sqrt(m/K)]; cfl : step factor;
    rec_t : (n_rec,) record times; out_y, out_v : (n_rec, J + 1) records, filled.
    Returns (records written, status: 0 ok, 1 blow-up, time of blow-up).
    """
    n = Y.size
    work = LongWaveWork(np.empty(n - 1), np.empty(n), np.empty(n), np.empty(n), np.empty(n))
    # the RK4 stage arrays as locals: held in a NamedTuple the run measured ~1 % slower
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    Ys = np.empty(n)
    v1 = np.empty(n)
    v2 = np.empty(n)
    v3 = np.empty(n)
    e, w_sigma, hybrid = lw.e, lw.w_sigma, lw.hybrid
    nrec = rec_t.size
    i_rec = 0
    t = 0.0
    wave = math.sqrt(12.0 * (1.0 + e))
    vmax0 = 1.0 + drive.a * drive.omega
    eps = 1e-12 * max(1.0, t_end)
    while True:
        ts, in_tap, seg_end = _drive_segment(t, drive, eps)
        _lw_set_ends(t, Y, V, drive, ts, in_tap, hybrid, top)
        while i_rec < nrec and rec_t[i_rec] <= t + eps:
            out_y[i_rec] = Y
            out_v[i_rec] = V
            i_rec += 1
        if t >= t_end - eps:
            return i_rec, 0, t
        stop = _next_stop(seg_end, t_end, rec_t, i_rec)
        while stop - t > eps:
            cmax = _max_compression(Y, lw.dz)
            hs = min(stop - t, cfl / (wave + 12.0 * e * cmax / w_sigma))
            at = _top_accel(t, hybrid, top)
            a0 = _lw_set_ends(t, Y, V, drive, ts, in_tap, hybrid, top)
            _lw_accel(Y, V, lw, a0, at, work, k1)
            th = t + 0.5 * hs
            at = _top_accel(th, hybrid, top)
            rk4_stage(Y, V, 0.5 * hs, Ys)
            rk4_stage(V, k1, 0.5 * hs, v1)
            a0 = _lw_set_ends(th, Ys, v1, drive, ts, in_tap, hybrid, top)
            _lw_accel(Ys, v1, lw, a0, at, work, k2)
            rk4_stage(Y, v1, 0.5 * hs, Ys)
            rk4_stage(V, k2, 0.5 * hs, v2)
            a0 = _lw_set_ends(th, Ys, v2, drive, ts, in_tap, hybrid, top)
            _lw_accel(Ys, v2, lw, a0, at, work, k3)
            rk4_stage(Y, v2, hs, Ys)
            rk4_stage(V, k3, hs, v3)
            t1 = t + hs
            at = _top_accel(t1, hybrid, top)
            a0 = _lw_set_ends(t1, Ys, v3, drive, ts, in_tap, hybrid, top)
            _lw_accel(Ys, v3, lw, a0, at, work, k4)
            rk4_combine(Y, V, v1, v2, v3, hs, Y)
            rk4_combine(V, k1, k2, k3, k4, hs, V)
            t = t1
            if _blown_up(Y, V, vmax0):
                return i_rec, 1, t
            _lw_set_ends(t, Y, V, drive, ts, in_tap, hybrid, top)


def longwave_equilibrium(q: ColumnParams, z: np.ndarray) -> np.ndarray:
    """Rest state of the discretized derived model with Y(0) = 0 and a free top.

    The half-node forces balance the weight above them exactly: Φ_{j+½} = G (N − z_{j+½}),
    so Y_{j+1} − Y_j = Δz (1 − Φ_{j+½}). The compression is the chain's, C(z) = G (N − z)
    (the chain has c_k = (N − k) 𝔐 at label k, Eq. 26). Chain units; returns (J+1,).
    """
    zh = 0.5 * (z[1:] + z[:-1])
    dz = np.diff(z)
    return np.concatenate([[0.0], np.cumsum(dz * (1.0 - q.g * (q.N - zh)))])


def solve_longwave(
    q: ColumnParams,
    t_end: float,
    *,
    dz: float,
    top=None,
    record_dt: float | None = None,
    sigma_width: float = 0.01,
    cfl: float = 1.0,
    initial=None,
) -> dict:
    """Integrate the derived long-wave model in chain units (docs/column.md, "Long wave").

    Parameters
    ----------
    q : ColumnParams in chain units (:func:`dimensionless`)
    t_end : float, in units of sqrt(m/K)
    dz : float, label spacing in units of h; N/dz is rounded to an integer
    top : (t, y_top, v_top), optional, chain units: the discrete column's top surface
        y_N + r (hybrid treatment, Section 4); the continuum's top node follows it,
        shifted by the difference of rest heights. Without it the top is free (Φ = 0).
    record_dt : output interval (default 0.01 T)
    sigma_width : w_σ, the width of the smooth sign σ(W) = tanh(W/w_σ), in units of the
        chain's sound speed h sqrt(K/m)
    initial : (Y, V) on the nodes, optional (default: the rest state)

    Returns
    -------
    dict: ``z`` (J+1,) labels, ``t`` (n,), ``y`` and ``v`` (n, J+1), ``rho`` (n, J) the
    linear density (m/h)/Y_z of the cells (Eq. 41 in Lagrangian form), all in chain units.
    """
    _require_dimensionless(q, "solve_longwave")
    J = max(2, int(round(q.N / dz)))
    z = np.linspace(0.0, float(q.N), J + 1)
    dz = float(z[1] - z[0])
    if initial is None:
        Y = longwave_equilibrium(q, z)
        V = np.zeros_like(Y)
    else:
        Y = np.array(initial[0], dtype=np.float64)
        V = np.array(initial[1], dtype=np.float64)
    hybrid = top is not None
    if hybrid:
        top_t = np.asarray(top[0], dtype=np.float64)
        top_y = np.asarray(top[1], dtype=np.float64) - float(top[1][0]) + float(Y[-1])
        top_v = np.asarray(top[2], dtype=np.float64)
        top_a = np.gradient(top_v, top_t)
    else:
        top_t = top_y = top_v = top_a = np.zeros(2)
        top_t[1] = 1.0
    record_dt = record_dt or 0.01 * q.T
    rec_t = np.arange(int(math.floor(t_end / record_dt + 1e-9)) + 1) * record_dt
    out_y = np.full((rec_t.size, J + 1), np.nan)
    out_v = np.full((rec_t.size, J + 1), np.nan)
    lw = LongWave(dz, q.g, q.e, float(sigma_width), hybrid)
    top_track = DiscreteTop(top_t, top_y, top_v, top_a)
    n, status, t_bad = _lw_run(
        Y, V, lw, floor_drive(q), top_track, float(t_end), float(cfl), rec_t, out_y, out_v
    )
    if status:
        from ..errors import SimulationError

        raise SimulationError("column long-wave: solution blew up", time=t_bad, dz=dz)
    y = out_y[:n]
    return {
        "z": z,
        "z_cell": 0.5 * (z[1:] + z[:-1]),
        "t": rec_t[:n],
        "y": y,
        "v": out_v[:n],
        "rho": dz / np.diff(y, axis=1),
    }


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


# --------------------------------------------------------------------------- BSR
class PrintedKernel(NamedTuple):
    """The coefficients of Eq. (45) as printed, in the units of the column given: the
    stiffness per mass ``K_m`` = K/m [1/time²] (0: transport only), the radius ``r``
    [length], the restitution ``e``, the centre ``b`` and width ``c`` [length] of the
    Gaussian Θ (Eq. 44), gravity ``g`` [length/time²]."""

    K_m: float
    r: float
    e: float
    b: float
    c: float
    g: float


@njit
def _bsr_force(u, u_bottom, z_cell, dz, H, eq45, phi, out):
    """Source of Eq. (45) at cell centres: −g − (K/m) ∫Θ[1 − eσ(Δu)](2r − |y|)dy.

    The integral is the trapezoid rule on the nodes y = kΔz, |k| ≤ H = h/Δz; u beyond the
    bottom is the floor's velocity, beyond the top the last cell's. Zero elastic force
    above the free top φ.

    u, out : (n,) velocities [length/time] and sources [length/time²] at the cell centres
    ``z_cell`` (n,) [length], cells of width ``dz``; ``u_bottom`` the floor's velocity;
    eq45 : PrintedKernel; phi : height of the free top [length] (inf: none).
    """
    K_m, r, e, b, c, g = eq45
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


@njit
def _momentum_rates(u, u_bottom, z_cell, dz, H, eq45, phi, adv, src):
    """The two terms of u_t in Eq. (45) in one call: the transport −∂z(u²/2) into ``adv``
    (:func:`_burgers_rate`) and the source into ``src`` (:func:`_bsr_force`), both (n,)
    [length/time²]; arguments as there."""
    _burgers_rate(u, u_bottom, dz, adv)
    _bsr_force(u, u_bottom, z_cell, dz, H, eq45, phi, src)


def bsr_kernel_force(p: ColumnParams, z_cell, u, dz, u_bottom=0.0, phi=np.inf, b=None, c=None):
    """The right-hand side of Eq. (45) at cell centres (see :func:`_bsr_force`)."""
    H = int(round(p.h / dz))
    out = np.empty_like(np.asarray(u, dtype=np.float64))
    eq45 = PrintedKernel(
        p.K / p.m,
        p.r,
        p.e,
        float(7 * p.h if b is None else b),
        float(3 * p.h if c is None else c),
        p.g,
    )
    u = np.asarray(u, dtype=np.float64)
    _bsr_force(u, float(u_bottom), np.asarray(z_cell, float), dz, H, eq45, float(phi), out)
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
    kernel: str = "printed",
) -> dict:
    """Integrate a BSR model (Eqs. 45–48) with SSP-RK3 finite volumes.

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
    kernel : ``"printed"`` (Eq. 45 as printed, :func:`_bsr_force`) or ``"none"``
        (transport only)
    stop_when_collapsed : stop once every tracer rests on the floor (the model has no force
        that can lift it again without a tap moving the floor; positions then stay put)

    Returns
    -------
    dict: ``z`` (n,) cell centres, ``t``, ``u`` (n_t, n) [length/time], ``rho`` (n_t, n)
    [mass/length], ``tracers`` (n_t, n_tr) [length], ``collapse_time`` [time] or NaN.
    """
    from .model import equilibrium_positions

    S = 2 * p.N * p.r
    Z = S + 4 * p.h if height is None else float(height)
    H = int(round(p.h / dz))
    if H < 1 or abs(H * dz - p.h) > 1e-9 * p.h:
        raise ValueError(f"BSR: h/dz must be an integer, got h = {p.h}, dz = {dz}")
    n = int(round(Z / dz))
    zc = (np.arange(n) + 0.5) * dz
    if kernel not in ("printed", "none"):
        raise ValueError(f"BSR: kernel must be printed or none, got {kernel!r}")
    b, c = 7 * p.h, 3 * p.h
    eq45 = PrintedKernel(p.K / p.m if kernel == "printed" else 0.0, p.r, p.e, b, c, p.g)
    u = np.zeros(n) if exact is None else np.array(exact(zc, 0.0), dtype=np.float64)
    rho = np.where(zc < S, p.m / (2 * p.r), 0.0)
    phi = _TopBoundary(top, S)
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
        _momentum_rates(uu, ub, zc, dz, H, eq45, phi(t), adv, src)
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


# --------------------------------------------------------------------------- derived BSR
BSR_KERNEL_WIDTH = 1.0
"""Default half-width b of the derived BSR's label kernel (docs/column.md, "BSR derived
from the force law"): b = 1 spreads each particle's mass evenly over its diameter."""


def bsr_bond_weights(ds: float, width: float = BSR_KERNEL_WIDTH) -> np.ndarray:
    """Bond weights W_j of the derived BSR for the label offsets Δ_j = j ds, j = 1 … nb.

    The force on the material at label s sums the chain's law over the material at
    labels s ± Δ with the weight w(Δ) = k(Δ)/Δ, k the triangular density of half-width
    ``width`` about Δ = 1 (the distribution of label separations between the material
    of two abutting particles when each particle's mass is spread evenly over a label
    interval of length ``width``). The midpoint rule gives W_j = ds k(Δ_j)/Δ_j, with k
    normalised on the grid (Σ ds k(Δ_j) = 1) so that the bulk of the rest state balances
    gravity exactly. ``width = 0`` is the point-particle kernel, k = δ(Δ − 1).
    Label units (h); returns (nb,) float64.
    """
    if not (ds > 0 and width >= 0):
        raise ValueError(f"need ds > 0 and width >= 0, got ds={ds!r}, width={width!r}")
    if width == 0.0:
        nb = int(round(1.0 / ds))
        if abs(nb * ds - 1.0) > 1e-9:
            raise ValueError(f"the point-particle kernel needs 1/ds integer, got ds={ds!r}")
        w = np.zeros(nb)
        w[-1] = 1.0
        return w
    nb = int(math.floor((1.0 + width) / ds + 1e-9))
    delta = np.arange(1, nb + 1) * ds
    k = np.maximum(1.0 - np.abs(delta - 1.0) / width, 0.0)
    if not k.sum() > 0:
        raise ValueError(f"the kernel of half-width {width} has no bond on a grid of ds={ds}")
    k /= k.sum() * ds
    return ds * k / delta


def bsr_rest_map(q: ColumnParams, s) -> np.ndarray:
    """The chain's rest state as a map of the labels: Y(s) with Y_s = 1 − G (N − s) and
    Y(k − ½) = y_k of the discrete rest state (Eq. 26), continued below s = 0 (the floor's
    ghost material). Chain units."""
    s = np.asarray(s, dtype=np.float64)
    G, N = q.g, float(q.N)
    return (0.5 - N * G) + (s - 0.5) - G * (N * (s - 0.5) - 0.5 * (s * s - 0.25))


@njit
def _bsr_accel(y, v, yg, vg, W, ds, G, e, w_sigma, first_pinned, out):
    """Accelerations of the derived BSR's material points, chain units.

    a(s) = −G − Σ_j W_j Φ(s, s + Δ_j) + Σ_j W_j Φ(s − Δ_j, s),
    Φ(lo, hi) = [1 − e tanh(((v_hi − v_lo)/Δ)/w_σ)] (1 − (y_hi − y_lo)/Δ)⁺,

    the law of Eq. (24) on the bond's compression per unit label length. Points i < 0 in
    label order are the floor's ghosts (``yg``, ``vg``: ghost g at label −(g + ½) ds).
    Points from ``first_pinned`` on are prescribed (their ``out`` is 0).
    """
    M = y.size
    nb = W.size
    ng = yg.size
    for i in range(M):
        if i >= first_pinned:
            out[i] = 0.0
            continue
        a = -G
        for j in range(1, nb + 1):
            wj = W[j - 1]
            if wj == 0.0:
                continue
            dl = j * ds
            k = i + j
            if k < M:
                c = 1.0 - (y[k] - y[i]) / dl
                if c > 0.0:
                    a -= wj * (1.0 - e * math.tanh((v[k] - v[i]) / (dl * w_sigma))) * c
            k = i - j
            if k >= 0:
                yb = y[k]
                vb = v[k]
            else:
                gi = -k - 1
                if gi >= ng:
                    continue
                yb = yg[gi]
                vb = vg[gi]
            c = 1.0 - (y[i] - yb) / dl
            if c > 0.0:
                a += wj * (1.0 - e * math.tanh((v[i] - vb) / (dl * w_sigma))) * c
        out[i] = a


class DerivedBsr(NamedTuple):
    """The derived BSR on its material points, chain units: the bond weights ``W`` (nb,)
    of the label offsets Δ_j = j ``ds`` [h] (:func:`bsr_bond_weights`), gravity ``G`` =
    mg/(Kh), restitution ``e``, the width ``w_sigma`` of σ(W) = tanh(W/w_σ)
    [h sqrt(K/m)]; the points from ``first_pinned`` on (the hybrid top's; M for a free
    top) sit at the heights ``pinned`` (M − first_pinned,) [h] above the discrete top
    particle's centre."""

    W: np.ndarray
    ds: float
    G: float
    e: float
    w_sigma: float
    first_pinned: int
    pinned: np.ndarray


class FloorGhosts(NamedTuple):
    """The floor's ghost material, ghost g at label −(g + ½) ds, chain units: its heights
    ``rest`` (ng,) [h] above the floor at rest, and its current heights ``y`` and
    velocities ``v`` (ng,) [h, h sqrt(K/m)], set by :func:`_bsr_set_bounds`."""

    rest: np.ndarray
    y: np.ndarray
    v: np.ndarray


@njit_inline
def _bsr_set_bounds(t, y, v, bsr, ghosts, drive, tap_start, in_tap, top):
    """Ghosts ride with the floor; pinned points (hybrid top) with the discrete top.

    y, v : (M,) the material points' heights and velocities, the pinned ones set at time
    t; bsr : DerivedBsr; ghosts : FloorGhosts (``y``, ``v`` set); drive : FloorDrive in
    the tap that starts at ``tap_start`` (``in_tap``) or between taps; top : DiscreteTop.
    """
    y0, v0, _ = _floor_at(t, drive, tap_start, in_tap)
    yg, vg, Yg = ghosts.y, ghosts.v, ghosts.rest
    for g in range(yg.size):
        yg[g] = y0 + Yg[g]
        vg[g] = v0
    first_pinned = bsr.first_pinned
    if first_pinned < y.size:
        yt = np.interp(t, top.t, top.y)
        vt = np.interp(t, top.t, top.v)
        for i in range(first_pinned, y.size):
            y[i] = yt + bsr.pinned[i - first_pinned]
            v[i] = vt


@njit
def _bsr_run(Y, V, bsr, ghosts, drive, top, t_end, cfl, rec_t, out_y):
    """RK4 of :func:`_bsr_accel`, steps ending at the floor's switches and the records.

    The step follows the fastest linear rates, which do not depend on ds: the elastic
    frequency ω² ≤ 4 Σ W_j/Δ_j and the rate 2 e c_max/w_σ Σ W_j/Δ_j of the viscosity the
    smooth σ implies.

    Y, V : (M,) the state, advanced in place; bsr : DerivedBsr; ghosts : FloorGhosts;
    drive : FloorDrive; top : DiscreteTop (used if ``bsr.first_pinned`` < M);
    t_end [sqrt(m/K)]; cfl : step factor; rec_t : (n_rec,) record times; out_y :
    (n_rec, M) recorded heights, filled. Returns (records written, status: 0 ok,
    1 blow-up, time).
    """
    M = Y.size
    k1 = np.empty(M)
    k2 = np.empty(M)
    k3 = np.empty(M)
    k4 = np.empty(M)
    Ys = np.empty(M)
    v1 = np.empty(M)
    v2 = np.empty(M)
    v3 = np.empty(M)
    W, ds, e, w_sigma = bsr.W, bsr.ds, bsr.e, bsr.w_sigma
    # the bundles' fields read once, outside the steps: read per call the run measured 2 % slower
    yg, vg, G, first_pinned = ghosts.y, ghosts.v, bsr.G, bsr.first_pinned
    s2 = 0.0
    for j in range(W.size):
        s2 += W[j] / ((j + 1) * ds)
    wave = math.sqrt(4.0 * s2)
    vmax0 = 1.0 + drive.a * drive.omega
    nrec = rec_t.size
    i_rec = 0
    t = 0.0
    eps = 1e-12 * max(1.0, t_end)
    while True:
        ts, in_tap, seg_end = _drive_segment(t, drive, eps)
        _bsr_set_bounds(t, Y, V, bsr, ghosts, drive, ts, in_tap, top)
        while i_rec < nrec and rec_t[i_rec] <= t + eps:
            out_y[i_rec] = Y
            i_rec += 1
        if t >= t_end - eps:
            return i_rec, 0, t
        stop = _next_stop(seg_end, t_end, rec_t, i_rec)
        while stop - t > eps:
            cmax = _max_compression(Y, ds)
            hs = min(stop - t, cfl / (wave + 2.0 * e * cmax * s2 / w_sigma))
            _bsr_set_bounds(t, Y, V, bsr, ghosts, drive, ts, in_tap, top)
            _bsr_accel(Y, V, yg, vg, W, ds, G, e, w_sigma, first_pinned, k1)
            th = t + 0.5 * hs
            rk4_stage(Y, V, 0.5 * hs, Ys)
            rk4_stage(V, k1, 0.5 * hs, v1)
            _bsr_set_bounds(th, Ys, v1, bsr, ghosts, drive, ts, in_tap, top)
            _bsr_accel(Ys, v1, yg, vg, W, ds, G, e, w_sigma, first_pinned, k2)
            rk4_stage(Y, v1, 0.5 * hs, Ys)
            rk4_stage(V, k2, 0.5 * hs, v2)
            _bsr_set_bounds(th, Ys, v2, bsr, ghosts, drive, ts, in_tap, top)
            _bsr_accel(Ys, v2, yg, vg, W, ds, G, e, w_sigma, first_pinned, k3)
            rk4_stage(Y, v2, hs, Ys)
            rk4_stage(V, k3, hs, v3)
            t1 = t + hs
            _bsr_set_bounds(t1, Ys, v3, bsr, ghosts, drive, ts, in_tap, top)
            _bsr_accel(Ys, v3, yg, vg, W, ds, G, e, w_sigma, first_pinned, k4)
            rk4_combine(Y, V, v1, v2, v3, hs, Y)
            rk4_combine(V, k1, k2, k3, k4, hs, V)
            t = t1
            if _blown_up(Y, V, vmax0):
                return i_rec, 1, t
            _bsr_set_bounds(t, Y, V, bsr, ghosts, drive, ts, in_tap, top)


def bsr_rest_state(q: ColumnParams, s, W, ds, first_pinned=None, sigma_width=0.01):
    """The derived BSR's own rest state on the labels ``s``: the chain's rest map
    (:func:`bsr_rest_map`) balances gravity exactly where every bond is present; within
    one kernel width of the free top bonds above are missing, and the points there settle
    to a(y) = 0, solved here (scipy.optimize.root). Pinned points keep the chain's rest."""
    from scipy.optimize import root

    s = np.asarray(s, dtype=np.float64)
    Y0 = bsr_rest_map(q, s)
    M = s.size
    fp = M if first_pinned is None else int(first_pinned)
    ng = W.size
    yg = bsr_rest_map(q, -(np.arange(ng) + 0.5) * ds)
    vg = np.zeros(ng)
    v = np.zeros(M)
    out = np.empty(M)
    near_top = np.arange(M) < fp  # every free point: the settling reaches down the bonds

    def resid(x):
        y = Y0.copy()
        y[near_top] = x
        _bsr_accel(y, v, yg, vg, W, ds, q.g, q.e, sigma_width, fp, out)
        return out[near_top] / q.g

    sol = root(resid, Y0[near_top], method="hybr", options={"xtol": 1e-13})
    y = Y0.copy()
    y[near_top] = sol.x
    if not np.max(np.abs(resid(sol.x))) < 1e-8:
        from ..errors import SimulationError

        raise SimulationError("column derived BSR: no rest state found", residual=sol.fun)
    return y


def _eulerian_density(y, ds, z):
    """Linear density ρ(z) = ds/(y_{i+1} − y_i) of a Lagrangian map at the heights z, between
    the lowest and the highest material point (0 elsewhere) [m/h]."""
    ym = 0.5 * (y[1:] + y[:-1])
    rho = ds / np.maximum(np.diff(y), 1e-12)
    out = np.interp(z, ym, rho)
    out[(z < y[0] - 0.5 * ds) | (z > y[-1] + 0.5 * ds)] = 0.0
    return out


def solve_bsr_derived(
    q: ColumnParams,
    t_end: float,
    *,
    ds: float,
    kernel_width: float = BSR_KERNEL_WIDTH,
    top=None,
    record_dt: float | None = None,
    sigma_width: float = 0.01,
    cfl: float = 1.0,
    density_dz: float = 0.125,
) -> dict:
    """Integrate the derived BSR model in chain units (docs/column.md, "BSR derived from
    the force law").

    Lagrangian material points at the labels s_i = (i + ½) ds of the column's mass
    (s ∈ [0, N], particle k ↔ [k − 1, k]) move under :func:`_bsr_accel`: each pair of
    material points at label separation Δ within the kernel interacts through the law
    of Eq. (24) acting on its compression per unit label length. Below s = 0 ghost
    material continues the rest map and rides with the floor (the chain's floor contact
    is the bond to a ghost particle at y0 − r). Starts from the model's own rest state
    (:func:`bsr_rest_state`); RK4 in time.

    Parameters
    ----------
    q : ColumnParams in chain units; t_end in sqrt(m/K)
    ds : label spacing (h); 1/ds is rounded to an integer
    kernel_width : half-width b of the triangular label kernel (0: point particles, the
        chain on every sub-lattice of labels)
    top : (t, y_top, v_top), optional: the discrete top surface (hybrid treatment); the
        material of the top particle (labels in [N − 1, N]) moves with the discrete top
        particle, rigidly. Without it the top is free.
    sigma_width : w_σ of σ(W) = tanh(W/w_σ) [units of h sqrt(K/m)]
    density_dz : spacing of the heights at which the linear density is given

    Returns
    -------
    dict: ``s`` (M,) labels, ``t`` (n,), ``y`` (n, M) heights of the material points,
    ``tracers`` (n, N) heights at the particle centres' labels k − ½, ``z`` (n_z,) heights and
    ``rho`` (n, n_z) the linear density there [m/h], ``collapse_time`` NaN (the model
    holds the column up), ``min_spacing`` the smallest y_{i+1} − y_i over the records in
    units of ds (1 at no compression; ≤ 0: material points have passed each other, the map
    is no longer a continuum — the kernel resists compression inside one particle only
    weakly, docs/column.md).
    """
    _require_dimensionless(q, "solve_bsr_derived")
    K = max(1, int(round(1.0 / ds)))
    ds = 1.0 / K
    M = q.N * K
    s = (np.arange(M) + 0.5) * ds
    W = bsr_bond_weights(ds, kernel_width)
    Yg = bsr_rest_map(q, -(np.arange(W.size) + 0.5) * ds)
    hybrid = top is not None
    first_pinned = int(np.searchsorted(s, q.N - 1.0)) if hybrid else M
    Y = bsr_rest_state(q, s, W, ds, first_pinned, sigma_width)
    V = np.zeros(M)
    Ypin = Y[first_pinned:] - bsr_rest_map(q, q.N - 0.5)
    if hybrid:
        top_t = np.asarray(top[0], dtype=np.float64)
        top_y = np.asarray(top[1], dtype=np.float64) - q.r  # the top particle's centre
        top_v = np.asarray(top[2], dtype=np.float64)
    else:
        top_t, top_y, top_v = np.array([0.0, 1.0]), np.zeros(2), np.zeros(2)
    top_a = np.zeros(top_t.size)  # the pinned points follow positions: no acceleration read
    record_dt = record_dt or 0.01 * q.T
    rec_t = np.arange(int(math.floor(t_end / record_dt + 1e-9)) + 1) * record_dt
    out_y = np.full((rec_t.size, M), np.nan)
    bsr = DerivedBsr(W, ds, q.g, q.e, float(sigma_width), first_pinned, Ypin)
    ghosts = FloorGhosts(Yg, np.empty(Yg.size), np.empty(Yg.size))
    top_track = DiscreteTop(top_t, top_y, top_v, top_a)
    n, status, t_bad = _bsr_run(
        Y, V, bsr, ghosts, floor_drive(q), top_track, float(t_end), float(cfl), rec_t, out_y
    )
    if status:
        from ..errors import SimulationError

        raise SimulationError("column derived BSR: solution blew up", time=t_bad, ds=ds)
    y = out_y[:n]
    centres = np.arange(1, q.N + 1) - 0.5
    tracers = np.array([np.interp(centres, s, row) for row in y])
    z = (np.arange(int(round((q.N + 4.0) / density_dz))) + 0.5) * density_dz
    return {
        "s": s,
        "t": rec_t[:n],
        "y": y,
        "tracers": tracers,
        "z": z,
        "rho": np.array([_eulerian_density(row, ds, z) for row in y]),
        "min_spacing": float(np.min(np.diff(y, axis=1))) / ds,
        "collapse_time": np.nan,
    }
