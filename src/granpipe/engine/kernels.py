"""Jitted step loops: velocity Verlet with gravity, walls, neighbour lists, tangent dynamics.

Three tiers (STYLE.md, stumpy): serial per-replica leaves (``_drum_replica``,
``_box_replica``), drivers over a leading replica axis (serial and ``prange``;
each iteration touches only its own replica, so results are bit-identical however
many replicas run side by side), and the Python wrapper in
:mod:`granpipe.engine.simulation`.

Storage (per replica, struct of arrays, float64; indices below): ``vec`` (NV, N, 2)
holds per-disk vectors, ``sca`` (NS, N) per-disk scalars, ``ivec`` (NI, N) per-disk
integers; the neighbour list is CSR (``pair_start``, ``pair_ij[1]``) plus the flat
owner index ``pair_ij[0]`` and per-pair constants ``pair_c``. The step loop
allocates nothing.

One step ``n -> n+1`` (velocity Verlet; forces use half-step velocities, as DEM
codes such as LAMMPS do, so the map is explicit)::

    w      = v_n + (dt/2) F_n / m            (and spins)
    r_n+1  = r_n + dt w
    walls at t_n+1 (positions), t_n+1/2 (velocities); rebuild the list if needed
    F_n+1  = m g + sum of contact forces at (r_n+1, w)
    v_n+1  = w + (dt/2) F_n+1 / m

The tangent step is the exact linearization of this discrete map (drum law):
``dw = dv + (dt/2) dF/m``, ``dr += dt dw``, ``dF = J_r dr + J_v dw`` (walls carry
no perturbation), ``dv = dw + (dt/2) dF/m``; ``(dr, dv, dF)`` is carried between
steps exactly as ``(r, v, F)`` is.

Performance layout (measured on the drum pile and the box crystal with
``benchmarks/engine_passes.py``): the pair forces run in three passes over the flat
pair list — gather the relative coordinates into contiguous rows (four pairs at a time
from the flat position and velocity rows, stored as row vectors:
:func:`granpipe.engine.simd.gather4`), evaluate the contact law on them (a loop LLVM
vectorises: the law leaves are written with selects only), scatter the forces —
because LLVM does not emit hardware gathers here and a fused loop is latency bound.
The scatter is one flat pass too: short per-disk inner loops mispredict their exits
(that cost more than the arithmetic), and the owner's sums stay in registers until its
row ends. The per-disk passes work on flat ``2N`` arrays and reduce flags by integer
counts so that they vectorise; bad states are located only after a flag is raised. The
second half kick of a step is done in the pass of the next step's first kick (same
force, same operations), with the sum behind ``V`` and the displacement test in the same
pass (:func:`granpipe.engine.simd.kick8`); the tangent vector's kicks and the norms
behind lambda likewise share one pass (:func:`_tangent_pass`). Flat-wall contacts are
looked for only among the disks of a near-wall list (:func:`_near_walls`). The
compacted pair pass of dilute states skips groups of four pairs that are all apart
after one four-lane test. With the tangent vector the drum uses instead one fused pass
in two vectorised halves, four pairs at a time (:func:`_drum_pair_pass`,
:mod:`granpipe.engine.simd`; same bits).
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange as numba_prange

from granpipe._jit import njit, pnjit
from granpipe.engine.laws import box_force, box_wall_force, drum_force, drum_force_jvp
from granpipe.engine.layout import (  # noqa: F401 (re-exported: kernels.POS etc.)
    B_D,
    B_DVX,
    B_DVY,
    B_DX,
    B_DY,
    B_E0,
    B_E1,
    B_E2,
    B_E3,
    B_FX,
    B_FY,
    B_G0,
    B_G1,
    B_L,
    B_M,
    B_S,
    B_XI,
    BOTTOM_WALL,
    CELL_ITEMS,
    CELL_OF,
    CONTACT_SUM,
    CONTACTS,
    COUNT_STALE,
    DEEP_OVERLAP,
    FORCE_REBUILD,
    FRC,
    IM2,
    INV_INERTIA,
    INV_MASS,
    IS_WALL,
    LAST_OMEGA,
    LAST_PAIR_CONTACTS,
    LEFT_WALL,
    LIST_OVERFLOW,
    LOG2_SCALE,
    MG,
    MOB2,
    N_PAIRS,
    N_REBUILDS,
    N_WALLS,
    NB,
    NCLOCK,
    NCOUNT,
    NEAR_WALLS,
    NI,
    NONFINITE,
    NPC,
    NS,
    NV,
    OK,
    OVERLAP_FRAC,
    P_DIFF,
    P_LIM,
    P_MEFF,
    P_SUM,
    PAIR_CONTACTS,
    PI,
    PJ,
    PK,
    POS,
    POS_BUILD,
    RADIUS,
    RIGHT_WALL,
    SPIN,
    STEP,
    STEPS_RUN,
    T_FRC,
    T_ORIGIN,
    T_POS,
    T_PREV,
    T_SPIN,
    T_TORQUE,
    T_VEL,
    TANGENT_NONFINITE,
    THETA,
    THETA_BUILD,
    TORQUE,
    VEL,
    WALL_REF,
    WALL_RMAX,
    XI_BOTTOM,
    XI_LEFT,
    XI_RIGHT,
    ZB_NEAR,
)
from granpipe.engine.neighbours import build_pairs, carry_history
from granpipe.engine.simd import (
    BIG,
    drum_back4,
    drum_back4_tail,
    drum_back4_tangent,
    drum_back4_tangent_tail,
    gather4,
    gather4_spins,
    gather4_spins_tail,
    gather4_tail,
    kick8,
    kick8_first,
    kick8_v2,
    pair_front4,
    pair_front4_tail,
    speed2_lanes,
    tangent8,
    tangent8_first,
    tangent8_last,
    touch_bits4,
)
from granpipe.engine.walls import (
    bottom_height,
    bottom_velocity,
    wall_omega,
    wall_torque_factor,
    wall_velocity,
)

# renormalise the tangent vector when |du|² leaves [2^-400, 2^400]; by powers of two (exact)
_RENORM_HI = 2.0**400
_RENORM_LO = 2.0**-400
_RENORM_MAX = 2.0**950
_BIG = BIG  # the bound of simd.kick8


@njit
def _fail(info, status, particle, other, step):
    info[0] = status
    info[1] = particle
    info[2] = other
    info[3] = step
    return status


@njit
def _flat(a):
    """A (N, 2) C-contiguous array as a flat (2N,) view."""
    return a.reshape(a.size)


# --------------------------------------------------------------------------- walls, list


@njit
def _update_wall_disks(vec, sca, walls, n_walls, wd, theta, omega):
    """Place the wall disks at angle ``theta`` with velocities ``omega x (r - c)``."""
    pos = vec[POS]
    vel = vec[VEL]
    ref = vec[WALL_REF]
    spin = sca[SPIN]
    cx = wd[0]
    cy = wd[1]
    c = math.cos(theta)
    s = math.sin(theta)
    for m in range(n_walls):
        i = walls[m]
        rx = ref[i, 0]
        ry = ref[i, 1]
        x = cx + c * rx - s * ry
        y = cy + s * rx + c * ry
        pos[i, 0] = x
        pos[i, 1] = y
        vel[i, 0] = -omega * (y - cy)
        vel[i, 1] = omega * (x - cx)
        spin[i] = omega


@njit
def _pair_constants(sca, pair_start, pair_ij, pair_c, npairs, overlap_frac):
    """Owner index and per-pair constants of a freshly built list (the overlap bound is
    ``overlap_frac`` times the smaller radius)."""
    radius = sca[RADIUS]
    inv_mass = sca[INV_MASS]
    n = pair_start.shape[0] - 1
    pi = pair_ij[0]
    pj = pair_ij[1]
    for i in range(n):
        for k in range(pair_start[i], pair_start[i + 1]):
            pi[k] = i
    for k in range(npairs):
        i = pi[k]
        j = pj[k]
        ai = radius[i]
        aj = radius[j]
        pair_c[P_SUM, k] = ai + aj
        pair_c[P_LIM, k] = overlap_frac * min(ai, aj)
        pair_c[P_MEFF, k] = 1.0 / (inv_mass[i] + inv_mass[j])
        pair_c[P_DIFF, k] = ai - aj


@njit
def _rebuild(
    vec, sca, ivec, skin, pair_start, pair_ij, pair_c, cell_count, cell_start, clock, counters
):
    counters[NEAR_WALLS] = -1  # the cell pass overwrites the near-wall list
    npairs = build_pairs(
        vec[POS],
        sca[RADIUS],
        ivec[IS_WALL],
        skin,
        cell_count,
        cell_start,
        ivec[CELL_ITEMS],
        ivec[CELL_OF],
        pair_start,
        pair_ij[1],
    )
    if npairs < 0:
        return False
    _pair_constants(sca, pair_start, pair_ij, pair_c, npairs, clock[OVERLAP_FRAC])
    p = _flat(vec[POS])
    b = _flat(vec[POS_BUILD])
    for k in range(p.shape[0]):
        b[k] = p[k]
    clock[THETA_BUILD] = clock[THETA]
    counters[N_PAIRS] = npairs
    counters[N_REBUILDS] += 1
    counters[FORCE_REBUILD] = 0
    counters[COUNT_STALE] = 1
    return True


@njit
def _rebuild_with_history(
    vec,
    sca,
    ivec,
    skin,
    pair_start,
    pair_ij,
    pair_c,
    pair_xi,
    old_start,
    old_j,
    old_xi,
    cell_count,
    cell_start,
    clock,
    counters,
):
    n = vec.shape[1]
    npairs = counters[N_PAIRS]
    pj = pair_ij[1]
    for i in range(n + 1):
        old_start[i] = pair_start[i]
    for k in range(npairs):
        old_j[k] = pj[k]
        old_xi[k] = pair_xi[k]
    if not _rebuild(
        vec, sca, ivec, skin, pair_start, pair_ij, pair_c, cell_count, cell_start, clock, counters
    ):
        return False
    if npairs == 0:
        for k in range(counters[N_PAIRS]):
            pair_xi[k] = 0.0
    else:
        carry_history(old_start, old_j, old_xi, pair_start, pj, pair_xi)
    return True


# --------------------------------------------------------------------------- per-disk passes


@njit
def _set_gravity(vec, sca, gx, gy):
    """Gravity force ``m g`` of every mobile disk (zero for walls) into row MG."""
    mg = vec[MG]
    mob = vec[MOB2]
    inv_mass = sca[INV_MASS]
    for i in range(mg.shape[0]):
        m = 1.0 / inv_mass[i] if mob[i, 0] > 0.0 else 0.0
        mg[i, 0] = m * gx
        mg[i, 1] = m * gy


@njit
def _kick_drift(vec, sca, dt, thr, spin_on, finish, want_v2):
    """First half kick and drift (walls too: zero inverse mass, positions reset after).

    With ``finish``, the second half kick of the previous step is done in the same pass
    (it uses the same force: ``v = w + (dt/2) F/m``, then ``w' = v + (dt/2) F/m``, the
    operations of :func:`_final_kick` followed by the first kick), so that the per-disk
    rows are read once per step. Returns ``(moved, v2, bad)``: ``moved`` if some disk is
    now farther than ``thr`` (= skin/2) from where it was at the last list build; for the
    finished step, ``v2`` (sum of ``|v|²`` over mobile disks if ``want_v2``, else 0: the
    sum of :func:`_v2`) and ``bad`` (a non-finite or huge half-step velocity or spin).

    Kicks, drift, ``v2`` and the displacement test are one vectorised pass over groups of
    four disks (:func:`granpipe.engine.simd.kick8`; the remaining disks below, the same
    operations); the tangent vector has its own pass (:func:`_tangent_pass`).
    """
    p = _flat(vec[POS])
    v = _flat(vec[VEL])
    f = _flat(vec[FRC])
    im = _flat(vec[IM2])
    mob = _flat(vec[MOB2])
    b = _flat(vec[POS_BUILD])
    h = 0.5 * dt
    thr2 = thr * thr
    n2 = p.shape[0]
    m8 = n2 - n2 % 8
    m4 = n2 - n2 % 4
    if not finish:
        s0, s1, s2, s3, bad, moved = kick8_first(p, v, f, im, mob, b, h, dt, thr2, m8)
    elif want_v2:
        s0, s1, s2, s3, bad, moved = kick8_v2(p, v, f, im, mob, b, h, dt, thr2, m8)
    else:
        s0, s1, s2, s3, bad, moved = kick8(p, v, f, im, mob, b, h, dt, thr2, m8)
    for k in range(m8, n2):
        a = h * (f[k] * im[k])
        u = v[k] + a
        if finish and want_v2:
            # the lanes of speed2_lanes up to m4, the rest into the first (as in _v2)
            c = u * u * mob[k]
            lane = k % 4 if k < m4 else 0
            if lane == 0:
                s0 += c
            elif lane == 1:
                s1 += c
            elif lane == 2:
                s2 += c
            else:
                s3 += c
        w = u + a if finish else u
        v[k] = w
        p[k] = p[k] + dt * w
        if finish:
            bad += 0 if abs(w) < _BIG else 1
    for i in range(m8 // 2, n2 // 2):
        dx = p[2 * i] - b[2 * i]
        dy = p[2 * i + 1] - b[2 * i + 1]
        moved += 1 if dx * dx + dy * dy > thr2 else 0
    v2 = (s0 + s1) + (s2 + s3)
    if spin_on:
        spin = sca[SPIN]
        trq = sca[TORQUE]
        inv_i = sca[INV_INERTIA]
        if finish:
            for i in range(spin.shape[0]):
                a = h * (trq[i] * inv_i[i])
                w = (spin[i] + a) + a
                spin[i] = w
                bad += 0 if abs(w) < _BIG else 1
        else:
            for i in range(spin.shape[0]):
                spin[i] = spin[i] + h * (trq[i] * inv_i[i])
    return moved > 0, v2, bad > 0


@njit
def _v2(vec, h):
    """``sum |v + h F/m|²`` over mobile disks: the speed after a pending second half kick.

    Four partial sums (lane ``c`` takes components ``k = c mod 4``): a fixed order
    (reproducible) that does not serialise on one add, summed four-wide
    (:func:`granpipe.engine.simd.speed2_lanes`).
    """
    v = _flat(vec[VEL])
    f = _flat(vec[FRC])
    im = _flat(vec[IM2])
    mob = _flat(vec[MOB2])
    m = v.shape[0] - v.shape[0] % 4
    s0, s1, s2, s3 = speed2_lanes(v, f, im, mob, h, m)
    for k in range(m, v.shape[0]):
        u = v[k] + h * (f[k] * im[k])
        s0 += u * u * mob[k]
    return (s0 + s1) + (s2 + s3)


@njit
def _final_kick(vec, sca, dt, spin_on, want_v2):
    """Second half kick; returns (sum |v|² over mobile disks if ``want_v2``, non-finite flag)."""
    v = _flat(vec[VEL])
    f = _flat(vec[FRC])
    im = _flat(vec[IM2])
    h = 0.5 * dt
    v2 = _v2(vec, h) if want_v2 else 0.0
    bad = 0
    for k in range(v.shape[0]):
        w = v[k] + h * (f[k] * im[k])
        v[k] = w
        bad += 0 if abs(w) < _BIG else 1
    if spin_on:
        spin = sca[SPIN]
        trq = sca[TORQUE]
        inv_i = sca[INV_INERTIA]
        for i in range(spin.shape[0]):
            w = spin[i] + h * (trq[i] * inv_i[i])
            spin[i] = w
            bad += 0 if abs(w) < _BIG else 1
    return v2, bad > 0


@njit
def _first_nonfinite(vec, sca):
    """Index of the first mobile disk with a non-finite velocity or spin."""
    vel = vec[VEL]
    spin = sca[SPIN]
    mob = vec[MOB2]
    for i in range(vel.shape[0]):
        if mob[i, 0] > 0.0 and not (abs(vel[i, 0]) + abs(vel[i, 1]) + abs(spin[i]) < _BIG):
            return i
    return -1


@njit
def _tangent_pass(vec, sca, ivec, dt, mode):
    """The tangent vector's per-disk pass; returns ``(num, den, total)``.

    ``mode`` 0: first half kick and drift of the step, ``dw = dv + (dt/2) dF/m``,
    ``dr += dt dw``. ``mode`` 1: first the previous step's second half kick (same
    ``dF``) and its norms, then the kick and drift of mode 0; ``mode`` 2 (end of a
    run): the second half kick and norms only. The norms are of the finished step:
    ``num = |du(t)|²_S`` and ``den = |du(t - dt)|²_S`` with S the disks with at least
    two contacts at that step (walls count), ``total = |du(t)|²`` over mobile disks
    (zero in mode 0). Four disks a group (:func:`granpipe.engine.simd.tangent8`:
    each sum in four lanes over disks ``i = c mod 4``, added in a fixed order, so the
    result does not depend on anything but the state); the remaining disks below.
    """
    tr = _flat(vec[T_POS])
    tv = _flat(vec[T_VEL])
    tf = _flat(vec[T_FRC])
    im = _flat(vec[IM2])
    mob = _flat(vec[MOB2])
    prev = sca[T_PREV]
    contacts = ivec[CONTACTS]
    n = prev.shape[0]
    n4 = n - n % 4
    h = 0.5 * dt
    if mode == 0:
        q = tangent8_first(tr, tv, tf, im, mob, prev, contacts, h, dt, n4)
    elif mode == 1:
        q = tangent8(tr, tv, tf, im, mob, prev, contacts, h, dt, n4)
    else:
        q = tangent8_last(tr, tv, tf, im, mob, prev, contacts, h, dt, n4)
    num = q[0]
    den = q[4]
    total = q[8]
    for i in range(n4, n):
        x = 2 * i
        y = x + 1
        ax = h * (tf[x] * im[x])
        ay = h * (tf[y] * im[y])
        ux = tv[x] + ax
        uy = tv[y] + ay
        if mode != 0:
            qi = (tr[x] * tr[x] + tr[y] * tr[y] + ux * ux + uy * uy) * mob[x]
            s = contacts[i] >= 2
            num += qi if s else 0.0
            den += prev[i] if s else 0.0
            prev[i] = qi
            total += qi
        if mode == 2:
            tv[x] = ux
            tv[y] = uy
        else:
            wx = ux if mode == 0 else ux + ax
            wy = uy if mode == 0 else uy + ay
            tv[x] = wx
            tv[y] = wy
            tr[x] = tr[x] + dt * wx
            tr[y] = tr[y] + dt * wy
    num = (num + q[1]) + (q[2] + q[3])
    den = (den + q[5]) + (q[6] + q[7])
    total = (total + q[9]) + (q[10] + q[11])
    return num, den, total


@njit
def _tangent_done(vec, sca, num, total, info, step, counters):
    """Check a finished step's tangent norms (:func:`_tangent_pass`) and renormalise.

    Returns False (and records the failure at ``step``) on a non-finite vector. The
    renormalisation multiplies ``(dr, dv, dF)`` and the stored norms by a power of two:
    exact, so it commutes with the kick and drift already applied in the same pass.
    """
    if not (total < math.inf):
        _fail(info, TANGENT_NONFINITE, -1, -1, step)
        return False
    # scale by the part that enters lambda (rattlers' components may be far larger or
    # smaller), but never let the whole vector come near overflow
    ref = num if num > 0.0 else total
    if ref > _RENORM_HI or (0.0 < ref < _RENORM_LO) or total > _RENORM_MAX:
        e = int(math.floor(0.5 * math.log2(ref)))
        e = max(e, int(math.ceil(0.5 * math.log2(total))) - 450)
        c = math.ldexp(1.0, -e)
        c2 = c * c
        a = _flat(vec[T_POS])
        b = _flat(vec[T_VEL])
        d = _flat(vec[T_FRC])
        prev = sca[T_PREV]
        for k in range(a.shape[0]):
            a[k] *= c
            b[k] *= c
            d[k] *= c
        for i in range(prev.shape[0]):
            prev[i] *= c2
        counters[LOG2_SCALE] += e
    return True


# --------------------------------------------------------------------------- pair passes


@njit
def _gather(vec, sca, pair_ij, buf, npairs, mode):
    """Relative positions and velocities of every listed pair into contiguous rows.

    ``mode`` 2 adds the two spins (box).
    Four pairs at a time from the flat position and velocity rows, the lanes stored as
    row vectors (:func:`granpipe.engine.simd.gather4`; bit-identical to the scalar
    subtraction).
    """
    pi = pair_ij[PI]
    pj = pair_ij[PJ]
    cap = buf.shape[1]
    rows = buf.reshape(buf.size)
    m4 = npairs - npairs % 4
    p = _flat(vec[POS])
    v = _flat(vec[VEL])
    if mode == 2:
        # the two spins (rows B_E0, B_E1) in the same pass
        w = sca[SPIN]
        at = B_DX * cap
        wat = B_E0 * cap
        for k in range(0, m4, 4):
            gather4_spins(p, v, pi, pj, k, 4, rows, cap, at, w, wat)
        if m4 < npairs:
            gather4_spins_tail(p, v, pi, pj, m4, npairs - m4, rows, cap, at, w, wat)
        return
    for k in range(0, m4, 4):
        gather4(p, v, pi, pj, k, 4, rows, cap, B_DX * cap)
    if m4 < npairs:
        gather4_tail(p, v, pi, pj, m4, npairs - m4, rows, cap, B_DX * cap)


@njit
def _drum_pairs(buf, ssum, slim, touch, law, npairs):
    """Drum-law force of every listed pair (zero if apart). Returns (contacts, bad)."""
    k_n = law[0]
    g_n = law[1]
    g_t = law[2]
    mu = law[3]
    dxa = buf[B_DX]
    dya = buf[B_DY]
    dvx = buf[B_DVX]
    dvy = buf[B_DVY]
    fxa = buf[B_FX]
    fya = buf[B_FY]
    ncon = 0
    nbad = 0
    for k in range(npairs):
        dx = dxa[k]
        dy = dya[k]
        s = ssum[k]
        r2 = dx * dx + dy * dy
        r = math.sqrt(r2)
        inv_r = 1.0 / r
        delta = r - s
        fx, fy, f_n, f_t, regime = drum_force(
            dx * inv_r, dy * inv_r, delta, dvx[k], dvy[k], k_n, g_n, g_t, mu
        )
        t = r2 <= s * s
        fxa[k] = fx if t else 0.0
        fya[k] = fy if t else 0.0
        touch[k] = 1 if t else 0
        ncon += 1 if t else 0
        nbad += 1 if -delta > slim[k] else 0
    return ncon, nbad > 0


@njit
def _drum_pairs_tangent(buf, ssum, slim, touch, law, npairs):
    """Drum-law forces and their perturbation ``J . (dd, dv)`` for every listed pair."""
    k_n = law[0]
    g_n = law[1]
    g_t = law[2]
    mu = law[3]
    dxa = buf[B_DX]
    dya = buf[B_DY]
    dvx = buf[B_DVX]
    dvy = buf[B_DVY]
    ex = buf[B_E0]
    ey = buf[B_E1]
    evx = buf[B_E2]
    evy = buf[B_E3]
    fxa = buf[B_FX]
    fya = buf[B_FY]
    gxa = buf[B_G0]
    gya = buf[B_G1]
    ncon = 0
    nbad = 0
    nchanged = 0
    for k in range(npairs):
        dx = dxa[k]
        dy = dya[k]
        s = ssum[k]
        r2 = dx * dx + dy * dy
        r = math.sqrt(r2)
        inv_r = 1.0 / r
        nx = dx * inv_r
        ny = dy * inv_r
        delta = r - s
        vx = dvx[k]
        vy = dvy[k]
        fx, fy, f_n, f_t, regime = drum_force(nx, ny, delta, vx, vy, k_n, g_n, g_t, mu)
        gx, gy = drum_force_jvp(
            nx,
            ny,
            inv_r,
            vx,
            vy,
            f_n,
            f_t,
            regime,
            ex[k],
            ey[k],
            evx[k],
            evy[k],
            k_n,
            g_n,
            g_t,
            mu,
        )
        t = r2 <= s * s
        fxa[k] = fx if t else 0.0
        fya[k] = fy if t else 0.0
        gxa[k] = gx if t else 0.0
        gya[k] = gy if t else 0.0
        c = 1 if t else 0
        nchanged += 1 if touch[k] != c else 0
        touch[k] = c
        ncon += c
        nbad += 1 if -delta > slim[k] else 0
    return ncon, nbad > 0, nchanged > 0


@njit
def _box_pairs(buf, ssum, slim, smeff, sdiff, pair_xi, touch, law, dt_hist, npairs):
    """Box-law force and torques of every listed pair; advances (or resets) histories."""
    kap_n = law[0]
    kap_t = law[1]
    g_n = law[2]
    g_t = law[3]
    mu = law[4]
    dxa = buf[B_DX]
    dya = buf[B_DY]
    dvx = buf[B_DVX]
    dvy = buf[B_DVY]
    wia = buf[B_E0]
    wja = buf[B_E1]
    fxa = buf[B_FX]
    fya = buf[B_FY]
    tia = buf[B_G0]
    tja = buf[B_G1]
    ncon = 0
    nbad = 0
    for k in range(npairs):
        dx = dxa[k]
        dy = dya[k]
        s = ssum[k]
        r2 = dx * dx + dy * dy
        r = math.sqrt(r2)
        inv_r = 1.0 / r
        overlap = s - r
        diff = sdiff[k]
        fx, fy, tau_i, tau_j, xi_new, f_n, f_t, slip = box_force(
            dx * inv_r,
            dy * inv_r,
            overlap,
            0.5 * (r + diff),
            0.5 * (r - diff),
            dvx[k],
            dvy[k],
            wia[k],
            wja[k],
            smeff[k],
            pair_xi[k],
            dt_hist,
            kap_n,
            kap_t,
            g_n,
            g_t,
            mu,
        )
        t = r2 <= s * s
        fxa[k] = fx if t else 0.0
        fya[k] = fy if t else 0.0
        tia[k] = tau_i if t else 0.0
        tja[k] = tau_j if t else 0.0
        pair_xi[k] = xi_new if t else 0.0
        touch[k] = 1 if t else 0
        ncon += 1 if t else 0
        nbad += 1 if overlap > slim[k] else 0
    return ncon, nbad > 0


@njit
def _scatter(vec, sca, ivec, pair_start, pair_ij, buf, touch, torques, recount):
    """Add the pair forces (and torques) to the disks; with ``recount``, count each disk's
    touching pairs into ``PAIR_CONTACTS``.

    One flat pass over the half list (no short inner loops whose exits mispredict): the
    partner's sums go to memory pair by pair, the owner's stay in registers until its row
    ends (consecutive pairs share the owner, and adding to its memory pair by pair would
    chain store-to-load forwarding). Every disk's sum runs in the order of the list.
    """
    f = _flat(vec[FRC])
    mg = _flat(vec[MG])
    for k in range(f.shape[0]):
        f[k] = mg[k]
    n = pair_start.shape[0] - 1
    npairs = pair_start[n]
    pi = pair_ij[PI]
    pj = pair_ij[PJ]
    fx = buf[B_FX]
    fy = buf[B_FY]
    g0 = buf[B_G0]
    g1 = buf[B_G1]
    two = np.uint32(2)
    one = np.uint32(1)
    trq = sca[TORQUE]
    if torques:
        for i in range(n):
            trq[i] = 0.0
    if npairs > 0:
        prev = pi[0]
        ax = 0.0
        ay = 0.0
        bx = 0.0
        if torques:
            for k in range(npairs):
                i = pi[k]
                j = pj[k]
                j2 = two * j
                a = fx[k]
                b = fy[k]
                c = g0[k]
                f[j2] -= a
                f[j2 + one] -= b
                trq[j] += g1[k]
                if i != prev:
                    p2 = two * prev
                    f[p2] += ax
                    f[p2 + one] += ay
                    trq[prev] += bx
                    ax = 0.0
                    ay = 0.0
                    bx = 0.0
                ax += a
                ay += b
                bx += c
                prev = i
            trq[prev] += bx
        else:
            for k in range(npairs):
                i = pi[k]
                j2 = two * pj[k]
                a = fx[k]
                b = fy[k]
                f[j2] -= a
                f[j2 + one] -= b
                if i != prev:
                    p2 = two * prev
                    f[p2] += ax
                    f[p2 + one] += ay
                    ax = 0.0
                    ay = 0.0
                ax += a
                ay += b
                prev = i
        p2 = two * prev
        f[p2] += ax
        f[p2 + one] += ay
    if recount:
        _recount(ivec, pair_ij, touch, npairs)


@njit
def _recount(ivec, pair_ij, touch, npairs):
    """Count each disk's touching listed pairs into ``PAIR_CONTACTS``."""
    pi = pair_ij[PI]
    pj = pair_ij[PJ]
    pc = ivec[PAIR_CONTACTS]
    for i in range(pc.shape[0]):
        pc[i] = 0
    if npairs > 0:
        prev = pi[0]
        ci = 0
        for k in range(npairs):
            i = pi[k]
            c = touch[k]
            pc[pj[k]] += c
            if i != prev:
                pc[prev] += ci
                ci = 0
            ci += c
            prev = i
        pc[prev] += ci


@njit
def _first_deep_pair(pair_ij, buf, ssum, slim, npairs, compact):
    """First evaluated pair whose overlap exceeds its bound (called after a flag was raised)."""
    for q in range(npairs):
        dx = buf[B_DX, q]
        dy = buf[B_DY, q]
        r = math.sqrt(dx * dx + dy * dy)
        if ssum[q] - r > slim[q]:
            k = pair_ij[PK, q] if compact else q
            return pair_ij[PI, k], pair_ij[PJ, k]
    return -1, -1


@njit
def _drum_pair_pass(vec, pair_ij, pair_c, buf, touch, law, npairs, tangent, pc):
    """Drum-law forces (and perturbations) of all listed pairs, added to ``FRC`` (``T_FRC``)
    over gravity; returns ``(touching pairs, some pair too deep, some touch flag changed)``.

    Each touch flag that changes moves the per-disk counts of touching pairs ``pc``
    (``ivec[PAIR_CONTACTS]``) of its two disks by one, so that counts that were right
    before the pass are right after it without a recount (a few flags change per step;
    the recount, timed alone, was ~1.4 ns per mobile disk of the drum pile).

    Two vectorised halves, four pairs at a time (:mod:`granpipe.engine.simd`): the
    geometry (relative positions and velocities, ``r``, normal; bound by the square root
    and division), then the law and the scatter. Same arithmetic and summation order as the separate
    gather, law and scatter passes (:func:`_gather`, :func:`_drum_pairs`,
    :func:`_scatter`), so the same bits.
    """
    f = _flat(vec[FRC])
    mg = _flat(vec[MG])
    tf = _flat(vec[T_FRC])
    for k in range(f.shape[0]):
        f[k] = mg[k]
    if tangent:
        for k in range(tf.shape[0]):
            tf[k] = 0.0
    p = _flat(vec[POS])
    v = _flat(vec[VEL])
    tp = _flat(vec[T_POS]) if tangent else p[:0]
    tv = _flat(vec[T_VEL]) if tangent else v[:0]
    pi = pair_ij[PI]
    pj = pair_ij[PJ]
    ssum = pair_c[P_SUM]
    slim = pair_c[P_LIM]
    cap = buf.shape[1]
    rows = buf.reshape(buf.size)
    m4 = npairs - npairs % 4
    ncon = 0
    nbad = 0
    nchanged = 0
    for k in range(0, npairs, 4):
        if k < m4:
            c = pair_front4(p, v, tp, tv, pi, pj, k, 4, ssum, slim, touch, rows, cap)
        else:
            nv = npairs - k
            c = pair_front4_tail(p, v, tp, tv, pi, pj, k, nv, ssum, slim, touch, rows, cap)
        ncon += c & 7
        nbad += (c >> 3) & 7
        changed = c >> 6
        if changed != 0:
            nchanged += 1
            for lane in range(4):
                if (changed >> lane) & 1:
                    q = k + lane
                    d = 1 if touch[q] != 0 else -1
                    pc[pi[q]] += d
                    pc[pj[q]] += d
    if npairs == 0:
        return 0, False, False
    prev = np.int64(pi[0])
    ax = 0.0
    ay = 0.0
    bx = 0.0
    by = 0.0
    for k in range(0, m4, 4):
        if tangent:
            prev, ax, ay, bx, by = drum_back4_tangent(
                rows, cap, k, 4, f, tf, pi, pj, touch, law, prev, ax, ay, bx, by
            )
        else:
            prev, ax, ay, bx, by = drum_back4(
                rows, cap, k, 4, f, tf, pi, pj, touch, law, prev, ax, ay, bx, by
            )
    if m4 < npairs:
        nv = npairs - m4
        if tangent:
            prev, ax, ay, bx, by = drum_back4_tangent_tail(
                rows, cap, m4, nv, f, tf, pi, pj, touch, law, prev, ax, ay, bx, by
            )
        else:
            prev, ax, ay, bx, by = drum_back4_tail(
                rows, cap, m4, nv, f, tf, pi, pj, touch, law, prev, ax, ay, bx, by
            )
    f[2 * prev] += ax
    f[2 * prev + 1] += ay
    if tangent:
        tf[2 * prev] += bx
        tf[2 * prev + 1] += by
    return ncon, nbad > 0, nchanged > 0


@njit
def _gather_compact(vec, sca, pair_ij, pair_c, pair_xi, buf, npairs, mode):
    """Like :func:`_gather`, keeping only touching pairs (with their constants and history).

    Non-touching pairs of the box law lose their history here. Returns their count m; the
    buffers hold m entries and ``pair_ij[PK, :m]`` their pair indices. Groups of four
    listed pairs that are all apart are skipped after one four-lane test
    (:func:`granpipe.engine.simd.touch_bits4`; in a dilute state most are, and a branch
    per pair mispredicts on the few that touch).
    """
    p = _flat(vec[POS])
    v = _flat(vec[VEL])
    tr = _flat(vec[T_POS])
    tv = _flat(vec[T_VEL])
    spin = sca[SPIN]
    pi = pair_ij[PI]
    pj = pair_ij[PJ]
    ssum = pair_c[P_SUM]
    m = 0
    m4 = npairs - npairs % 4
    for g in range(0, m4, 4):
        if touch_bits4(p, pi, pj, g, ssum) == 0:
            if mode == 2:
                for k in range(g, g + 4):
                    pair_xi[k] = 0.0
            continue
        for k in range(g, g + 4):
            m = _compact_pair(p, v, tr, tv, spin, pair_ij, pair_c, pair_xi, buf, k, m, mode)
    for k in range(m4, npairs):
        m = _compact_pair(p, v, tr, tv, spin, pair_ij, pair_c, pair_xi, buf, k, m, mode)
    return m


@njit
def _compact_pair(p, v, tr, tv, spin, pair_ij, pair_c, pair_xi, buf, k, m, mode):
    """Listed pair ``k`` into entry ``m`` of the compacted buffers if it touches (else, box
    law, its history is dropped); returns the new count."""
    i = pair_ij[PI, k]
    j = pair_ij[PJ, k]
    two = np.uint32(2)
    one = np.uint32(1)
    i2 = two * i
    j2 = two * j
    x = p[i2] - p[j2]
    y = p[i2 + one] - p[j2 + one]
    s = pair_c[P_SUM, k]
    if x * x + y * y > s * s:
        if mode == 2:
            pair_xi[k] = 0.0
        return m
    buf[B_DX, m] = x
    buf[B_DY, m] = y
    buf[B_DVX, m] = v[i2] - v[j2]
    buf[B_DVY, m] = v[i2 + one] - v[j2 + one]
    buf[B_S, m] = s
    buf[B_L, m] = pair_c[P_LIM, k]
    if mode == 1:
        buf[B_E0, m] = tr[i2] - tr[j2]
        buf[B_E1, m] = tr[i2 + one] - tr[j2 + one]
        buf[B_E2, m] = tv[i2] - tv[j2]
        buf[B_E3, m] = tv[i2 + one] - tv[j2 + one]
    elif mode == 2:
        buf[B_E0, m] = spin[i]
        buf[B_E1, m] = spin[j]
        buf[B_M, m] = pair_c[P_MEFF, k]
        buf[B_D, m] = pair_c[P_DIFF, k]
        buf[B_XI, m] = pair_xi[k]
    pair_ij[PK, m] = k
    return m + 1


@njit
def _scatter_compact(vec, sca, ivec, pair_ij, buf, pair_xi, m, tangent, torques, recount):
    """:func:`_scatter` over the m compacted (touching) pairs; writes box histories back."""
    f = _flat(vec[FRC])
    mg = _flat(vec[MG])
    for k in range(f.shape[0]):
        f[k] = mg[k]
    pi = pair_ij[PI]
    pj = pair_ij[PJ]
    pk = pair_ij[PK]
    fx = buf[B_FX]
    fy = buf[B_FY]
    g0 = buf[B_G0]
    g1 = buf[B_G1]
    two = np.uint32(2)
    one = np.uint32(1)
    contacts = ivec[PAIR_CONTACTS]
    trq = sca[TORQUE]
    tf = _flat(vec[T_FRC])
    if recount:
        for i in range(contacts.shape[0]):
            contacts[i] = 0
    if tangent:
        for k in range(tf.shape[0]):
            tf[k] = 0.0
    if torques:
        for i in range(trq.shape[0]):
            trq[i] = 0.0
    for q in range(m):
        k = pk[q]
        i = pi[k]
        j = pj[k]
        i2 = two * i
        j2 = two * j
        a = fx[q]
        b = fy[q]
        f[i2] += a
        f[i2 + one] += b
        f[j2] -= a
        f[j2 + one] -= b
        if tangent:
            a = g0[q]
            b = g1[q]
            tf[i2] += a
            tf[i2 + one] += b
            tf[j2] -= a
            tf[j2 + one] -= b
        if torques:
            trq[i] += g0[q]
            trq[j] += g1[q]
            pair_xi[k] = buf[B_XI, q]
        if recount:
            contacts[i] += 1
            contacts[j] += 1


# --------------------------------------------------------------------------- flat walls


@njit
def _wall_gap(w, pos, i, fw, zb):
    """Distance from disk ``i``'s centre to flat wall ``w`` (0 left, 1 right, 2 bottom)."""
    if w == 0:
        return pos[i, 0] - fw[1]
    if w == 1:
        return fw[3] - pos[i, 0]
    return pos[i, 1] - zb


@njit
def _wall_overlap(w, pos, i, fw, zb, ai):
    """Overlap ``a_i - gap`` of disk ``i`` with flat wall ``w``; negative if apart or absent."""
    if fw[2 * w] == 0.0:
        return -1.0
    return ai - _wall_gap(w, pos, i, fw, zb)


@njit
def _wall_normal(w):
    """Unit normal of flat wall ``w`` pointing into the box."""
    return (1.0 if w == 0 else (-1.0 if w == 1 else 0.0)), (1.0 if w == 2 else 0.0)


@njit
def _near_walls(vec, sca, ivec, fw, zb, skin, reset, clock, counters):
    """List in ``ivec[CELL_ITEMS]`` the mobile disks within ``2 skin`` of touching a flat
    wall (ascending); zero the wall shear histories of the others (with ``reset``).

    The list is rebuilt with the neighbour list and when the bottom has moved more than
    ``skin/2`` since: until then a disk has moved at most ``skin`` from where it was
    listed (each less than ``skin/2`` from its place at the list build) and the bottom at
    most ``skin/2``, so a disk not listed cannot touch a wall, and its history is zero.
    """
    p = _flat(vec[POS])
    mob = _flat(vec[MOB2])
    radius = sca[RADIUS]
    near = ivec[CELL_ITEMS]
    x_left = fw[1] if fw[0] != 0.0 else -_BIG
    x_right = fw[3] if fw[2] != 0.0 else _BIG
    z_bottom = zb if fw[4] != 0.0 else -_BIG
    margin = 2.0 * skin
    m = 0
    for i in range(radius.shape[0]):
        x = p[2 * i]
        y = p[2 * i + 1]
        a = radius[i] + margin
        if mob[2 * i] != 0.0 and (x - x_left <= a or x_right - x <= a or y - z_bottom <= a):
            near[m] = i
            m += 1
        elif reset:
            sca[XI_LEFT, i] = 0.0
            sca[XI_RIGHT, i] = 0.0
            sca[XI_BOTTOM, i] = 0.0
    counters[NEAR_WALLS] = m
    clock[ZB_NEAR] = zb


@njit
def _wall_candidates(vec, sca, ivec, fw, zb, reset, nnear, out, info, step, overlap_frac):
    """Disks of the near-wall list (``nnear`` in ``ivec[CELL_ITEMS]``) touching at least one
    flat wall, listed in ``out``; returns how many, or -1 (recorded in ``info``) if one
    overlaps a wall by more than ``overlap_frac`` times its radius.

    One pass for all three walls (an absent wall sits at infinity). With ``reset``, the
    shear history against each wall (``sca[XI_LEFT + w]``) of the listed disks not
    touching it is zeroed. Most disks touch no wall, so the branch is well predicted and
    the contact loops only see the touching disks.
    """
    pos = vec[POS]
    p = _flat(vec[POS])
    radius = sca[RADIUS]
    near = ivec[CELL_ITEMS]
    xi_l = sca[XI_LEFT]
    xi_r = sca[XI_RIGHT]
    xi_b = sca[XI_BOTTOM]
    x_left = fw[1] if fw[0] != 0.0 else -_BIG
    x_right = fw[3] if fw[2] != 0.0 else _BIG
    z_bottom = zb if fw[4] != 0.0 else -_BIG
    m = 0
    for q in range(nnear):
        i = near[q]
        x = p[2 * i]
        y = p[2 * i + 1]
        a = radius[i]
        t_l = x - x_left <= a
        t_r = x_right - x <= a
        t_b = y - z_bottom <= a
        if reset:
            xi_l[i] = xi_l[i] if t_l else 0.0
            xi_r[i] = xi_r[i] if t_r else 0.0
            xi_b[i] = xi_b[i] if t_b else 0.0
        if t_l | t_r | t_b:
            for w in range(3):
                if _wall_overlap(w, pos, i, fw, zb, a) > overlap_frac * a:
                    _fail(info, DEEP_OVERLAP, i, -1 - w, step)
                    return -1
            out[m] = i
            m += 1
    return m


@njit
def _flat_walls(law_id, vec, sca, ivec, law, fw, zb, vb, tangent, dt_hist, count, info, step, near):
    """Contacts of the disks with the flat walls under the drum law (``law_id`` 0, with the
    tangent perturbation if ``tangent``) or the box law (1: per-disk shear histories
    advanced by ``dt_hist``, torques). Returns the contact count, or -1 (bad state).

    ``near`` is ``(skin, clock, counters)``: the disks tested are those of the near-wall
    list (:func:`_near_walls`, rebuilt here when stale).
    """
    pos = vec[POS]
    vel = vec[VEL]
    frc = vec[FRC]
    tr = vec[T_POS]
    tv = vec[T_VEL]
    tf = vec[T_FRC]
    radius = sca[RADIUS]
    inv_mass = sca[INV_MASS]
    spin = sca[SPIN]
    trq = sca[TORQUE]
    contacts = ivec[CONTACTS]
    ncon = 0
    cand = ivec[CELL_OF]  # scratch between list builds
    skin, clock, counters = near
    if counters[NEAR_WALLS] < 0:
        _near_walls(vec, sca, ivec, fw, zb, skin, law_id == 1, clock, counters)
    m = _wall_candidates(
        vec,
        sca,
        ivec,
        fw,
        zb,
        law_id == 1,
        counters[NEAR_WALLS],
        cand,
        info,
        step,
        clock[OVERLAP_FRAC],
    )
    if m < 0:
        return -1
    for q in range(m):
        i = cand[q]
        ai = radius[i]
        for w in range(3):
            overlap = _wall_overlap(w, pos, i, fw, zb, ai)
            if overlap < 0.0:
                continue
            nx, ny = _wall_normal(w)
            vx = vel[i, 0]
            vy = vel[i, 1] - wall_velocity(fw, w, vb)
            if law_id == 0:
                fx, fy, f_n, f_t, regime = drum_force(
                    nx, ny, -overlap, vx, vy, law[0], law[1], law[2], law[3]
                )
                if tangent:
                    dfx, dfy = drum_force_jvp(
                        nx,
                        ny,
                        0.0,
                        vx,
                        vy,
                        f_n,
                        f_t,
                        regime,
                        tr[i, 0],
                        tr[i, 1],
                        tv[i, 0],
                        tv[i, 1],
                        law[0],
                        law[1],
                        law[2],
                        law[3],
                    )
                    tf[i, 0] += dfx
                    tf[i, 1] += dfy
            else:
                xi_w = sca[XI_LEFT + w]
                fx, fy, tau_i, tau_j, xi_new, f_n, f_t, slip = box_wall_force(
                    nx,
                    ny,
                    overlap,
                    ai,
                    vx,
                    vy,
                    spin[i],
                    1.0 / inv_mass[i],
                    xi_w[i],
                    dt_hist,
                    law[0],
                    law[1],
                    law[2],
                    law[3],
                    law[5] if w == 2 else law[6],
                )
                xi_w[i] = xi_new
                trq[i] += tau_i * wall_torque_factor(fw)
            frc[i, 0] += fx
            frc[i, 1] += fy
            ncon += 1
            if count:
                contacts[i] += 1
    return ncon


@njit
def _count_contacts(vec, sca, ivec, pair_ij, pair_c, npairs, fw, zb):
    """Contact counts at the current positions (those of the last force evaluation), by the
    same test as the force passes (``r² <= (a_i + a_j)²``), flat walls included."""
    contacts = ivec[CONTACTS]
    p = _flat(vec[POS])
    pos = vec[POS]
    mob = vec[MOB2]
    radius = sca[RADIUS]
    pi = pair_ij[PI]
    pj = pair_ij[PJ]
    ssum = pair_c[P_SUM]
    two = np.uint32(2)
    one = np.uint32(1)
    for i in range(contacts.shape[0]):
        contacts[i] = 0
    for k in range(npairs):
        i = pi[k]
        j = pj[k]
        x = p[two * i] - p[two * j]
        y = p[two * i + one] - p[two * j + one]
        s = ssum[k]
        c = 1 if x * x + y * y <= s * s else 0
        contacts[i] += c
        contacts[j] += c
    for w in range(3):
        if fw[2 * w] == 0.0:
            continue
        for i in range(pos.shape[0]):
            if mob[i, 0] != 0.0 and _wall_gap(w, pos, i, fw, zb) <= radius[i]:
                contacts[i] += 1


# --------------------------------------------------------------------------- one replica


@njit
def _time(clock, counters, dt):
    return clock[T_ORIGIN] + counters[STEP] * dt


@njit
def _bottom(fw, t):
    """Height and velocity of the flat bottom at time ``t`` (0, 0 without one)."""
    if fw[4] == 0.0:
        return 0.0, 0.0
    return bottom_height(fw, t), bottom_velocity(fw, t)


@njit
def _advance_walls(vec, sca, walls, wd, fw, clock, counters, dt, half_skin):
    """Move the walls over the step that starts now; returns (walls moved far, z_b, v_b)."""
    t0 = _time(clock, counters, dt)
    t1 = clock[T_ORIGIN] + (counters[STEP] + 1) * dt
    moved = False
    n_walls = counters[N_WALLS]
    if n_walls > 0:
        omega = wall_omega(wd, t0 + 0.5 * dt)
        if omega != 0.0 or clock[LAST_OMEGA] != 0.0:
            clock[THETA] += omega * dt
            _update_wall_disks(vec, sca, walls, n_walls, wd, clock[THETA], omega)
            clock[LAST_OMEGA] = omega
            # a wall disk at distance R has moved by at most R |theta - theta_build|
            moved = clock[WALL_RMAX] * abs(clock[THETA] - clock[THETA_BUILD]) > half_skin
    zb = 0.0
    vb = 0.0
    if fw[4] != 0.0:
        zb = bottom_height(fw, t1)
        vb = bottom_velocity(fw, t0 + 0.5 * dt)
        if abs(zb - clock[ZB_NEAR]) > half_skin:
            counters[NEAR_WALLS] = -1
    return moved, zb, vb


@njit
def _contact_counts_done(ivec, counters, count, valid, compact):
    """Copy pair-contact counts into CONTACTS (flat walls add theirs next); keep track of
    whether the stored counts (``valid``: recounted or kept by the pass) and touch flags
    still match the list."""
    if count:
        pc = ivec[PAIR_CONTACTS]
        contacts = ivec[CONTACTS]
        for i in range(pc.shape[0]):
            contacts[i] = pc[i]
    # compacted passes index the touch flags by compact position, not by pair
    counters[COUNT_STALE] = 0 if (valid and not compact) else 1


@njit
def _has_flat(fw):
    return fw[0] != 0.0 or fw[2] != 0.0 or fw[4] != 0.0


@njit
def _drum_forces(
    vec,
    sca,
    ivec,
    law,
    fw,
    zb,
    vb,
    pair_start,
    pair_ij,
    pair_c,
    buf,
    touch,
    counters,
    skin,
    clock,
    tangent,
    count,
    info,
    step,
):
    """All drum-law forces of one evaluation; returns the contact count or -1 (bad).

    The law runs on all listed pairs, or only on the touching ones (compacted first) when
    fewer than half of them touched at the previous evaluation; the results are the same.
    """
    npairs = counters[N_PAIRS]
    compact = 2 * counters[LAST_PAIR_CONTACTS] < npairs
    kept = False
    if compact:
        m = _gather_compact(vec, sca, pair_ij, pair_c, buf[B_XI], buf, npairs, 1 if tangent else 0)
        ssum = buf[B_S]
        slim = buf[B_L]
        if tangent:
            ncon, bad, changed = _drum_pairs_tangent(buf, ssum, slim, touch, law, m)
        else:
            ncon, bad = _drum_pairs(buf, ssum, slim, touch, law, m)
            changed = True
    elif tangent:
        # the fused four-lane pass: measured faster than separate passes with the tangent
        # vector (~6 %), slower without it (docs/engine_performance.md)
        m = npairs
        ssum = pair_c[P_SUM]
        slim = pair_c[P_LIM]
        # the pass moves the per-disk counts flag by flag: right if they were right before
        kept = counters[COUNT_STALE] == 0
        ncon, bad, changed = _drum_pair_pass(
            vec, pair_ij, pair_c, buf, touch, law, m, True, ivec[PAIR_CONTACTS]
        )
        if bad:  # the fused pass keeps no relative positions: gather them to find the pair
            _gather(vec, sca, pair_ij, buf, m, 0)
    else:
        m = npairs
        ssum = pair_c[P_SUM]
        slim = pair_c[P_LIM]
        _gather(vec, sca, pair_ij, buf, m, 0)
        ncon, bad = _drum_pairs(buf, ssum, slim, touch, law, m)
        changed = True
    if bad:
        i, j = _first_deep_pair(pair_ij, buf, ssum, slim, m, compact)
        _fail(info, DEEP_OVERLAP, i, j, step)
        return -1
    # per-disk counts of touching pairs are redone only if some pair's flag changed (and
    # the pass did not move them itself)
    recount = count and (compact or counters[COUNT_STALE] != 0 or (changed and not kept))
    if compact:
        _scatter_compact(vec, sca, ivec, pair_ij, buf, buf[B_XI], m, tangent, False, recount)
    elif not tangent:
        _scatter(vec, sca, ivec, pair_start, pair_ij, buf, touch, False, recount)
    elif recount:
        _recount(ivec, pair_ij, touch, m)
    _contact_counts_done(ivec, counters, count, recount or kept, compact)
    counters[LAST_PAIR_CONTACTS] = ncon
    if _has_flat(fw):
        near = (skin, clock, counters)
        nw = _flat_walls(0, vec, sca, ivec, law, fw, zb, vb, tangent, 0.0, count, info, step, near)
        if nw < 0:
            return -1
        ncon += nw
    return ncon


@njit
def _box_forces(
    vec,
    sca,
    ivec,
    law,
    fw,
    zb,
    vb,
    dt_hist,
    pair_start,
    pair_ij,
    pair_c,
    pair_xi,
    buf,
    touch,
    counters,
    skin,
    clock,
    count,
    info,
    step,
):
    """All box-law forces and torques of one evaluation; contact count or -1 (bad).

    Compacted like :func:`_drum_forces` when few listed pairs touch.
    """
    npairs = counters[N_PAIRS]
    compact = 2 * counters[LAST_PAIR_CONTACTS] < npairs
    if compact:
        m = _gather_compact(vec, sca, pair_ij, pair_c, pair_xi, buf, npairs, 2)
        ssum = buf[B_S]
        slim = buf[B_L]
        ncon, bad = _box_pairs(
            buf, ssum, slim, buf[B_M], buf[B_D], buf[B_XI], touch, law, dt_hist, m
        )
    else:
        m = npairs
        _gather(vec, sca, pair_ij, buf, npairs, 2)
        ssum = pair_c[P_SUM]
        slim = pair_c[P_LIM]
        ncon, bad = _box_pairs(
            buf, ssum, slim, pair_c[P_MEFF], pair_c[P_DIFF], pair_xi, touch, law, dt_hist, m
        )
    if bad:
        i, j = _first_deep_pair(pair_ij, buf, ssum, slim, m, compact)
        _fail(info, DEEP_OVERLAP, i, j, step)
        return -1
    if compact:
        _scatter_compact(vec, sca, ivec, pair_ij, buf, pair_xi, m, False, True, count)
    else:
        _scatter(vec, sca, ivec, pair_start, pair_ij, buf, touch, True, count)
    _contact_counts_done(ivec, counters, count, count, compact)
    counters[LAST_PAIR_CONTACTS] = ncon
    if _has_flat(fw):
        near = (skin, clock, counters)
        nw = _flat_walls(
            1, vec, sca, ivec, law, fw, zb, vb, False, dt_hist, count, info, step, near
        )
        if nw < 0:
            return -1
        ncon += nw
    return ncon


@njit
def _at(st, r):
    """Replica ``r`` of the storage tuple ``st``: the arrays of
    :data:`granpipe.engine.layout.STORAGE` (``vec, sca, ivec, walls, pair_start,
    pair_ij, pair_c, pair_xi, pair_dxi, old_start, old_j, old_xi, old_dxi, buf, touch,
    cell_count, cell_start, clock, counters``), each with a leading replica axis."""
    return (
        st[0][r],
        st[1][r],
        st[2][r],
        st[3][r],
        st[4][r],
        st[5][r],
        st[6][r],
        st[7][r],
        st[8][r],
        st[9][r],
        st[10][r],
        st[11][r],
        st[12][r],
        st[13][r],
        st[14][r],
        st[15][r],
        st[16][r],
        st[17][r],
        st[18][r],
    )


# block accumulators of a run (float64 (_NBLK,)): sum of V, steps in the block, sum of
# lambda, steps where lambda is defined, index of the next block
_V_SUM, _IN_BLOCK, _LAM_SUM, _LAM_N, _BLOCK = range(5)
_NBLK = 5


@njit
def _block_means(v2, stride, blk, out_speed, out_nlam, out_lam):
    """Add a finished step's ``V = sqrt(v2)`` to the block; every ``stride`` steps write the
    block means of ``V`` (and of lambda if ``out_lam`` is not empty) and start a new one."""
    blk[_V_SUM] += math.sqrt(v2)
    blk[_IN_BLOCK] += 1.0
    if blk[_IN_BLOCK] == stride:
        b = int(blk[_BLOCK])
        out_speed[b] = blk[_V_SUM] / stride
        if out_lam.shape[0] > 0:
            lam_n = int(blk[_LAM_N])
            out_nlam[b] = lam_n
            out_lam[b] = blk[_LAM_SUM] / lam_n if lam_n > 0 else np.nan
        blk[:] = 0.0
        blk[_BLOCK] = b + 1


@njit
def _end_run(vec, sca, dt, spin_on, stride, blk, out_speed, out_nlam, out_lam, info, counters):
    """The last step's second half kick (pending in the step loop) and its block means."""
    v2, bad = _final_kick(vec, sca, dt, spin_on, stride > 0)
    if bad:
        return _fail(info, NONFINITE, _first_nonfinite(vec, sca), -1, counters[STEP])
    if stride > 0:
        _block_means(v2, stride, blk, out_speed, out_nlam, out_lam)
    return OK


@njit
def _lambda_step(vec, sca, num, den, total, dt, blk, info, step, counters):
    """A finished step's ``lambda = (1/2dt) ln(num/den)`` into the block (where defined);
    False on a non-finite tangent vector (:func:`_tangent_done`)."""
    if not _tangent_done(vec, sca, num, total, info, step, counters):
        return False
    if num > 0.0 and den > 0.0:
        blk[_LAM_SUM] += 0.5 * math.log(num / den) / dt
        blk[_LAM_N] += 1.0
    return True


@njit
def _drum_replica(
    n_steps, stride, tangent, dt, g, law, wd, fw, skin, st, out_lam, out_nlam, out_speed, info
):
    """Advance one replica ``n_steps`` under the drum law (optionally with its tangent vector).

    Records, when ``stride > 0``, block means over ``stride`` steps of ``lambda`` (per-step
    growth rate over non-rattlers; only steps where it is defined count, ``out_nlam``
    says how many) and of ``V = sqrt(sum |v|²)``. Returns the status code.
    """
    # fmt: off
    (vec, sca, ivec, walls, pair_start, pair_ij, pair_c, _pair_xi, _pair_dxi, _old_start,
     _old_j, _old_xi, _old_dxi, buf, touch, cell_count, cell_start, clock, counters) = st
    # fmt: on
    half_skin = 0.5 * skin
    _set_gravity(vec, sca, g[0], g[1])
    blk = np.zeros(_NBLK)
    zb = 0.0
    for s in range(n_steps):
        step = counters[STEP] + 1
        # the last step's second half kick is done with this step's first (same force)
        moved, v2, bad = _kick_drift(vec, sca, dt, half_skin, False, s > 0, stride > 0)
        if bad:
            return _fail(info, NONFINITE, _first_nonfinite(vec, sca), -1, step - 1)
        if tangent:
            # the tangent vector's kicks and the last step's norms, in one pass
            num, den, total = _tangent_pass(vec, sca, ivec, dt, 1 if s > 0 else 0)
            if s > 0 and not _lambda_step(
                vec, sca, num, den, total, dt, blk, info, step - 1, counters
            ):
                return info[0]
        if s > 0 and stride > 0:
            _block_means(v2, stride, blk, out_speed, out_nlam, out_lam)
        wmoved, zb, vb = _advance_walls(vec, sca, walls, wd, fw, clock, counters, dt, half_skin)
        counters[STEP] = step
        if moved or wmoved or counters[FORCE_REBUILD] != 0:
            if not _rebuild(
                vec,
                sca,
                ivec,
                skin,
                pair_start,
                pair_ij,
                pair_c,
                cell_count,
                cell_start,
                clock,
                counters,
            ):
                return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _drum_forces(
            vec,
            sca,
            ivec,
            law,
            fw,
            zb,
            vb,
            pair_start,
            pair_ij,
            pair_c,
            buf,
            touch,
            counters,
            skin,
            clock,
            tangent,
            tangent,
            info,
            step,
        )
        if ncon < 0:
            return info[0]
        counters[CONTACT_SUM] += ncon
        counters[STEPS_RUN] += 1
    if n_steps > 0 and tangent:
        num, den, total = _tangent_pass(vec, sca, ivec, dt, 2)
        if not _lambda_step(vec, sca, num, den, total, dt, blk, info, counters[STEP], counters):
            return info[0]
    if n_steps > 0:
        code = _end_run(
            vec, sca, dt, False, stride, blk, out_speed, out_nlam, out_lam, info, counters
        )
        if code != OK:
            return code
    if n_steps > 0 and not tangent:
        _count_contacts(vec, sca, ivec, pair_ij, pair_c, counters[N_PAIRS], fw, zb)
    return OK


@njit
def _box_replica(n_steps, stride, dt, g, law, wd, fw, skin, st, out_speed, info):
    """Advance one replica ``n_steps`` under the box law; block means of ``V`` if ``stride``."""
    # fmt: off
    (vec, sca, ivec, walls, pair_start, pair_ij, pair_c, pair_xi, _pair_dxi, old_start,
     old_j, old_xi, _old_dxi, buf, touch, cell_count, cell_start, clock, counters) = st
    # fmt: on
    half_skin = 0.5 * skin
    _set_gravity(vec, sca, g[0], g[1])
    blk = np.zeros(_NBLK)
    no_lam = np.zeros(0)
    no_nlam = np.zeros(0, np.int64)
    zb = 0.0
    for s in range(n_steps):
        step = counters[STEP] + 1
        moved, v2, bad = _kick_drift(vec, sca, dt, half_skin, True, s > 0, stride > 0)
        if bad:
            return _fail(info, NONFINITE, _first_nonfinite(vec, sca), -1, step - 1)
        if s > 0 and stride > 0:
            _block_means(v2, stride, blk, out_speed, no_nlam, no_lam)
        wmoved, zb, vb = _advance_walls(vec, sca, walls, wd, fw, clock, counters, dt, half_skin)
        counters[STEP] = step
        if moved or wmoved or counters[FORCE_REBUILD] != 0:
            if not _rebuild_with_history(
                vec,
                sca,
                ivec,
                skin,
                pair_start,
                pair_ij,
                pair_c,
                pair_xi,
                old_start,
                old_j,
                old_xi,
                cell_count,
                cell_start,
                clock,
                counters,
            ):
                return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _box_forces(
            vec,
            sca,
            ivec,
            law,
            fw,
            zb,
            vb,
            dt,
            pair_start,
            pair_ij,
            pair_c,
            pair_xi,
            buf,
            touch,
            counters,
            skin,
            clock,
            False,
            info,
            step,
        )
        if ncon < 0:
            return info[0]
        counters[CONTACT_SUM] += ncon
        counters[STEPS_RUN] += 1
    if n_steps > 0:
        code = _end_run(vec, sca, dt, True, stride, blk, out_speed, no_nlam, no_lam, info, counters)
        if code != OK:
            return code
        _count_contacts(vec, sca, ivec, pair_ij, pair_c, counters[N_PAIRS], fw, zb)
    return OK


# --------------------------------------------------------------------------- refresh


@njit
def _refresh_replica(law_id, tangent, rebuild, g, law, wd, fw, skin, st, dt, info):
    """Place the walls, rebuild the list and evaluate forces at the current state.

    Uses full-step velocities and wall velocities at the current time; the shear history is
    not advanced. Used when a state is created or edited (:meth:`Simulation.refresh`).
    Without ``rebuild`` the walls and the list stay as they are (setting a tangent vector:
    the caller keeps the forces and takes only their perturbation).
    """
    # fmt: off
    (vec, sca, ivec, walls, pair_start, pair_ij, pair_c, pair_xi, _pair_dxi, old_start,
     old_j, old_xi, _old_dxi, buf, touch, cell_count, cell_start, clock, counters) = st
    # fmt: on
    t = _time(clock, counters, dt)
    n_walls = counters[N_WALLS]
    if n_walls > 0 and rebuild:
        omega = wall_omega(wd, t)
        _update_wall_disks(vec, sca, walls, n_walls, wd, clock[THETA], omega)
        clock[LAST_OMEGA] = omega
    zb, vb = _bottom(fw, t)
    step = counters[STEP]
    _set_gravity(vec, sca, g[0], g[1])
    # a non-finite state is reported before anything else
    i = _first_nonfinite(vec, sca)
    if i >= 0:
        return _fail(info, NONFINITE, i, -1, step)
    if law_id == 0:
        if rebuild and not _rebuild(
            vec,
            sca,
            ivec,
            skin,
            pair_start,
            pair_ij,
            pair_c,
            cell_count,
            cell_start,
            clock,
            counters,
        ):
            return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _drum_forces(
            vec,
            sca,
            ivec,
            law,
            fw,
            zb,
            vb,
            pair_start,
            pair_ij,
            pair_c,
            buf,
            touch,
            counters,
            skin,
            clock,
            tangent,
            True,
            info,
            step,
        )
    else:
        if rebuild and not _rebuild_with_history(
            vec,
            sca,
            ivec,
            skin,
            pair_start,
            pair_ij,
            pair_c,
            pair_xi,
            old_start,
            old_j,
            old_xi,
            cell_count,
            cell_start,
            clock,
            counters,
        ):
            return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _box_forces(
            vec,
            sca,
            ivec,
            law,
            fw,
            zb,
            vb,
            0.0,
            pair_start,
            pair_ij,
            pair_c,
            pair_xi,
            buf,
            touch,
            counters,
            skin,
            clock,
            True,
            info,
            step,
        )
    if ncon < 0:
        return info[0]
    if tangent:
        tr = vec[T_POS]
        tv = vec[T_VEL]
        prev = sca[T_PREV]
        mob = vec[MOB2]
        for i in range(tr.shape[0]):
            q = tr[i, 0] ** 2 + tr[i, 1] ** 2 + tv[i, 0] ** 2 + tv[i, 1] ** 2
            prev[i] = q * mob[i, 0]
    return OK


# --------------------------------------------------------------------------- drivers


@njit
def drum_run_serial(
    n_steps, stride, tangent, dt, g, law, wd, fw, skin, st, out_lam, out_nlam, out_speed, info
):
    """Drum law over replicas one after another (arrays with a leading replica axis)."""
    for r in range(info.shape[0]):
        _drum_replica(
            n_steps,
            stride,
            tangent,
            dt,
            g,
            law,
            wd,
            fw,
            skin,
            _at(st, r),
            out_lam[r],
            out_nlam[r],
            out_speed[r],
            info[r],
        )


@pnjit
def drum_run_parallel(
    n_steps, stride, tangent, dt, g, law, wd, fw, skin, st, out_lam, out_nlam, out_speed, info
):
    """Drum law over replicas under ``prange`` (each iteration writes only its replica)."""
    for r in numba_prange(info.shape[0]):
        _drum_replica(
            n_steps,
            stride,
            tangent,
            dt,
            g,
            law,
            wd,
            fw,
            skin,
            _at(st, r),
            out_lam[r],
            out_nlam[r],
            out_speed[r],
            info[r],
        )


@njit
def box_run_serial(n_steps, stride, dt, g, law, wd, fw, skin, st, out_speed, info):
    """Box law over replicas one after another."""
    for r in range(info.shape[0]):
        _box_replica(
            n_steps,
            stride,
            dt,
            g,
            law,
            wd,
            fw,
            skin,
            _at(st, r),
            out_speed[r],
            info[r],
        )


@pnjit
def box_run_parallel(n_steps, stride, dt, g, law, wd, fw, skin, st, out_speed, info):
    """Box law over replicas under ``prange``."""
    for r in numba_prange(info.shape[0]):
        _box_replica(
            n_steps,
            stride,
            dt,
            g,
            law,
            wd,
            fw,
            skin,
            _at(st, r),
            out_speed[r],
            info[r],
        )


@njit
def refresh_serial(law_id, tangent, rebuild, g, law, wd, fw, skin, st, dt, info):
    """:func:`_refresh_replica` over replicas."""
    for r in range(info.shape[0]):
        _refresh_replica(
            law_id,
            tangent,
            rebuild,
            g,
            law,
            wd,
            fw,
            skin,
            _at(st, r),
            dt,
            info[r],
        )


# --------------------------------------------------------------------------- the contract


def _drum_run(fn):
    """``fn`` (a drum driver) in the contract's argument order (law first;
    :class:`granpipe.engine.contract.Kernels`)."""

    def run(law, n_steps, stride, tangent, dt, g, wd, fw, skin, st, out_lam, out_nlam, speed, info):
        fn(n_steps, stride, tangent, dt, g, law, wd, fw, skin, st, out_lam, out_nlam, speed, info)

    return run


def _box_run(fn):
    """``fn`` (a box driver) in the contract's argument order (it records no lambda)."""

    def run(law, n_steps, stride, tangent, dt, g, wd, fw, skin, st, out_lam, out_nlam, speed, info):
        fn(n_steps, stride, dt, g, law, wd, fw, skin, st, speed, info)

    return run


def _refresh_as(law_id):
    def refresh(law, tangent, rebuild, g, wd, fw, skin, st, dt, info):
        refresh_serial(law_id, tangent, rebuild, g, law, wd, fw, skin, st, dt, info)

    return refresh


def _drum_set_tangent(law, g, wd, fw, skin, st, dt, info):
    """The drum law's perturbation ``dF = J_r dr + J_v dv`` of a tangent vector just set,
    at the current (full-step) velocities; the stored forces (from half-step velocities)
    are kept, so that setting a tangent vector never changes the trajectory."""
    vec = st[0]
    saved = vec[:, FRC].copy()
    refresh_serial(0, True, False, g, law, wd, fw, skin, st, dt, info)
    vec[:, FRC] = saved


def _no_tangent(*args):
    raise NotImplementedError("this law has no tangent dynamics")


def drum_kernels():
    """The drum law's own passes (four-lane fused pair pass with the tangent vector)."""
    from granpipe.engine.contract import Kernels, profile_hook

    return Kernels(
        _drum_run(drum_run_serial),
        _drum_run(drum_run_parallel),
        _refresh_as(0),
        _drum_set_tangent,
        True,
        True,
        profile_hook("drum_passes"),
    )


def box_kernels():
    """The box law's own passes (shear history, flat walls; no tangent dynamics)."""
    from granpipe.engine.contract import Kernels, profile_hook

    return Kernels(
        _box_run(box_run_serial),
        _box_run(box_run_parallel),
        _refresh_as(1),
        _no_tangent,
        True,
        False,
        profile_hook("box_passes"),
    )
