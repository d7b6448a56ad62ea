"""Random non-overlapping placement of the mobile disks inside the drum (Sec. II.2).

"We place the N non-wall disks randomly inside the drum and allow them to fall
to the bottom": random sequential addition, uniform over the free disk of the
drum, rejecting any trial that overlaps a disk already placed or the wall. At
the paper's filling (~24 % of the free area) a trial is accepted after a few
attempts, so placement costs milliseconds.
"""

from __future__ import annotations

import numpy as np

__all__ = ["random_placement", "min_gap"]


def random_placement(
    diameters: np.ndarray,
    inner_radius: float,
    rng: np.random.Generator,
    *,
    gap: float = 0.05,
    max_attempts: int = 100_000,
) -> np.ndarray:
    """Positions of disks placed uniformly at random without overlap.

    Parameters
    ----------
    diameters : (N,) float64 [d_s]
        Disk diameters d_i.
    inner_radius : float [d_s]
        Radius of the free disk (R − d_w/2): a disk of diameter d is kept within
        ``inner_radius − d/2 − gap`` of the axis.
    rng : numpy.random.Generator
        The replica's stream; the result depends on it only.
    gap : float [d_s]
        Minimum clearance between two disks and between a disk and the wall,
        so that the fall starts with no contact at all.
    max_attempts : int
        Trials per disk before giving up (``RuntimeError``: the drum is too full).

    Returns
    -------
    (N, 2) float64 [d_s], centred on the drum axis. Disks are placed in a random
    order (so neither species is favoured for the free space).
    """
    d = np.asarray(diameters, dtype=np.float64)
    n = len(d)
    pos = np.full((n, 2), np.nan)
    placed = np.zeros(n, dtype=bool)
    for i in rng.permutation(n):
        rmax = inner_radius - d[i] / 2.0 - gap
        if rmax <= 0:
            raise RuntimeError(f"disk {i} (d={d[i]}) does not fit in the drum")
        for _ in range(max_attempts):
            r = rmax * np.sqrt(rng.random())
            phi = 2.0 * np.pi * rng.random()
            trial = np.array([r * np.cos(phi), r * np.sin(phi)])
            others = pos[placed]
            if len(others):
                dist = np.hypot(*(others - trial).T)
                if np.any(dist < (d[placed] + d[i]) / 2.0 + gap):
                    continue
            pos[i] = trial
            placed[i] = True
            break
        else:
            raise RuntimeError(
                f"random placement failed after {max_attempts} attempts for disk {i}: "
                "the drum is too full for random sequential addition"
            )
    return pos


def min_gap(positions: np.ndarray, diameters: np.ndarray) -> float:
    """Smallest surface-to-surface distance between two disks [d_s] (negative = overlap)."""
    p = np.asarray(positions, dtype=np.float64)
    d = np.asarray(diameters, dtype=np.float64)
    diff = p[:, None, :] - p[None, :, :]
    dist = np.hypot(diff[..., 0], diff[..., 1])
    gap = dist - (d[:, None] + d[None, :]) / 2.0
    np.fill_diagonal(gap, np.inf)
    return float(gap.min())
