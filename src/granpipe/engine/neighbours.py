"""Neighbour search: cell lists feeding a Verlet half list with a skin.

The list holds every pair ``(i, j)``, ``i < j``, not both walls, with
``|r_i - r_j| < a_i + a_j + skin`` at build time, in CSR form: the partners of ``i``
are ``pair_j[pair_start[i]:pair_start[i + 1]]``, sorted. It is valid (no contact
can be missing) until some disk has moved by more than ``skin / 2`` since the build;
the kernels then rebuild it. Sorted partners make the list a deterministic function
of the positions, and let the box law carry each contact's shear history across a
rebuild by merging the old and new lists (:func:`carry_history`).

Memory is fixed when a state is created (:func:`pair_capacity`), so the step loop
never allocates: if no two disks overlap by more than ``f`` times the smaller radius
(the engine's bad-state bound, ``Simulation.max_overlap``), no two centres are closer
than ``2 s`` with ``s = (1 - f/2) a_min``, and a disk can have at most
``((2 a_max + skin + s) / s)²`` neighbours; a larger count means the state is already
bad and the kernel reports it.
"""

from __future__ import annotations

import math

import numpy as np

from granpipe._jit import njit
from granpipe.engine import layout as L

__all__ = ["pair_capacity", "cell_capacity", "build_pairs", "carry_history", "rebuild"]


def pair_capacity(radii, skin, max_overlap=0.5) -> int:
    """Capacity of the half list for disks of the given radii (see module docstring).

    Parameters
    ----------
    radii : (N,) float64 [length]
    skin : float [length]
    max_overlap : float
        The bad-state bound on overlaps, as a fraction ``f < 2`` of the smaller radius.
    """
    radii = np.asarray(radii, dtype=np.float64)
    n = radii.size
    if n < 2:
        return 1
    a_min, a_max = float(radii.min()), float(radii.max())
    s = (1.0 - 0.5 * float(max_overlap)) * a_min
    per_disk = ((2.0 * a_max + skin + s) / s) ** 2
    return int(math.ceil(0.5 * per_disk * n)) + 16


def cell_capacity(n) -> int:
    """Number of cells the grid may use (more cells are merged by widening them)."""
    return 2 * int(n) + 64


@njit
def build_pairs(
    pos, radius, is_wall, skin, cell_count, cell_start, cell_items, cell_of, pair_start, pair_j
):
    """Build the Verlet half list from a cell list.

    Parameters
    ----------
    pos : (N, 2) float64 [length]
    radius : (N,) float64 [length]
    is_wall : (N,) bool
        Wall-wall pairs are left out.
    skin : float [length]
    cell_count, cell_start : (C + 1,) int64
        Scratch, ``C = cell_capacity(N)``.
    cell_items, cell_of : (N,) int64
        Scratch.
    pair_start : (N + 1,) int64
        Out: CSR offsets.
    pair_j : (P,) uint32
        Out: partners, sorted within each row; ``P`` = capacity.

    Returns
    -------
    n_pairs : int
        Number of pairs, or -1 if the capacity ``P`` was exceeded.
    """
    n = pos.shape[0]
    cap = pair_j.shape[0]
    n_cells_max = cell_count.shape[0] - 1
    xmin = np.inf
    xmax = -np.inf
    ymin = np.inf
    ymax = -np.inf
    amax = 0.0
    for i in range(n):
        x = pos[i, 0]
        y = pos[i, 1]
        xmin = min(xmin, x)
        xmax = max(xmax, x)
        ymin = min(ymin, y)
        ymax = max(ymax, y)
        amax = max(amax, radius[i])
    size = 2.0 * amax + skin
    nx = int((xmax - xmin) / size) + 1
    ny = int((ymax - ymin) / size) + 1
    while nx * ny > n_cells_max:
        size *= 1.25
        nx = int((xmax - xmin) / size) + 1
        ny = int((ymax - ymin) / size) + 1
    inv = 1.0 / size
    n_cells = nx * ny
    for c in range(n_cells + 1):
        cell_count[c] = 0
    for i in range(n):
        cx = min(int((pos[i, 0] - xmin) * inv), nx - 1)
        cy = min(int((pos[i, 1] - ymin) * inv), ny - 1)
        c = cy * nx + cx
        cell_of[i] = c
        cell_count[c + 1] += 1
    cell_start[0] = 0
    for c in range(n_cells):
        cell_start[c + 1] = cell_start[c] + cell_count[c + 1]
        cell_count[c + 1] = 0
    for i in range(n):
        c = cell_of[i]
        cell_items[cell_start[c] + cell_count[c + 1]] = i
        cell_count[c + 1] += 1

    k = 0
    for i in range(n):
        pair_start[i] = k
        c = cell_of[i]
        cx = c % nx
        cy = c // nx
        xi = pos[i, 0]
        yi = pos[i, 1]
        ai = radius[i] + skin
        wi = is_wall[i]
        for oy in range(-1, 2):
            yy = cy + oy
            if yy < 0 or yy >= ny:
                continue
            for ox in range(-1, 2):
                xx = cx + ox
                if xx < 0 or xx >= nx:
                    continue
                cc = yy * nx + xx
                for m in range(cell_start[cc], cell_start[cc + 1]):
                    j = cell_items[m]
                    if j <= i or (wi and is_wall[j]):
                        continue
                    dx = xi - pos[j, 0]
                    dy = yi - pos[j, 1]
                    rc = ai + radius[j]
                    if dx * dx + dy * dy < rc * rc:
                        if k >= cap:
                            return -1
                        # insertion keeps each row sorted
                        p = k
                        while p > pair_start[i] and pair_j[p - 1] > j:
                            pair_j[p] = pair_j[p - 1]
                            p -= 1
                        pair_j[p] = j
                        k += 1
    pair_start[n] = k
    return k


@njit
def carry_history(old_start, old_j, old_xi, new_start, new_j, new_xi):
    """Copy each pair's shear history from the old list to the new one (sorted merge).

    Pairs new to the list start with zero history. A pair in contact is within
    ``a_i + a_j`` and so always in the new list; pairs not in contact have zero history.
    """
    n = new_start.shape[0] - 1
    for i in range(n):
        p = old_start[i]
        pe = old_start[i + 1]
        for k in range(new_start[i], new_start[i + 1]):
            j = new_j[k]
            while p < pe and old_j[p] < j:
                p += 1
            if p < pe and old_j[p] == j:
                new_xi[k] = old_xi[p]
            else:
                new_xi[k] = 0.0


@njit
def _pair_constants(sca, pair_start, pair_ij, pair_c, npairs, overlap_frac):
    """Owner index and per-pair constants of a freshly built list (the overlap bound is
    ``overlap_frac`` times the smaller radius)."""
    radius = sca[L.RADIUS]
    inv_mass = sca[L.INV_MASS]
    n = pair_start.shape[0] - 1
    pi = pair_ij[L.PI]
    pj = pair_ij[L.PJ]
    for i in range(n):
        for k in range(pair_start[i], pair_start[i + 1]):
            pi[k] = i
    for k in range(npairs):
        i = pi[k]
        j = pj[k]
        ai = radius[i]
        aj = radius[j]
        pair_c[L.P_SUM, k] = ai + aj
        pair_c[L.P_LIM, k] = overlap_frac * min(ai, aj)
        pair_c[L.P_MEFF, k] = 1.0 / (inv_mass[i] + inv_mass[j])
        pair_c[L.P_DIFF, k] = ai - aj


@njit
def rebuild(vec, sca, ivec, skin, st, history, tangent):
    """Rebuild the neighbour list of one replica (``st``: its storage tuple,
    :data:`granpipe.engine.layout.STORAGE`) at the current positions; with ``history``
    (laws with shear history) carry each kept pair's history over (:func:`carry_history`),
    and with ``tangent`` its perturbation too. Returns False on a list overflow.
    """
    # fmt: off
    (_vec, _sca, _ivec, _walls, pair_start, pair_ij, pair_c, pair_xi, pair_dxi, old_start,
     old_j, old_xi, old_dxi, _buf, _touch, _flip, cell_count, cell_start, clock,
     counters) = st
    # fmt: on
    npairs = counters[L.N_PAIRS]
    pj = pair_ij[L.PJ]
    if history:
        for i in range(pair_start.shape[0]):
            old_start[i] = pair_start[i]
        for k in range(npairs):
            old_j[k] = pj[k]
            old_xi[k] = pair_xi[k]
            old_dxi[k] = pair_dxi[k] if tangent else 0.0
    counters[L.NEAR_WALLS] = -1  # the cell pass overwrites the near-wall list
    m = build_pairs(
        vec[L.POS],
        sca[L.RADIUS],
        ivec[L.IS_WALL],
        skin,
        cell_count,
        cell_start,
        ivec[L.CELL_ITEMS],
        ivec[L.CELL_OF],
        pair_start,
        pj,
    )
    if m < 0:
        return False
    _pair_constants(sca, pair_start, pair_ij, pair_c, m, clock[L.OVERLAP_FRAC])
    p = vec[L.POS]
    b = vec[L.POS_BUILD]
    for i in range(p.shape[0]):
        b[i, 0] = p[i, 0]
        b[i, 1] = p[i, 1]
    clock[L.THETA_BUILD] = clock[L.THETA]
    counters[L.N_PAIRS] = m
    counters[L.N_REBUILDS] += 1
    counters[L.FORCE_REBUILD] = 0
    counters[L.COUNT_STALE] = 1
    if history:
        if npairs == 0:
            for k in range(m):
                pair_xi[k] = 0.0
                pair_dxi[k] = 0.0
        else:
            carry_history(old_start, old_j, old_xi, pair_start, pj, pair_xi)
            if tangent:
                carry_history(old_start, old_j, old_dxi, pair_start, pj, pair_dxi)
    return True
