"""The sheared cell's local measures: rearrangements of the contact network, and |δu| vs |v|.

Reduced units: lengths in d_s (the small disk's diameter), times in t0.

* :func:`neighbour_edges` — the neighbour network of the mobile disks: the edges of the
  Delaunay triangulation of *all* disk centres (wall disks included as points, so that
  the annulus' hole and its outer boundary are filled by real points and do not create
  long spurious edges) whose both ends are mobile and whose centre distance is below
  ``cutoff`` × (a_i + a_j). The cutoff (1.5 by default) drops the long edges that span
  voids (and, were walls absent, the hole). Edges of touching disks are Gabriel edges
  of a packing without overlaps (size ratio < 1 + √2): no other centre lies in the circle
  on the pair's segment, so they are in the triangulation whatever the other disks do
  and leave it only when the pair separates. Edges are
  integer codes i·N + j (i < j), sorted and unique, so comparing two networks is a set
  operation on int64 arrays.
* :func:`network_changes` — size of the symmetric difference of two networks. A T1 swap
  (a neighbour pair separates and the other diagonal of their rhombus joins) changes 2.
  A near-square quadrilateral of neighbours can flip its Delaunay diagonal on a tiny
  motion; both diagonals (√2 d) pass the cutoff, so such flips are counted: a detector
  threshold ``min_changes`` above 2 asks for more than one such flip.
* :func:`rearrangement_events` — the starts of bursts of changes after a quiet spell
  (a window-count by cumulative sums, as :func:`granpipe.analysis.events.first_run`).

Plain numpy and scipy; nothing here runs the engine.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay

__all__ = [
    "neighbour_edges",
    "network_changes",
    "rearrangement_events",
]


def neighbour_edges(
    positions: np.ndarray, radii: np.ndarray, mobile: np.ndarray, cutoff: float = 1.5
) -> np.ndarray:
    """The neighbour network of the mobile disks, as sorted unique edge codes.

    Parameters
    ----------
    positions : (N, 2) float
        Centres of all disks, walls included [d_s].
    radii : (N,) float
        Radii a_i [d_s].
    mobile : (N,) bool
        True for the mobile disks; edges touching a wall disk are dropped.
    cutoff : float
        An edge is kept if |r_i − r_j| < cutoff · (a_i + a_j).

    Returns
    -------
    (E,) int64: codes i·N + j with i < j, sorted and unique (empty if N < 3).
    """
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
    """Number of edges in one network and not the other (the symmetric difference).

    ``before``/``after``: (E,) int codes from :func:`neighbour_edges` for the same N.
    A T1 swap gives 2 (one edge lost, one gained).
    """
    return int(np.setxor1d(before, after).size)


def rearrangement_events(changes: np.ndarray, min_changes: int, quiet: int) -> np.ndarray:
    """Samples where a burst of network changes starts after a quiet spell.

    Parameters
    ----------
    changes : (S,) int
        changes[k] = :func:`network_changes` between samples k − 1 and k (changes[0] = 0).
    min_changes : int >= 1
        A sample is *active* if changes[k] >= min_changes.
    quiet : int >= 0
        Samples k − quiet .. k − 1 must all be inactive for an active k to be an event;
        0 makes every active sample an event. A sample k < quiet is never an event:
        the record's start does not count as a quiet spell (one not yet seen whole).

    Returns
    -------
    (K,) int64: the event sample indices, increasing.
    """
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
