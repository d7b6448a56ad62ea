"""The generic scalar passes: any law of the contract, forward and with tangent dynamics.

The reference path of :mod:`granpipe.engine.contract`: one pair pass, one per-disk pass
and one replica loop, written once, that run any law through its leaves
(:func:`~granpipe.engine.contract.pair_force`, :func:`~granpipe.engine.contract.
pair_force_jvp`), with spin and tangential history where the law has them. numba
compiles them once per law (per parameter type). Plain loops, no vector intrinsics:
correctness first; a law that needs more speed opts into a path of its own
(:meth:`granpipe.engine.contract.ContactLaw.kernels`).

Storage: the engine's (:mod:`granpipe.engine.layout`: its rows and the ``STORAGE``
tuple), with the spin perturbation and its torque in the rows
``T_SPIN``, ``T_TORQUE`` and the history's perturbation per listed pair in
``pair_dxi``. Contacts are between disks; wall disks (``is_wall``) move as prescribed
and turn with the drum (their spin is the wall's angular velocity). A flat wall is the
second disk of a contact made infinitely heavy and still (the bottom moving with the
drive), with the law's parameters at that wall
(:meth:`~granpipe.engine.contract.ContactLaw.wall_leaf_params`) and a shear history
(and its perturbation) per disk and wall.

One step ``n -> n+1`` (velocity Verlet, forces at half-step velocities, as everywhere
in the engine)::

    w = v_n + (dt/2) F_n/m,   s = omega_n + (dt/2) T_n/I,   r_n+1 = r_n + dt w
    walls to t_n+1; rebuild the list if needed (histories carried over)
    F_n+1, T_n+1, xi_n+1 = contacts at (r_n+1, w, s, xi_n), history advanced by dt
    v_n+1 = w + (dt/2) F_n+1/m,   omega_n+1 = s + (dt/2) T_n+1/I

The tangent step is the exact linearisation of this map: the same lines with
``(dr, dv, domega, dxi)`` and ``(dF, dT, dxi_n+1) = J (dd, dw, ds, dxi_n)`` from the
law's Jacobian leaf (walls carry no perturbation). The local Lyapunov exponent is
recorded as for the drum law, over the disks with at least two contacts, with the
per-disk norm ``|dr|² + |dv|² + (a domega)²`` (``a`` the radius: the spin's
perturbation as a velocity at the rim, so that the norm is the drum law's for a disk
that does not turn).

Pieces: each pair's smooth piece at the last evaluation is kept in ``touch`` (0: apart,
``1 + piece`` otherwise), so that a tangent vector set later is the derivative of the
same piece the forces came from.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange as numba_prange

from granpipe._jit import njit, pnjit
from granpipe.engine.contract import Kernels, pair_force, pair_force_jvp, profile_hook
from granpipe.engine.kernels import (
    _BIG,
    _LAM_N,
    _LAM_SUM,
    _NBLK,
    _RENORM_HI,
    _RENORM_LO,
    _RENORM_MAX,
    _advance_walls,
    _at,
    _block_means,
    _bottom,
    _fail,
    _rebuild,
    _set_gravity,
    _time,
    _update_wall_disks,
    _wall_gap,
    _wall_normal,
)
from granpipe.engine.layout import (
    CONTACT_SUM,
    CONTACTS,
    DEEP_OVERLAP,
    FORCE_REBUILD,
    FRC,
    INV_INERTIA,
    INV_MASS,
    IS_WALL,
    LAST_OMEGA,
    LEFT_WALL,
    LIST_OVERFLOW,
    LOG2_SCALE,
    MG,
    N_PAIRS,
    N_WALLS,
    NONFINITE,
    OK,
    OVERLAP_FRAC,
    P_LIM,
    P_MEFF,
    P_SUM,
    PI,
    PIECE_LEFT,
    PJ,
    POS,
    POS_BUILD,
    RADIUS,
    SPIN,
    STEP,
    STEPS_RUN,
    T_FRC,
    T_POS,
    T_PREV,
    T_SPIN,
    T_TORQUE,
    T_VEL,
    T_XI_LEFT,
    TANGENT_NONFINITE,
    THETA,
    TORQUE,
    VEL,
    XI_LEFT,
)
from granpipe.engine.neighbours import carry_history
from granpipe.engine.walls import wall_omega, wall_torque_factor, wall_velocity

__all__ = ["GENERIC_KERNELS"]


# --------------------------------------------------------------------------- pair pass


@njit
def _pair_pass(law, vec, sca, ivec, pair_ij, pair_c, pair_xi, pair_dxi, touch, npairs, dt, mode):
    """Contact forces of every listed pair into the force and torque rows.

    ``mode`` 0: forward only (history advanced by ``dt``, pieces stored); 1: forward and
    tangent; 2: tangent only (perturbations of the stored pieces; forces, torques and
    histories untouched). Returns ``(contacts, k_bad)``: the number of touching pairs and
    the first pair deeper than its bound (-1 if none).
    """
    pos = vec[POS]
    vel = vec[VEL]
    frc = vec[FRC]
    radius = sca[RADIUS]
    spin = sca[SPIN]
    trq = sca[TORQUE]
    tr = vec[T_POS]
    tv = vec[T_VEL]
    tf = vec[T_FRC]
    tw = sca[T_SPIN]
    tt = sca[T_TORQUE]
    contacts = ivec[CONTACTS]
    pi = pair_ij[PI]
    pj = pair_ij[PJ]
    forward = mode != 2
    tangent = mode != 0
    ncon = 0
    for k in range(npairs):
        i = pi[k]
        j = pj[k]
        dx = pos[i, 0] - pos[j, 0]
        dy = pos[i, 1] - pos[j, 1]
        r2 = dx * dx + dy * dy
        s = pair_c[P_SUM, k]
        if r2 > s * s:
            if forward:
                pair_xi[k] = 0.0
                touch[k] = 0
            if tangent:
                pair_dxi[k] = 0.0
            continue
        r = math.sqrt(r2)
        if s - r > pair_c[P_LIM, k]:
            return ncon, k
        ncon += 1
        contacts[i] += 1
        contacts[j] += 1
        nx = dx / r
        ny = dy / r
        ai = radius[i]
        aj = radius[j]
        lev_i = 0.5 * (r + ai - aj)
        lev_j = 0.5 * (r + aj - ai)
        vx = vel[i, 0] - vel[j, 0]
        vy = vel[i, 1] - vel[j, 1]
        m_eff = pair_c[P_MEFF, k]
        fx, fy, ti, tj, xi_new, f_n, f_t, piece = pair_force(
            law, nx, ny, r - s, lev_i, lev_j, vx, vy, spin[i], spin[j], m_eff, pair_xi[k], dt
        )
        if forward:
            frc[i, 0] += fx
            frc[i, 1] += fy
            frc[j, 0] -= fx
            frc[j, 1] -= fy
            trq[i] += ti
            trq[j] += tj
            pair_xi[k] = xi_new
            touch[k] = 1 + piece
        if tangent:
            dfx, dfy, dti, dtj, dxi_new = pair_force_jvp(
                law,
                nx,
                ny,
                1.0 / r,
                lev_i,
                lev_j,
                vx,
                vy,
                spin[i],
                spin[j],
                m_eff,
                f_n,
                f_t,
                touch[k] - 1,
                dt,
                tr[i, 0] - tr[j, 0],
                tr[i, 1] - tr[j, 1],
                tv[i, 0] - tv[j, 0],
                tv[i, 1] - tv[j, 1],
                tw[i],
                tw[j],
                pair_dxi[k],
            )
            tf[i, 0] += dfx
            tf[i, 1] += dfy
            tf[j, 0] -= dfx
            tf[j, 1] -= dfy
            tt[i] += dti
            tt[j] += dtj
            pair_dxi[k] = dxi_new
    return ncon, -1


@njit
def _wall_pass(walls, vec, sca, ivec, fw, zb, vb, dt, mode, overlap_frac):
    """Contacts of every mobile disk with the flat walls (``walls``: the leaves' parameters
    at the left, right and bottom wall), as the pair pass does for a pair whose second
    disk is the wall: infinitely heavy, not turning, moving with the bottom's velocity
    ``vb`` (at height ``zb``); normal from the wall into the box, contact point
    mid-overlap (lever ``a_i - overlap/2``), ``m_eff`` the disk's mass, the shear history
    per disk and wall (``sca[XI_LEFT + w]``, its perturbation ``sca[T_XI_LEFT + w]``).
    The wall does not move in tangent space, so the relative perturbation is the disk's.

    Returns ``(contacts, bad disk, bad wall)``: the disk and wall (0, 1, 2) of the first
    overlap deeper than ``overlap_frac`` times the disk's radius (-1 if none).
    """
    pos = vec[POS]
    vel = vec[VEL]
    frc = vec[FRC]
    radius = sca[RADIUS]
    inv_mass = sca[INV_MASS]
    spin = sca[SPIN]
    trq = sca[TORQUE]
    tr = vec[T_POS]
    tv = vec[T_VEL]
    tf = vec[T_FRC]
    tw = sca[T_SPIN]
    tt = sca[T_TORQUE]
    wall = ivec[IS_WALL]
    contacts = ivec[CONTACTS]
    forward = mode != 2
    tangent = mode != 0
    ncon = 0
    for w in range(3):
        if fw[2 * w] == 0.0:
            continue
        law = walls[w]
        xi_w = sca[XI_LEFT + w]
        dxi_w = sca[T_XI_LEFT + w]
        piece_w = ivec[PIECE_LEFT + w]
        nx, ny = _wall_normal(w)
        for i in range(pos.shape[0]):
            if wall[i] != 0:
                continue
            ai = radius[i]
            overlap = ai - _wall_gap(w, pos, i, fw, zb)
            if overlap < 0.0:
                if forward:
                    xi_w[i] = 0.0
                    piece_w[i] = 0
                if tangent:
                    dxi_w[i] = 0.0
                continue
            if overlap > overlap_frac * ai:
                return ncon, i, w
            ncon += 1
            contacts[i] += 1
            lev_i = ai - 0.5 * overlap
            vx = vel[i, 0]
            vy = vel[i, 1] - wall_velocity(fw, w, vb)
            m_i = 1.0 / inv_mass[i]
            fx, fy, ti, _tj, xi_new, f_n, f_t, piece = pair_force(
                law, nx, ny, -overlap, lev_i, 0.0, vx, vy, spin[i], 0.0, m_i, xi_w[i], dt
            )
            if forward:
                frc[i, 0] += fx
                frc[i, 1] += fy
                trq[i] += ti * wall_torque_factor(fw)
                xi_w[i] = xi_new
                piece_w[i] = 1 + piece
            if tangent:
                dfx, dfy, dti, _dtj, dxi_new = pair_force_jvp(
                    law, nx, ny, 0.0, lev_i, 0.0, vx, vy, spin[i], 0.0, m_i, f_n, f_t,
                    piece_w[i] - 1, dt, tr[i, 0], tr[i, 1], tv[i, 0], tv[i, 1], tw[i], 0.0,
                    dxi_w[i],
                )  # fmt: skip
                tf[i, 0] += dfx
                tf[i, 1] += dfy
                tt[i] += dti * wall_torque_factor(fw)
                dxi_w[i] = dxi_new
    return ncon, -1, -1


@njit
def _forces(
    law, vec, sca, ivec, pair_ij, pair_c, pair_xi, pair_dxi, touch, counters, dt, mode, info, step,
    fw, zb, vb, overlap_frac,
):  # fmt: skip
    """Zero the rows (gravity into the forces), run the pair pass and the flat walls'
    pass, clear the wall disks' rows. ``law`` is ``(pair parameters, (left, right,
    bottom) wall parameters)``.

    Returns the contact count, or -1 after recording a bad overlap in ``info``.
    """
    frc = vec[FRC]
    mg = vec[MG]
    trq = sca[TORQUE]
    tf = vec[T_FRC]
    tt = sca[T_TORQUE]
    contacts = ivec[CONTACTS]
    n = frc.shape[0]
    for i in range(n):
        contacts[i] = 0
        if mode != 2:
            frc[i, 0] = mg[i, 0]
            frc[i, 1] = mg[i, 1]
            trq[i] = 0.0
        if mode != 0:
            tf[i, 0] = 0.0
            tf[i, 1] = 0.0
            tt[i] = 0.0
    ncon, bad = _pair_pass(
        law[0], vec, sca, ivec, pair_ij, pair_c, pair_xi, pair_dxi, touch, counters[N_PAIRS],
        dt, mode,
    )  # fmt: skip
    if bad >= 0:
        _fail(info, DEEP_OVERLAP, pair_ij[PI, bad], pair_ij[PJ, bad], step)
        return -1
    nwall, bad_i, bad_w = _wall_pass(law[1], vec, sca, ivec, fw, zb, vb, dt, mode, overlap_frac)
    if bad_i >= 0:
        _fail(info, DEEP_OVERLAP, bad_i, LEFT_WALL - bad_w, step)
        return -1
    ncon += nwall
    wall = ivec[IS_WALL]
    for i in range(n):
        if wall[i] != 0:
            frc[i, 0] = 0.0
            frc[i, 1] = 0.0
            trq[i] = 0.0
            tf[i, 0] = 0.0
            tf[i, 1] = 0.0
            tt[i] = 0.0
    return ncon


@njit
def _rebuild_generic(vec, sca, ivec, skin, st, counters, clock):
    """Rebuild the list; carry the histories (and their perturbations) of kept pairs."""
    # fmt: off
    (_vec, _sca, _ivec, _walls, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, old_start,
     old_j, old_xi, old_dxi, _buf, touch, cell_count, cell_start, _clock, _counters) = st
    # fmt: on
    n = vec.shape[1]
    npairs = counters[N_PAIRS]
    pj = pair_ij[PJ]
    for i in range(n + 1):
        old_start[i] = pair_start[i]
    for k in range(npairs):
        old_j[k] = pj[k]
        old_xi[k] = pair_xi[k]
        old_dxi[k] = pair_dxi[k]
    if not _rebuild(
        vec, sca, ivec, skin, pair_start, pair_ij, pair_c, cell_count, cell_start, clock, counters
    ):
        return False
    if npairs == 0:
        for k in range(counters[N_PAIRS]):
            pair_xi[k] = 0.0
            pair_dxi[k] = 0.0
    else:
        carry_history(old_start, old_j, old_xi, pair_start, pj, pair_xi)
        carry_history(old_start, old_j, old_dxi, pair_start, pj, pair_dxi)
    # pieces are recomputed at the next evaluation; a pair with history touched
    for k in range(counters[N_PAIRS]):
        touch[k] = 0
    return True


# --------------------------------------------------------------------------- per-disk passes


@njit
def _kick_drift(vec, sca, ivec, dt, half_skin, tangent):
    """First half kick and drift of the mobile disks (and of the tangent vector).

    Returns ``(moved, bad)``: some disk is farther than ``half_skin`` from where it was
    at the last list build; a half-step velocity or spin is not finite (or huge).
    """
    pos = vec[POS]
    vel = vec[VEL]
    frc = vec[FRC]
    build = vec[POS_BUILD]
    spin = sca[SPIN]
    trq = sca[TORQUE]
    inv_m = sca[INV_MASS]
    inv_i = sca[INV_INERTIA]
    wall = ivec[IS_WALL]
    tr = vec[T_POS]
    tv = vec[T_VEL]
    tf = vec[T_FRC]
    tw = sca[T_SPIN]
    tt = sca[T_TORQUE]
    h = 0.5 * dt
    thr2 = half_skin * half_skin
    moved = False
    bad = False
    for i in range(pos.shape[0]):
        if wall[i] != 0:
            continue
        for c in range(2):
            w = vel[i, c] + h * (frc[i, c] * inv_m[i])
            vel[i, c] = w
            pos[i, c] = pos[i, c] + dt * w
            bad = bad or not abs(w) < _BIG
        s = spin[i] + h * (trq[i] * inv_i[i])
        spin[i] = s
        bad = bad or not abs(s) < _BIG
        ex = pos[i, 0] - build[i, 0]
        ey = pos[i, 1] - build[i, 1]
        moved = moved or ex * ex + ey * ey > thr2
        if tangent:
            for c in range(2):
                dw = tv[i, c] + h * (tf[i, c] * inv_m[i])
                tv[i, c] = dw
                tr[i, c] = tr[i, c] + dt * dw
            tw[i] = tw[i] + h * (tt[i] * inv_i[i])
    return moved, bad


@njit
def _final_kick(vec, sca, ivec, dt, tangent):
    """Second half kick; returns ``(sum |v|² over mobile disks, bad)``."""
    vel = vec[VEL]
    frc = vec[FRC]
    spin = sca[SPIN]
    trq = sca[TORQUE]
    inv_m = sca[INV_MASS]
    inv_i = sca[INV_INERTIA]
    wall = ivec[IS_WALL]
    tv = vec[T_VEL]
    tf = vec[T_FRC]
    tw = sca[T_SPIN]
    tt = sca[T_TORQUE]
    h = 0.5 * dt
    v2 = 0.0
    bad = False
    for i in range(vel.shape[0]):
        if wall[i] != 0:
            continue
        for c in range(2):
            w = vel[i, c] + h * (frc[i, c] * inv_m[i])
            vel[i, c] = w
            v2 += w * w
            bad = bad or not abs(w) < _BIG
        s = spin[i] + h * (trq[i] * inv_i[i])
        spin[i] = s
        bad = bad or not abs(s) < _BIG
        if tangent:
            for c in range(2):
                tv[i, c] = tv[i, c] + h * (tf[i, c] * inv_m[i])
            tw[i] = tw[i] + h * (tt[i] * inv_i[i])
    return v2, bad


@njit
def _first_bad(vec, sca, ivec):
    """Index of the first mobile disk with a non-finite (or huge) velocity or spin."""
    vel = vec[VEL]
    spin = sca[SPIN]
    wall = ivec[IS_WALL]
    for i in range(vel.shape[0]):
        if wall[i] == 0 and not (abs(vel[i, 0]) + abs(vel[i, 1]) + abs(spin[i]) < _BIG):
            return i
    return -1


@njit
def _disk_norm(vec, sca, i):
    """``|dr_i|² + |dv_i|² + (a_i domega_i)²``."""
    tr = vec[T_POS]
    tv = vec[T_VEL]
    rw = sca[RADIUS, i] * sca[T_SPIN, i]
    return tr[i, 0] ** 2 + tr[i, 1] ** 2 + tv[i, 0] ** 2 + tv[i, 1] ** 2 + rw * rw


@njit
def _norms(vec, sca, ivec):
    """``(num, den, total)`` of a finished step: the tangent norm² over the disks with at
    least two contacts now and at the previous step, and over all mobile disks; the
    per-disk norms are kept for the next step."""
    prev = sca[T_PREV]
    wall = ivec[IS_WALL]
    contacts = ivec[CONTACTS]
    num = 0.0
    den = 0.0
    total = 0.0
    for i in range(prev.shape[0]):
        if wall[i] != 0:
            continue
        q = _disk_norm(vec, sca, i)
        if contacts[i] >= 2:
            num += q
            den += prev[i]
        prev[i] = q
        total += q
    return num, den, total


@njit
def _renormalise(vec, sca, pair_dxi, npairs, num, total, counters):
    """Scale the tangent vector by a power of two when its norm leaves the safe range
    (exact; the scale is kept in ``LOG2_SCALE``)."""
    ref = num if num > 0.0 else total
    if not (ref > _RENORM_HI or (0.0 < ref < _RENORM_LO) or total > _RENORM_MAX):
        return
    e = int(math.floor(0.5 * math.log2(ref)))
    e = max(e, int(math.ceil(0.5 * math.log2(total))) - 450)
    c = math.ldexp(1.0, -e)
    for row in (T_POS, T_VEL, T_FRC):
        a = vec[row]
        for i in range(a.shape[0]):
            a[i, 0] *= c
            a[i, 1] *= c
    for row in (T_SPIN, T_TORQUE):
        b = sca[row]
        for i in range(b.shape[0]):
            b[i] *= c
    prev = sca[T_PREV]
    for i in range(prev.shape[0]):
        prev[i] *= c * c
    for k in range(npairs):
        pair_dxi[k] *= c
    counters[LOG2_SCALE] += e


# --------------------------------------------------------------------------- one replica


@njit
def _replica(
    law, n_steps, stride, tangent, dt, g, wd, fw, skin, st, out_lam, out_nlam, out_speed, info
):
    """Advance one replica ``n_steps``; block means of ``V`` (and lambda) every ``stride``."""
    # fmt: off
    (vec, sca, ivec, walls, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, old_start,
     old_j, old_xi, old_dxi, buf, touch, cell_count, cell_start, clock, counters) = st
    # fmt: on
    half_skin = 0.5 * skin
    _set_gravity(vec, sca, g[0], g[1])
    blk = np.zeros(_NBLK)
    mode = 1 if tangent else 0
    for _ in range(n_steps):
        step = counters[STEP] + 1
        moved, bad = _kick_drift(vec, sca, ivec, dt, half_skin, tangent)
        if bad:
            return _fail(info, NONFINITE, _first_bad(vec, sca, ivec), -1, step - 1)
        wmoved, zb, vb = _advance_walls(vec, sca, walls, wd, fw, clock, counters, dt, half_skin)
        counters[STEP] = step
        if moved or wmoved or counters[FORCE_REBUILD] != 0:
            if not _rebuild_generic(vec, sca, ivec, skin, st, counters, clock):
                return _fail(info, LIST_OVERFLOW, -1, -1, step)
        ncon = _forces(
            law,
            vec,
            sca,
            ivec,
            pair_ij,
            pair_c,
            pair_xi,
            pair_dxi,
            touch,
            counters,
            dt,
            mode,
            info,
            step,
            fw,
            zb,
            vb,
            clock[OVERLAP_FRAC],
        )
        if ncon < 0:
            return info[0]
        v2, bad = _final_kick(vec, sca, ivec, dt, tangent)
        if bad:
            return _fail(info, NONFINITE, _first_bad(vec, sca, ivec), -1, step)
        if tangent:
            num, den, total = _norms(vec, sca, ivec)
            if not (total < math.inf):
                return _fail(info, TANGENT_NONFINITE, -1, -1, step)
            _renormalise(vec, sca, pair_dxi, counters[N_PAIRS], num, total, counters)
            if num > 0.0 and den > 0.0:
                blk[_LAM_SUM] += 0.5 * math.log(num / den) / dt
                blk[_LAM_N] += 1.0
        if stride > 0:
            _block_means(v2, stride, blk, out_speed, out_nlam, out_lam)
        counters[CONTACT_SUM] += ncon
        counters[STEPS_RUN] += 1
    return OK


@njit
def _refresh_replica(law, tangent, rebuild, g, wd, fw, skin, st, dt, info):
    """Place the walls, rebuild the list and evaluate the forces at the current state
    (full-step velocities; histories not advanced, ``dt = 0``); with ``tangent`` the
    perturbations too, and the per-disk norms behind lambda."""
    # fmt: off
    (vec, sca, ivec, walls, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, old_start,
     old_j, old_xi, old_dxi, buf, touch, cell_count, cell_start, clock, counters) = st
    # fmt: on
    t = _time(clock, counters, dt)
    n_walls = counters[N_WALLS]
    if n_walls > 0 and rebuild:
        omega = wall_omega(wd, t)
        _update_wall_disks(vec, sca, walls, n_walls, wd, clock[THETA], omega)
        clock[LAST_OMEGA] = omega
    step = counters[STEP]
    zb, vb = _bottom(fw, t)
    _set_gravity(vec, sca, g[0], g[1])
    i = _first_bad(vec, sca, ivec)
    if i >= 0:
        return _fail(info, NONFINITE, i, -1, step)
    if rebuild and not _rebuild_generic(vec, sca, ivec, skin, st, counters, clock):
        return _fail(info, LIST_OVERFLOW, -1, -1, step)
    ncon = _forces(
        law,
        vec,
        sca,
        ivec,
        pair_ij,
        pair_c,
        pair_xi,
        pair_dxi,
        touch,
        counters,
        0.0,
        1 if tangent else 0,
        info,
        step,
        fw,
        zb,
        vb,
        clock[OVERLAP_FRAC],
    )
    if ncon < 0:
        return info[0]
    if tangent:
        _norms(vec, sca, ivec)
    return OK


@njit
def _tangent_replica(law, g, wd, fw, skin, st, dt, info):
    """The perturbations ``(dF, dT, dxi)`` of a freshly set tangent vector, on the pieces
    of the last evaluation; the forward state is not touched."""
    # fmt: off
    (vec, sca, ivec, walls, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, old_start,
     old_j, old_xi, old_dxi, buf, touch, cell_count, cell_start, clock, counters) = st
    # fmt: on
    zb, vb = _bottom(fw, _time(clock, counters, dt))
    ncon = _forces(
        law,
        vec,
        sca,
        ivec,
        pair_ij,
        pair_c,
        pair_xi,
        pair_dxi,
        touch,
        counters,
        0.0,
        2,
        info,
        counters[STEP],
        fw,
        zb,
        vb,
        clock[OVERLAP_FRAC],
    )
    if ncon < 0:
        return info[0]
    _norms(vec, sca, ivec)
    return OK


# --------------------------------------------------------------------------- drivers


@njit
def run_serial(
    law, n_steps, stride, tangent, dt, g, wd, fw, skin, st, out_lam, out_nlam, out_speed, info
):
    """:func:`_replica` over replicas one after another (arrays with a leading replica axis)."""
    for r in range(info.shape[0]):
        _replica(
            law,
            n_steps,
            stride,
            tangent,
            dt,
            g,
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
def run_parallel(
    law, n_steps, stride, tangent, dt, g, wd, fw, skin, st, out_lam, out_nlam, out_speed, info
):
    """:func:`_replica` over replicas under ``prange`` (each iteration writes only its own)."""
    for r in numba_prange(info.shape[0]):
        _replica(
            law,
            n_steps,
            stride,
            tangent,
            dt,
            g,
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
def refresh_serial(law, tangent, rebuild, g, wd, fw, skin, st, dt, info):
    """:func:`_refresh_replica` over replicas."""
    for r in range(info.shape[0]):
        _refresh_replica(law, tangent, rebuild, g, wd, fw, skin, _at(st, r), dt, info[r])


@njit
def set_tangent_serial(law, g, wd, fw, skin, st, dt, info):
    """:func:`_tangent_replica` over replicas."""
    for r in range(info.shape[0]):
        _tangent_replica(law, g, wd, fw, skin, _at(st, r), dt, info[r])


@njit
def evaluate_pair(law, nx, ny, delta, lever_i, lever_j, vx, vy, w_i, w_j, m_eff, xi, dt):
    """:func:`~granpipe.engine.contract.pair_force` called from Python (tests, studies)."""
    return pair_force(law, nx, ny, delta, lever_i, lever_j, vx, vy, w_i, w_j, m_eff, xi, dt)


@njit
def evaluate_pair_jvp(
    law, nx, ny, curv, lever_i, lever_j, vx, vy, w_i, w_j, m_eff, f_n, f_t, piece, dt,
    ddx, ddy, dvx, dvy, dw_i, dw_j, dxi,
):  # fmt: skip
    """:func:`~granpipe.engine.contract.pair_force_jvp` called from Python."""
    return pair_force_jvp(
        law, nx, ny, curv, lever_i, lever_j, vx, vy, w_i, w_j, m_eff, f_n, f_t, piece, dt,
        ddx, ddy, dvx, dvy, dw_i, dw_j, dxi,
    )  # fmt: skip


def leaf_parameters(law):
    """What the generic passes take of a law: the leaves' parameters at the pairs and at
    the (left, right, bottom) flat walls."""
    return (law.leaf_params(), law.wall_leaf_params())


GENERIC_KERNELS = Kernels(
    run_serial, run_parallel, refresh_serial, set_tangent_serial, True, True,
    profile_hook("generic_passes"), leaf_parameters,
)  # fmt: skip
