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
* :func:`edge_change_counts` — per disk, the changed edges it is an end of (the disks
  that rearrange in a sample).
* :func:`contact_pairs`, :func:`contact_number`, :func:`elastic_measures` — the jamming
  measures (docs/shear.md, "The cell's jamming point"): the overlapping pairs, the mean
  contact number z of the non-rattlers (rattlers removed iteratively), and the elastic
  energy, the pressure on the outer ring and the torque on the inner ring of the normal
  springs of Eq. (1).
* :func:`bulk_hexatic_order` — the mean |ψ6| of the disks away from both rings (freud).
* :func:`stress_release_events` — drops of a series (the elastic energy, the torque) by
  more than a fraction of its median, after a quiet spell.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.spatial import Delaunay, cKDTree

from ..analysis.order import bond_order

# the jamming measures a replica records at every sample (name: units, long name;
# docs/shear.md, "The cell's jamming point")
JAMMING = {
    "z_frictionless": ("1", "mean contacts of the non-rattlers, rattlers: fewer than 3 "
                       "(frictionless reading, isostatic at 4)"),
    "z_frictional": ("1", "mean contacts of the non-rattlers, rattlers: fewer than 2 "
                     "(frictional reading, isostatic at 3)"),
    "rattlers_frictionless": ("1", "fraction of the mobile disks that are rattlers (fewer "
                              "than 3 contacts, removed iteratively)"),
    "rattlers_frictional": ("1", "fraction of the mobile disks that are rattlers (fewer than 2 "
                            "contacts, removed iteratively)"),
    "energy": ("m_s g d_s", "energy of the normal springs, sum of k_n delta^2 / 2"),
    "pressure": ("m_s g/d_s", "the normal springs' outward push on the outer ring over its "
                 "envelope's length"),
    "torque": ("m_s g d_s", "the normal springs' torque on the inner ring about the centre "
               "(counter-clockwise > 0)"),
    "overlap": ("d_s", "mean overlap of the contacts"),
    "hexatic": ("1", "mean |psi6| of the disks farther than bulk_depth from both rings"),
}  # fmt: skip

__all__ = ["JAMMING", "neighbour_edges", "network_changes", "rearrangement_events",
           "edge_change_counts", "Contacts", "contact_pairs", "contact_number", "elastic_measures",
           "bulk_hexatic_order", "stress_release_events"]  # fmt: skip


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


def edge_change_counts(before: np.ndarray, after: np.ndarray, n: int) -> np.ndarray:
    """(n,) int64: for each of the ``n`` disks, the edges of the symmetric difference of
    two networks of :func:`neighbour_edges` (codes i·n + j) that it is an end of."""
    changed = np.setxor1d(before, after)
    return np.bincount(np.concatenate([changed // n, changed % n]), minlength=n)


class Contacts(NamedTuple):
    """The overlapping pairs of a configuration: ``i`` < ``j`` (K,) int64 disk indices,
    ``overlap`` (K,) [d_s] = a_i + a_j − |r_i − r_j| > 0, ``normal`` (K, 2) the unit
    vector from j to i."""

    i: np.ndarray
    j: np.ndarray
    overlap: np.ndarray
    normal: np.ndarray


def contact_pairs(positions: np.ndarray, radii: np.ndarray, mobile: np.ndarray) -> Contacts:
    """The contacts (overlap > 0) of ``positions`` (N, 2) [d_s], ``radii`` (N,) [d_s]
    with at least one mobile disk (``mobile`` (N,) bool): two wall disks never count."""
    p = np.asarray(positions, dtype=np.float64)
    a = np.asarray(radii, dtype=np.float64)
    mob = np.asarray(mobile, dtype=bool)
    pairs = cKDTree(p).query_pairs(2.0 * float(a.max()), output_type="ndarray")
    i, j = pairs[:, 0].astype(np.int64), pairs[:, 1].astype(np.int64)
    d = p[i] - p[j]
    dist = np.hypot(d[:, 0], d[:, 1])
    overlap = a[i] + a[j] - dist
    keep = (overlap > 0) & (mob[i] | mob[j])
    return Contacts(i[keep], j[keep], overlap[keep], d[keep] / dist[keep, None])


def contact_number(contacts: Contacts, mobile: np.ndarray, min_contacts: int):
    """Mean contact number z of the non-rattlers and the rattlers.

    A rattler is a mobile disk with fewer than ``min_contacts`` contacts among the disks
    that are not rattlers (wall disks count and are never rattlers); rattlers are
    removed until none is left to remove (a disk held by a rattler is not held). z is
    the mean number of contacts of the remaining mobile disks with each other and the
    walls. 2D: ``min_contacts`` = 3 (d + 1) with the frictionless isostatic value
    z = 4, 2 (d) with the frictional one z = 3.

    Returns ``(z, rattler)``: z = 0 when every mobile disk is a rattler (no contact
    network holds, as below jamming); ``rattler`` (N,) bool.
    """
    mob = np.asarray(mobile, dtype=bool)
    n = len(mob)
    i, j = contacts.i, contacts.j
    rattler = np.zeros(n, dtype=bool)
    while True:
        live = ~(rattler[i] | rattler[j])
        count = np.bincount(i[live], minlength=n) + np.bincount(j[live], minlength=n)
        new = mob & ~rattler & (count < int(min_contacts))
        if not new.any():
            break
        rattler |= new
    held = mob & ~rattler
    return (float(count[held].mean()) if held.any() else 0.0), rattler


def elastic_measures(contacts: Contacts, positions: np.ndarray, k_n: float,
                     inner: np.ndarray, outer: np.ndarray, r_outer: float) -> dict:  # fmt: skip
    """The normal springs of Eq. (1) (f = k_n δ along the normal; the dashpots left out:
    the stored, not the dissipated, part of the stress).

    Parameters
    ----------
    contacts : :func:`contact_pairs` (wall disks carry higher indices than mobile ones)
    positions : (N, 2) [d_s], about the cell's centre
    k_n : [m_s g / d_s]
    inner, outer : (N,) bool, the inner (turning) and the outer ring's wall disks
    r_outer : [d_s], the outer ring's inner envelope

    Returns
    -------
    dict: ``energy`` Σ ½ k_n δ² [m_s g d_s]; ``pressure`` the outward push of the disks on
    the outer ring over its envelope's length 2π r_outer [m_s g/d_s]; ``torque`` the
    disks' torque on the inner ring about the centre [m_s g d_s] (counter-clockwise > 0,
    the ring's sense of turning: the disks resist it when negative); ``overlap`` the mean
    δ [d_s] (NaN without contacts).
    """
    c = contacts
    f = float(k_n) * c.overlap  # (K,) along c.normal, on i from j
    energy = float(0.5 * np.sum(f * c.overlap))
    p = np.asarray(positions, dtype=np.float64)
    # a wall disk is always j (higher index): the force on it is −f n at its centre r_j
    rj = p[c.j]
    on_outer = np.asarray(outer, dtype=bool)[c.j]
    radial = np.sum(rj * c.normal, axis=1) / np.hypot(rj[:, 0], rj[:, 1])
    pressure = float(np.sum(-f[on_outer] * radial[on_outer]) / (2.0 * np.pi * float(r_outer)))
    on_inner = np.asarray(inner, dtype=bool)[c.j]
    cross = rj[:, 0] * c.normal[:, 1] - rj[:, 1] * c.normal[:, 0]
    torque = float(np.sum(-f[on_inner] * cross[on_inner]))
    overlap = float(c.overlap.mean()) if len(c.overlap) else float("nan")
    return {"energy": energy, "pressure": pressure, "torque": torque, "overlap": overlap}


def bulk_hexatic_order(positions: np.ndarray, r_in: float, r_out: float,
                       depth: float) -> float:  # fmt: skip
    """Mean |ψ6| (freud, each disk's six nearest neighbours) over the disks farther than
    ``depth`` [d_s] from both envelopes ``r_in`` < |r| < ``r_out`` of the annulus about
    the origin; ``positions`` (N, 2) [d_s] of the mobile disks. NaN without such disks.
    1 on a triangular lattice; a disordered packing gives far less."""
    p = np.asarray(positions, dtype=np.float64)
    r = np.hypot(p[:, 0], p[:, 1])
    bulk = (r > float(r_in) + depth) & (r < float(r_out) - depth)
    if not bulk.any():
        return float("nan")
    psi, _ = bond_order(p, 6, r_max=4.0, n_neighbours=6)
    return float(np.nanmean(np.abs(psi[bulk])))


def stress_release_events(series: np.ndarray, drop: float, quiet: int) -> np.ndarray:
    """(K,) int64 sample indices where ``series`` (S,) (e.g. the elastic energy at each
    sample) falls from the sample before by at least ``drop`` (> 0) times its median over
    the record, after ``quiet`` samples without such a fall (:func:`rearrangement_events`
    on the falls): the stress-releasing events of an elastic packing."""
    x = np.asarray(series, dtype=np.float64)
    if not drop > 0:
        raise ValueError("drop must be a positive fraction of the median")
    fall = np.r_[0.0, x[:-1] - x[1:]]
    active = (fall > 0) & (fall >= float(drop) * np.median(x)) if x.size else fall > 0
    return rearrangement_events(active.astype(np.int64), 1, quiet)
