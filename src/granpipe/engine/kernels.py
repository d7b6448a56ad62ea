"""Jitted step loops: velocity Verlet with gravity, walls, neighbour lists, tangent dynamics.

Three tiers (STYLE.md, stumpy): serial per-replica leaves (``_drum_replica``,
``_box_replica``), drivers over a leading replica axis (serial and ``prange``;
each iteration touches only its own replica, so results are bit-identical however
many replicas run side by side), and the Python wrapper in
:mod:`granpipe.engine.simulation`.

Storage (per replica, struct of arrays, float64; indices below): ``vec`` (NV, N, 2)
holds per-disk vectors, ``sca`` (NS, N) per-disk scalars, ``ivec`` (NI, N) per-disk
integers. The step loop allocates nothing.

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
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange as numba_prange

from granpipe._jit import njit, pnjit
from granpipe.engine.laws import box_force, drum_force, drum_force_jvp
from granpipe.engine.neighbours import build_pairs, carry_history
from granpipe.engine.walls import bottom_height, bottom_velocity, wall_omega

# rows of vec (NV, N, 2)
POS, VEL, FRC, POS_BUILD, WALL_REF, T_POS, T_VEL, T_FRC = range(8)
NV = 8
# rows of sca (NS, N)
RADIUS, INV_MASS, INV_INERTIA, SPIN, TORQUE, T_PREV, XI_LEFT, XI_RIGHT, XI_BOTTOM = range(9)
NS = 9
# rows of ivec (NI, N)
IS_WALL, CONTACTS, CELL_ITEMS, CELL_OF = range(4)
NI = 4
# clock (3,): time origin, wall angle, wall angular velocity of the last step
T_ORIGIN, THETA, LAST_OMEGA = range(3)
NCLOCK = 3
# counters (8,)
STEP, N_PAIRS, N_REBUILDS, FORCE_REBUILD, LOG2_SCALE, CONTACT_SUM, STEPS_RUN, N_WALLS = range(8)
NCOUNT = 8
# info (4,): status, particle, other, step
OK, NONFINITE, DEEP_OVERLAP, LIST_OVERFLOW, TANGENT_NONFINITE = range(5)
# "other" codes for flat walls in info
LEFT_WALL, RIGHT_WALL, BOTTOM_WALL = -1, -2, -3

# renormalise the tangent vector when |du|² leaves [2^-400, 2^400]; by powers of two (exact)
_RENORM_HI = 2.0**400
_RENORM_LO = 2.0**-400
_RENORM_MAX = 2.0**950
_BIG = 1e300


@njit
def _fail(info, status, particle, other, step):
    info[0] = status
    info[1] = particle
    info[2] = other
    info[3] = step
    return status


# --------------------------------------------------------------------------- walls, list


@njit
def _update_wall_disks(vec, sca, walls, n_walls, wd, theta, omega):
    """Place the wall disks at angle ``theta``, velocities ``omega x (r - c)``; max displ.²."""
    pos = vec[POS]
    vel = vec[VEL]
    ref = vec[WALL_REF]
    build = vec[POS_BUILD]
    spin = sca[SPIN]
    cx = wd[0]
    cy = wd[1]
    c = math.cos(theta)
    s = math.sin(theta)
    maxd2 = 0.0
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
        dx = x - build[i, 0]
        dy = y - build[i, 1]
        maxd2 = max(maxd2, dx * dx + dy * dy)
    return maxd2


@njit
def _rebuild(vec, sca, ivec, skin, pair_start, pair_j, cell_count, cell_start, counters):
    n = vec.shape[1]
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
        pair_j,
    )
    if npairs < 0:
        return False
    pos = vec[POS]
    build = vec[POS_BUILD]
    for i in range(n):
        build[i, 0] = pos[i, 0]
        build[i, 1] = pos[i, 1]
    counters[N_PAIRS] = npairs
    counters[N_REBUILDS] += 1
    counters[FORCE_REBUILD] = 0
    return True


@njit
def _rebuild_with_history(
    vec,
    sca,
    ivec,
    skin,
    pair_start,
    pair_j,
    pair_xi,
    old_start,
    old_j,
    old_xi,
    cell_count,
    cell_start,
    counters,
):
    n = vec.shape[1]
    npairs = counters[N_PAIRS]
    for i in range(n + 1):
        old_start[i] = pair_start[i]
    for k in range(npairs):
        old_j[k] = pair_j[k]
        old_xi[k] = pair_xi[k]
    if not _rebuild(vec, sca, ivec, skin, pair_start, pair_j, cell_count, cell_start, counters):
        return False
    if npairs == 0:
        # the first build: nothing to carry (old_start may be stale)
        for k in range(counters[N_PAIRS]):
            pair_xi[k] = 0.0
    else:
        carry_history(old_start, old_j, old_xi, pair_start, pair_j, pair_xi)
    return True


# --------------------------------------------------------------------------- drum law forces


@njit
def _drum_forces(vec, sca, ivec, gx, gy, law, fw, zb, vb, pair_start, pair_j, tangent, info, step):
    """Forces (and with ``tangent`` their perturbation) under the drum law; contact counts.

    Returns the number of contacts, or -1 after recording a deep overlap in ``info``.
    """
    pos = vec[POS]
    vel = vec[VEL]
    frc = vec[FRC]
    tr = vec[T_POS]
    tv = vec[T_VEL]
    tf = vec[T_FRC]
    radius = sca[RADIUS]
    inv_mass = sca[INV_MASS]
    is_wall = ivec[IS_WALL]
    contacts = ivec[CONTACTS]
    k_n = law[0]
    g_n = law[1]
    g_t = law[2]
    mu = law[3]
    n = pos.shape[0]
    for i in range(n):
        contacts[i] = 0
        if is_wall[i]:
            frc[i, 0] = 0.0
            frc[i, 1] = 0.0
        else:
            m = 1.0 / inv_mass[i]
            frc[i, 0] = m * gx
            frc[i, 1] = m * gy
        if tangent:
            tf[i, 0] = 0.0
            tf[i, 1] = 0.0
    ncon = 0
    for i in range(n):
        k0 = pair_start[i]
        k1 = pair_start[i + 1]
        if k0 == k1:
            continue
        xi = pos[i, 0]
        yi = pos[i, 1]
        vxi = vel[i, 0]
        vyi = vel[i, 1]
        ai = radius[i]
        fxi = 0.0
        fyi = 0.0
        dfxi = 0.0
        dfyi = 0.0
        ci = 0
        for k in range(k0, k1):
            j = pair_j[k]
            dx = xi - pos[j, 0]
            dy = yi - pos[j, 1]
            aj = radius[j]
            s = ai + aj
            r2 = dx * dx + dy * dy
            if r2 > s * s:
                continue
            r = math.sqrt(r2)
            inv_r = 1.0 / r
            nx = dx * inv_r
            ny = dy * inv_r
            delta = r - s
            if -delta > 0.5 * min(ai, aj):
                _fail(info, DEEP_OVERLAP, i, j, step)
                return -1
            vx = vxi - vel[j, 0]
            vy = vyi - vel[j, 1]
            fx, fy, f_n, f_t, regime = drum_force(nx, ny, delta, vx, vy, k_n, g_n, g_t, mu)
            fxi += fx
            fyi += fy
            frc[j, 0] -= fx
            frc[j, 1] -= fy
            ci += 1
            contacts[j] += 1
            if tangent:
                dfx, dfy = drum_force_jvp(
                    nx,
                    ny,
                    inv_r,
                    vx,
                    vy,
                    f_n,
                    f_t,
                    regime,
                    tr[i, 0] - tr[j, 0],
                    tr[i, 1] - tr[j, 1],
                    tv[i, 0] - tv[j, 0],
                    tv[i, 1] - tv[j, 1],
                    k_n,
                    g_n,
                    g_t,
                    mu,
                )
                dfxi += dfx
                dfyi += dfy
                tf[j, 0] -= dfx
                tf[j, 1] -= dfy
        frc[i, 0] += fxi
        frc[i, 1] += fyi
        contacts[i] += ci
        ncon += ci
        if tangent:
            tf[i, 0] += dfxi
            tf[i, 1] += dfyi
    if fw[0] != 0.0 or fw[2] != 0.0 or fw[4] != 0.0:
        for i in range(n):
            if is_wall[i]:
                continue
            ai = radius[i]
            for w in range(3):
                if fw[2 * w] == 0.0:
                    continue
                if w == 0:
                    h = pos[i, 0] - fw[1]
                    nx = 1.0
                    ny = 0.0
                    vx = vel[i, 0]
                    vy = vel[i, 1]
                elif w == 1:
                    h = fw[3] - pos[i, 0]
                    nx = -1.0
                    ny = 0.0
                    vx = vel[i, 0]
                    vy = vel[i, 1]
                else:
                    h = pos[i, 1] - zb
                    nx = 0.0
                    ny = 1.0
                    vx = vel[i, 0]
                    vy = vel[i, 1] - vb
                delta = h - ai
                if delta > 0.0:
                    continue
                if -delta > 0.5 * ai:
                    _fail(info, DEEP_OVERLAP, i, -1 - w, step)
                    return -1
                fx, fy, f_n, f_t, regime = drum_force(nx, ny, delta, vx, vy, k_n, g_n, g_t, mu)
                frc[i, 0] += fx
                frc[i, 1] += fy
                contacts[i] += 1
                ncon += 1
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
                        k_n,
                        g_n,
                        g_t,
                        mu,
                    )
                    tf[i, 0] += dfx
                    tf[i, 1] += dfy
    return ncon


# --------------------------------------------------------------------------- box law forces


@njit
def _box_forces(
    vec, sca, ivec, gx, gy, law, fw, zb, vb, dt_hist, pair_start, pair_j, pair_xi, info, step
):
    """Forces and torques under the box law; advances shear histories by ``dt_hist``."""
    pos = vec[POS]
    vel = vec[VEL]
    frc = vec[FRC]
    radius = sca[RADIUS]
    inv_mass = sca[INV_MASS]
    spin = sca[SPIN]
    trq = sca[TORQUE]
    is_wall = ivec[IS_WALL]
    contacts = ivec[CONTACTS]
    kap_n = law[0]
    kap_t = law[1]
    g_n = law[2]
    g_t = law[3]
    mu = law[4]
    n = pos.shape[0]
    for i in range(n):
        contacts[i] = 0
        trq[i] = 0.0
        if is_wall[i]:
            frc[i, 0] = 0.0
            frc[i, 1] = 0.0
        else:
            m = 1.0 / inv_mass[i]
            frc[i, 0] = m * gx
            frc[i, 1] = m * gy
    ncon = 0
    for i in range(n):
        k0 = pair_start[i]
        k1 = pair_start[i + 1]
        if k0 == k1:
            continue
        xi = pos[i, 0]
        yi = pos[i, 1]
        vxi = vel[i, 0]
        vyi = vel[i, 1]
        wi = spin[i]
        ai = radius[i]
        imi = inv_mass[i]
        fxi = 0.0
        fyi = 0.0
        ti = 0.0
        ci = 0
        for k in range(k0, k1):
            j = pair_j[k]
            dx = xi - pos[j, 0]
            dy = yi - pos[j, 1]
            aj = radius[j]
            s = ai + aj
            r2 = dx * dx + dy * dy
            if r2 > s * s:
                pair_xi[k] = 0.0
                continue
            r = math.sqrt(r2)
            inv_r = 1.0 / r
            overlap = s - r
            if overlap > 0.5 * min(ai, aj):
                _fail(info, DEEP_OVERLAP, i, j, step)
                return -1
            m_eff = 1.0 / (imi + inv_mass[j])
            fx, fy, tau_i, tau_j, xi_new, f_n, f_t, slip = box_force(
                dx * inv_r,
                dy * inv_r,
                overlap,
                0.5 * (r + ai - aj),
                0.5 * (r + aj - ai),
                vxi - vel[j, 0],
                vyi - vel[j, 1],
                wi,
                spin[j],
                m_eff,
                pair_xi[k],
                dt_hist,
                kap_n,
                kap_t,
                g_n,
                g_t,
                mu,
            )
            pair_xi[k] = xi_new
            fxi += fx
            fyi += fy
            ti += tau_i
            frc[j, 0] -= fx
            frc[j, 1] -= fy
            trq[j] += tau_j
            ci += 1
            contacts[j] += 1
        frc[i, 0] += fxi
        frc[i, 1] += fyi
        trq[i] += ti
        contacts[i] += ci
        ncon += ci
    if fw[0] != 0.0 or fw[2] != 0.0 or fw[4] != 0.0:
        xi_w = sca[XI_LEFT : XI_BOTTOM + 1]
        for i in range(n):
            if is_wall[i]:
                continue
            ai = radius[i]
            for w in range(3):
                if fw[2 * w] == 0.0:
                    continue
                if w == 0:
                    h = pos[i, 0] - fw[1]
                    nx = 1.0
                    ny = 0.0
                    vx = vel[i, 0]
                    vy = vel[i, 1]
                    mu_w = law[6]
                elif w == 1:
                    h = fw[3] - pos[i, 0]
                    nx = -1.0
                    ny = 0.0
                    vx = vel[i, 0]
                    vy = vel[i, 1]
                    mu_w = law[6]
                else:
                    h = pos[i, 1] - zb
                    nx = 0.0
                    ny = 1.0
                    vx = vel[i, 0]
                    vy = vel[i, 1] - vb
                    mu_w = law[5]
                overlap = ai - h
                if overlap < 0.0:
                    xi_w[w, i] = 0.0
                    continue
                if overlap > 0.5 * ai:
                    _fail(info, DEEP_OVERLAP, i, -1 - w, step)
                    return -1
                fx, fy, tau_i, tau_j, xi_new, f_n, f_t, slip = box_force(
                    nx,
                    ny,
                    overlap,
                    ai - 0.5 * overlap,
                    0.0,
                    vx,
                    vy,
                    spin[i],
                    0.0,
                    1.0 / inv_mass[i],
                    xi_w[w, i],
                    dt_hist,
                    kap_n,
                    kap_t,
                    g_n,
                    g_t,
                    mu_w,
                )
                xi_w[w, i] = xi_new
                frc[i, 0] += fx
                frc[i, 1] += fy
                trq[i] += tau_i
                contacts[i] += 1
                ncon += 1
    return ncon


# --------------------------------------------------------------------------- one replica


@njit
def _kick_drift(vec, sca, ivec, dt, spin_on, tangent):
    """First half kick and drift of the mobile disks; returns the max displacement² since build."""
    pos = vec[POS]
    vel = vec[VEL]
    frc = vec[FRC]
    build = vec[POS_BUILD]
    inv_mass = sca[INV_MASS]
    is_wall = ivec[IS_WALL]
    n = pos.shape[0]
    h = 0.5 * dt
    maxd2 = 0.0
    for i in range(n):
        if is_wall[i]:
            continue
        im = inv_mass[i]
        vx = vel[i, 0] + h * (frc[i, 0] * im)
        vy = vel[i, 1] + h * (frc[i, 1] * im)
        vel[i, 0] = vx
        vel[i, 1] = vy
        x = pos[i, 0] + dt * vx
        y = pos[i, 1] + dt * vy
        pos[i, 0] = x
        pos[i, 1] = y
        dx = x - build[i, 0]
        dy = y - build[i, 1]
        maxd2 = max(maxd2, dx * dx + dy * dy)
    if spin_on:
        spin = sca[SPIN]
        trq = sca[TORQUE]
        inv_i = sca[INV_INERTIA]
        for i in range(n):
            if not is_wall[i]:
                spin[i] = spin[i] + h * (trq[i] * inv_i[i])
    if tangent:
        tr = vec[T_POS]
        tv = vec[T_VEL]
        tf = vec[T_FRC]
        for i in range(n):
            if is_wall[i]:
                continue
            im = inv_mass[i]
            wx = tv[i, 0] + h * (tf[i, 0] * im)
            wy = tv[i, 1] + h * (tf[i, 1] * im)
            tv[i, 0] = wx
            tv[i, 1] = wy
            tr[i, 0] = tr[i, 0] + dt * wx
            tr[i, 1] = tr[i, 1] + dt * wy
    return maxd2


@njit
def _final_kick(vec, sca, ivec, dt, spin_on, info, step):
    """Second half kick; returns sum |v|² over mobile disks, or -1 on a non-finite state."""
    pos = vec[POS]
    vel = vec[VEL]
    frc = vec[FRC]
    inv_mass = sca[INV_MASS]
    is_wall = ivec[IS_WALL]
    n = pos.shape[0]
    h = 0.5 * dt
    v2 = 0.0
    for i in range(n):
        if is_wall[i]:
            continue
        im = inv_mass[i]
        vx = vel[i, 0] + h * (frc[i, 0] * im)
        vy = vel[i, 1] + h * (frc[i, 1] * im)
        vel[i, 0] = vx
        vel[i, 1] = vy
        v2 += vx * vx + vy * vy
        if not (abs(vx) + abs(vy) + abs(pos[i, 0]) + abs(pos[i, 1]) < _BIG):
            _fail(info, NONFINITE, i, -1, step)
            return -1.0
    if spin_on:
        spin = sca[SPIN]
        trq = sca[TORQUE]
        inv_i = sca[INV_INERTIA]
        for i in range(n):
            if is_wall[i]:
                continue
            w = spin[i] + h * (trq[i] * inv_i[i])
            spin[i] = w
            if not (abs(w) < _BIG):
                _fail(info, NONFINITE, i, -1, step)
                return -1.0
    return v2


@njit
def _tangent_kick(vec, sca, ivec, dt, info, step, counters):
    """Second half kick of the tangent vector, its growth over S, and renormalisation.

    Returns ``(num, den)``: ``|du(t)|²_S`` and ``|du(t - dt)|²_S`` with S the disks with
    at least two contacts at this step (walls count); ``num = -1`` on a non-finite vector.
    """
    tr = vec[T_POS]
    tv = vec[T_VEL]
    tf = vec[T_FRC]
    prev = sca[T_PREV]
    inv_mass = sca[INV_MASS]
    is_wall = ivec[IS_WALL]
    contacts = ivec[CONTACTS]
    n = tr.shape[0]
    h = 0.5 * dt
    num = 0.0
    den = 0.0
    total = 0.0
    for i in range(n):
        if is_wall[i]:
            continue
        im = inv_mass[i]
        wx = tv[i, 0] + h * (tf[i, 0] * im)
        wy = tv[i, 1] + h * (tf[i, 1] * im)
        tv[i, 0] = wx
        tv[i, 1] = wy
        q = tr[i, 0] * tr[i, 0] + tr[i, 1] * tr[i, 1] + wx * wx + wy * wy
        if contacts[i] >= 2:
            num += q
            den += prev[i]
        prev[i] = q
        total += q
    if not (total < math.inf):
        _fail(info, TANGENT_NONFINITE, -1, -1, step)
        return -1.0, 0.0
    # scale by the part that enters lambda (rattlers' components may be far larger or
    # smaller), but never let the whole vector come near overflow
    ref = num if num > 0.0 else total
    if ref > _RENORM_HI or (0.0 < ref < _RENORM_LO) or total > _RENORM_MAX:
        e = int(math.floor(0.5 * math.log2(ref)))
        e = max(e, int(math.ceil(0.5 * math.log2(total))) - 450)
        c = math.ldexp(1.0, -e)
        c2 = c * c
        for i in range(n):
            tr[i, 0] *= c
            tr[i, 1] *= c
            tv[i, 0] *= c
            tv[i, 1] *= c
            tf[i, 0] *= c
            tf[i, 1] *= c
            prev[i] *= c2
        counters[LOG2_SCALE] += e
    return num, den


@njit
def _time(clock, counters, dt):
    return clock[T_ORIGIN] + counters[STEP] * dt


@njit
def _advance_walls(vec, sca, walls, wd, fw, clock, counters, dt):
    """Move the walls over the step that starts now; returns (max wall displacement², z_b, v_b)."""
    t0 = _time(clock, counters, dt)
    t1 = clock[T_ORIGIN] + (counters[STEP] + 1) * dt
    maxd2 = 0.0
    n_walls = counters[N_WALLS]
    if n_walls > 0:
        omega = wall_omega(wd, t0 + 0.5 * dt)
        if omega != 0.0 or clock[LAST_OMEGA] != 0.0:
            clock[THETA] += omega * dt
            maxd2 = _update_wall_disks(vec, sca, walls, n_walls, wd, clock[THETA], omega)
            clock[LAST_OMEGA] = omega
    zb = 0.0
    vb = 0.0
    if fw[4] != 0.0:
        zb = bottom_height(fw, t1)
        vb = bottom_velocity(fw, t0 + 0.5 * dt)
    return maxd2, zb, vb


@njit
def _drum_replica(
    n_steps,
    stride,
    tangent,
    dt,
    g,
    law,
    wd,
    fw,
    skin,
    vec,
    sca,
    ivec,
    walls,
    pair_start,
    pair_j,
    cell_count,
    cell_start,
    clock,
    counters,
    out_lam,
    out_nlam,
    out_speed,
    info,
):
    """Advance one replica ``n_steps`` under the drum law (optionally with its tangent vector).

    Records, when ``stride > 0``, block means over ``stride`` steps of ``lambda`` (per-step
    growth rate over non-rattlers; only steps where it is defined count, ``out_nlam``
    says how many) and of ``V = sqrt(sum |v|²)``. Returns the status code.
    """
    half_skin2 = 0.25 * skin * skin
    lam_sum = 0.0
    lam_n = 0
    v_sum = 0.0
    b = 0
    in_block = 0
    for _ in range(n_steps):
        step = counters[STEP] + 1
        maxd2 = _kick_drift(vec, sca, ivec, dt, False, tangent)
        wd2, zb, vb = _advance_walls(vec, sca, walls, wd, fw, clock, counters, dt)
        counters[STEP] = step
        if max(maxd2, wd2) > half_skin2 or counters[FORCE_REBUILD] != 0:
            if not _rebuild(
                vec, sca, ivec, skin, pair_start, pair_j, cell_count, cell_start, counters
            ):
                return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _drum_forces(
            vec, sca, ivec, g[0], g[1], law, fw, zb, vb, pair_start, pair_j, tangent, info, step
        )
        if ncon < 0:
            return info[0]
        counters[CONTACT_SUM] += ncon
        counters[STEPS_RUN] += 1
        v2 = _final_kick(vec, sca, ivec, dt, False, info, step)
        if v2 < 0.0:
            return info[0]
        if tangent:
            num, den = _tangent_kick(vec, sca, ivec, dt, info, step, counters)
            if num < 0.0:
                return info[0]
            if num > 0.0 and den > 0.0:
                lam_sum += 0.5 * math.log(num / den) / dt
                lam_n += 1
        if stride > 0:
            v_sum += math.sqrt(v2)
            in_block += 1
            if in_block == stride:
                out_speed[b] = v_sum / stride
                out_nlam[b] = lam_n
                out_lam[b] = lam_sum / lam_n if lam_n > 0 else np.nan
                b += 1
                in_block = 0
                v_sum = 0.0
                lam_sum = 0.0
                lam_n = 0
    return OK


@njit
def _box_replica(
    n_steps,
    stride,
    dt,
    g,
    law,
    wd,
    fw,
    skin,
    vec,
    sca,
    ivec,
    walls,
    pair_start,
    pair_j,
    pair_xi,
    old_start,
    old_j,
    old_xi,
    cell_count,
    cell_start,
    clock,
    counters,
    out_speed,
    info,
):
    """Advance one replica ``n_steps`` under the box law; block means of ``V`` if ``stride``."""
    half_skin2 = 0.25 * skin * skin
    v_sum = 0.0
    b = 0
    in_block = 0
    for _ in range(n_steps):
        step = counters[STEP] + 1
        maxd2 = _kick_drift(vec, sca, ivec, dt, True, False)
        wd2, zb, vb = _advance_walls(vec, sca, walls, wd, fw, clock, counters, dt)
        counters[STEP] = step
        if max(maxd2, wd2) > half_skin2 or counters[FORCE_REBUILD] != 0:
            if not _rebuild_with_history(
                vec,
                sca,
                ivec,
                skin,
                pair_start,
                pair_j,
                pair_xi,
                old_start,
                old_j,
                old_xi,
                cell_count,
                cell_start,
                counters,
            ):
                return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _box_forces(
            vec,
            sca,
            ivec,
            g[0],
            g[1],
            law,
            fw,
            zb,
            vb,
            dt,
            pair_start,
            pair_j,
            pair_xi,
            info,
            step,
        )
        if ncon < 0:
            return info[0]
        counters[CONTACT_SUM] += ncon
        counters[STEPS_RUN] += 1
        v2 = _final_kick(vec, sca, ivec, dt, True, info, step)
        if v2 < 0.0:
            return info[0]
        if stride > 0:
            v_sum += math.sqrt(v2)
            in_block += 1
            if in_block == stride:
                out_speed[b] = v_sum / stride
                b += 1
                in_block = 0
                v_sum = 0.0
    return OK


# --------------------------------------------------------------------------- refresh


@njit
def _refresh_replica(
    law_id,
    tangent,
    g,
    law,
    wd,
    fw,
    skin,
    vec,
    sca,
    ivec,
    walls,
    pair_start,
    pair_j,
    pair_xi,
    old_start,
    old_j,
    old_xi,
    cell_count,
    cell_start,
    clock,
    counters,
    dt,
    info,
):
    """Place the walls, rebuild the list and evaluate forces at the current state.

    Uses full-step velocities and wall velocities at the current time; the shear history is
    not advanced. Used when a state is created or edited (:meth:`Simulation.refresh`).
    """
    t = _time(clock, counters, dt)
    n_walls = counters[N_WALLS]
    if n_walls > 0:
        omega = wall_omega(wd, t)
        _update_wall_disks(vec, sca, walls, n_walls, wd, clock[THETA], omega)
        clock[LAST_OMEGA] = omega
    zb = 0.0
    vb = 0.0
    if fw[4] != 0.0:
        zb = bottom_height(fw, t)
        vb = bottom_velocity(fw, t)
    step = counters[STEP]
    if law_id == 0:
        if not _rebuild(vec, sca, ivec, skin, pair_start, pair_j, cell_count, cell_start, counters):
            return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _drum_forces(
            vec, sca, ivec, g[0], g[1], law, fw, zb, vb, pair_start, pair_j, tangent, info, step
        )
    else:
        if not _rebuild_with_history(
            vec,
            sca,
            ivec,
            skin,
            pair_start,
            pair_j,
            pair_xi,
            old_start,
            old_j,
            old_xi,
            cell_count,
            cell_start,
            counters,
        ):
            return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _box_forces(
            vec,
            sca,
            ivec,
            g[0],
            g[1],
            law,
            fw,
            zb,
            vb,
            0.0,
            pair_start,
            pair_j,
            pair_xi,
            info,
            step,
        )
    if ncon < 0:
        return info[0]
    if tangent:
        tr = vec[T_POS]
        tv = vec[T_VEL]
        prev = sca[T_PREV]
        for i in range(tr.shape[0]):
            prev[i] = tr[i, 0] ** 2 + tr[i, 1] ** 2 + tv[i, 0] ** 2 + tv[i, 1] ** 2
    # a non-finite state is reported before the first step
    pos = vec[POS]
    vel = vec[VEL]
    for i in range(pos.shape[0]):
        if not (abs(vel[i, 0]) + abs(vel[i, 1]) + abs(pos[i, 0]) + abs(pos[i, 1]) < _BIG):
            return _fail(info, NONFINITE, i, -1, step)
    return OK


# --------------------------------------------------------------------------- drivers


@njit
def drum_run_serial(
    n_steps,
    stride,
    tangent,
    dt,
    g,
    law,
    wd,
    fw,
    skin,
    vec,
    sca,
    ivec,
    walls,
    pair_start,
    pair_j,
    cell_count,
    cell_start,
    clock,
    counters,
    out_lam,
    out_nlam,
    out_speed,
    info,
):
    """Drum law over replicas one after another (arrays with a leading replica axis)."""
    for r in range(vec.shape[0]):
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
            vec[r],
            sca[r],
            ivec[r],
            walls[r],
            pair_start[r],
            pair_j[r],
            cell_count[r],
            cell_start[r],
            clock[r],
            counters[r],
            out_lam[r],
            out_nlam[r],
            out_speed[r],
            info[r],
        )


@pnjit
def drum_run_parallel(
    n_steps,
    stride,
    tangent,
    dt,
    g,
    law,
    wd,
    fw,
    skin,
    vec,
    sca,
    ivec,
    walls,
    pair_start,
    pair_j,
    cell_count,
    cell_start,
    clock,
    counters,
    out_lam,
    out_nlam,
    out_speed,
    info,
):
    """Drum law over replicas under ``prange`` (each iteration writes only its replica)."""
    for r in numba_prange(vec.shape[0]):
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
            vec[r],
            sca[r],
            ivec[r],
            walls[r],
            pair_start[r],
            pair_j[r],
            cell_count[r],
            cell_start[r],
            clock[r],
            counters[r],
            out_lam[r],
            out_nlam[r],
            out_speed[r],
            info[r],
        )


@njit
def box_run_serial(
    n_steps,
    stride,
    dt,
    g,
    law,
    wd,
    fw,
    skin,
    vec,
    sca,
    ivec,
    walls,
    pair_start,
    pair_j,
    pair_xi,
    old_start,
    old_j,
    old_xi,
    cell_count,
    cell_start,
    clock,
    counters,
    out_speed,
    info,
):
    """Box law over replicas one after another."""
    for r in range(vec.shape[0]):
        _box_replica(
            n_steps,
            stride,
            dt,
            g,
            law,
            wd,
            fw,
            skin,
            vec[r],
            sca[r],
            ivec[r],
            walls[r],
            pair_start[r],
            pair_j[r],
            pair_xi[r],
            old_start[r],
            old_j[r],
            old_xi[r],
            cell_count[r],
            cell_start[r],
            clock[r],
            counters[r],
            out_speed[r],
            info[r],
        )


@pnjit
def box_run_parallel(
    n_steps,
    stride,
    dt,
    g,
    law,
    wd,
    fw,
    skin,
    vec,
    sca,
    ivec,
    walls,
    pair_start,
    pair_j,
    pair_xi,
    old_start,
    old_j,
    old_xi,
    cell_count,
    cell_start,
    clock,
    counters,
    out_speed,
    info,
):
    """Box law over replicas under ``prange``."""
    for r in numba_prange(vec.shape[0]):
        _box_replica(
            n_steps,
            stride,
            dt,
            g,
            law,
            wd,
            fw,
            skin,
            vec[r],
            sca[r],
            ivec[r],
            walls[r],
            pair_start[r],
            pair_j[r],
            pair_xi[r],
            old_start[r],
            old_j[r],
            old_xi[r],
            cell_count[r],
            cell_start[r],
            clock[r],
            counters[r],
            out_speed[r],
            info[r],
        )


@njit
def refresh_serial(
    law_id,
    tangent,
    g,
    law,
    wd,
    fw,
    skin,
    vec,
    sca,
    ivec,
    walls,
    pair_start,
    pair_j,
    pair_xi,
    old_start,
    old_j,
    old_xi,
    cell_count,
    cell_start,
    clock,
    counters,
    dt,
    info,
):
    """:func:`_refresh_replica` over replicas."""
    for r in range(vec.shape[0]):
        _refresh_replica(
            law_id,
            tangent,
            g,
            law,
            wd,
            fw,
            skin,
            vec[r],
            sca[r],
            ivec[r],
            walls[r],
            pair_start[r],
            pair_j[r],
            pair_xi[r],
            old_start[r],
            old_j[r],
            old_xi[r],
            cell_count[r],
            cell_start[r],
            clock[r],
            counters[r],
            dt,
            info[r],
        )


@njit
def tangent_forces_serial(
    g, law, fw, vec, sca, ivec, pair_start, pair_j, clock, counters, dt, info
):
    """Evaluate drum-law forces with their perturbation on the current list (no rebuild).

    The caller restores forces and contact counts afterwards; only ``T_FRC`` and ``T_PREV``
    are meant to change.
    """
    for r in range(vec.shape[0]):
        t = _time(clock[r], counters[r], dt)
        zb = 0.0
        vb = 0.0
        if fw[4] != 0.0:
            zb = bottom_height(fw, t)
            vb = bottom_velocity(fw, t)
        _drum_forces(
            vec[r],
            sca[r],
            ivec[r],
            g[0],
            g[1],
            law,
            fw,
            zb,
            vb,
            pair_start[r],
            pair_j[r],
            True,
            info[r],
            counters[r][STEP],
        )
        tr = vec[r][T_POS]
        tv = vec[r][T_VEL]
        prev = sca[r][T_PREV]
        for i in range(tr.shape[0]):
            prev[i] = tr[i, 0] ** 2 + tr[i, 1] ** 2 + tv[i, 0] ** 2 + tv[i, 1] ** 2
