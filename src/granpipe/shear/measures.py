"""The rearrangement detector of the shear cell (docs/shear.md, "Rearrangements").

* :func:`neighbour_edges` — the edges of the Delaunay triangulation of all centres (wall
  disks included, so the hole and the boundary add no long edges) between two mobile
  disks closer than ``cutoff`` (a_i + a_j), as sorted int64 codes i·N + j (i < j).
  Touching disks are Gabriel neighbours (size ratio < 1 + √2): their edge leaves the
  triangulation only when they separate.
* :func:`network_changes` — the size of the symmetric difference of two networks: a T1
  swap changes 2. A near-square quadrilateral can flip its diagonal on a tiny motion (2
  changes), so a threshold above 2 asks for more than one flip.
* :func:`rearrangement_events` — the starts of bursts of changes after a quiet spell.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

__all__ = ["neighbour_edges", "network_changes", "rearrangement_events"]


def neighbour_edges(
    positions: np.ndarray, radii: np.ndarray, mobile: np.ndarray, cutoff: float = 1.5
) -> np.ndarray:
    """(E,) int64 sorted unique codes i·N + j of the network of the mobile disks (``mobile``
    (N,) bool) from all centres ``positions`` (N, 2) [d_s] and ``radii`` (N,) [d_s]: an
    edge is kept if |r_i − r_j| < ``cutoff`` (a_i + a_j); empty if N < 3."""
    p = np.asarray(positions, dtype=float)
    a = np.asarray(radii, dtype=float)
    mob = np.asarray(mobile, dtype=bool)
    n = len(p)
    if n < 3:
        return np.zeros(0, dtype=np.int64)
    s = Delaunay(p).simplices.astype(np.int64)  # (M, 3)
    pairs = np.concatenate([s[:, [0, 1]], s[:, [1, 2]], s[:, [0, 2]]])  # (3M, 2)
    i, j = pairs.min(axis=1), pairs.max(axis=1)
    dist = np.hypot(*(p[i] - p[j]).T)
    keep = mob[i] & mob[j] & (dist < cutoff * (a[i] + a[j]))
    return np.unique(i[keep] * n + j[keep])


def network_changes(before: np.ndarray, after: np.ndarray) -> int:
    """Edges in one network of :func:`neighbour_edges` and not the other (same N)."""
    return int(np.setxor1d(before, after).size)


def rearrangement_events(changes: np.ndarray, min_changes: int, quiet: int) -> np.ndarray:
    """(K,) int64 increasing indices of the samples where a burst starts: ``changes`` (S,)
    (changes[k] between samples k − 1 and k) >= ``min_changes`` (>= 1) after ``quiet``
    (>= 0) samples below it; a sample k < quiet is never an event (the record's start is
    not a quiet spell seen whole)."""
    quiet, min_changes = int(quiet), int(min_changes)
    if quiet < 0:
        raise ValueError("quiet must be at least zero samples")
    if min_changes < 1:
        raise ValueError("min_changes must be at least 1 (otherwise every sample is active)")
    active = np.asarray(changes) >= min_changes
    S = active.size
    c = np.concatenate([[0], np.cumsum(active, dtype=np.int64)])  # c[k] = active in [0, k)
    k = np.arange(quiet, S, dtype=np.int64)
    before = c[k] - c[k - quiet]  # active samples in [k - quiet, k)
    return k[active[k] & (before == 0)]
