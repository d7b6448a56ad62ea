"""The passes of a step, written once for every contact law: gather, law rows, scatter.

Three tiers (STYLE.md, stumpy): serial per-replica leaves (:func:`replica`,
:func:`refresh_replica`), drivers over a leading replica axis (:func:`run_serial`,
:func:`refresh_serial`; each replica touches only its own storage, so results are
bit-identical however many replicas run side by side), and the Python wrapper in
:mod:`granpipe.engine.simulation`, which runs the replicas of an ensemble in threads (the
kernels release the GIL).

Every pass is compiled per law (its parameter type, :mod:`granpipe.engine.contract`) and
per mode (the markers :data:`FORWARD`, :data:`TANGENT`): the law's capabilities
(:func:`~granpipe.engine.contract.law_has_spin`, :func:`~granpipe.engine.contract.
law_has_history`) and the mode are compile-time constants, so a law without spin or
history, or a run without the tangent vector, carries none of their rows or branches
(the template instances of LAMMPS' OpenMP styles, in numba types).

Storage (per replica, struct of arrays, float64; rows in :mod:`granpipe.engine.layout`):
``vec`` (NV, N, 2) per-disk vectors, ``sca`` (NS, N) per-disk scalars, ``ivec`` (NI, N)
per-disk integers; the neighbour list is CSR (``pair_start``, ``pair_ij[PJ]``) plus the
flat owner index ``pair_ij[PI]``, per-pair constants ``pair_c`` and histories
``pair_xi`` (and their perturbations ``pair_dxi``). The step loop allocates nothing.

One step ``n -> n+1`` (velocity Verlet; forces use half-step velocities, as DEM codes
such as LAMMPS do, so the map is explicit)::

    w      = v_n + (dt/2) F_n / m            (spins: s = omega_n + (dt/2) T_n / I)
    r_n+1  = r_n + dt w
    walls at t_n+1 (positions), t_n+1/2 (velocities); rebuild the list if needed
    F_n+1, T_n+1, xi_n+1 = m g + contacts at (r_n+1, w, s, xi_n), history advanced by dt
    v_n+1  = w + (dt/2) F_n+1 / m            (omega_n+1 likewise)

The tangent step is the exact linearisation of this discrete map: the same lines with
``(dr, dv, domega, dxi)`` and ``(dF, dT, dxi_n+1) = J (dd, dw, ds, dxi_n)`` from the
law's Jacobian leaf (walls carry no perturbation); ``(dr, dv, dF)`` is carried between
steps exactly as ``(r, v, F)`` is.

One evaluation of the contacts (:func:`forces`) is three passes over the flat pair list
(measured: docs/engine_performance.md): :func:`gather` puts the relative coordinates of
every listed pair into contiguous rows (four pairs at a time,
:func:`granpipe.engine.simd.gather4`), :func:`law_rows` calls the law's leaf on them in a
plain loop with no early exit, which LLVM vectorises, and :func:`scatter` adds the forces
to the disks in one flat pass with the owner's sums in registers until its row ends.
When fewer than half the listed pairs touched at the last evaluation, the same passes
run over the touching pairs only (:func:`gather_compact`, :func:`scatter_compact`).
Flat walls have one pass of their own (:func:`flat_walls`) through the same leaves;
wall disks are pairs. The per-disk passes work on the flat ``2N`` rows with vector
intrinsics (:func:`kick_drift`, :func:`tangent_kicks`); the second half kick of a step
is done in the pass of the next step's first kick (same force, same operations), with
the sum behind ``V`` and the list's displacement test.

lambda(t) is recorded over the disks with at least two contacts (drum paper Sec. III),
with the per-disk norm ``|dr|² + |dv|²`` plus ``(a domega)²`` for laws with spin (the
spin's perturbation as a velocity at the rim).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import types
from numba.extending import overload

from granpipe._jit import JIT_OPTIONS, njit, njit_inline
from granpipe.engine import layout as L
from granpipe.engine import simd
from granpipe.engine import walls as W
from granpipe.engine.contract import (
    Contact,
    Perturbation,
    law_has_history,
    law_has_spin,
    pair_force,
    pair_force_jvp,
)
from granpipe.engine.neighbours import rebuild

__all__ = ["Forward", "Tangent", "FORWARD", "TANGENT", "tangent_on", "replica_of", "gather"]
__all__ += ["gather_compact", "law_rows", "scatter", "flat_walls", "forces", "kick_drift"]
__all__ += ["final_kick", "tangent_kicks", "replica", "refresh_replica", "run_serial"]
__all__ += ["place_replica", "place_serial", "refresh_serial"]


# --------------------------------------------------------------------------- modes


class Forward(NamedTuple):
    """Marker of the passes without the tangent vector."""

    tangent: int = 0


class Tangent(NamedTuple):
    """Marker of the passes with the tangent vector (forward and its linearisation)."""

    tangent: int = 1


FORWARD = Forward()
TANGENT = Tangent()


def tangent_on(mode):
    """Whether ``mode`` (:data:`FORWARD` or :data:`TANGENT`) carries the tangent vector;
    a compile-time constant in the passes."""
    return isinstance(mode, Tangent)


@overload(tangent_on, jit_options=JIT_OPTIONS)
def _tangent_on(mode):
    if not isinstance(mode, types.BaseNamedTuple):
        return None
    flag = mode.instance_class is Tangent
    return lambda mode: flag


# --------------------------------------------------------------------------- small helpers

# renormalise the tangent vector when |du|² leaves [2^-400, 2^400]; by powers of two (exact)
_RENORM_HI = 2.0**400
_RENORM_LO = 2.0**-400
_RENORM_MAX = 2.0**950


@njit
def _fail(info, status, particle, other, step):
    info[0] = status
    info[1] = particle
    info[2] = other
    info[3] = step
    return status


@njit
def _flat(a):
    """A C-contiguous array as a flat view (``(N, 2)`` rows as ``2N`` components)."""
    return a.reshape(a.size)


@njit
def replica_of(st, r):
    """Replica ``r`` of the storage tuple ``st`` (the arrays of
    :data:`granpipe.engine.layout.STORAGE`, each with a leading replica axis)."""
    return (
        st[0][r], st[1][r], st[2][r], st[3][r], st[4][r], st[5][r], st[6][r], st[7][r],
        st[8][r], st[9][r], st[10][r], st[11][r], st[12][r], st[13][r], st[14][r],
        st[15][r], st[16][r], st[17][r], st[18][r], st[19][r],
    )  # fmt: skip


@njit
def _set_gravity(vec, sca, gx, gy):
    """Gravity force ``m g`` of every mobile disk (zero for walls) into row L.MG."""
    mg = vec[L.MG]
    mob = vec[L.MOB2]
    inv_mass = sca[L.INV_MASS]
    for i in range(mg.shape[0]):
        m = 1.0 / inv_mass[i] if mob[i, 0] > 0.0 else 0.0
        mg[i, 0] = m * gx
        mg[i, 1] = m * gy


@njit
def _first_nonfinite(vec, sca):
    """Index of the first mobile disk with a non-finite (or huge) velocity or spin."""
    vel = vec[L.VEL]
    spin = sca[L.SPIN]
    mob = vec[L.MOB2]
    for i in range(vel.shape[0]):
        if mob[i, 0] > 0.0 and not (abs(vel[i, 0]) + abs(vel[i, 1]) + abs(spin[i]) < simd.BIG):
            return i
    return -1


# --------------------------------------------------------------------------- pair passes


@njit
def gather(law, mode, vec, sca, pair_ij, buf, npairs):
    """Relative positions and velocities of every listed pair into contiguous rows
    (``B_DX`` ..), with the spins (``B_WI``, ``B_WJ``; laws with spin) and the tangent
    vector's differences (``B_EX`` .., ``B_DWI``, ``B_DWJ``; :data:`TANGENT`).

    Four pairs at a time from the flat position and velocity rows, the lanes stored as
    row vectors (:func:`granpipe.engine.simd.gather4`; bit-identical to the scalar
    subtraction).
    """
    pi = pair_ij[L.PI]
    pj = pair_ij[L.PJ]
    cap = buf.shape[1]
    rows = buf.reshape(buf.size)
    p, v, w = _flat(vec[L.POS]), _flat(vec[L.VEL]), sca[L.SPIN]
    _gather_rows(law, p, v, w, pi, pj, npairs, rows, cap, L.B_DX, L.B_WI)
    if tangent_on(mode):
        tr, tv, tw = _flat(vec[L.T_POS]), _flat(vec[L.T_VEL]), sca[L.T_SPIN]
        _gather_rows(law, tr, tv, tw, pi, pj, npairs, rows, cap, L.B_EX, L.B_DWI)


@njit
def _gather_rows(law, p, v, w, pi, pj, npairs, rows, cap, row, wrow):
    """``p[i] - p[j]`` and ``v[i] - v[j]`` (flat ``2N`` rows) of every listed pair into
    the four buffer rows from ``row`` on, and (laws with spin) ``w[i]``, ``w[j]`` into the
    two from ``wrow`` on."""
    m4 = npairs - npairs % 4
    at = row * cap
    if law_has_spin(law):
        wat = wrow * cap
        for k in range(0, m4, 4):
            simd.gather4_spins(p, v, pi, pj, k, 4, rows, cap, at, w, wat)
        if m4 < npairs:
            simd.gather4_spins_tail(p, v, pi, pj, m4, npairs - m4, rows, cap, at, w, wat)
    else:
        for k in range(0, m4, 4):
            simd.gather4(p, v, pi, pj, k, 4, rows, cap, at)
        if m4 < npairs:
            simd.gather4_tail(p, v, pi, pj, m4, npairs - m4, rows, cap, at)


@njit
def gather_compact(law, mode, vec, sca, pair_ij, pair_c, pair_xi, pair_dxi, buf, npairs):
    """Like :func:`gather`, keeping only touching pairs, with their constants (rows
    ``B_S`` .. ``B_D``) and histories (``B_XI``, ``B_DXI``).

    A pair found apart loses its history here (and, with :data:`TANGENT`, its
    perturbation: a forward run leaves the tangent vector as it was, and a new one is set
    before the next run with it). Returns the count m of touching pairs;
    the rows hold m entries and ``pair_ij[L.PK, :m]`` their pair indices. Groups of four
    listed pairs that are all apart are skipped after one four-lane test
    (:func:`granpipe.engine.simd.touch_bits4`; in a dilute state most are, and a branch
    per pair mispredicts on the few that touch).
    """
    p = _flat(vec[L.POS])
    v = _flat(vec[L.VEL])
    tr = _flat(vec[L.T_POS])
    tv = _flat(vec[L.T_VEL])
    w = sca[L.SPIN]
    tw = sca[L.T_SPIN]
    pi = pair_ij[L.PI]
    pj = pair_ij[L.PJ]
    ssum = pair_c[L.P_SUM]
    m = 0
    m4 = npairs - npairs % 4
    for g in range(0, m4, 4):
        if simd.touch_bits4(p, pi, pj, g, ssum) == 0:
            if law_has_history(law):
                for k in range(g, g + 4):
                    pair_xi[k] = 0.0
                    if tangent_on(mode):
                        pair_dxi[k] = 0.0
            continue
        for k in range(g, g + 4):
            m = _compact_pair(law, mode, p, v, tr, tv, w, tw, pair_ij, pair_c, pair_xi, pair_dxi,
                              buf, k, m)  # fmt: skip
    for k in range(m4, npairs):
        m = _compact_pair(law, mode, p, v, tr, tv, w, tw, pair_ij, pair_c, pair_xi, pair_dxi,
                          buf, k, m)  # fmt: skip
    return m


@njit
def _compact_pair(law, mode, p, v, tr, tv, w, tw, pair_ij, pair_c, pair_xi, pair_dxi, buf, k,
                  m):  # fmt: skip
    """Listed pair ``k`` into entry ``m`` of the compacted rows if it touches (else its
    history is dropped); returns the new count. ``p, v, tr, tv``: the flat positions,
    velocities and their perturbations; ``w, tw``: the spins and theirs.

    Flat arguments: with the storage as named bundles the drum with tangent and the driven
    box ran 4-10 % slower (docs/engine_performance.md, round 13).
    """
    i = pair_ij[L.PI, k]
    j = pair_ij[L.PJ, k]
    two = np.uint32(2)
    one = np.uint32(1)
    i2 = two * i
    j2 = two * j
    x = p[i2] - p[j2]
    y = p[i2 + one] - p[j2 + one]
    s = pair_c[L.P_SUM, k]
    if x * x + y * y > s * s:
        if law_has_history(law):
            pair_xi[k] = 0.0
            if tangent_on(mode):
                pair_dxi[k] = 0.0
        return m
    buf[L.B_DX, m] = x
    buf[L.B_DY, m] = y
    buf[L.B_DVX, m] = v[i2] - v[j2]
    buf[L.B_DVY, m] = v[i2 + one] - v[j2 + one]
    buf[L.B_S, m] = s
    buf[L.B_L, m] = pair_c[L.P_LIM, k]
    buf[L.B_M, m] = pair_c[L.P_MEFF, k]
    buf[L.B_D, m] = pair_c[L.P_DIFF, k]
    if tangent_on(mode):
        buf[L.B_EX, m] = tr[i2] - tr[j2]
        buf[L.B_EY, m] = tr[i2 + one] - tr[j2 + one]
        buf[L.B_EVX, m] = tv[i2] - tv[j2]
        buf[L.B_EVY, m] = tv[i2 + one] - tv[j2 + one]
    if law_has_spin(law):
        buf[L.B_WI, m] = w[i]
        buf[L.B_WJ, m] = w[j]
        if tangent_on(mode):
            buf[L.B_DWI, m] = tw[i]
            buf[L.B_DWJ, m] = tw[j]
    if law_has_history(law):
        buf[L.B_XI, m] = pair_xi[k]
        if tangent_on(mode):
            buf[L.B_DXI, m] = pair_dxi[k]
    pair_ij[L.PK, m] = k
    return m + 1


# Inlined in numba's IR: as plain calls they left 150 calls in law_rows' machine code against
# the alias block's 96, and the drum with tangent ran 1-4 %, the driven box 3-5 % slower
# (docs/engine_performance.md, round 13).
@njit_inline
def _in_rows(buf):
    """The buffer's rows the gather writes, as views: ``(dx, dy, dvx, dvy, ex, ey, evx,
    evy, wi, wj, dwi, dwj)`` (:mod:`granpipe.engine.layout`, ``B_DX`` .. ``B_DWJ``)."""
    return (
        buf[L.B_DX], buf[L.B_DY], buf[L.B_DVX], buf[L.B_DVY], buf[L.B_EX], buf[L.B_EY],
        buf[L.B_EVX], buf[L.B_EVY], buf[L.B_WI], buf[L.B_WJ], buf[L.B_DWI], buf[L.B_DWJ],
    )  # fmt: skip


# Inlined for the same reason as _in_rows.
@njit_inline
def _out_rows(buf):
    """The buffer's rows the law writes, as views: ``(fx, fy, ti, tj, gx, gy, gti, gtj)``
    (``B_FX`` .. ``B_GTJ``)."""
    return (
        buf[L.B_FX], buf[L.B_FY], buf[L.B_TI], buf[L.B_TJ], buf[L.B_GX], buf[L.B_GY],
        buf[L.B_GTI], buf[L.B_GTJ],
    )  # fmt: skip


@njit
def law_rows(law, mode, buf, ssum, slim, smeff, sdiff, xis, dxis, touch, flip, m, dt):
    """The law's leaf on rows ``0 .. m-1`` of the gathered pairs: forces (and torques,
    histories and, with :data:`TANGENT`, their perturbations) into the buffer, zero where
    a pair is apart. Returns ``(touching pairs, some pair deeper than its bound, touch
    flags that changed)``.

    ``ssum, slim, smeff, sdiff`` are the pairs' ``a_i + a_j``, overlap bound, ``m_eff``
    and ``a_i - a_j``; ``xis``, ``dxis`` their histories and perturbations, advanced in
    place (one array read and written: a second output array, even the same one, made
    LLVM check for overlap at run time and fall back to scalar code). ``touch`` holds
    each pair's contact flag; with :data:`TANGENT`, ``flip`` gets its change (+1, -1, 0),
    so that per-disk contact counts can be moved instead of recounted. A plain loop with
    no early exit: LLVM vectorises it (tests/engine/test_contract.py checks the assembly).
    Flat arguments: with the storage as named bundles the drum with tangent and the driven
    box ran 4-10 % slower (docs/engine_performance.md, round 13).
    """
    spin = law_has_spin(law)
    history = law_has_history(law)
    tangent = tangent_on(mode)
    dxa, dya, dvxa, dvya, exa, eya, evxa, evya, wia, wja, dwia, dwja = _in_rows(buf)
    fxa, fya, tia, tja, gxa, gya, gtia, gtja = _out_rows(buf)
    ncon = 0
    nbad = 0
    nflip = 0
    for k in range(m):
        dx = dxa[k]
        dy = dya[k]
        s = ssum[k]
        r2 = dx * dx + dy * dy
        r = math.sqrt(r2)
        inv_r = 1.0 / r
        nx = dx * inv_r
        ny = dy * inv_r
        delta = r - s
        diff = sdiff[k]
        lev_i = 0.5 * (r + diff)
        lev_j = 0.5 * (r - diff)
        vx = dvxa[k]
        vy = dvya[k]
        wi = wia[k] if spin else 0.0
        wj = wja[k] if spin else 0.0
        m_eff = smeff[k]
        xi = xis[k] if history else 0.0
        contact = Contact(nx, ny, delta, inv_r, lev_i, lev_j, vx, vy, wi, wj, m_eff)
        fx, fy, ti, tj, xi_new, f_n, f_t, piece = pair_force(law, contact, xi, dt)
        t = r2 <= s * s
        fxa[k] = fx if t else 0.0
        fya[k] = fy if t else 0.0
        if spin:
            tia[k] = ti if t else 0.0
            tja[k] = tj if t else 0.0
        if history:
            xis[k] = xi_new if t else 0.0
        c = 1 if t else 0
        if tangent:
            e = Perturbation(
                exa[k], eya[k], evxa[k], evya[k], dwia[k] if spin else 0.0,
                dwja[k] if spin else 0.0, dxis[k] if history else 0.0,
            )  # fmt: skip
            gx, gy, gti, gtj, dxi_new = pair_force_jvp(law, contact, f_n, f_t, piece, dt, e)
            gxa[k] = gx if t else 0.0
            gya[k] = gy if t else 0.0
            if spin:
                gtia[k] = gti if t else 0.0
                gtja[k] = gtj if t else 0.0
            if history:
                dxis[k] = dxi_new if t else 0.0
            d = c - touch[k]
            flip[k] = d
            nflip += 1 if d != 0 else 0
        touch[k] = c
        ncon += c
        nbad += 1 if -delta > slim[k] else 0
    return ncon, nbad > 0, nflip


@njit
def _start_sums(law, mode, vec, sca):
    """Set the forces to gravity and zero the torques and perturbations (the spin rows
    only with spin, the perturbations only with tangent); (forces, their perturbations,
    torques, theirs) as flat views."""
    tangent = tangent_on(mode)
    f = _flat(vec[L.FRC])
    mg = _flat(vec[L.MG])
    tf = _flat(vec[L.T_FRC])
    trq = sca[L.TORQUE]
    tt = sca[L.T_TORQUE]
    for k in range(f.shape[0]):
        f[k] = mg[k]
        if tangent:
            tf[k] = 0.0
    if law_has_spin(law):
        for i in range(trq.shape[0]):
            trq[i] = 0.0
            if tangent:
                tt[i] = 0.0
    return f, tf, trq, tt


@njit
def scatter(law, mode, vec, sca, pair_start, pair_ij, buf):
    """Add the pair forces (torques, perturbations) of the whole list to the disks, over
    gravity.

    One flat pass over the half list (no short inner loops whose exits mispredict): the
    partner's sums go to memory pair by pair, the owner's stay in registers until its row
    ends (consecutive pairs share the owner, and adding to its memory pair by pair would
    chain store-to-load forwarding). Every disk's sum runs in the order of the list.
    """
    spin = law_has_spin(law)
    tangent = tangent_on(mode)
    f, tf, trq, tt = _start_sums(law, mode, vec, sca)
    n = pair_start.shape[0] - 1
    npairs = pair_start[n]
    if npairs == 0:
        return
    pi = pair_ij[L.PI]
    pj = pair_ij[L.PJ]
    fx, fy, ti, tj, gx, gy, gti, gtj = _out_rows(buf)
    two = np.uint32(2)
    one = np.uint32(1)
    prev = pi[0]
    ax = 0.0  # the owner's force,
    ay = 0.0
    at = 0.0  # torque,
    bx = 0.0  # force perturbation
    by = 0.0
    bt = 0.0  # and torque perturbation
    for k in range(npairs):
        i = pi[k]
        j = pj[k]
        j2 = two * j
        a = fx[k]
        b = fy[k]
        f[j2] -= a
        f[j2 + one] -= b
        if spin:
            trq[j] += tj[k]
        if tangent:
            tf[j2] -= gx[k]
            tf[j2 + one] -= gy[k]
            if spin:
                tt[j] += gtj[k]
        if i != prev:
            p2 = two * prev
            f[p2] += ax
            f[p2 + one] += ay
            ax = 0.0
            ay = 0.0
            if spin:
                trq[prev] += at
                at = 0.0
            if tangent:
                tf[p2] += bx
                tf[p2 + one] += by
                bx = 0.0
                by = 0.0
                if spin:
                    tt[prev] += bt
                    bt = 0.0
        ax += a
        ay += b
        if spin:
            at += ti[k]
        if tangent:
            bx += gx[k]
            by += gy[k]
            if spin:
                bt += gti[k]
        prev = i
    p2 = two * prev
    f[p2] += ax
    f[p2 + one] += ay
    if spin:
        trq[prev] += at
    if tangent:
        tf[p2] += bx
        tf[p2 + one] += by
        if spin:
            tt[prev] += bt


@njit
def scatter_compact(law, mode, vec, sca, ivec, pair_ij, buf, pair_xi, pair_dxi, m, count):
    """:func:`scatter` over the m compacted (touching) pairs; writes the histories back
    and, with ``count``, counts each disk's touching pairs into ``PAIR_CONTACTS``."""
    spin = law_has_spin(law)
    history = law_has_history(law)
    tangent = tangent_on(mode)
    f, tf, trq, tt = _start_sums(law, mode, vec, sca)
    contacts = ivec[L.PAIR_CONTACTS]
    if count:
        for i in range(contacts.shape[0]):
            contacts[i] = 0
    pi = pair_ij[L.PI]
    pj = pair_ij[L.PJ]
    pk = pair_ij[L.PK]
    two = np.uint32(2)
    one = np.uint32(1)
    for q in range(m):
        k = pk[q]
        i = pi[k]
        j = pj[k]
        i2 = two * i
        j2 = two * j
        a = buf[L.B_FX, q]
        b = buf[L.B_FY, q]
        f[i2] += a
        f[i2 + one] += b
        f[j2] -= a
        f[j2 + one] -= b
        if tangent:
            a = buf[L.B_GX, q]
            b = buf[L.B_GY, q]
            tf[i2] += a
            tf[i2 + one] += b
            tf[j2] -= a
            tf[j2 + one] -= b
        if spin:
            trq[i] += buf[L.B_TI, q]
            trq[j] += buf[L.B_TJ, q]
            if tangent:
                tt[i] += buf[L.B_GTI, q]
                tt[j] += buf[L.B_GTJ, q]
        if history:
            pair_xi[k] = buf[L.B_XI, q]
            if tangent:
                pair_dxi[k] = buf[L.B_DXI, q]
        if count:
            contacts[i] += 1
            contacts[j] += 1


@njit
def _recount(ivec, pair_ij, touch, npairs):
    """Count each disk's touching listed pairs into ``PAIR_CONTACTS``."""
    pi = pair_ij[L.PI]
    pj = pair_ij[L.PJ]
    pc = ivec[L.PAIR_CONTACTS]
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
def _apply_flips(ivec, pair_ij, flip, npairs):
    """Move the per-disk counts of touching pairs by the flags that changed
    (:func:`law_rows`; a few change per step)."""
    pc = ivec[L.PAIR_CONTACTS]
    pi = pair_ij[L.PI]
    pj = pair_ij[L.PJ]
    for k in range(npairs):
        d = flip[k]
        if d != 0:
            pc[pi[k]] += d
            pc[pj[k]] += d


@njit
def _first_deep_pair(pair_ij, buf, ssum, slim, npairs, compact):
    """First evaluated pair whose overlap exceeds its bound (called after a flag was raised)."""
    for q in range(npairs):
        dx = buf[L.B_DX, q]
        dy = buf[L.B_DY, q]
        r = math.sqrt(dx * dx + dy * dy)
        if ssum[q] - r > slim[q]:
            k = pair_ij[L.PK, q] if compact else q
            return pair_ij[L.PI, k], pair_ij[L.PJ, k]
    return -1, -1


# --------------------------------------------------------------------------- flat walls


@njit
def flat_walls(walls, law, mode, vec, sca, ivec, fw, zb, vb, dt, count, info, step, near):
    """Contacts of the disks with the flat walls, through the law's leaves with the wall's
    parameters (``walls``: at the left, right and bottom wall). A wall is the second disk
    of a contact, infinitely heavy and not turning, moving with the drive (the bottom,
    and the side walls if shaken); normal from the wall into the box, contact point
    mid-overlap (lever ``a_i - overlap/2``), ``m_eff`` the disk's mass, the shear history
    per disk and wall (``sca[L.XI_LEFT + w]``, its perturbation ``sca[L.T_XI_LEFT + w]``).

    ``near`` is ``(skin, clock, counters)``: the disks tested are those of the near-wall
    list (:func:`granpipe.engine.walls.wall_candidates`). Returns the contact count, or
    -1 (bad state recorded in ``info``). Flat arguments: with the storage as named bundles
    the drum with tangent and the driven box ran 4-10 % slower (docs/engine_performance.md,
    round 13).
    """
    spin = law_has_spin(law)
    history = law_has_history(law)
    tangent = tangent_on(mode)
    pos = vec[L.POS]
    vel = vec[L.VEL]
    frc = vec[L.FRC]
    tr = vec[L.T_POS]
    tv = vec[L.T_VEL]
    tf = vec[L.T_FRC]
    radius = sca[L.RADIUS]
    inv_mass = sca[L.INV_MASS]
    contacts = ivec[L.CONTACTS]
    cand = ivec[L.CELL_OF]  # scratch between list builds
    skin, clock, counters = near
    m = W.wall_candidates(
        vec, sca, ivec, fw, zb, skin, history, tangent, clock, counters, cand, info, step
    )
    if m < 0:
        return -1
    lever_torque = W.wall_torque_factor(fw)
    ncon = 0
    for q in range(m):
        i = cand[q]
        ai = radius[i]
        for w in range(3):
            if fw[2 * w] == 0.0:
                continue
            overlap = ai - W.wall_gap(w, pos, i, fw, zb)
            if overlap < 0.0:
                continue
            nx, ny = W.wall_normal(w)
            vx = vel[i, 0]
            vy = vel[i, 1] - W.wall_velocity(fw, w, vb)
            lev = ai - 0.5 * overlap
            m_i = 1.0 / inv_mass[i]
            wi = sca[L.SPIN, i] if spin else 0.0
            xi = sca[L.XI_LEFT + w, i] if history else 0.0
            # the wall's parameters by selects: a NamedTuple picked from the tuple by a
            # run-time index cost the box's wall pass 40 %
            law_w = walls[0] if w == 0 else (walls[1] if w == 1 else walls[2])
            contact = Contact(nx, ny, -overlap, 0.0, lev, 0.0, vx, vy, wi, 0.0, m_i)
            fx, fy, ti, _tj, xi_new, f_n, f_t, piece = pair_force(law_w, contact, xi, dt)
            frc[i, 0] += fx
            frc[i, 1] += fy
            if spin:
                sca[L.TORQUE, i] += ti * lever_torque
            if history:
                sca[L.XI_LEFT + w, i] = xi_new
            if tangent:
                e = Perturbation(
                    tr[i, 0], tr[i, 1], tv[i, 0], tv[i, 1], sca[L.T_SPIN, i] if spin else 0.0,
                    0.0, sca[L.T_XI_LEFT + w, i] if history else 0.0,
                )  # fmt: skip
                dfx, dfy, dti, _dtj, dxi_new = pair_force_jvp(
                    law_w, contact, f_n, f_t, piece, dt, e
                )
                tf[i, 0] += dfx
                tf[i, 1] += dfy
                if spin:
                    sca[L.T_TORQUE, i] += dti * lever_torque
                if history:
                    sca[L.T_XI_LEFT + w, i] = dxi_new
            ncon += 1
            if count:
                contacts[i] += 1
    return ncon


@njit
def count_contacts(vec, sca, ivec, pair_ij, pair_c, npairs, fw, zb):
    """Contact counts at the current positions (those of the last force evaluation), by the
    same test as the force passes (``r² <= (a_i + a_j)²``), flat walls included."""
    contacts = ivec[L.CONTACTS]
    p = _flat(vec[L.POS])
    pos = vec[L.POS]
    mob = vec[L.MOB2]
    radius = sca[L.RADIUS]
    pi = pair_ij[L.PI]
    pj = pair_ij[L.PJ]
    ssum = pair_c[L.P_SUM]
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
            if mob[i, 0] != 0.0 and W.wall_gap(w, pos, i, fw, zb) <= radius[i]:
                contacts[i] += 1


# --------------------------------------------------------------------------- one evaluation


@njit
def forces(
    laws, mode, vec, sca, ivec, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, buf, touch,
    flip, clock, counters, fw, zb, vb, dt, count, info, step, skin,
):  # fmt: skip
    """Every contact force of one evaluation (``laws``: the leaves' parameters at pairs
    and at the three flat walls), histories advanced by ``dt``; with ``count``, each
    disk's contacts (walls included) into ``CONTACTS``. Returns the
    contact count, or -1 after recording a bad overlap in ``info``. The arrays are one
    replica's storage (:data:`granpipe.engine.layout.STORAGE`), passed one by one
    (docs/engine_performance.md, round 13: as named bundles they cost the step loop 4-10 %).

    The law runs on all listed pairs, or only on the touching ones (compacted first) when
    fewer than half of them touched at the last evaluation; the results are the same.
    """
    law = laws[0]
    npairs = counters[L.N_PAIRS]
    compact = 2 * counters[L.LAST_PAIR_CONTACTS] < npairs
    if compact:
        m = gather_compact(law, mode, vec, sca, pair_ij, pair_c, pair_xi, pair_dxi, buf, npairs)
        ssum, slim, smeff, sdiff = buf[L.B_S], buf[L.B_L], buf[L.B_M], buf[L.B_D]
        xis, dxis = buf[L.B_XI], buf[L.B_DXI]
    else:
        m = npairs
        gather(law, mode, vec, sca, pair_ij, buf, m)
        ssum, slim, smeff, sdiff = (
            pair_c[L.P_SUM],
            pair_c[L.P_LIM],
            pair_c[L.P_MEFF],
            pair_c[L.P_DIFF],
        )
        xis, dxis = pair_xi, pair_dxi
    ncon, bad, nflip = law_rows(
        law, mode, buf, ssum, slim, smeff, sdiff, xis, dxis, touch, flip, m, dt
    )
    if bad:
        i, j = _first_deep_pair(pair_ij, buf, ssum, slim, m, compact)
        _fail(info, L.DEEP_OVERLAP, i, j, step)
        return -1
    valid = False
    if compact:
        scatter_compact(law, mode, vec, sca, ivec, pair_ij, buf, pair_xi, pair_dxi, m, count)
    else:
        scatter(law, mode, vec, sca, pair_start, pair_ij, buf)
        if count:
            # the flags of the last evaluation are the list's: move the counts by the
            # flags that changed; otherwise (list rebuilt, compacted or not counted)
            # count them again
            if counters[L.COUNT_STALE] == 0 and tangent_on(mode):
                if nflip > 0:
                    _apply_flips(ivec, pair_ij, flip, m)
            else:
                _recount(ivec, pair_ij, touch, m)
            valid = True
    if count:
        pc = ivec[L.PAIR_CONTACTS]
        contacts = ivec[L.CONTACTS]
        for i in range(pc.shape[0]):
            contacts[i] = pc[i]
    # compacted passes index the touch flags by compact position, not by pair
    counters[L.COUNT_STALE] = 0 if (valid and not compact) else 1
    counters[L.LAST_PAIR_CONTACTS] = ncon
    if W.has_flat(fw):
        nw = flat_walls(
            laws[1], law, mode, vec, sca, ivec, fw, zb, vb, dt, count, info, step,
            (skin, clock, counters),
        )  # fmt: skip
        if nw < 0:
            return -1
        ncon += nw
    return ncon


# --------------------------------------------------------------------------- per-disk passes


@njit
def kick_drift(law, vec, sca, dt, thr, finish, want_v2):
    """First half kick and drift (walls too: zero inverse mass, positions reset after).

    With ``finish``, the second half kick of the previous step is done in the same pass
    (it uses the same force: ``v = w + (dt/2) F/m``, then ``w' = v + (dt/2) F/m``, the
    operations of :func:`final_kick` followed by the first kick), so that the per-disk
    rows are read once per step. Returns ``(moved, v2, bad)``: ``moved`` if some disk is
    now farther than ``thr`` (= skin/2) from where it was at the last list build; for the
    finished step, ``v2`` (sum of ``|v|²`` over mobile disks if ``want_v2``, else 0) and
    ``bad`` (a non-finite or huge half-step velocity or spin).

    Kicks, drift, ``v2`` and the displacement test are one vectorised pass over groups of
    four disks (:func:`granpipe.engine.simd.kick8`; the remaining disks below, the same
    operations); spins (laws with spin) and the tangent vector have their own loops.
    """
    p = _flat(vec[L.POS])
    v = _flat(vec[L.VEL])
    f = _flat(vec[L.FRC])
    im = _flat(vec[L.IM2])
    mob = _flat(vec[L.MOB2])
    b = _flat(vec[L.POS_BUILD])
    h = 0.5 * dt
    thr2 = thr * thr
    n2 = p.shape[0]
    m8 = n2 - n2 % 8
    m4 = n2 - n2 % 4
    if not finish:
        s0, s1, s2, s3, bad, moved = simd.kick8_first(p, v, f, im, mob, b, h, dt, thr2, m8)
    elif want_v2:
        s0, s1, s2, s3, bad, moved = simd.kick8_v2(p, v, f, im, mob, b, h, dt, thr2, m8)
    else:
        s0, s1, s2, s3, bad, moved = simd.kick8(p, v, f, im, mob, b, h, dt, thr2, m8)
    for k in range(m8, n2):
        a = h * (f[k] * im[k])
        u = v[k] + a
        if finish and want_v2:
            # the lanes of simd.speed2_lanes up to m4, the rest into the first (as in final_kick)
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
            bad += 0 if abs(w) < simd.BIG else 1
    for i in range(m8 // 2, n2 // 2):
        dx = p[2 * i] - b[2 * i]
        dy = p[2 * i + 1] - b[2 * i + 1]
        moved += 1 if dx * dx + dy * dy > thr2 else 0
    v2 = (s0 + s1) + (s2 + s3)
    if law_has_spin(law):
        spin = sca[L.SPIN]
        trq = sca[L.TORQUE]
        inv_i = sca[L.INV_INERTIA]
        if finish:
            for i in range(spin.shape[0]):
                a = h * (trq[i] * inv_i[i])
                w = (spin[i] + a) + a
                spin[i] = w
                bad += 0 if abs(w) < simd.BIG else 1
        else:
            for i in range(spin.shape[0]):
                spin[i] = spin[i] + h * (trq[i] * inv_i[i])
    return moved > 0, v2, bad > 0


@njit
def final_kick(law, vec, sca, dt, want_v2):
    """Second half kick; returns (sum |v|² over mobile disks if ``want_v2``, non-finite
    flag). The sum runs in four partial sums (lane ``c`` takes components ``k = c mod
    4``): a fixed order (reproducible) that does not serialise on one add
    (:func:`granpipe.engine.simd.speed2_lanes`)."""
    v = _flat(vec[L.VEL])
    f = _flat(vec[L.FRC])
    im = _flat(vec[L.IM2])
    mob = _flat(vec[L.MOB2])
    h = 0.5 * dt
    v2 = 0.0
    if want_v2:
        m = v.shape[0] - v.shape[0] % 4
        s0, s1, s2, s3 = simd.speed2_lanes(v, f, im, mob, h, m)
        for k in range(m, v.shape[0]):
            u = v[k] + h * (f[k] * im[k])
            s0 += u * u * mob[k]
        v2 = (s0 + s1) + (s2 + s3)
    bad = 0
    for k in range(v.shape[0]):
        w = v[k] + h * (f[k] * im[k])
        v[k] = w
        bad += 0 if abs(w) < simd.BIG else 1
    if law_has_spin(law):
        spin = sca[L.SPIN]
        trq = sca[L.TORQUE]
        inv_i = sca[L.INV_INERTIA]
        for i in range(spin.shape[0]):
            w = spin[i] + h * (trq[i] * inv_i[i])
            spin[i] = w
            bad += 0 if abs(w) < simd.BIG else 1
    return v2, bad > 0


@njit
def tangent_kicks(law, vec, sca, ivec, dt, stage):
    """The tangent vector's per-disk pass; returns ``(num, den, total)``.

    ``stage`` 0: first half kick and drift of the step, ``dw = dv + (dt/2) dF/m``,
    ``dr += dt dw``. ``stage`` 1: first the previous step's second half kick (same
    ``dF``) and its norms, then the kick and drift of stage 0; ``stage`` 2 (end of a
    run): the second half kick and norms only. The norms are of the finished step:
    ``num = |du(t)|²_S`` and ``den = |du(t - dt)|²_S`` with S the disks with at least
    two contacts at that step (walls count), ``total = |du(t)|²`` over mobile disks
    (zero in stage 0). Four disks a group (:func:`granpipe.engine.simd.tangent8`: each
    sum in four lanes over disks ``i = c mod 4``, added in a fixed order, so the result
    does not depend on anything but the state); the remaining disks below. With spin,
    the spins' perturbations are kicked alongside and ``(a domega)²`` is added to each
    disk's norm.
    """
    tr = _flat(vec[L.T_POS])
    tv = _flat(vec[L.T_VEL])
    tf = _flat(vec[L.T_FRC])
    im = _flat(vec[L.IM2])
    mob = _flat(vec[L.MOB2])
    prev = sca[L.T_PREV]
    contacts = ivec[L.CONTACTS]
    n = prev.shape[0]
    n4 = n - n % 4
    h = 0.5 * dt
    spin = law_has_spin(law)
    tw, tt, inv_i, radius = sca[L.T_SPIN], sca[L.T_TORQUE], sca[L.INV_INERTIA], sca[L.RADIUS]
    if spin:
        q = _tangent_groups(stage, tr, tv, tf, im, mob, prev, contacts, h, dt, n4,
                            (tw, tt, inv_i, radius))  # fmt: skip
    else:
        q = _tangent_groups(stage, tr, tv, tf, im, mob, prev, contacts, h, dt, n4, ())
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
        qi = (tr[x] * tr[x] + tr[y] * tr[y] + ux * ux + uy * uy) * mob[x]
        if spin:
            a = h * (tt[i] * inv_i[i])
            u = tw[i] + a
            rw = radius[i] * u
            qi += rw * rw * mob[x]
            tw[i] = u if stage != 1 else u + a
        if stage != 0:
            s = contacts[i] >= 2
            num += qi if s else 0.0
            den += prev[i] if s else 0.0
            prev[i] = qi
            total += qi
        if stage == 2:
            tv[x] = ux
            tv[y] = uy
        else:
            wx = ux if stage == 0 else ux + ax
            wy = uy if stage == 0 else uy + ay
            tv[x] = wx
            tv[y] = wy
            tr[x] = tr[x] + dt * wx
            tr[y] = tr[y] + dt * wy
    num = (num + q[1]) + (q[2] + q[3])
    den = (den + q[5]) + (q[6] + q[7])
    total = (total + q[9]) + (q[10] + q[11])
    return num, den, total


@njit
def _tangent_groups(stage, tr, tv, tf, im, mob, prev, contacts, h, dt, n4, spins):
    """The disks ``i < n4`` of :func:`tangent_kicks` in groups of four (``spins``: the
    spin rows of a law with spin, else ``()``)."""
    if stage == 0:
        return simd.tangent8_first(tr, tv, tf, im, mob, prev, contacts, h, dt, n4, spins)
    if stage == 1:
        return simd.tangent8(tr, tv, tf, im, mob, prev, contacts, h, dt, n4, spins)
    return simd.tangent8_last(tr, tv, tf, im, mob, prev, contacts, h, dt, n4, spins)


@njit
def _tangent_norms(law, vec, sca):
    """Each disk's squared tangent norm into ``T_PREV`` (after a fresh evaluation)."""
    tr = vec[L.T_POS]
    tv = vec[L.T_VEL]
    prev = sca[L.T_PREV]
    mob = vec[L.MOB2]
    for i in range(tr.shape[0]):
        q = tr[i, 0] ** 2 + tr[i, 1] ** 2 + tv[i, 0] ** 2 + tv[i, 1] ** 2
        prev[i] = q * mob[i, 0]
        if law_has_spin(law):
            rw = sca[L.RADIUS, i] * sca[L.T_SPIN, i]
            prev[i] += rw * rw * mob[i, 0]


@njit
def _tangent_done(law, vec, sca, pair_dxi, num, total, info, step, counters):
    """Check a finished step's tangent norms (:func:`tangent_kicks`) and renormalise.

    Returns False (and records the failure at ``step``) on a non-finite vector. The
    renormalisation multiplies the whole tangent vector (and the stored norms) by a power
    of two: exact, so it commutes with the kick and drift already applied in the same
    pass.
    """
    if not (total < math.inf):
        _fail(info, L.TANGENT_NONFINITE, -1, -1, step)
        return False
    # scale by the part that enters lambda (rattlers' components may be far larger or
    # smaller), but never let the whole vector come near overflow
    ref = num if num > 0.0 else total
    if ref > _RENORM_HI or (0.0 < ref < _RENORM_LO) or total > _RENORM_MAX:
        e = int(math.floor(0.5 * math.log2(ref)))
        e = max(e, int(math.ceil(0.5 * math.log2(total))) - 450)
        c = math.ldexp(1.0, -e)
        c2 = c * c
        for row in (L.T_POS, L.T_VEL, L.T_FRC):
            a = _flat(vec[row])
            for k in range(a.shape[0]):
                a[k] *= c
        prev = sca[L.T_PREV]
        for i in range(prev.shape[0]):
            prev[i] *= c2
        if law_has_spin(law):
            for row in (L.T_SPIN, L.T_TORQUE):
                for i in range(prev.shape[0]):
                    sca[row, i] *= c
        if law_has_history(law):
            for k in range(counters[L.N_PAIRS]):
                pair_dxi[k] *= c
            for w in range(3):
                for i in range(prev.shape[0]):
                    sca[L.T_XI_LEFT + w, i] *= c
        counters[L.LOG2_SCALE] += e
    return True


# --------------------------------------------------------------------------- one replica

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
def _lambda_step(law, vec, sca, pair_dxi, num, den, total, dt, blk, info, step, counters):
    """A finished step's ``lambda = (1/2dt) ln(num/den)`` into the block (where defined);
    False on a non-finite tangent vector (:func:`_tangent_done`)."""
    if not _tangent_done(law, vec, sca, pair_dxi, num, total, info, step, counters):
        return False
    if num > 0.0 and den > 0.0:
        blk[_LAM_SUM] += 0.5 * math.log(num / den) / dt
        blk[_LAM_N] += 1.0
    return True


@njit
def replica(laws, mode, n_steps, stride, dt, g, wd, fw, skin, st, out_lam, out_nlam, out_speed,
            info):  # fmt: skip
    """Advance one replica ``n_steps`` (with the tangent vector under :data:`TANGENT`).

    Records, when ``stride > 0``, block means over ``stride`` steps of
    ``V = sqrt(sum |v|²)`` and, with the tangent vector, of ``lambda`` (per-step growth
    rate over non-rattlers; only steps where it is defined count, ``out_nlam`` says how
    many). Returns the status code. Flat arguments: with the storage and the records as
    named bundles the drum with tangent and the driven box ran 4-10 % slower
    (docs/engine_performance.md, round 13).
    """
    # fmt: off
    (vec, sca, ivec, walls, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, _old_start,
     _old_j, _old_xi, _old_dxi, buf, touch, flip, _cell_count, _cell_start, clock,
     counters) = st
    # fmt: on
    law = laws[0]
    tangent = tangent_on(mode)
    history = law_has_history(law)
    half_skin = 0.5 * skin
    _set_gravity(vec, sca, g[0], g[1])
    blk = np.zeros(_NBLK)
    zb = 0.0
    for s in range(n_steps):
        step = counters[L.STEP] + 1
        # the last step's second half kick is done with this step's first (same force)
        moved, v2, bad = kick_drift(law, vec, sca, dt, half_skin, s > 0, stride > 0)
        if bad:
            return _fail(info, L.NONFINITE, _first_nonfinite(vec, sca), -1, step - 1)
        if tangent:
            # the tangent vector's kicks and the last step's norms, in one pass
            num, den, total = tangent_kicks(law, vec, sca, ivec, dt, 1 if s > 0 else 0)
            if s > 0 and not _lambda_step(
                law, vec, sca, pair_dxi, num, den, total, dt, blk, info, step - 1, counters
            ):
                return info[0]
        if s > 0 and stride > 0:
            _block_means(v2, stride, blk, out_speed, out_nlam, out_lam)
        wmoved, zb, vb = W.advance_walls(vec, sca, walls, wd, fw, clock, counters, dt, half_skin)
        counters[L.STEP] = step
        if moved or wmoved or counters[L.FORCE_REBUILD] != 0:
            if not rebuild(vec, sca, ivec, skin, st, history, tangent):
                return _fail(info, L.LIST_OVERFLOW, -1, -1, step)
        ncon = forces(
            laws, mode, vec, sca, ivec, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, buf,
            touch, flip, clock, counters, fw, zb, vb, dt, tangent, info, step, skin,
        )  # fmt: skip
        if ncon < 0:
            return info[0]
        counters[L.CONTACT_SUM] += ncon
        counters[L.STEPS_RUN] += 1
    if n_steps > 0 and tangent:
        num, den, total = tangent_kicks(law, vec, sca, ivec, dt, 2)
        if not _lambda_step(
            law, vec, sca, pair_dxi, num, den, total, dt, blk, info, counters[L.STEP], counters
        ):
            return info[0]
    if n_steps > 0:
        v2, bad = final_kick(law, vec, sca, dt, stride > 0)
        if bad:
            return _fail(info, L.NONFINITE, _first_nonfinite(vec, sca), -1, counters[L.STEP])
        if stride > 0:
            _block_means(v2, stride, blk, out_speed, out_nlam, out_lam)
    if n_steps > 0 and not tangent:
        count_contacts(vec, sca, ivec, pair_ij, pair_c, counters[L.N_PAIRS], fw, zb)
    return L.OK


@njit
def place_replica(laws, mode, rebuild_list, g, wd, fw, skin, st, dt, info):
    """Set gravity and check a state before it is evaluated; with ``rebuild_list`` place the
    walls at the state's time and rebuild the list (histories carried). The first half of
    a refresh (:meth:`granpipe.engine.Simulation.refresh`)."""
    # fmt: off
    (vec, sca, ivec, walls, _pair_start, _pair_ij, _pair_c, _pair_xi, _pair_dxi, _old_start,
     _old_j, _old_xi, _old_dxi, _buf, _touch, _flip, _cell_count, _cell_start, clock,
     counters) = st
    # fmt: on
    n_walls = counters[L.N_WALLS]
    if n_walls > 0 and rebuild_list:
        omega = W.wall_omega(wd, W.time_now(clock, counters, dt))
        W.place_wall_disks(vec, sca, walls, n_walls, wd, clock[L.THETA], omega)
        clock[L.LAST_OMEGA] = omega
    _set_gravity(vec, sca, g[0], g[1])
    # a non-finite state is reported before anything else
    i = _first_nonfinite(vec, sca)
    if i >= 0:
        return _fail(info, L.NONFINITE, i, -1, counters[L.STEP])
    history = law_has_history(laws[0])
    if rebuild_list and not rebuild(vec, sca, ivec, skin, st, history, tangent_on(mode)):
        return _fail(info, L.LIST_OVERFLOW, -1, -1, counters[L.STEP])
    return L.OK


@njit
def refresh_replica(laws, mode, fw, skin, st, dt, info):
    """Evaluate the forces at the current state: full-step velocities, wall velocities at
    the current time, contacts counted; under :data:`TANGENT` the perturbations too, and
    the per-disk norms behind lambda. The second half of a refresh; the evaluation
    advances no history (``dt = 0``), and the caller restores the histories it changed
    (a refresh looks at a state's forces; the next step advances its histories)."""
    # fmt: off
    (vec, sca, ivec, _walls, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, _old_start,
     _old_j, _old_xi, _old_dxi, buf, touch, flip, _cell_count, _cell_start, clock,
     counters) = st
    # fmt: on
    zb, vb = W.bottom(fw, W.time_now(clock, counters, dt))
    ncon = forces(
        laws, mode, vec, sca, ivec, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, buf,
        touch, flip, clock, counters, fw, zb, vb, 0.0, True, info, counters[L.STEP], skin,
    )  # fmt: skip
    if ncon < 0:
        return info[0]
    if tangent_on(mode):
        _tangent_norms(laws[0], vec, sca)
    return L.OK


# --------------------------------------------------------------------------- drivers


@njit
def run_serial(laws, mode, n_steps, stride, dt, g, wd, fw, skin, st, out_lam, out_nlam,
               out_speed, info):  # fmt: skip
    """:func:`replica` over replicas one after another (arrays with a leading replica axis);
    its flat arguments are :func:`replica`'s (docs/engine_performance.md, round 13)."""
    for r in range(info.shape[0]):
        replica(
            laws, mode, n_steps, stride, dt, g, wd, fw, skin, replica_of(st, r), out_lam[r],
            out_nlam[r], out_speed[r], info[r],
        )  # fmt: skip


@njit
def place_serial(laws, mode, rebuild_list, g, wd, fw, skin, st, dt, info):
    """:func:`place_replica` over replicas."""
    for r in range(info.shape[0]):
        place_replica(laws, mode, rebuild_list, g, wd, fw, skin, replica_of(st, r), dt, info[r])


@njit
def refresh_serial(laws, mode, fw, skin, st, dt, info):
    """:func:`refresh_replica` over replicas."""
    for r in range(info.shape[0]):
        refresh_replica(laws, mode, fw, skin, replica_of(st, r), dt, info[r])
