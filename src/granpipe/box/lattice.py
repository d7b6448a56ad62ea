"""Initial placements of the box study (paper Sec. III), before any dynamics.

Reduced units: σ = 1 (disk diameter), the plate at rest at height ``z = 0``, side walls
at ``x = 0`` and ``x = Lx``.

*Crystal* (orientation A of the paper's Fig. 2: close-packed rows horizontal). Rows are
``√3/2`` apart, neighbouring rows shifted by σ/2, the bottom row resting on the plate.
Two fits in a box of width ``Lx`` (docs/box.md, hazard (ii)):

``spanning`` (20/19 in Lx = 20; the default)
    even rows hold ``floor(Lx)`` disks touching both walls exactly (at Lx = 20), odd
    rows ``floor(Lx) - 1``. Every disk rests in a pocket or against a wall: at rest under
    gravity it stays a perfect crystal (bulk |ψ6| = 1 to 1e-9). It is the paper's
    "perfect hexagonal lattice" read literally; with frictional side walls it wedges on
    up-strokes (hazard (ii)).
``inset`` (19/19 in Lx = 20)
    every row holds ``n = floor(Lx) - 1`` disks; even rows start ``(Lx - n + 1/2)/2``
    from the left wall and odd rows σ/2 further, so each row has free space
    (0.25σ / 0.75σ at Lx = 20). No row is wedged, but one end of every row rests on a
    single disk: relaxing under gravity the lattice slides and the row ends roll into
    the gaps (bulk |ψ6| ≈ 0.98, a few disordered disks at the walls, measured).

The last row is partly filled, its disks on the central sites of the row, so that the
crystal has no vacancy below its surface.

*Random*: random sequential addition of non-overlapping disks in a rectangle above the
plate at a given area fraction; the fall and settling are run by
:mod:`granpipe.box.prepare`.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["crystal_row_lengths", "crystal_positions", "random_positions", "ROW_SPACING"]

ROW_SPACING = math.sqrt(3.0) / 2.0
"""Vertical distance between close-packed rows of unit disks [σ]."""


def crystal_row_lengths(lx: float, rows: str) -> tuple[int, int]:
    """Disks in even and odd rows for a box of width ``lx`` [σ] and fit ``rows``."""
    n = math.floor(lx + 1e-9)
    if rows == "inset":
        return n - 1, n - 1
    if rows == "spanning":
        return n, n - 1
    raise ValueError(f"crystal rows must be 'inset' or 'spanning', got {rows!r}")


def crystal_positions(n: int, lx: float, rows: str = "inset") -> np.ndarray:
    """Sites of a hexagonal crystal in orientation A resting on the plate at ``z = 0``.

    Parameters
    ----------
    n : int
        Number of disks N.
    lx : float [σ]
        Box width.
    rows : {"inset", "spanning"}
        Row fit (module docstring).

    Returns
    -------
    positions : (N, 2) float64 [σ]
        Centres, row by row from the bottom; row ``r`` at ``z = 1/2 + r √3/2``.
    """
    n_even, n_odd = crystal_row_lengths(lx, rows)
    if min(n_even, n_odd) < 1:
        raise ValueError(f"box width {lx} holds no crystal row")
    if rows == "spanning":
        x_even = 0.5 + np.arange(n_even)
        x_odd = 1.0 + np.arange(n_odd)
    else:
        left = 0.5 * (lx - n_even + 0.5)  # free space 0.25σ-ish, mirror symmetric pair
        x_even = left + np.arange(n_even)
        x_odd = left + 0.5 + np.arange(n_odd)
    out = []
    row = 0
    left_to_place = int(n)
    while left_to_place > 0:
        xs = x_even if row % 2 == 0 else x_odd
        if left_to_place < xs.size:
            # central sites of a partly filled top row
            start = (xs.size - left_to_place) // 2
            xs = xs[start : start + left_to_place]
        z = 0.5 + row * ROW_SPACING
        out.append(np.column_stack([xs, np.full(xs.size, z)]))
        left_to_place -= xs.size
        row += 1
    return np.concatenate(out, axis=0)


def random_positions(
    n: int, lx: float, packing_fraction: float, rng: np.random.Generator
) -> np.ndarray:
    """Random sequential addition of ``n`` unit disks above the plate, no overlaps.

    The disks fill ``0 < x < lx``, ``0 < z < H`` with ``H`` chosen for the requested area
    fraction ``φ`` (``N π/4 = φ lx H``), well below the RSA jamming limit (≈ 0.547).

    Parameters
    ----------
    n : int
    lx : float [σ]
    packing_fraction : float
        φ, at most 0.5.
    rng : numpy.random.Generator
        The replica's stream (:func:`granpipe.seeds.replica_rng`).

    Returns
    -------
    positions : (N, 2) float64 [σ]
    """
    if not 0 < packing_fraction <= 0.5:
        raise ValueError(f"packing fraction must be in (0, 0.5], got {packing_fraction}")
    height = n * math.pi / 4.0 / (packing_fraction * lx)
    height = max(height, 1.0)
    # cell grid of side >= 1 for the overlap test
    ncx = max(1, int((lx - 1.0) // 1.0))
    ncz = max(1, int((height - 1.0) // 1.0))
    cwx = (lx - 1.0) / ncx
    cwz = (height - 1.0) / ncz if height > 1.0 else 1.0
    cells: dict[tuple[int, int], list[int]] = {}
    pos = np.empty((n, 2))
    placed = 0
    attempts = 0
    max_attempts = 1000 * n + 10000
    while placed < n:
        attempts += 1
        if attempts > max_attempts:
            raise RuntimeError(
                f"random placement stalled after {placed} of {n} disks; lower the packing fraction"
            )
        x = 0.5 + rng.random() * (lx - 1.0)
        z = 0.5 + rng.random() * max(height - 1.0, 0.0)
        cx = min(int((x - 0.5) / cwx), ncx - 1)
        cz = min(int((z - 0.5) / cwz), ncz - 1)
        ok = True
        for ix in (cx - 1, cx, cx + 1):
            for iz in (cz - 1, cz, cz + 1):
                for j in cells.get((ix, iz), ()):
                    dx = pos[j, 0] - x
                    dz = pos[j, 1] - z
                    if dx * dx + dz * dz < 1.0:
                        ok = False
                        break
                if not ok:
                    break
            if not ok:
                break
        if ok:
            pos[placed] = (x, z)
            cells.setdefault((cx, cz), []).append(placed)
            placed += 1
    return pos
