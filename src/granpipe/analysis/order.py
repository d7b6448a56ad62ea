"""Bond-orientational order of 2D disks (freud): ψ_k per disk and its classes.

ψ_k(i) = (1/n_i) Σ_j exp(i k θ_ij) over the neighbours j of disk i, θ_ij the angle of
r_j − r_i to the x axis (freud.order.Hexatic). |ψ6| = 1 on a perfect triangular lattice
(|ψ4| = 1 on a square one) and small in a disordered packing. The box study colours its
snapshots by these classes (Fortini & Huang's Fig. 1, docs/box.md) and checks that a
crystal start is still a crystal; the shear cell reports the mean |ψ6| of its bulk
beside its jamming measures (docs/shear.md), since nearly equal disks order in 2D.
Nothing here knows a study.
"""

from __future__ import annotations

import numpy as np

__all__ = ["bond_order", "local_order", "classify_order", "ORDER_LABELS"]


def _freud_system(positions, r_max, periodic_box):
    import freud

    pos = np.asarray(positions, dtype=np.float64)
    if periodic_box is None:
        lo, hi = pos.min(axis=0), pos.max(axis=0)
        # Padding of 2 r_max + 1 on each side: no neighbour query can wrap.
        L = (hi - lo) + 4.0 * r_max + 2.0
        centre = 0.5 * (lo + hi)
    else:
        L = np.asarray(periodic_box, dtype=np.float64)
        centre = np.zeros(2) + 0.5 * L  # periodic box spans [0, L)
    box = freud.box.Box(Lx=float(L[0]), Ly=float(L[1]), is2D=True)
    # Centred on the origin (freud's box is [-L/2, L/2)), float32 inside freud.
    pts = np.zeros((len(pos), 3), dtype=np.float32)
    pts[:, :2] = pos - centre
    pts = box.wrap(pts)
    return box, pts


def bond_order(
    positions: np.ndarray,
    k: int = 6,
    *,
    r_max: float = 1.2,
    n_neighbours: int | None = None,
    periodic_box: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Bond-orientational order ψ_k of each particle (freud.order.Hexatic).

    ψ_k(i) = (1/n_i) Σ_j exp(i k θ_ij), θ_ij the angle of r_j − r_i to the x axis,
    over the neighbours j of i: within ``r_max`` [σ], at most the ``n_neighbours``
    nearest if given.

    Parameters
    ----------
    positions : (N, 2) float [σ]
    k : int, 6 (hexagonal) or 4 (square)
    periodic_box : (Lx, Ly), optional
        Periodic box [0, Lx) × [0, Ly). Default non-periodic: the system is placed
        in a freud box padded by 2 r_max + 1 on every side, so no neighbour wraps.

    Returns
    -------
    psi : (N,) complex128, NaN for a particle without neighbours
    n : (N,) int, neighbours used
    """
    return _local_order(positions, (k,), r_max, n_neighbours, periodic_box)


def _local_order(positions, ks, r_max, n_neighbours, periodic_box):
    import freud

    box, pts = _freud_system(positions, r_max, periodic_box)
    query = {"r_max": float(r_max), "exclude_ii": True}
    if n_neighbours is not None:
        query["num_neighbors"] = int(n_neighbours)
    nlist = freud.locality.AABBQuery(box, pts).query(pts, query).toNeighborList()
    n = np.bincount(nlist.query_point_indices, minlength=len(pts)).astype(np.int64)
    out = []
    for k in ks:
        op = freud.order.Hexatic(k=int(k))
        op.compute((box, pts), neighbors=nlist)
        psi = np.asarray(op.particle_order, dtype=np.complex128)
        out.append(np.where(n > 0, psi, np.nan + 1j * np.nan))
    return (*out, n)


#: Codes of :func:`classify_order`.
ORDER_LABELS = {0: "disordered", 1: "hexagonal", 2: "square"}


def classify_order(
    psi6: np.ndarray,
    psi4: np.ndarray,
    n: np.ndarray,
    *,
    threshold: float = 0.7,
    min_neighbours: int = 3,
) -> np.ndarray:
    """Local order class per particle from |ψ6|, |ψ4| (the colours of Fig. 1).

    1 = hexagonal: |ψ6| ≥ threshold > |ψ4|; 2 = square: |ψ4| ≥ threshold > |ψ6|;
    0 = disordered otherwise, and always for fewer than ``min_neighbours``
    neighbours (two opposite neighbours give |ψ6| = |ψ4| = 1). Threshold 0.7:
    a perfect lattice gives 1 (its wall rows too: 4 neighbours at 0°, 60°,
    120°, 180° in a hexagonal crystal), the other lattice gives 0, and a
    dense random packing spreads over [0, 1].
    """
    a6, a4 = np.abs(np.asarray(psi6)), np.abs(np.asarray(psi4))
    enough = np.asarray(n) >= min_neighbours
    a6 = np.where(np.isfinite(a6), a6, 0.0)
    a4 = np.where(np.isfinite(a4), a4, 0.0)
    hexa = enough & (a6 >= threshold) & (a4 < threshold)
    square = enough & (a4 >= threshold) & (a6 < threshold)
    return np.where(hexa, 1, np.where(square, 2, 0)).astype(np.int8)


def local_order(
    positions: np.ndarray,
    *,
    r_max: float = 1.2,
    n_neighbours: int | None = None,
    periodic_box: tuple[float, float] | None = None,
    threshold: float = 0.7,
) -> dict[str, np.ndarray]:
    """ψ6, ψ4 (same neighbour list), neighbour counts and order class per particle.

    Returns a dict with ``psi6``, ``psi4`` (N,) complex, ``n`` (N,) int and
    ``order`` (N,) int8 codes of :data:`ORDER_LABELS`; parameters as
    :func:`bond_order` and :func:`classify_order`. The 1.2σ default neighbour
    radius takes the first shell of a dense disk packing (contacts at ~1σ)
    and excludes the square lattice's diagonals (√2σ) and the hexagonal
    second shell (√3σ).
    """
    psi6, psi4, n = _local_order(positions, (6, 4), r_max, n_neighbours, periodic_box)
    order = classify_order(psi6, psi4, n, threshold=threshold)
    return {"psi6": psi6, "psi4": psi4, "n": n, "order": order}
