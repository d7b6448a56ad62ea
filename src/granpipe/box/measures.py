"""Measures of the box study: detection, temperature, slips, order, and their pooling.

Fortini & Huang (2015), Appendix B and Sec. V, with the corrections of docs/box.md. On
given arrays (geometry only, no simulation):

* :func:`select_tracers` — the N_t particles of the row closest to mid-height of
  the bed at the start (the paper's horizontal line of tracers).
* :func:`convection_measure` — s_c of Eqs. (B1)–(B2); convection when s_c > σ.
* :func:`bouncing_measure` — s_b with our correction, docs/box.md of Eq. (B4): s(k) of
  Eq. (B3), then s_b² = mean_k (s(k) − mean_k s)²; bouncing bed when s_b > σ/30.
* :func:`bed_gap`, :func:`detachment_fraction` — the direct measure: fraction of
  the cycle during which the lowest grain is above the plate.
* :func:`granular_temperature` — Eq. (2).
* :func:`slip_flags`, :func:`slip_probability` — slips of bulk particles per
  period (Sec. V and note [36]).
* :func:`bond_order`, :func:`local_order`, :func:`classify_order` — ψ6 and ψ4
  per particle (freud), hexagonal / square / disordered (Fig. 1).
* :func:`bulk_mask`, :func:`delaunay_coordination`, :func:`crystal_check` — is a crystal
  start still a defect-free crystal: bulk |ψ6|, hexagonal fraction and dislocations
  (bulk disks with other than six Delaunay neighbours).

Coordinates: positions are (N, 2) arrays of (x, z) [σ], z upwards; heights of
the plate z_b [σ].

Per point (:func:`point_dataset`, from the run files): concatenates the parts of each
replica, applies Appendix B (s_c, corrected s_b), the direct detachment measure,
Eq. (2) and the slip criterion of Sec. V, and pools the replicas of a point.

Pooling: T_g and p_s are averaged over all measured periods of all replicas, their
standard errors are those of the per-period values (periods treated as independent; a
bed's memory is a few periods, so the SEM is somewhat optimistic at few periods); s_c,
s_b and the detachment fraction are replica means (with the replica spread when R > 1).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr
from scipy import stats
from scipy.spatial import cKDTree

from ..analysis.order import ORDER_LABELS, bond_order, classify_order, local_order

__all__ = [
    "free_surface_height",
    "select_tracers",
    "convection_measure",
    "bouncing_measure",
    "bed_gap",
    "detachment_fraction",
    "granular_temperature",
    "nearest_neighbours",
    "slip_flags",
    "SlipResult",
    "slip_probability",
    "bond_order",
    "local_order",
    "classify_order",
    "ORDER_LABELS",
    "bulk_mask",
    "delaunay_coordination",
    "CrystalCheck",
    "crystal_check",
    "CONVECTION_THRESHOLD",
    "BOUNCING_THRESHOLD",
    "ReplicaRun",
    "concat_parts",
    "point_dataset",
    "convergence",
]

#: s_c > σ: convection (Appendix B), in units of σ.
CONVECTION_THRESHOLD = 1.0
#: s_b > σ/30: bouncing bed (Appendix B), in units of σ.
BOUNCING_THRESHOLD = 1.0 / 30.0


# ------------------------------------------------------------------ geometry
def free_surface_height(positions: np.ndarray, sigma: float = 1.0, *, fraction: float = 0.5):
    """Height [σ] of the free surface of a bed: the top of its dense part.

    Parameters
    ----------
    positions : (N, 2) float [σ], columns (x, z)
    fraction : float
        Heights are binned in slabs of thickness σ; the bulk density is the
        median count of the slabs below the median particle height. Going up
        from there, the first slab holding fewer than ``fraction`` × bulk marks
        the end of the bed; the surface is the highest particle centre below it.

    A few grains flying above the bed (high K_m) do not move the surface, unlike
    ``max(z)``. For a crystal it is the centre height of the top row.
    """
    z = np.asarray(positions, dtype=np.float64)[:, 1]
    z0 = z.min()
    nb = int(np.floor((z.max() - z0) / sigma)) + 1
    idx = np.minimum(((z - z0) / sigma).astype(np.int64), nb - 1)
    counts = np.bincount(idx, minlength=nb)
    mid_bin = int((np.median(z) - z0) / sigma)
    bulk = np.median(counts[: mid_bin + 1])
    sparse = np.nonzero((counts < fraction * bulk) & (np.arange(nb) > mid_bin))[0]
    top_bin = sparse[0] if sparse.size else nb
    return float(z[idx < top_bin].max())


def select_tracers(
    positions: np.ndarray,
    sigma: float = 1.0,
    *,
    row_tol: float = 0.5,
    mid_height: float | None = None,
    n_tracers: int | None = None,
) -> np.ndarray:
    """Indices of the tracer row: the particles of the row closest to mid-height.

    Parameters
    ----------
    positions : (N, 2) float [σ], the bed at the start of the measurement
    row_tol : float
        A particle belongs to the row if its height is within ``row_tol``·σ of the
        row height (the median height of the members, iterated from the particle
        closest to ``mid_height``). σ/2 separates the rows of a hexagonal
        crystal (spacing √3σ/2) and groups the wavy rows of a random packing.
    mid_height : float, optional
        Default: halfway between the lowest particle centre and the free surface
        (:func:`free_surface_height`).
    n_tracers : int, optional
        Keep only the ``n_tracers`` members closest to the row height.

    Returns
    -------
    (N_t,) int, sorted by x.
    """
    pos = np.asarray(positions, dtype=np.float64)
    z = pos[:, 1]
    if mid_height is None:
        mid_height = 0.5 * (z.min() + free_surface_height(pos, sigma))
    z_row = z[np.argmin(np.abs(z - mid_height))]
    for _ in range(5):
        member = np.abs(z - z_row) < row_tol * sigma
        new = float(np.median(z[member]))
        if new == z_row:
            break
        z_row = new
    idx = np.nonzero(np.abs(z - z_row) < row_tol * sigma)[0]
    if n_tracers is not None and len(idx) > n_tracers:
        idx = idx[np.argsort(np.abs(z[idx] - z_row), kind="stable")[:n_tracers]]
    return idx[np.argsort(pos[idx, 0], kind="stable")]


# ----------------------------------------------------------------- detection
def convection_measure(z_tracers: np.ndarray) -> tuple[float, np.ndarray]:
    """s_c of Eqs. (B1)–(B2) from tracer heights at the start of each cycle.

    Parameters
    ----------
    z_tracers : (n_cycles, N_t) float [σ]
        z_j^i, tracer i at the start of cycle j. NaN entries are ignored.

    Returns
    -------
    s_c : float [σ], with s_c² = (1/N_f) Σ_j s_j²; convection when s_c > σ
    s_j : (n_cycles,) float [σ], s_j² = (1/N_t) Σ_i (z_j^i − ⟨z_j⟩)² (Eq. B1, ddof 0)
    """
    z = np.asarray(z_tracers, dtype=np.float64)
    if z.ndim != 2:
        raise ValueError("z_tracers must be (n_cycles, N_t)")
    s_j2 = np.nanvar(z, axis=1)
    return float(np.sqrt(np.nanmean(s_j2))), np.sqrt(s_j2)


def bouncing_measure(z_tracers: np.ndarray, z_plate: np.ndarray) -> tuple[float, np.ndarray]:
    """s_b: spread over the phases of the tracers' mean height above the plate.

    Parameters
    ----------
    z_tracers : (n_cycles, n_phases, N_t) float [σ]
        z_j^i(k): tracer i at phase k of cycle j (phases sampled uniformly).
    z_plate : (n_cycles, n_phases) or (n_phases,) float [σ]
        z_b(k), the plate height at the same instants.

    Returns
    -------
    s_b : float [σ]
        s_b² = (1/N_k) Σ_k (s(k) − s̄)², s̄ = mean_k s(k). This is docs/box.md's
        correction: Eq. (B4) as printed, (1/N_k) Σ_k s²(k), is the mean *square*
        height of the tracers above the plate (≈ (N_l σ/2)²) and always exceeds
        (σ/30)². A bed comoving with the plate has s(k) constant and s_b = 0.
        Bouncing bed when s_b > σ/30.
    s_k : (n_phases,) float [σ], s(k) of Eq. (B3)
    """
    z = np.asarray(z_tracers, dtype=np.float64)
    zb = np.asarray(z_plate, dtype=np.float64)
    if z.ndim != 3:
        raise ValueError("z_tracers must be (n_cycles, n_phases, N_t)")
    if zb.ndim == 1:
        zb = np.broadcast_to(zb, z.shape[:2])
    height = np.nanmean(z, axis=2) - zb  # ⟨z_j(k)⟩ − z_b(k), (n_cycles, n_phases)
    s_k = np.nanmean(height, axis=0)
    return float(np.sqrt(np.mean((s_k - s_k.mean()) ** 2))), s_k


def roll_contrast(positions: np.ndarray, lx: float, sigma: float = 1.0) -> np.ndarray:
    """Wall-to-centre contrast of the vertical displacement per period, c_j [σ].

    The paper's wall-induced convection (Sec. I): the side walls drag the disks next to
    them down, so a roll carries the bed down at the walls and up at the centre. Per
    period j, over the disks of the bed at its start (centre below the free surface,
    :func:`free_surface_height`: the gas above it is left out),

        c_j = ⟨Δz_i⟩_centre − ⟨Δz_i⟩_walls,   Δz_i = z_i(j + 1) − z_i(j),

    the centre the disks with |x_i − L_x/2| < L_x/4, the walls the others. A motion of the
    whole bed (irregular bouncing: the frames at the same phase find it at different
    heights) cancels in the difference, and diffusion gives ⟨c_j⟩ = 0; a roll gives a
    mean c_j > 0 that persists from period to period.

    Parameters
    ----------
    positions : (n_periods + 1, N, 2) float [σ]
        Positions at the same phase of consecutive periods.
    lx : float [σ]
        Box width (side walls at x = 0 and L_x).

    Returns
    -------
    (n_periods,) float [σ]; NaN for a period with no bed disk at the centre or at a wall.
    """
    pos = np.asarray(positions, dtype=np.float64)
    if pos.ndim != 3 or pos.shape[0] < 2:
        raise ValueError("positions must be (n_periods + 1, N, 2) with at least two frames")
    out = np.full(pos.shape[0] - 1, np.nan)
    for j in range(pos.shape[0] - 1):
        x, z = pos[j, :, 0], pos[j, :, 1]
        bed = z <= free_surface_height(pos[j], sigma)
        dz = pos[j + 1, :, 1] - z
        centre = bed & (np.abs(x - 0.5 * lx) < 0.25 * lx)
        walls = bed & ~centre
        if centre.any() and walls.any():
            out[j] = dz[centre].mean() - dz[walls].mean()
    return out


def roll_significance(contrast: np.ndarray, n_periods: int | None = None) -> float:
    """The roll criterion beside Eq. (B2): how many standard deviations ⟨c_j⟩ lies above 0.

    Student's t = mean(c_j)/SE(c_j) over the first ``n_periods`` periods (all by default),
    turned into the normal score of the same one-sided tail (scipy.stats: t's survival
    function with n − 1 degrees of freedom, then the normal's inverse), so that for a bed
    without rolls (c_j independent, mean zero: diffusion, a bouncing bed) it is a standard
    normal variable at every record length. A roll's score grows as the square root of
    the record. Rolls when it exceeds ``detection.roll_significance`` (3: one such bed in
    ~740 is taken for a roll); a negative score is a roll the other way round.

    Parameters
    ----------
    contrast : (n_periods,) float [σ], :func:`roll_contrast`

    Returns
    -------
    float; NaN with fewer than two finite c_j, 0 for a bed that does not move (every c_j
    zero), ±inf for a contrast without scatter.
    """
    c = np.asarray(contrast, dtype=np.float64)[:n_periods]
    c = c[np.isfinite(c)]
    if c.size < 2:
        return math.nan
    se = c.std(ddof=1) / math.sqrt(c.size)
    if se == 0:
        return 0.0 if c.mean() == 0 else math.copysign(math.inf, c.mean())
    return float(stats.norm.isf(stats.t.sf(c.mean() / se, c.size - 1)))


def roll_displacement(contrast: np.ndarray, n_periods: int | None = None) -> float:
    """How far the bed's centre has risen above its walls over the first ``n_periods``
    periods (all by default), Σ_j c_j [σ]: the distance a roll has carried the bed.

    A roll's rise grows as the record; a steady drift of the packing (a comoving bed
    compacting, a crystal creeping) gives a contrast so regular that its score is large
    while the bed has moved by a small fraction of a disk (measured: 0.01 σ over 200
    periods at Γ 1.0, docs/box.md). NaN with no finite c_j.

    Parameters
    ----------
    contrast : (n_periods,) float [σ], :func:`roll_contrast`
    """
    c = np.asarray(contrast, dtype=np.float64)[:n_periods]
    c = c[np.isfinite(c)]
    return float(c.sum()) if c.size else math.nan


def roll_level(score: float, displacement: float, detection: Mapping) -> float:
    """The roll criterion as one number, rolls where it is >= 1: the score
    (:func:`roll_significance`, :func:`combined_score`) over ``detection.roll_significance``
    and, unless ``detection.roll_displacement`` is 0, the centre's rise
    (:func:`roll_displacement`) over that many σ, whichever is smaller — a roll must be
    persistent and have carried the bed. NaN where either is NaN.
    """
    level = score / float(detection["roll_significance"])
    d_min = float(detection["roll_displacement"])
    if d_min > 0:
        rise = displacement / d_min
        level = math.nan if math.isnan(rise) else min(level, rise)
    return float(level)


def combined_score(scores: Sequence[float]) -> float:
    """The roll score of a point from its replicas' (:func:`roll_significance`): Stouffer's
    Σ z_r / √n over the finite ones, which stays a standard normal variable for beds
    without rolls whatever the replica count (the mean of n scores would have spread
    1/√n, so that a fixed threshold grew stricter with the replicas); NaN with none."""
    z = np.asarray(scores, dtype=np.float64)
    z = z[np.isfinite(z)]
    return float(z.sum() / math.sqrt(z.size)) if z.size else math.nan


def bed_gap(z: np.ndarray, z_plate: np.ndarray, sigma: float = 1.0) -> np.ndarray:
    """Gap under the bed [σ]: lowest particle bottom minus plate height.

    Parameters
    ----------
    z : (..., N) float [σ], particle centre heights (any leading shape, e.g.
        (n_cycles, n_phases, N))
    z_plate : (...) float [σ], plate height at the same instants

    Returns (...) float: min_i z_i − σ/2 − z_b; negative while a grain touches
    the plate (overlap), positive when the whole bed is in flight.
    """
    return np.min(np.asarray(z, dtype=np.float64), axis=-1) - 0.5 * sigma - np.asarray(z_plate)


def detachment_fraction(gap: np.ndarray, tol: float = 1e-3) -> tuple[float, np.ndarray]:
    """Fraction of the cycle with a gap under the bed (docs/box.md, hazard iii).

    Parameters
    ----------
    gap : (n_cycles, n_phases) float [σ], from :func:`bed_gap`, phases sampled
        uniformly over each cycle
    tol : float [σ]
        A phase counts as detached when gap > tol. Default 1e-3σ: ten times the
        static overlap of the bottom row under the heaviest bed (N_l = 80:
        80 mg/κ_n = 8e-5σ) so that contact jitter is not flight, and thirty times
        below the σ/30 criterion of s_b.

    Returns
    -------
    fraction : float in [0, 1], mean over cycles
    per_cycle : (n_cycles,) float
    """
    g = np.atleast_2d(np.asarray(gap, dtype=np.float64))
    per_cycle = np.mean(g > tol, axis=-1)
    return float(per_cycle.mean()), per_cycle


# -------------------------------------------------------------- observables
def granular_temperature(velocities: np.ndarray, mass: float | np.ndarray = 1.0) -> np.ndarray:
    """Instantaneous granular temperature of Eq. (2), one value per frame.

    Parameters
    ----------
    velocities : (n_frames, N, 2) or (N, 2) float [σ/t0]
    mass : float or (N,) [m]

    Returns
    -------
    (n_frames,) or scalar float [m g σ]:
        (1/N) Σ_i ½ m_i |v_i − v_cm|², v_cm the mass-weighted mean velocity. The
        paper's T_g is the time average ⟨·⟩ of this (take ``.mean()`` over frames
        sampled uniformly in time); T_g* = T_g/(mgσ) equals it in reduced units.
    """
    v = np.asarray(velocities, dtype=np.float64)
    m = np.broadcast_to(np.asarray(mass, dtype=np.float64), v.shape[-2])
    v_cm = np.einsum("i,...ij->...j", m, v) / m.sum()
    dv = v - v_cm[..., np.newaxis, :]
    return 0.5 * np.einsum("i,...ij,...ij->...", m, dv, dv) / v.shape[-2]


def nearest_neighbours(
    positions: np.ndarray, n_neighbours: int = 6, r_max: float = 1.2
) -> np.ndarray:
    """Nearest neighbours within ``r_max``, non-periodic (scipy cKDTree).

    Returns (N, n_neighbours) int indices, nearest first, padded with -1 where a
    particle has fewer than ``n_neighbours`` within ``r_max`` [σ].
    """
    pos = np.asarray(positions, dtype=np.float64)
    tree = cKDTree(pos)
    k = min(n_neighbours + 1, len(pos))
    dist, idx = tree.query(pos, k=k, distance_upper_bound=r_max)
    idx = np.where(np.isfinite(dist), idx, -1)[:, 1:]  # column 0 is the particle itself
    if idx.shape[1] < n_neighbours:
        idx = np.pad(idx, ((0, 0), (0, n_neighbours - idx.shape[1])), constant_values=-1)
    return idx


def slip_flags(
    start: np.ndarray,
    end: np.ndarray,
    *,
    neighbours: np.ndarray | None = None,
    n_neighbours: int = 6,
    r_max: float = 1.2,
    threshold: float = 0.2,
    min_count: int = 2,
    bulk_depth: float = 10.0,
    free_surface: float | None = None,
    sigma: float = 1.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Which bulk particles slipped over one period (Sec. V, note [36]).

    Parameters
    ----------
    start, end : (N, 2) float [σ]
        Positions at the start and end of the period (same phase).
    neighbours : (N, k) int, optional
        Nearest neighbours at the start (-1 padded); default
        :func:`nearest_neighbours` (up to ``n_neighbours`` within ``r_max``·σ).
    threshold : float
        A neighbour j counts when the separation vector changes by more than
        ``threshold``·σ: |(r_j − r_i)_end − (r_j − r_i)_start| > 0.2σ.
    min_count : int
        Particle i slips when at least ``min_count`` (2) neighbours count.
    bulk_depth : float
        Bulk = centre more than ``bulk_depth``·σ (10σ) below the free surface
        at the start (:func:`free_surface_height` unless ``free_surface`` given).

    Returns
    -------
    slipped : (N,) bool, False outside the bulk
    bulk : (N,) bool

    Notes
    -----
    The criterion is on separation *vectors*, as the paper words it, so a uniform
    translation never slips, but a rigid rotation by θ changes each vector by
    2|r| sin(θ/2) ≈ σθ and counts once θ > ~0.2 rad (impossible for a bed held
    between side walls).
    """
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    if neighbours is None:
        neighbours = nearest_neighbours(a, n_neighbours, r_max * sigma)
    nb = np.asarray(neighbours)
    valid = nb >= 0
    j = np.where(valid, nb, 0)
    change = (b[j] - b[:, np.newaxis, :]) - (a[j] - a[:, np.newaxis, :])
    moved = valid & (np.hypot(change[..., 0], change[..., 1]) > threshold * sigma)
    if free_surface is None:
        free_surface = free_surface_height(a, sigma)
    bulk = a[:, 1] < free_surface - bulk_depth * sigma
    return bulk & (moved.sum(axis=1) >= min_count), bulk


@dataclass(frozen=True)
class SlipResult:
    """Slip probability p_s over periods.

    p_s : float, mean over periods of the fraction of bulk particles that slip
    sem : float, standard error of p_s from the period-to-period scatter
    per_period : (n_periods,) fraction per period (NaN if no bulk particle)
    n_slips, n_trials : int, total slips and total bulk particle-periods (for
        the binomial treatment of zero counts in the Arrhenius fit)
    """

    p_s: float
    sem: float
    per_period: np.ndarray
    n_slips: int
    n_trials: int

    @property
    def n_periods(self) -> int:
        return int(np.isfinite(self.per_period).sum())


def slip_options(slips: Mapping) -> dict:
    """:func:`slip_flags` keywords from the ``box.slips`` config section."""
    return {
        "threshold": float(slips["displacement"]),
        "min_count": int(slips["min_neighbours"]),
        "r_max": float(slips["neighbour_cutoff"]),
        "bulk_depth": float(slips["surface_depth"]),
    }


def slip_probability(positions: np.ndarray, **kwargs) -> SlipResult:
    """p_s: fraction of bulk particles slipping per period, averaged over periods.

    Parameters
    ----------
    positions : (n_periods + 1, N, 2) float [σ]
        Positions at the same phase of consecutive periods (the paper: 200).
    **kwargs
        Passed to :func:`slip_flags` (neighbours and bulk recomputed at each
        period's start).
    """
    pos = np.asarray(positions, dtype=np.float64)
    per, slips, trials = [], 0, 0
    for p in range(pos.shape[0] - 1):
        kw = dict(kwargs)
        kw.pop("neighbours", None)
        s, bulk = slip_flags(pos[p], pos[p + 1], **kw)
        nb = int(bulk.sum())
        per.append(s.sum() / nb if nb else np.nan)
        slips += int(s.sum())
        trials += nb
    per = np.asarray(per)
    n = np.isfinite(per).sum()
    p_s = float(np.nanmean(per)) if n else np.nan
    sem = float(np.nanstd(per, ddof=1) / np.sqrt(n)) if n > 1 else np.nan
    return SlipResult(p_s, sem, per, slips, trials)


# ------------------------------------------------------------- crystal check
def bulk_mask(positions: np.ndarray, lx: float, depth: float = 2.0) -> np.ndarray:
    """(N,) bool: disks more than ``depth`` σ from the side walls (x = 0, ``lx``), from the
    lowest disk and from the free surface (:func:`free_surface_height`)."""
    pos = np.asarray(positions, dtype=np.float64)
    top = free_surface_height(pos)
    zmin = pos[:, 1].min()
    return (
        (pos[:, 0] > depth)
        & (pos[:, 0] < lx - depth)
        & (pos[:, 1] > zmin + depth)
        & (pos[:, 1] < top - depth)
    )


def delaunay_coordination(positions: np.ndarray) -> np.ndarray:
    """(N,) int: Delaunay neighbours of every point (scipy.spatial.Delaunay).

    Six for every interior site of a triangular lattice; a dislocation is a bound pair
    of a five- and a seven-fold site. Unlike a distance cutoff, the count does not change
    under small thermal displacements of a dense triangular packing (its Delaunay
    triangulation has no four co-circular points).
    """
    from scipy.spatial import Delaunay

    pts = np.asarray(positions, dtype=np.float64)
    indptr, _ = Delaunay(pts).vertex_neighbor_vertices
    return np.diff(indptr).astype(np.int64)


@dataclass(frozen=True)
class CrystalCheck:
    """Order of a bed's bulk (:func:`crystal_check`).

    Attributes
    ----------
    psi6 : float
        Mean |ψ6| of the bulk disks (NaN without bulk).
    hexagonal : float
        Fraction of bulk disks classed hexagonal (:func:`classify_order`).
    dislocations : int
        Bulk disks with other than six Delaunay neighbours (each dislocation core
        contributes a 5-7 pair, so this is about twice the number of dislocations).
    n_bulk : int
    intact : bool
        ``psi6 >= min_psi6`` and no dislocation: still the defect-free crystal.
    """

    psi6: float
    hexagonal: float
    dislocations: int
    n_bulk: int
    intact: bool


def crystal_check(
    positions: np.ndarray,
    lx: float,
    *,
    r_max: float = 1.2,
    threshold: float = 0.7,
    min_psi6: float = 0.9,
    depth: float = 2.0,
    local: dict | None = None,
) -> CrystalCheck:
    """Whether a bed's bulk (:func:`bulk_mask`) is still a defect-free hexagonal crystal.

    Parameters
    ----------
    positions : (N, 2) float [σ]
    lx : float [σ]
        Box width.
    r_max, threshold
        ψ6 neighbour radius and hexagonal class threshold (:func:`local_order`).
    min_psi6 : float
        Least bulk mean |ψ6| of an intact crystal.
    depth : float [σ]
        Bulk window (:func:`bulk_mask`).
    local : dict, optional
        :func:`local_order` of ``positions`` with the same ``r_max`` and ``threshold``,
        if the caller has it already (it is not computed twice).
    """
    pos = np.asarray(positions, dtype=np.float64)
    inside = bulk_mask(pos, lx, depth)
    lo = local if local is not None else local_order(pos, r_max=r_max, threshold=threshold)
    a6 = np.abs(lo["psi6"][inside])
    a6 = a6[np.isfinite(a6)]
    n_bulk = int(inside.sum())
    if n_bulk == 0:
        return CrystalCheck(float("nan"), float("nan"), 0, 0, False)
    psi6 = float(a6.mean()) if a6.size else float("nan")
    hexagonal = float(np.mean(lo["order"][inside] == 1))
    dislocations = int(np.count_nonzero(delaunay_coordination(pos)[inside] != 6))
    intact = bool(np.isfinite(psi6) and psi6 >= min_psi6 and dislocations == 0)
    return CrystalCheck(psi6, hexagonal, dislocations, n_bulk, intact)


# ------------------------------------------------------------------ per point
class ReplicaRun:
    """The parts of one replica joined along the measured periods.

    Attributes: ``z_tracers`` (P, N_k, N_t), ``z_plate``, ``bed_gap``, ``T_g``, ``z_cm``,
    ``vz_cm``, ``plate_contacts`` (P, N_k), ``frames`` (P + 1, N, 2) [σ] at the cycle
    starts, ``phase_frames`` (P, n_s − 1, N, 2) [σ] at the other slip phases (``n_s``
    phases in all, ``protocol.slip_phases``), ``ramp_positions`` (N, 2) [σ] when the
    start-up ramp had ended (None in a run file without it), ``transient`` dict of (S,)
    arrays, ``attrs`` of part 0, ``wall_seconds`` and ``steps`` summed over parts.
    """

    def __init__(self, parts: Sequence[xr.Dataset]):
        first = parts[0]
        cat = {
            k: np.concatenate([p[k].values for p in parts], axis=0)
            for k in ("z_tracers", "z_plate", "bed_gap", "T_g", "z_cm", "vz_cm", "plate_contacts")
        }
        self.__dict__.update(cat)
        frames = [parts[0]["positions"].values]
        for p in parts[1:]:
            frames.append(p["positions"].values[1:])
        self.frames = np.concatenate(frames, axis=0).astype(np.float64)
        if "phase_positions" in first:
            self.phase_frames = np.concatenate(
                [p["phase_positions"].values for p in parts], axis=0
            ).astype(np.float64)
        else:
            self.phase_frames = np.empty((self.frames.shape[0] - 1, 0, *self.frames.shape[1:]))
        self.n_s = self.phase_frames.shape[1] + 1
        ramp = first.get("positions_ramp_end")
        self.ramp_positions = None if ramp is None else ramp.values.astype(np.float64)
        self.transient = {
            k[len("transient_") :]: first[k].values
            for k in first.data_vars
            if k.startswith("transient_")
        }
        self.attrs = dict(first.attrs)
        self.wall_seconds = float(sum(float(p.attrs["wall_seconds"]) for p in parts))
        self.steps = int(sum(int(p.attrs["steps"]) for p in parts))
        self.n = self.frames.shape[1]


def concat_parts(parts: Sequence[xr.Dataset]) -> ReplicaRun:
    return ReplicaRun(parts)


def _sem(values: np.ndarray) -> float:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else math.nan


def _var(dims, data, units, long_name):
    return (dims, data, {"units": units, "long_name": long_name})


def _nanmean(values) -> float:
    v = np.asarray(values)
    return float(np.nanmean(v)) if np.isfinite(v).any() else math.nan


@dataclass(frozen=True)
class _ReplicaMeasures:
    """The estimators of one replica that the rows of :data:`PER_REPLICA` read."""

    run: ReplicaRun
    s_c: float
    s_j: np.ndarray
    s_b: float
    s_k: np.ndarray
    detachment: float
    tg_periods: np.ndarray
    slips: SlipResult
    local: dict[str, dict]
    checks: dict[str, CrystalCheck]  # "start", "end" and "ramp" (None without its frame)
    amp_omega: float
    phase_slips: list[SlipResult]  # (n_s,) p_s at each slip phase, the cycle start first
    flight: np.ndarray  # (n_s,) fraction of periods with a gap under the bed at each
    roll: np.ndarray  # (P,) c_j of :func:`roll_contrast`

    def ramp_check(self, field: str) -> float:
        """``field`` of the crystal check when the start-up ramp had ended (NaN, or 0 for
        ``intact``, without that frame)."""
        c = self.checks["ramp"]
        if c is None:
            return 0 if field == "intact" else math.nan
        return float(getattr(c, field))

    def launch(self, key: str) -> float:
        """Largest upward speed ``transient_<key>`` over A ω (NaN without a transient)."""
        tr = self.run.transient
        if tr and self.amp_omega > 0:
            return float(np.max(tr[key]) / self.amp_omega)
        return math.nan


def _replica_measures(run: ReplicaRun, detection, slips, order, lx, amp_omega):
    s_c, s_j = convection_measure(run.z_tracers[:, 0, :])
    s_b, s_k = bouncing_measure(run.z_tracers, run.z_plate)
    frac, _ = detachment_fraction(run.bed_gap, tol=float(detection["detachment_gap"]))
    slip_kw = slip_options(slips)
    phase_slips = [slip_probability(run.frames, **slip_kw)] + [
        slip_probability(run.phase_frames[:, m], **slip_kw) for m in range(run.n_s - 1)
    ]
    flight = np.mean(run.bed_gap[:, slip_phases(run)] > float(detection["detachment_gap"]), 0)
    r_max, threshold = float(order["neighbour_cutoff"]), float(order["threshold"])
    frames = {w: run.frames[i] for w, (i, _) in _WHEN.items()}
    local = {w: local_order(f, r_max=r_max, threshold=threshold) for w, f in frames.items()}
    checks = {
        w: crystal_check(
            f, lx, r_max=r_max, threshold=threshold,
            min_psi6=float(order["crystal_min_psi6"]), local=local[w],
        )
        for w, f in frames.items()
    }  # fmt: skip
    checks["ramp"] = (  # the crystal check of start-up damage
        None if run.ramp_positions is None
        else crystal_check(run.ramp_positions, lx, r_max=r_max, threshold=threshold,
                           min_psi6=float(order["crystal_min_psi6"]))
    )  # fmt: skip
    return _ReplicaMeasures(
        run, s_c, s_j, s_b, s_k, frac, run.T_g.mean(axis=1), phase_slips[0], local, checks,
        amp_omega, phase_slips, flight, roll_contrast(run.frames, lx),
    )  # fmt: skip


def slip_phases(run: ReplicaRun) -> list[int]:
    """(n_s,) the sampling phase k of each slip phase, k = m N_k/n_s."""
    n_k = run.z_plate.shape[1]
    return [m * n_k // run.n_s for m in range(run.n_s)]


def _phase_slip_vars(phase_slips: Sequence[Sequence[SlipResult]], flight) -> dict:
    """p_s at each slip phase (``slip_phase``), all replicas pooled as the point's p_s is
    and per replica (``<name>_replica``), and how often the bed is off the plate at that
    phase.

    Parameters
    ----------
    phase_slips : per replica, the (n_s,) :class:`SlipResult` of each slip phase
    flight : per replica, (n_s,) fraction of periods with a gap under the bed at the phase
    """
    n_s = len(flight[0])
    per = [np.concatenate([rep[m].per_period for rep in phase_slips]) for m in range(n_s)]
    count = {
        key: np.asarray([sum(getattr(rep[m], key) for rep in phase_slips) for m in range(n_s)])
        for key in ("n_slips", "n_trials")
    }
    dims, rdims = ("slip_phase",), ("replica", "slip_phase")
    replica = {
        "p_s": [[r.p_s for r in rep] for rep in phase_slips],
        "p_s_sem": [[r.sem for r in rep] for rep in phase_slips],
        "n_slips": [[r.n_slips for r in rep] for rep in phase_slips],
        "n_trials": [[r.n_trials for r in rep] for rep in phase_slips],
    }
    return {
        **{
            f"{key}_phase_replica": _var(rdims, np.asarray(v), "1", f"{key} at the phase")
            for key, v in replica.items()
        },
        "p_s_phase": _var(
            dims, np.asarray([_nanmean(v) for v in per]), "1", "slip probability at the phase"
        ),
        "p_s_sem_phase": _var(
            dims, np.asarray([_sem(v) for v in per]), "1", "standard error of p_s_phase"
        ),
        "n_slips_phase": _var(dims, count["n_slips"], "1", "slips counted at the phase"),
        "n_trials_phase": _var(dims, count["n_trials"], "1", "bulk disk-periods at the phase"),
        "flight_phase": _var(
            dims,
            np.mean(np.asarray(flight), axis=0),
            "1",
            "fraction of periods with a gap under the bed at the phase (the bed in flight)",
        ),  # fmt: skip
    }


@dataclass(frozen=True)
class Measure:
    """One per-replica quantity of a point: ``<name>_replica`` (replica,) in the dataset.

    ``gather`` reads it from a replica's estimators. ``point`` makes the point's scalar
    ``<name>``: ``"mean"`` over replicas (NaN-skipping), ``"sum"`` over replicas,
    ``"combined"``: the replicas' normal scores combined (:func:`combined_score`),
    ``"pooled_mean"``/``"pooled_sem"`` over every replica's periods of ``pool``
    (a key of :data:`PERIOD_POOLS`); None keeps the replica values only.
    """

    name: str
    units: str
    long_name: str
    gather: Callable[[_ReplicaMeasures], float | int]
    point: str | None = "mean"
    pool: str | None = None


#: Per-period records pooled over replicas, by name.
PERIOD_POOLS: dict[str, Callable[[_ReplicaMeasures], np.ndarray]] = {
    "T_g": lambda m: m.tg_periods,
    "p_s": lambda m: m.slips.per_period,
}


#: Where each snapshot of the measurement is taken: frame index and phrase.
_WHEN = {"start": (0, "start"), "end": (-1, "the end")}


def _crystal_rows() -> tuple[Measure, ...]:
    """The rows of :func:`crystal_check` at the start and the end, field by field."""
    fields = (
        ("psi6", "bulk mean |psi6| at the {when} of the measurement", float, "mean"),
        ("hexagonal", "fraction of bulk disks with hexagonal local order at {at}", float, "mean"),
        ("dislocations", "bulk disks with other than 6 Delaunay neighbours at {at}", int, "mean"),
        ("intact", "bulk |psi6| >= crystal_min_psi6 and no dislocation at {at}", int, None),
    )

    def gather(field, when, kind):
        return lambda m: kind(getattr(m.checks[when], field))

    return tuple(
        Measure(f"{field}_{when}", "1", text.format(when=when, at=at),
                gather(field, when, kind), point)
        for field, text, kind, point in fields
        for when, (_, at) in _WHEN.items()
    )  # fmt: skip


#: The per-replica quantities of a point, in dataset order.
PER_REPLICA: tuple[Measure, ...] = (
    Measure("s_c", "sigma", "convection measure s_c (Eqs. B1-B2)", lambda m: m.s_c),
    Measure("s_b", "sigma", "bouncing measure s_b (spread of s(k) over phases, docs/box.md)",
            lambda m: m.s_b),
    Measure("s_b_printed", "sigma", "Eq. (B4) as printed: sqrt(mean_k s(k)^2)",
            lambda m: float(np.sqrt(np.mean(m.s_k**2)))),
    Measure("detachment_fraction", "1", "fraction of the cycle with a gap under the bed",
            lambda m: m.detachment),
    Measure("max_gap", "sigma", "mean over cycles of the largest gap under the bed",
            lambda m: float(m.run.bed_gap.max(axis=1).mean())),
    Measure("T_g", "m*g*sigma", "granular temperature, time average (Eq. 2)",
            lambda m: float(m.tg_periods.mean()), "pooled_mean", "T_g"),
    Measure("T_g_sem", "m*g*sigma", "standard error of T_g over periods",
            lambda m: _sem(m.tg_periods), "pooled_sem", "T_g"),
    Measure("p_s", "1", "slip probability per period", lambda m: m.slips.p_s,
            "pooled_mean", "p_s"),
    Measure("p_s_sem", "1", "standard error of p_s over periods", lambda m: m.slips.sem,
            "pooled_sem", "p_s"),
    Measure("n_slips", "1", "slips counted", lambda m: m.slips.n_slips, "sum"),
    Measure("n_trials", "1", "bulk disk-periods examined", lambda m: m.slips.n_trials, "sum"),
    *_crystal_rows(),
    Measure("launch_ratio", "1",
            "largest bed centre-of-mass upward speed in transient / (A omega)",
            lambda m: m.launch("vz_cm")),
    Measure("launch_ratio_disk", "1", "largest disk upward speed in the transient / (A omega)",
            lambda m: m.launch("max_vz"), None),
    Measure("plate_contact_fraction", "1", "fraction of samples with a disk on the plate",
            lambda m: float(np.mean(m.run.plate_contacts > 0)), None),
    Measure("roll_velocity", "sigma", "mean wall-to-centre contrast of dz per period",
            lambda m: _nanmean(m.roll)),
    Measure("roll_significance", "1", "roll score: normal score of the mean contrast against 0",
            lambda m: roll_significance(m.roll), "combined"),
    Measure("roll_displacement", "sigma", "rise of the bed's centre above its walls, sum of c_j",
            lambda m: roll_displacement(m.roll)),
    Measure("psi6_ramp", "1", "bulk mean |psi6| when the start-up ramp has ended",
            lambda m: m.ramp_check("psi6")),
    Measure("dislocations_ramp", "1", "bulk disks with other than 6 Delaunay neighbours, ramp end",
            lambda m: m.ramp_check("dislocations")),
    Measure("intact_ramp", "1", "bulk |psi6| >= crystal_min_psi6 and no dislocation at ramp end",
            lambda m: int(m.ramp_check("intact")), None),
    Measure("wall_seconds", "s", "wall time of the runs", lambda m: m.run.wall_seconds, None),
    Measure("steps", "1", "time steps run (transient included)", lambda m: m.run.steps, None),
)  # fmt: skip

_POINT_REDUCERS: dict[str, Callable[[np.ndarray], float | int]] = {
    "mean": _nanmean,
    "sum": lambda v: int(np.sum(v)),
    "pooled_mean": _nanmean,
    "pooled_sem": _sem,
    "combined": combined_score,
}


def point_dataset(
    runs: Mapping[int, ReplicaRun],
    detection: Mapping,
    slips: Mapping,
    order: Mapping,
    lx: float,
) -> xr.Dataset:
    """Measures of one point from its replicas (``runs[r]``), as a labelled Dataset.

    The per-replica quantities and their point values are the rows of
    :data:`PER_REPLICA`; the flags, s(k), the per-period records and the snapshots of
    replica 0 follow.

    Parameters
    ----------
    detection, slips, order : mapping
        The ``box.detection``, ``box.slips``, ``box.order`` config sections.
    lx : float [σ]
        Box width (for the bulk window of :func:`crystal_check`).
    """
    reps = sorted(runs)
    R = len(reps)
    first = runs[reps[0]]
    amp_omega = float(first.attrs["amplitude"]) * float(first.attrs["omega"])
    ms = [_replica_measures(runs[r], detection, slips, order, lx, amp_omega) for r in reps]
    per_rep = {q.name: [q.gather(m) for m in ms] for q in PER_REPLICA}
    pools = {k: [f(m) for m in ms] for k, f in PERIOD_POOLS.items()}
    data = {
        f"{q.name}_replica": _var(("replica",), np.asarray(per_rep[q.name]), q.units, q.long_name)
        for q in PER_REPLICA
    }
    for q in PER_REPLICA:
        if q.point is not None:
            values = np.concatenate(pools[q.pool]) if q.pool else per_rep[q.name]
            data[q.name] = _var((), _POINT_REDUCERS[q.point](values), q.units, q.long_name)
    s_c, s_b = data["s_c"][1], data["s_b"][1]
    frac = data["detachment_fraction"][1]
    snap = ms[0]
    data.update(
        {
            "convection": _var(
                (), int(s_c > float(detection["convection_s_c"])), "1", "convection flag s_c > σ"
            ),
            "bouncing": _var(
                (), int(s_b > float(detection["bouncing_s_b"])), "1", "bouncing-bed flag s_b > σ/30"
            ),
            "detached": _var(
                (),
                int(frac > float(detection["detachment_fraction"])),
                "1",
                "bed leaves the plate (detachment fraction above the threshold)",
            ),  # fmt: skip
            "crystal_intact": _var(
                (),
                int(all(per_rep["intact_start"])),
                "1",
                "every replica's bulk at measurement start is a defect-free crystal: mean "
                "|psi6| >= crystal_min_psi6 and no disk with other than 6 Delaunay neighbours",
            ),  # fmt: skip
            "rolls": _var(
                (),
                int(
                    roll_level(
                        data["roll_significance"][1], data["roll_displacement"][1], detection
                    )
                    >= 1.0
                ),
                "1",
                "roll flag: the roll score exceeds detection.roll_significance and the "
                "centre has risen detection.roll_displacement above the walls",
            ),  # fmt: skip
            "crystal_intact_ramp": _var(
                (),
                int(all(per_rep["intact_ramp"])),
                "1",
                "every replica's bulk is a defect-free crystal when the start-up ramp has ended",
            ),  # fmt: skip
            **_phase_slip_vars([m.phase_slips for m in ms], [m.flight for m in ms]),
            "roll_contrast": _var(
                ("replica", "slip_period"),
                np.asarray([m.roll for m in ms]),
                "sigma",
                "c_j: wall-to-centre contrast of the bed's vertical displacement over period j",
            ),  # fmt: skip
            "s_k": _var(
                ("phase",), np.mean([m.s_k for m in ms], axis=0), "sigma", "s(k) of Eq. (B3)"
            ),
            "s_j": _var(
                ("replica", "period"),
                np.asarray([m.s_j for m in ms]),
                "sigma",
                "s_j of Eq. (B1) per cycle",
            ),  # fmt: skip
            "T_g_period": _var(
                ("replica", "period"), np.asarray(pools["T_g"]), "m*g*sigma", "T_g per period"
            ),
            "p_s_period": _var(
                ("replica", "slip_period"),
                np.asarray(pools["p_s"]),
                "1",
                "slip fraction per period",
            ),  # fmt: skip
        }
    )
    for when, (i, at) in _WHEN.items():
        lo = snap.local[when]
        data[f"positions_{when}"] = _var(
            ("particle", "xy"), snap.run.frames[i], "sigma",
            f"disk centres at the {when} of the measurement (replica 0)",
        )  # fmt: skip
        data[f"order_{when}"] = _var(
            ("particle",), lo["order"], "1", f"local order at {at} (0 dis, 1 hex, 2 sq)"
        )
        data[f"psi6_abs_{when}"] = _var(("particle",), np.abs(lo["psi6"]), "1", f"|psi6| at {at}")
    n_periods = int(np.isfinite(np.concatenate(pools["T_g"])).sum())
    n_k = first.z_plate.shape[1]
    ds = xr.Dataset(
        data,
        coords={
            "replica": _var(("replica",), np.asarray(reps), "1", "replica index"),
            "phase": _var(("phase",), np.arange(n_k) / n_k, "1", "phase k/N_k of the cycle"),
            "slip_phase": _var(
                ("slip_phase",),
                np.asarray(slip_phases(first)) / n_k,
                "1",
                "phase of the slip frames",
            ),
        },
    )
    a = first.attrs
    ds.attrs.update(
        {
            "study": "box",
            "stage": "ensemble",
            "point": a["point"],
            "N_l": int(a["N_l"]),
            "N": int(a["N"]),
            "Gamma": float(a["Gamma"]),
            "K_m": float(a["Gamma"]) ** 2,
            "init": a["init"],
            "mu_w": float(a["mu_w"]),
            "side_walls": str(a["side_walls"]),
            "wall_torque": str(a["wall_torque"]),
            "replicas": R,
            "measured_periods": n_periods // max(R, 1),
            "wall_seconds": float(np.sum(per_rep["wall_seconds"])),
            "steps": int(np.sum(per_rep["steps"])),
            "ns_per_particle_step": 1e9
            * float(np.sum(per_rep["wall_seconds"]))
            / max(float(np.sum(per_rep["steps"])) * int(a["N"]), 1.0),
        }
    )
    return ds


def convergence(
    z_tracers: np.ndarray,
    z_plate: np.ndarray,
    T_g: np.ndarray,
    frames: np.ndarray,
    slips: Mapping,
    periods: Sequence[int],
) -> dict[str, np.ndarray]:
    """s_c, s_b, T_g* and p_s of one replica from its first P measured periods, for each P
    in ``periods`` (how many periods a point needs; docs/box.md, "Measured periods").

    Parameters are the record of a replica (:class:`ReplicaRun` attributes of the same
    names): ``z_tracers`` (P, N_k, N_t), ``z_plate`` and ``T_g`` (P, N_k), ``frames``
    (P + 1, N, 2). The same estimators as :func:`point_dataset` on the truncated record:
    s_c² the mean of s_j² over the first P cycles (Eq. B2), s_b from s(k) of the first P
    cycles, T_g* the mean of the per-period temperatures, p_s the mean of the per-period
    slip fractions.

    Returns a dict of (len(periods),) arrays ``P``, ``s_c``, ``s_b``, ``T_g``, ``p_s``.
    """
    P = np.asarray([int(p) for p in periods])
    n = z_tracers.shape[0]
    if P.min() < 1 or P.max() > n:
        raise ValueError(f"periods must lie in 1..{n}, got {P.min()}..{P.max()}")
    _, s_j = convection_measure(z_tracers[:, 0, :])
    tg = np.asarray(T_g).mean(axis=1)
    sl = slip_probability(
        np.asarray(frames[: P.max() + 1], dtype=np.float64), **slip_options(slips)
    )
    out = {"P": P, "s_c": [], "s_b": [], "T_g": [], "p_s": []}
    for p in P:
        out["s_c"].append(float(np.sqrt(np.mean(s_j[:p] ** 2))))
        out["s_b"].append(bouncing_measure(z_tracers[:p], z_plate[:p])[0])
        out["T_g"].append(float(tg[:p].mean()))
        per = sl.per_period[:p]
        out["p_s"].append(float(np.nanmean(per)) if np.isfinite(per).any() else math.nan)
    return {k: np.asarray(v) for k, v in out.items()}
