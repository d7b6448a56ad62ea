"""The discrete tapped column: Eq. (19) with the tap drive of Eqs. (2)–(3), and its tangent.

Physics (paper Eqs. 4–19, monodisperse, docs/column.md). Particle i (0-based here) at height
y_i, velocity v_i; contact j sits below particle j: contact 0 between the floor y0(t) and
particle 0, contact j ≥ 1 between particles j−1 and j. Its compression and separation rate
are::

    c_0 = r − (y_0 − y0(t)),        w_0 = v_0 − ẏ0(t)
    c_j = 2r − (y_j − y_{j−1}),     w_j = v_j − v_{j−1}

and the Walton–Braun–Mindlin force it exerts (repulsive, Eq. 18) is
F_j = K [1 − e σ(w_j)] c_j χ(c_j), so that m ÿ_i = −m g + F_i − F_{i+1} (Eq. 19;
F_N = 0). Loading (w < 0) uses the stiffer spring K(1 + e), unloading K(1 − e).

How the exact sign and step (Eq. 9) are integrated. Between switches the system is
linear, so a contact is in one of four *modes*:

* ``OPEN``   c ≤ 0, F = 0
* ``LOAD``   c > 0, w < 0, F = K(1 + e) c
* ``UNLOAD`` c > 0, w > 0, F = K(1 − e) c
* ``STICK``  c > 0, w ≡ 0: the Filippov sliding mode of the discontinuity at w = 0. Any
  force in the band [K(1 − e) c, K(1 + e) c] is admissible (σ(0) ∈ [−1, 1]); the two
  particles (or particle and floor) move as one rigid block and the force is the one
  that keeps them together. This is how the column comes to rest in finite time: the
  WBM hysteresis acts like dry friction at w = 0, and the equilibrium start of Eq. (27)
  is such a stuck state with σ(0) = 0 exactly.

Within a mode the equations are integrated with classical RK4 at a fixed step h. Every
switch is *located* (event location): event functions (c for OPEN→LOAD and UNLOAD→OPEN,
w for LOAD/UNLOAD, the distance of the required force to the band edges for STICK) are
checked at the end of each step; a sign change is bracketed and its time found by
Illinois regula falsi on RK4 sub-steps of the same step (dense output of order 4), the
step is cut there, the mode updated and integration restarted. At a w = 0 event the
contact is first tried in STICK; if the force it needs leaves the band it is released
into LOAD or UNLOAD, and released contacts are checked for consistency (the sign of their
relative acceleration), an active-set iteration over the chain. Floor velocity jumps at
t = kT and kT + π/ω (Eq. 3) are time events at segment boundaries. The global error is
O(h⁴) away from grazing contacts; the restitution test shows it (tests/column).

Tangent dynamics. Inside a mode the variational equations are the linear mode equations
with g = 0 and the floor unperturbed (δc_0 = −δy_0), integrated by the same RK4 stages,
so the tangent is the exact derivative of the discrete map between switches. At a switch
of σ at c > 0 (LOAD↔UNLOAD, or entry into STICK) the vector field jumps and the tangent
is corrected by the saltation matrix S = I + (f₊ − f₋) ∇w / ẇ₋ (Müller 1995; Dieci &
Lopez 2011): δv ← δv + (a₊ − a₋) δw / ẇ₋. At entry into STICK this sets δw to zero (the
sliding mode removes the transverse direction). Switches where the field is continuous
(c = 0: the force vanishes there; release from STICK at a band edge) and time-triggered
switches need no correction (S = I). With ``saltation=False`` the correction is skipped
("plain variational" dynamics), to measure what it changes.

The smooth model (Eq. 30: σ → tanh(α_σ s), χ → (1 + tanh(α_χ s))/2) has no switches; it
is integrated with the same fixed-step RK4 and its analytic Jacobian.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .._jit import njit, njit_inline

__all__ = [
    "OPEN",
    "LOAD",
    "UNLOAD",
    "STICK",
    "STATUS_OK",
    "STATUS_OVERLAP",
    "STATUS_NONFINITE",
    "STATUS_ZENO",
    "N_STATS",
    "STAT_NAMES",
]

# Contact modes.
OPEN = 0
LOAD = 1
UNLOAD = 2
STICK = 3

# Packed parameters (ColumnParams.as_array()).
P_M = 0
P_R = 1
P_G = 2
P_K = 3
P_E = 4
P_A = 5
P_OMEGA = 6
P_T = 7
P_ASIG = 8
P_ACHI = 9
P_TAU = 10

# Return codes of the kernels.
STATUS_OK = 0
STATUS_OVERLAP = 1
STATUS_NONFINITE = 2
STATUS_ZENO = 3

# Counters (stats array).
S_STEPS = 0
S_EVENTS = 1
S_STICKS = 2
S_RELEASES = 3
S_CROSSINGS = 4
S_OPENCLOSE = 5
S_SAFETY = 6
S_CAP = 7
S_SALT_BIG = 8
N_STATS = 9
STAT_NAMES = (
    "steps",
    "events",
    "stick_entries",
    "stick_releases",
    "sign_crossings",
    "open_close",
    "late_detections",
    "active_set_cap_hits",
    "large_saltation",
)

_BIG = 1e300

# Rows of the work array W, shape (N_WORK, N).
W_Y1 = 0
W_V1 = 1
W_DY1 = 2
W_DV1 = 3
W_YT = 4
W_VT = 5
W_DYT = 6
W_DVT = 7
W_KY = 8  # 4 rows
W_KV = 12  # 4 rows
W_KDY = 16  # 4 rows
W_KDV = 20  # 4 rows
W_C = 24
W_W = 25
W_F = 26
W_ACC = 27
W_DC = 28
W_DF = 29
W_DACC = 30
W_AMINUS = 31
W_YS = 32
W_VS = 33
N_WORK = 34


# --------------------------------------------------------------------------- drive
class ChainState(NamedTuple):
    """The chain's arrays, updated in place: positions y [length] and velocities v
    [length/time], shape (N,); the tangent vector dy, dv in the same units, (N,); the
    contact modes (N,) int8 (OPEN, LOAD, UNLOAD, STICK; entry 0 the floor contact)."""

    y: np.ndarray
    v: np.ndarray
    dy: np.ndarray
    dv: np.ndarray
    modes: np.ndarray


class Integrator(NamedTuple):
    """Fixed inputs of a run: ``par`` (P_* layout), RK4 step ``h`` [time], ``smooth``
    (smooth-sign model), ``tangent`` (evolve dy, dv), ``saltation`` (saltation at σ
    switches), tangent-norm scales ``sy`` [length] and ``sv`` [length/time], the velocity
    scale ``vscale`` [length/time] of the tolerances."""

    par: np.ndarray
    h: float
    smooth: bool
    tangent: bool
    saltation: bool
    sy: float
    sv: float
    vscale: float


class Records(NamedTuple):
    """Outputs filled in place: records ``rec_y``, ``rec_v`` (n_rec, N) at rec_t0 + i
    rec_dt [time]; samples ``samp_y``, ``samp_v``, ``samp_modes`` (n_periods, n_frac, N) at
    (k + samp_fracs[f]) T; ``log_growth`` (n_periods,); counters ``stats`` (N_STATS,)."""

    rec_t0: float
    rec_dt: float
    rec_y: np.ndarray
    rec_v: np.ndarray
    samp_fracs: np.ndarray
    samp_y: np.ndarray
    samp_v: np.ndarray
    samp_modes: np.ndarray
    log_growth: np.ndarray
    stats: np.ndarray


class WorkBuffers(NamedTuple):
    """Scratch of the event-located integration: ``W`` (N_WORK, N) (rows W_*), event
    values ``G0``, ``G1``, ``Gt`` (N, 2), the active set ``active`` and ``justrel`` (N,)
    bool, and the counters ``stats`` (N_STATS,) int64."""

    W: np.ndarray
    G0: np.ndarray
    G1: np.ndarray
    Gt: np.ndarray
    active: np.ndarray
    justrel: np.ndarray
    stats: np.ndarray


# Tolerances of the integration (_advance, _advance_smooth, run_periods), each relative to the scale
# named after it: h the RK4 step, the event scale of _event_scale ([length] for a gap,
# [force] for a stuck contact, [velocity] for a separation rate), vscale [velocity].
END_TOL = 1e-12  # × h: a remaining interval this short means t_end is reached
MERGE_TOL = 1e-6  # × h: a remainder this short after a step is merged into that step
LATE_TOL = 1e-7  # × event scale: an event value this negative at a step start is late
STICK_W_TOL = 1e-9  # × vscale: a separation rate this small repairs a late mode to STICK
ROUNDOFF_TOL = 1e-9  # × event scale: a start value this negative is round-off of a crossing
CROSS_TOL = 1e-12  # × event scale: an end value this negative is a crossing
TIME_TOL = 1e-9  # × h: times this close are equal (records, samples, segment ends)
TINY_STEP = 1e-9  # × h: an event step this short counts toward the Zeno limit
ZENO_MAX_TINY = 200  # consecutive tiny event steps that stop the run as STATUS_ZENO


@njit
def floor_motion(t, tap_start, in_tap, a, omega):
    """Floor position, velocity, acceleration at time t (Eqs. 2–3).

    ``in_tap`` selects the branch explicitly (segments never straddle a switch), so the
    jumps of ẏ0 at kT and kT + π/ω are exact time events.
    """
    if in_tap:
        s = omega * (t - tap_start)
        return a * math.sin(s), a * omega * math.cos(s), -a * omega * omega * math.sin(s)
    return 0.0, 0.0, 0.0


# --------------------------------------------------------------------------- geometry
@njit
def compressions(y, yf, r, c):
    """c_0 = r − (y_0 − yf), c_j = 2r − (y_j − y_{j−1}) into ``c`` (N,)."""
    n = y.size
    c[0] = r - (y[0] - yf)
    for j in range(1, n):
        c[j] = 2.0 * r - (y[j] - y[j - 1])


@njit
def separation_rates(v, vf, w):
    """w_0 = v_0 − vf, w_j = v_j − v_{j−1} into ``w`` (N,)."""
    n = v.size
    w[0] = v[0] - vf
    for j in range(1, n):
        w[j] = v[j] - v[j - 1]


@njit
def block_accelerations(c, modes, K, e, m, g, af, F, acc):
    """Accelerations of a chain whose contacts are in the given modes.

    Contacts in STICK glue particles into rigid blocks; a block glued to the floor moves
    with it (acceleration ``af``). Each block accelerates under gravity and the forces of
    its two boundary contacts; the force in each stuck contact is then the one that keeps
    the part of the block above it on the block's motion. With g = 0, af = 0 and ``c`` the
    perturbation δc, the same function gives the tangent accelerations.

    Parameters
    ----------
    c : (N,) compressions [length]
    modes : (N,) int8 contact modes
    F : (N,) out, repulsive contact forces [force] (required force for STICK contacts)
    acc : (N,) out, accelerations [length/time²]
    """
    n = c.size
    kl = K * (1.0 + e)
    ku = K * (1.0 - e)
    for j in range(n):
        md = modes[j]
        if md == LOAD:
            F[j] = kl * c[j]
        elif md == UNLOAD:
            F[j] = ku * c[j]
        else:
            F[j] = 0.0
    p = 0
    while p < n:
        q = p
        while q + 1 < n and modes[q + 1] == STICK:
            q += 1
        nb = q - p + 1
        f_above = F[q + 1] if q + 1 < n else 0.0
        if p == 0 and modes[0] == STICK:
            A = af
        else:
            A = (F[p] - f_above) / (nb * m) - g
        for i in range(p, q + 1):
            acc[i] = A
        for k in range(q, p, -1):
            F[k] = (q - k + 1) * m * (A + g) + f_above
        if p == 0 and modes[0] == STICK:
            F[0] = nb * m * (A + g) + f_above
        p = q + 1


@njit
def _accelerations(y, t, tap_start, in_tap, par, modes, c, F, acc):
    yf, vf, af = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    compressions(y, yf, par[P_R], c)
    block_accelerations(c, modes, par[P_K], par[P_E], par[P_M], par[P_G], af, F, acc)


@njit
def _tangent_accelerations(dy, par, modes, dc, dF, dacc):
    compressions(dy, 0.0, 0.0, dc)
    block_accelerations(dc, modes, par[P_K], par[P_E], par[P_M], 0.0, 0.0, dF, dacc)


# --------------------------------------------------------------------------- RK4
@njit_inline
def rk4_stage(x, k, f, out):
    """Stage point of classical RK4: out = x + f k, with f = c_s h (c_s = 1/2 or 1).

    x, k, out : (n,) arrays (a state and its rate, in the state's units per time); f
    [time]. Shared by the discrete chain and the continuum solvers.
    """
    for i in range(x.size):
        out[i] = x[i] + f * k[i]


@njit_inline
def rk4_combine(x, k1, k2, k3, k4, h, out):
    """End of a classical RK4 step: out = x + h/6 (k1 + 2 k2 + 2 k3 + k4); out may be x.

    x, k1..k4, out : (n,) arrays (a state and its four stage rates); h [time].
    """
    h6 = h / 6.0
    for i in range(x.size):
        out[i] = x[i] + h6 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])


@njit_inline
def _rk4_rows(x, W, row, h, out):
    """rk4_combine with the stage rates in rows row .. row + 3 of W."""
    rk4_combine(x, W[row], W[row + 1], W[row + 2], W[row + 3], h, out)


@njit
def _rk4_step(y, v, dy, dv, t, hs, tap_start, in_tap, par, modes, tangent, W):
    """One classical RK4 step of size ``hs`` with frozen modes into W[W_Y1..W_DV1]."""
    n = y.size
    c = W[W_C]
    F = W[W_F]
    yt = W[W_YT]
    vt = W[W_VT]
    dyt = W[W_DYT]
    dvt = W[W_DVT]
    for st in range(4):
        if st == 0:
            tt = t
            for i in range(n):
                yt[i] = y[i]
                vt[i] = v[i]
                if tangent:
                    dyt[i] = dy[i]
                    dvt[i] = dv[i]
        else:
            frac = 0.5 if st < 3 else 1.0
            tt = t + frac * hs
            f = frac * hs
            rk4_stage(y, W[W_KY + st - 1], f, yt)
            rk4_stage(v, W[W_KV + st - 1], f, vt)
            if tangent:
                rk4_stage(dy, W[W_KDY + st - 1], f, dyt)
                rk4_stage(dv, W[W_KDV + st - 1], f, dvt)
        _accelerations(yt, tt, tap_start, in_tap, par, modes, c, F, W[W_KV + st])
        for i in range(n):
            W[W_KY + st, i] = vt[i]
        if tangent:
            _tangent_accelerations(dyt, par, modes, W[W_DC], W[W_DF], W[W_KDV + st])
            for i in range(n):
                W[W_KDY + st, i] = dvt[i]
    _rk4_rows(y, W, W_KY, hs, W[W_Y1])
    _rk4_rows(v, W, W_KV, hs, W[W_V1])
    if tangent:
        _rk4_rows(dy, W, W_KDY, hs, W[W_DY1])
        _rk4_rows(dv, W, W_KDV, hs, W[W_DV1])


# --------------------------------------------------------------------------- events
@njit
def _event_values(y, v, t, tap_start, in_tap, par, modes, W, G):
    """Event functions G (N, 2): positive while a contact's mode is consistent.

    OPEN: (−c, ·); LOAD: (−w, ·); UNLOAD: (w, c); STICK: (F − K(1−e)c, K(1+e)c − F).
    Unused entries are +1e300.
    """
    n = y.size
    yf, vf, af = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    c = W[W_C]
    w = W[W_W]
    F = W[W_F]
    compressions(y, yf, par[P_R], c)
    separation_rates(v, vf, w)
    block_accelerations(c, modes, par[P_K], par[P_E], par[P_M], par[P_G], af, F, W[W_ACC])
    kl = par[P_K] * (1.0 + par[P_E])
    ku = par[P_K] * (1.0 - par[P_E])
    for j in range(n):
        md = modes[j]
        G[j, 0] = _BIG
        G[j, 1] = _BIG
        if md == OPEN:
            G[j, 0] = -c[j]
        elif md == LOAD:
            G[j, 0] = -w[j]
        elif md == UNLOAD:
            G[j, 0] = w[j]
            G[j, 1] = c[j]
        else:
            G[j, 0] = F[j] - ku * c[j]
            G[j, 1] = kl * c[j] - F[j]


@njit
def _event_scale(md, k, par, vscale):
    """Scale of event function (mode md, index k), for tolerances."""
    if md == OPEN or (md == UNLOAD and k == 1):
        return par[P_R]
    if md == STICK:
        return par[P_K] * par[P_R]
    return vscale


@njit
def _locate(j, k, fa0, fb0, state, par, t, hs, tap_start, in_tap, W, Gt):
    """Time s in (0, hs] just past the zero of event function (j, k) (Illinois).

    fa0, fb0 : its values at t and t + hs; state : ChainState at t; W, Gt scratch.
    """
    y, v, dy, dv, modes = state
    a_s = 0.0
    b_s = hs
    fa = fa0
    fb = fb0
    side = 0
    tol = max(1e-13 * hs, 4.0 * 2.220446049250313e-16 * abs(t))
    for _ in range(80):
        if b_s - a_s <= tol:
            break
        s = (a_s * fb - b_s * fa) / (fb - fa)
        if not (a_s < s < b_s):
            s = 0.5 * (a_s + b_s)
        _rk4_step(y, v, dy, dv, t, s, tap_start, in_tap, par, modes, False, W)
        _event_values(W[W_Y1], W[W_V1], t + s, tap_start, in_tap, par, modes, W, Gt)
        fs = Gt[j, k]
        if fs <= 0.0:
            b_s = s
            fb = fs
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a_s = s
            fa = fs
            if side == 1:
                fb *= 0.5
            side = 1
    return b_s


@njit
def _mode_from_state(cj, wj):
    """Mode implied by compression and separation rate (w = 0 → STICK candidate)."""
    if cj <= 0.0:
        return OPEN
    if wj < 0.0:
        return LOAD
    if wj > 0.0:
        return UNLOAD
    return STICK


@njit
def _resolve(y, v, t, tap_start, in_tap, par, modes, active, justrel, W, stats):
    """Active-set resolution of stuck contacts at one instant.

    Contacts flagged ``active`` (w has just reached 0 at c > 0) are tried in STICK; the
    stuck contact whose required force leaves its band by the most is released (LOAD if
    the band is too weak, UNLOAD if too strong), and released contacts whose relative
    acceleration points back across w = 0 are stuck again, until consistent.
    """
    n = y.size
    yf, vf, af = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    c = W[W_C]
    F = W[W_F]
    acc = W[W_ACC]
    K = par[P_K]
    e = par[P_E]
    compressions(y, yf, par[P_R], c)
    for j in range(n):
        justrel[j] = False
        if active[j] and c[j] > 0.0 and modes[j] != STICK:
            modes[j] = STICK
            stats[S_STICKS] += 1
    athr = 1e-12 * K * par[P_R] / par[P_M]
    for _ in range(4 * n + 8):
        block_accelerations(c, modes, K, e, par[P_M], par[P_G], af, F, acc)
        best = -1
        bestv = -1.0
        for j in range(n):
            if modes[j] == STICK:
                sc = K * max(c[j], 1e-300)
                viol = max(F[j] - K * (1.0 + e) * c[j], K * (1.0 - e) * c[j] - F[j]) / sc
                if e == 0.0:
                    viol += 1.0  # no band without hysteresis: never stick
                if viol >= 0.0 and viol > bestv:  # marginal (at an edge) counts as out
                    bestv = viol
                    best = j
        if best >= 0:
            # the nearer edge decides (a marginal force sits on an edge up to round-off)
            modes[best] = LOAD if F[best] > K * c[best] else UNLOAD
            if c[best] <= 0.0:
                modes[best] = OPEN
            justrel[best] = True
            stats[S_RELEASES] += 1
            continue
        bad = -1
        for j in range(n):
            if e > 0.0 and justrel[j] and (modes[j] == LOAD or modes[j] == UNLOAD):
                arel = acc[j] - (acc[j - 1] if j > 0 else af)
                if (modes[j] == LOAD and arel > athr) or (modes[j] == UNLOAD and arel < -athr):
                    bad = j
                    break
        if bad >= 0:
            modes[bad] = STICK
            justrel[bad] = False
            stats[S_STICKS] += 1
            continue
        return
    stats[S_CAP] += 1


@njit
def _snap_blocks(v, dv, t, tap_start, in_tap, par, modes, tangent):
    """Give every stuck block one velocity (momentum mean; the floor's if glued to it)."""
    n = v.size
    yf, vf, af = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    p = 0
    while p < n:
        q = p
        while q + 1 < n and modes[q + 1] == STICK:
            q += 1
        floor_att = p == 0 and modes[0] == STICK
        if q > p or floor_att:
            if floor_att:
                vb = vf
                dvb = 0.0
            else:
                vb = 0.0
                dvb = 0.0
                for i in range(p, q + 1):
                    vb += v[i]
                    dvb += dv[i]
                vb /= q - p + 1
                dvb /= q - p + 1
            for i in range(p, q + 1):
                v[i] = vb
                if tangent:
                    dv[i] = dvb
        p = q + 1


@njit
def _check_state(y, t, tap_start, in_tap, par):
    """Status and particle index at the end of a step at ``t``: overlap past a centre or
    past the floor (pass-through) or non-finite."""
    yf, _, _ = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    n = y.size
    for i in range(n):
        if not math.isfinite(y[i]):
            return STATUS_NONFINITE, i
    if y[0] - yf <= 0.0:
        return STATUS_OVERLAP, 0
    for i in range(1, n):
        if y[i] - y[i - 1] <= 0.0:
            return STATUS_OVERLAP, i
    return STATUS_OK, -1


@njit
def _process_event(state, integ, work, t, tap_start, in_tap, jstar, kstar):
    """Mode changes at a located event (jstar, kstar) at t; saltation of the tangent for
    w-type switches. state : ChainState, integ : Integrator, work : WorkBuffers."""
    y, v, dy, dv, modes = state
    par, _, _, tangent, saltation, _, _, _ = integ
    W, G0, _, Gt, active, justrel, stats = work
    n = y.size
    yf, vf, af = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    # accelerations just before the switch (old modes) and the switching rate of jstar
    _accelerations(y, t, tap_start, in_tap, par, modes, W[W_C], W[W_F], W[W_AMINUS])
    am = W[W_AMINUS]
    md_star = modes[jstar]
    w_type = (md_star == LOAD) or (md_star == UNLOAD and kstar == 0)
    wdot = am[jstar] - (am[jstar - 1] if jstar > 0 else af)
    dw = 0.0
    if tangent:
        dw = dv[jstar] - (dv[jstar - 1] if jstar > 0 else 0.0)
    _event_values(y, v, t, tap_start, in_tap, par, modes, W, Gt)
    w = W[W_W]
    for j in range(n):
        active[j] = False
    old_star = modes[jstar]
    for j in range(n):
        for k in range(2):
            hit = (j == jstar and k == kstar) or Gt[j, k] <= 0.0
            if not hit:
                continue
            md = modes[j]
            if md == OPEN:
                if w[j] < 0.0:
                    modes[j] = LOAD
                    stats[S_OPENCLOSE] += 1
            elif md == UNLOAD and k == 1:
                modes[j] = OPEN
                stats[S_OPENCLOSE] += 1
            elif md == LOAD or md == UNLOAD:
                active[j] = True
            # STICK band events: _resolve releases them.
    _resolve(y, v, t, tap_start, in_tap, par, modes, active, justrel, W, stats)
    _snap_blocks(v, dv, t, tap_start, in_tap, par, modes, tangent)
    if w_type and modes[jstar] != old_star:
        stats[S_CROSSINGS] += 1
        if tangent and saltation and wdot != 0.0:
            _accelerations(y, t, tap_start, in_tap, par, modes, W[W_C], W[W_F], W[W_ACC])
            fac = dw / wdot
            if abs(fac) * par[P_K] / par[P_M] > 1e8 * par[P_R]:
                stats[S_SALT_BIG] += 1
            for i in range(n):
                dv[i] += (W[W_ACC, i] - am[i]) * fac
            _snap_blocks(v, dv, t, tap_start, in_tap, par, modes, tangent)


@njit
def _time_event(state, integ, work, t, tap_start, in_tap):
    """Floor velocity jumped (start or end of a tap): re-derive the floor contact's mode.

    state : ChainState, integ : Integrator, work : WorkBuffers; t, tap_start [time].
    """
    y, v, _, dv, modes = state
    par, _, _, tangent, _, _, _, _ = integ
    W, _, _, _, active, justrel, stats = work
    n = y.size
    yf, vf, af = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    c0 = par[P_R] - (y[0] - yf)
    w0 = v[0] - vf
    for j in range(n):
        active[j] = False
    if modes[0] != OPEN or c0 > 0.0:
        md = _mode_from_state(c0, w0)
        if md == STICK:
            active[0] = True
        else:
            modes[0] = md
    _resolve(y, v, t, tap_start, in_tap, par, modes, active, justrel, W, stats)
    _snap_blocks(v, dv, t, tap_start, in_tap, par, modes, tangent)


@njit
def _at_rest(v, modes):
    """All contacts (floor included) stuck and every velocity exactly zero."""
    for i in range(v.size):
        if modes[i] != STICK or v[i] != 0.0:
            return False
    return True


@njit_inline
def _is_late(G0, j, md, par, vscale):
    """True if an event function of particle j (mode md) is below −LATE_TOL × its scale.

    G0 : (N, 2) event values at the step start, mixed units (see _event_scale).
    """
    bad = False
    for k in range(2):
        if G0[j, k] < -LATE_TOL * _event_scale(md, k, par, vscale):
            bad = True
    return bad


@njit_inline
def _any_late(G0, modes, par, vscale):
    """True if any particle has a late event value (_is_late); G0 (N, 2), modes (N,)."""
    late = False
    for j in range(modes.size):
        if _is_late(G0, j, modes[j], par, vscale):
            late = True
    return late


@njit
def _repair_late(state, integ, work, t, tap_start, in_tap):
    """Repair the modes inconsistent at the start of a step (a re-crossing missed, see
    _any_late).

    y, v, dv : (N,) [length], [velocity], [velocity] (tangent); modes (N,) int8; G0 (N, 2)
    event values at t, refreshed here after a repair. A late mode (not STICK) becomes the
    mode of its compression and separation rate (W rows W_C [length], W_W [velocity]); if
    that is STICK, or a contact with a separation rate below STICK_W_TOL × vscale, the
    contact joins the active set resolved by _resolve. Counts the repair in S_SAFETY.
    state : ChainState, integ : Integrator, work : WorkBuffers.
    """
    y, v, _, dv, modes = state
    par, _, _, tangent, _, _, _, vscale = integ
    W, G0, _, _, active, justrel, stats = work
    n = y.size
    stats[S_SAFETY] += 1
    c = W[W_C]
    w = W[W_W]
    for j in range(n):
        active[j] = False
        md = modes[j]
        if _is_late(G0, j, md, par, vscale) and md != STICK:
            nm = _mode_from_state(c[j], w[j])
            if nm == STICK or (nm != OPEN and abs(w[j]) < STICK_W_TOL * vscale):
                active[j] = True
            else:
                modes[j] = nm
    _resolve(y, v, t, tap_start, in_tap, par, modes, active, justrel, W, stats)
    _snap_blocks(v, dv, t, tap_start, in_tap, par, modes, tangent)
    _event_values(y, v, t, tap_start, in_tap, par, modes, W, G0)


@njit_inline
def _skipped(g0, g1, muted):
    """An event that no step examines: unused (g0 at _BIG), not crossed within the step
    (g1 > 0 or not below g0) or muted."""
    return g0 >= _BIG or g1 > 0.0 or g1 >= g0 or muted


@njit_inline
def _any_candidate(G0, G1, muted):
    """True if some event (j, k) is one that _first_event examines: not muted, start value
    G0 below _BIG, end value G1 ≤ 0 and below G0. G0, G1 (N, 2) event values at the step
    start and end (mixed units, see _event_scale); muted (N, 2) bool.

    The cheap test before _first_event, as _any_late before _repair_late: inlined,
    _first_event takes a reference to each of the dozen arrays it reads from the bundles,
    and numba cannot prune those increfs/decrefs because its loop calls _locate (about 24
    NRT calls per step, some 3 % of the chain's time); behind this test only steps with a
    candidate pay them.
    """
    found = False
    for j in range(G0.shape[0]):
        for k in range(2):
            g0 = G0[j, k]
            g1 = G1[j, k]
            if not _skipped(g0, g1, muted[j, k]):
                found = True
    return found


@njit_inline
def _first_event(state, integ, work, t, hs, tap_start, in_tap, muted):
    """Earliest event of the RK4 step (t, t + hs]: (s, j, k), j = −1 if none.

    G0, G1 : (N, 2) event values at t and t + hs (mixed units, see _event_scale); s
    [time] in [0, hs] from _locate, 0 for a crossing at the end of the previous step
    within round-off. Muted (N, 2) events are skipped; a start value below −ROUNDOFF_TOL ×
    scale is a late detection, left to _repair_late at the next step. state :
    ChainState, integ : Integrator, work : WorkBuffers.
    """
    y = state.y
    modes = state.modes
    par = integ.par
    vscale = integ.vscale
    W, G0, G1, Gt, _, _, _ = work
    s_best = 2.0 * hs
    jb = -1
    kb = -1
    for j in range(y.size):
        for k in range(2):
            g0 = G0[j, k]
            g1 = G1[j, k]
            if _skipped(g0, g1, muted[j, k]):
                continue
            if g0 > 0.0:
                s = _locate(j, k, g0, g1, state, par, t, hs, tap_start, in_tap, W, Gt)
            elif g0 > -ROUNDOFF_TOL * _event_scale(modes[j], k, par, vscale) and (
                g1 < -CROSS_TOL * _event_scale(modes[j], k, par, vscale)
            ):
                s = 0.0
            else:
                continue
            if s < s_best:
                s_best = s
                jb = j
                kb = k
    return s_best, jb, kb


@njit_inline
def _take_step(y, v, dy, dv, W, tangent):
    """Copy the RK4 end state (W rows W_Y1, W_V1, W_DY1, W_DV1) into y, v (and dy, dv)."""
    for i in range(y.size):
        y[i] = W[W_Y1, i]
        v[i] = W[W_V1, i]
        if tangent:
            dy[i] = W[W_DY1, i]
            dv[i] = W[W_DV1, i]


@njit_inline
def _unchanged_modes(W, modes):
    """True if the modes equal those saved in W row W_YS before the event."""
    for i in range(modes.size):
        if W[W_YS, i] != modes[i]:
            return False
    return True


@njit
def _advance(state, integ, work, t, t_end, tap_start, in_tap, step0):
    """Integrate from t to t_end (no drive switch inside) with located mode switches.

    Each step: repair late modes (_repair_late), one RK4 step of h (the last one up to
    t_end), the earliest event in it (_first_event, if _any_candidate); without one the
    step is taken, with one the step is redone up to the event and the event processed
    (_process_event). More than ZENO_MAX_TINY consecutive event steps shorter than
    TINY_STEP × h stop the run (STATUS_ZENO). state : ChainState, integ : Integrator,
    work : WorkBuffers; t, t_end, tap_start [time]; in_tap bool; step0 steps so far.
    Returns (t, status, particle, steps).
    """
    y, v, dy, dv, modes = state
    par, h, _, tangent, saltation, _, _, vscale = integ
    W, G0, G1, Gt, active, justrel, stats = work
    n = y.size
    steps = step0
    n_tiny = 0
    # an immediate event that changed no mode is not retried before the next full step
    muted = np.zeros((n, 2), dtype=np.bool_)
    # the RK4 end state, W rows made views once (a view per step is an incref/decref pair)
    y1 = W[W_Y1]
    v1 = W[W_V1]
    while t_end - t > END_TOL * h:
        if not in_tap and _at_rest(v, modes):
            # Every contact stuck and the floor still: the state is exactly static (all
            # accelerations and velocities zero, required forces constant), so no event
            # can occur before the drive changes. Jump to the stop.
            t = t_end
            break
        hs = min(h, t_end - t)
        if t_end - (t + hs) < MERGE_TOL * h:
            hs = t_end - t
        _event_values(y, v, t, tap_start, in_tap, par, modes, W, G0)
        if _any_late(G0, modes, par, vscale):
            _repair_late(state, integ, work, t, tap_start, in_tap)
        _rk4_step(y, v, dy, dv, t, hs, tap_start, in_tap, par, modes, tangent, W)
        _event_values(y1, v1, t + hs, tap_start, in_tap, par, modes, W, G1)
        s_best, jb, kb = 2.0 * hs, -1, -1
        if _any_candidate(G0, G1, muted):
            s_best, jb, kb = _first_event(state, integ, work, t, hs, tap_start, in_tap, muted)
        if jb < 0:
            _take_step(y, v, dy, dv, W, tangent)
            t += hs
            steps += 1
            stats[S_STEPS] += 1
            n_tiny = 0
            muted[:, :] = False
        else:
            _rk4_step(y, v, dy, dv, t, s_best, tap_start, in_tap, par, modes, tangent, W)
            _take_step(y, v, dy, dv, W, tangent)
            t += s_best
            stats[S_EVENTS] += 1
            for i in range(n):
                W[W_YS, i] = modes[i]
            _process_event(state, integ, work, t, tap_start, in_tap, jb, kb)
            if s_best == 0.0 and _unchanged_modes(W, modes):
                muted[jb, kb] = True
            if s_best < TINY_STEP * h:
                n_tiny += 1
                if n_tiny > ZENO_MAX_TINY:
                    return t, STATUS_ZENO, jb, steps
            else:
                n_tiny = 0
        status, who = _check_state(y, t, tap_start, in_tap, par)
        if status != STATUS_OK:
            return t, status, who, steps
    return t, STATUS_OK, -1, steps


# --------------------------------------------------------------------------- smooth model
@njit
def _smooth_forces(y, v, t, tap_start, in_tap, par, F, acc):
    """Eq. (30) forces F_j = K(1 − e tanh(α_σ w))c(1 + tanh(α_χ c))/2 and accelerations."""
    n = y.size
    yf, vf, af = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    K = par[P_K]
    e = par[P_E]
    r = par[P_R]
    for j in range(n):
        if j == 0:
            c = r - (y[0] - yf)
            w = v[0] - vf
        else:
            c = 2.0 * r - (y[j] - y[j - 1])
            w = v[j] - v[j - 1]
        F[j] = (
            K
            * (1.0 - e * math.tanh(par[P_ASIG] * w))
            * c
            * 0.5
            * (1.0 + math.tanh(par[P_ACHI] * c))
        )
    for i in range(n):
        above = F[i + 1] if i + 1 < n else 0.0
        acc[i] = (F[i] - above) / par[P_M] - par[P_G]


@njit
def _smooth_tangent(y, v, dy, dv, t, tap_start, in_tap, par, dF, dacc):
    """Tangent accelerations of the smooth model (analytic Jacobian of Eq. 30 forces)."""
    n = y.size
    yf, vf, af = floor_motion(t, tap_start, in_tap, par[P_A], par[P_OMEGA])
    K = par[P_K]
    e = par[P_E]
    r = par[P_R]
    asg = par[P_ASIG]
    ach = par[P_ACHI]
    for j in range(n):
        if j == 0:
            c = r - (y[0] - yf)
            w = v[0] - vf
            dcj = -dy[0]
            dwj = dv[0]
        else:
            c = 2.0 * r - (y[j] - y[j - 1])
            w = v[j] - v[j - 1]
            dcj = -(dy[j] - dy[j - 1])
            dwj = dv[j] - dv[j - 1]
        ts = math.tanh(asg * w)
        tc = math.tanh(ach * c)
        chi = 0.5 * (1.0 + tc)
        dchi = 0.5 * ach * (1.0 - tc * tc)
        dF_dc = K * (1.0 - e * ts) * (chi + c * dchi)
        dF_dw = -K * e * asg * (1.0 - ts * ts) * c * chi
        dF[j] = dF_dc * dcj + dF_dw * dwj
    for i in range(n):
        above = dF[i + 1] if i + 1 < n else 0.0
        dacc[i] = (dF[i] - above) / par[P_M]


@njit
def _advance_smooth(state, integ, work, t, t_end, tap_start, in_tap, step0):
    """Fixed-step RK4 of the smooth model (and its variational equations) to t_end.

    state : ChainState, integ : Integrator, work : WorkBuffers; t, t_end [time].
    """
    y, v, dy, dv, _ = state
    par, h, _, tangent, _, _, _, _ = integ
    W, _, _, _, _, _, stats = work
    n = y.size
    steps = step0
    F = W[W_F]
    yt = W[W_YT]
    vt = W[W_VT]
    dyt = W[W_DYT]
    dvt = W[W_DVT]
    while t_end - t > END_TOL * h:
        hs = min(h, t_end - t)
        if t_end - (t + hs) < MERGE_TOL * h:
            hs = t_end - t
        for st in range(4):
            if st == 0:
                tt = t
                for i in range(n):
                    yt[i] = y[i]
                    vt[i] = v[i]
                    dyt[i] = dy[i]
                    dvt[i] = dv[i]
            else:
                frac = 0.5 if st < 3 else 1.0
                tt = t + frac * hs
                for i in range(n):
                    yt[i] = y[i] + frac * hs * W[W_KY + st - 1, i]
                    vt[i] = v[i] + frac * hs * W[W_KV + st - 1, i]
                    dyt[i] = dy[i] + frac * hs * W[W_KDY + st - 1, i]
                    dvt[i] = dv[i] + frac * hs * W[W_KDV + st - 1, i]
            _smooth_forces(yt, vt, tt, tap_start, in_tap, par, F, W[W_KV + st])
            for i in range(n):
                W[W_KY + st, i] = vt[i]
            if tangent:
                _smooth_tangent(
                    yt, vt, dyt, dvt, tt, tap_start, in_tap, par, W[W_DF], W[W_KDV + st]
                )
                for i in range(n):
                    W[W_KDY + st, i] = dvt[i]
        h6 = hs / 6.0
        for i in range(n):
            y[i] += h6 * (W[W_KY, i] + 2.0 * W[W_KY + 1, i] + 2.0 * W[W_KY + 2, i] + W[W_KY + 3, i])
            v[i] += h6 * (W[W_KV, i] + 2.0 * W[W_KV + 1, i] + 2.0 * W[W_KV + 2, i] + W[W_KV + 3, i])
            if tangent:
                dy[i] += h6 * (
                    W[W_KDY, i] + 2.0 * W[W_KDY + 1, i] + 2.0 * W[W_KDY + 2, i] + W[W_KDY + 3, i]
                )
                dv[i] += h6 * (
                    W[W_KDV, i] + 2.0 * W[W_KDV + 1, i] + 2.0 * W[W_KDV + 2, i] + W[W_KDV + 3, i]
                )
        t += hs
        steps += 1
        stats[S_STEPS] += 1
        status, who = _check_state(y, t, tap_start, in_tap, par)
        if status != STATUS_OK:
            return t, status, who, steps
    return t, STATUS_OK, -1, steps


# --------------------------------------------------------------------------- driver
@njit
def _tangent_norm(dy, dv, sy, sv):
    s = 0.0
    for i in range(dy.size):
        s += (dy[i] / sy) ** 2 + (dv[i] / sv) ** 2
    return math.sqrt(s)


@njit
def run_periods(state, integ, rec, k0, n_periods):
    """Evolve the column over taps k0 .. k0 + n_periods − 1 (t from k0 T to (k0+n) T).

    State arrays are updated in place. Records (if ``rec_y`` has rows) at times
    rec_t0 + i rec_dt; samples of y, v and the contact modes at (k + f) T for f in
    ``samp_fracs`` into ``samp_y[k − k0, f]``, ``samp_v``, ``samp_modes`` (f = 1: the state
    the next tap starts from, before its floor-velocity jump; a sample time equal to a
    segment end adds no step, so sampling never changes the trajectory); with
    ``tangent``, the tangent vector (dy, dv) is renormalized (norm
    sqrt(Σ (dy/sy)² + (dv/sv)²)) at the end of every period and
    ``log_growth[k − k0]`` gets the log of its growth over that period.

    state : ChainState (updated in place); integ : Integrator; rec : Records (filled
    in place); k0, n_periods : int.

    Returns
    -------
    status, particle, time, n_records
    """
    y, v, dy, dv, modes = state
    par, h, smooth, tangent, saltation, sy, sv, vscale = integ
    rec_t0, rec_dt, rec_y, rec_v, samp_fracs, samp_y, samp_v, samp_modes, log_growth, stats = rec
    n = y.size
    W = np.zeros((N_WORK, n))
    G0 = np.zeros((n, 2))
    G1 = np.zeros((n, 2))
    Gt = np.zeros((n, 2))
    active = np.zeros(n, dtype=np.bool_)
    justrel = np.zeros(n, dtype=np.bool_)
    work = WorkBuffers(W, G0, G1, Gt, active, justrel, stats)
    T = par[P_T]
    tau = par[P_TAU] if par[P_A] > 0.0 else 0.0
    n_rec_max = rec_y.shape[0]
    i_rec = 0
    t = k0 * T
    # skip records before the start
    while i_rec < n_rec_max and rec_t0 + i_rec * rec_dt < t - TIME_TOL * h:
        i_rec += 1
    steps = 0
    n_samp = samp_fracs.size
    log_extra = 0.0
    if not smooth:
        for j in range(n):
            active[j] = False
        # make the initial modes consistent (equilibrium start: all stuck)
        _resolve(y, v, t, t, False, par, modes, active, justrel, W, stats)
        _snap_blocks(v, dv, t, t, False, par, modes, tangent)
    for kk in range(n_periods):
        k = k0 + kk
        t_start = k * T
        log_extra = 0.0
        for seg in range(2):
            if seg == 0:
                if tau <= 0.0:
                    continue
                seg_a = t_start
                seg_b = t_start + tau
                in_tap = True
            else:
                seg_a = t_start + tau
                seg_b = (k + 1) * T
                in_tap = False
            t = seg_a
            if not smooth and tau > 0.0:
                _time_event(state, integ, work, t, t_start, in_tap)
            while True:
                # record / sample everything due at the current time
                while i_rec < n_rec_max and rec_t0 + i_rec * rec_dt <= t + TIME_TOL * h:
                    for i in range(n):
                        rec_y[i_rec, i] = y[i]
                        rec_v[i_rec, i] = v[i]
                    i_rec += 1
                stop = seg_b
                if i_rec < n_rec_max:
                    tr = rec_t0 + i_rec * rec_dt
                    if tr < stop:
                        stop = tr
                for f in range(n_samp):
                    ts = (k + samp_fracs[f]) * T
                    if t + TIME_TOL * h < ts < stop:
                        stop = ts
                if stop - t <= TIME_TOL * h:
                    break
                if smooth:
                    t, status, who, steps = _advance_smooth(
                        state, integ, work, t, stop, t_start, in_tap, steps
                    )
                else:
                    t, status, who, steps = _advance(
                        state, integ, work, t, stop, t_start, in_tap, steps
                    )
                if status != STATUS_OK:
                    return status, who, t, i_rec
                for f in range(n_samp):
                    ts = (k + samp_fracs[f]) * T
                    if abs(t - ts) <= TIME_TOL * h:
                        for i in range(n):
                            samp_y[kk, f, i] = y[i]
                            samp_v[kk, f, i] = v[i]
                            samp_modes[kk, f, i] = modes[i]
                if tangent:
                    nrm = _tangent_norm(dy, dv, sy, sv)
                    if nrm > 1e100 or nrm < 1e-100:
                        log_extra += math.log(nrm)
                        for i in range(n):
                            dy[i] /= nrm
                            dv[i] /= nrm
        if tangent:
            nrm = _tangent_norm(dy, dv, sy, sv)
            log_growth[kk] = math.log(nrm) + log_extra
            for i in range(n):
                dy[i] /= nrm
                dv[i] /= nrm
        t = (k + 1) * T
    # record at the final time if due
    while i_rec < n_rec_max and rec_t0 + i_rec * rec_dt <= t + TIME_TOL * h:
        for i in range(n):
            rec_y[i_rec, i] = y[i]
            rec_v[i_rec, i] = v[i]
        i_rec += 1
    return STATUS_OK, -1, t, i_rec


# =========================================================================== Python API
class ColumnState:
    """Mutable state of one column: positions, velocities, contact modes, tangent vector.

    Attributes
    ----------
    y, v : (N,) float64 [length], [length/time]
    modes : (N,) int8 contact modes (OPEN, LOAD, UNLOAD, STICK)
    dy, dv : (N,) float64 tangent vector (dimensions of y and v)
    period : int, index of the next tap to run (the state is at time ``period * T``)
    """

    def __init__(self, y, v=None, modes=None, dy=None, dv=None, period=0):
        self.y = np.array(y, dtype=np.float64)
        n = self.y.size
        self.v = np.zeros(n) if v is None else np.array(v, dtype=np.float64)
        self.modes = (
            np.full(n, STICK, dtype=np.int8) if modes is None else np.array(modes, dtype=np.int8)
        )
        self.dy = np.zeros(n) if dy is None else np.array(dy, dtype=np.float64)
        self.dv = np.zeros(n) if dv is None else np.array(dv, dtype=np.float64)
        self.period = int(period)

    def copy(self) -> ColumnState:
        return ColumnState(self.y, self.v, self.modes, self.dy, self.dv, self.period)


def default_step(p, factor: float = 0.1) -> float:
    """Default RK4 step h = factor / ω_max, ω_max = 2 sqrt(K(1+e)/m) [time].

    For the smooth model the step also resolves the viscous rate e K c α_σ / m of σ_α near
    w = 0 (c ≤ r), so h ≤ factor·m/(e K r α_σ).
    """
    h = factor / p.max_frequency
    if p.smooth and p.e > 0:
        h = min(h, factor * p.m / (p.e * p.K * p.r * p.alpha_sigma))
    return h


def tangent_scales(p) -> tuple[float, float]:
    """Scales (s_y, s_v) of the tangent norm sqrt(Σ (δy/s_y)² + (δv/s_v)²): r and ω_c r."""
    return p.r, p.contact_frequency * p.r


def smooth_equilibrium(p) -> np.ndarray:
    """Rest positions of the smooth model (Eq. 30): K c χ_α(c) = weight above, per contact.

    Returns (N,) float64 [length]; reduces to :func:`params.equilibrium_positions` as
    α_χ → ∞.
    """
    from .model import equilibrium_positions

    y = equilibrium_positions(p)  # also checks 𝔐 < r/N
    weights = p.m * p.g * np.arange(p.N, 0, -1, dtype=np.float64)  # contact j carries N−j
    c = weights / p.K
    for _ in range(100):
        tc = np.tanh(p.alpha_chi * c)
        chi = 0.5 * (1 + tc)
        f = p.K * c * chi - weights
        df = p.K * (chi + c * 0.5 * p.alpha_chi * (1 - tc * tc))
        dc = f / df
        c -= dc
        if np.max(np.abs(dc)) < 1e-15 * p.r:
            break
    y = np.empty(p.N)
    y[0] = p.r - c[0]
    for j in range(1, p.N):
        y[j] = y[j - 1] + 2 * p.r - c[j]
    return y


def initial_state(p, perturbation=None) -> ColumnState:
    """The equilibrium start at rest (docs/column.md), all contacts stuck; optional δy added.

    Parameters
    ----------
    perturbation : (N,) float64 [length], optional
        Added to the rest positions (the column then starts slightly off equilibrium; every
        contact stays stuck while its force remains inside the hysteresis band).
    """
    from .model import equilibrium_positions

    y = smooth_equilibrium(p) if p.smooth else equilibrium_positions(p)
    if perturbation is not None:
        y = y + np.asarray(perturbation, dtype=np.float64)
    return ColumnState(y)


def mechanical_energy(p, y, v, y_floor=0.0) -> np.ndarray:
    """Kinetic + gravitational + elastic energy (elastic with stiffness K, e = 0 only).

    Parameters
    ----------
    y, v : (..., N) [length], [length/time]

    Returns
    -------
    E : (...) [energy]
    """
    y = np.asarray(y)
    v = np.asarray(v)
    c = np.empty_like(y)
    c[..., 0] = p.r - (y[..., 0] - y_floor)
    c[..., 1:] = 2 * p.r - np.diff(y, axis=-1)
    elastic = 0.5 * p.K * np.sum(np.where(c > 0, c * c, 0.0), axis=-1)
    return 0.5 * p.m * np.sum(v * v, axis=-1) + p.m * p.g * np.sum(y, axis=-1) + elastic


def _raise_status(status, who, t, p, **context):
    from ..errors import SimulationError

    if status == STATUS_OVERLAP:
        what = "floor" if who == 0 else f"particle {who - 1}"
        raise SimulationError(
            f"column: particle {who} passed through the {what}",
            particle=int(who),
            time=float(t),
            **context,
        )
    if status == STATUS_NONFINITE:
        raise SimulationError(
            "column: non-finite position", particle=int(who), time=float(t), **context
        )
    if status == STATUS_ZENO:
        raise SimulationError(
            "column: more than 200 mode switches without the clock advancing (Zeno)",
            particle=int(who),
            time=float(t),
            **context,
        )


def simulate(
    p,
    state: ColumnState,
    n_periods: int,
    *,
    h: float | None = None,
    record_dt: float | None = None,
    sample_fracs=(0.99,),
    tangent: bool = False,
    saltation: bool = True,
    **context,
) -> dict:
    """Run ``n_periods`` taps from ``state`` (updated in place).

    Parameters
    ----------
    p : ColumnParams
    state : ColumnState at time ``state.period * T``
    n_periods : int
    h : float [time], RK4 step (default :func:`default_step`)
    record_dt : float [time], optional; record y, v every ``record_dt``
    sample_fracs : sequence of float in (0, 1]; sample y, v and modes at (k + f)T
    tangent : bool; evolve the tangent vector (normalized at the end of every period)
    saltation : bool; apply saltation corrections at σ switches

    Returns
    -------
    dict with ``t`` (n_rec,), ``y``/``v`` (n_rec, N), ``samples`` (n_periods, n_frac, N)
    [length] with ``samples_v`` [length/time] and ``sample_modes`` (int8, −1 if not
    sampled) at the same times, ``log_growth`` (n_periods,) (log of the tangent growth per
    period), ``stats`` (dict of counters).
    """
    h = default_step(p) if h is None else float(h)
    k0 = state.period
    if record_dt:
        n_rec = int(np.floor(n_periods * p.T / record_dt + 1e-9)) + 1
        rec_t0 = k0 * p.T
    else:
        n_rec, rec_t0, record_dt = 0, 0.0, 1.0
    rec_y = np.zeros((n_rec, p.N))
    rec_v = np.zeros((n_rec, p.N))
    fr = np.asarray(sample_fracs, dtype=np.float64)
    samp = np.full((n_periods, fr.size, p.N), np.nan)
    samp_v = np.full((n_periods, fr.size, p.N), np.nan)
    samp_modes = np.full((n_periods, fr.size, p.N), -1, dtype=np.int8)
    growth = np.full(n_periods, np.nan)
    stats = np.zeros(N_STATS, dtype=np.int64)
    sy, sv = tangent_scales(p)
    if tangent:
        nrm = np.sqrt(np.sum((state.dy / sy) ** 2 + (state.dv / sv) ** 2))
        if not nrm > 0:
            raise ValueError("tangent=True needs a nonzero tangent vector in the state")
        state.dy /= nrm
        state.dv /= nrm
    status, who, t, n_done = run_periods(
        ChainState(state.y, state.v, state.dy, state.dv, state.modes),
        Integrator(
            p.as_array(),
            h,
            bool(p.smooth),
            bool(tangent),
            bool(saltation),
            sy,
            sv,
            p.velocity_scale,
        ),  # fmt: skip
        Records(
            rec_t0, float(record_dt), rec_y, rec_v, fr, samp, samp_v, samp_modes, growth, stats
        ),
        k0,
        int(n_periods),
    )
    if status != STATUS_OK:
        _raise_status(status, who, t, p, **context)
    state.period = k0 + int(n_periods)
    return {
        "t": rec_t0 + record_dt * np.arange(n_done),
        "y": rec_y[:n_done],
        "v": rec_v[:n_done],
        "samples": samp,
        "samples_v": samp_v,
        "sample_modes": samp_modes,
        "log_growth": growth,
        "stats": dict(zip(STAT_NAMES, stats.tolist(), strict=True)),
    }
