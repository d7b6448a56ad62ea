"""Initial states of the box study (paper Sec. III; docs/box.md "Initial states").

Both preparations run with the plate at rest at ``z = 0`` between side walls at ``x = 0``
and ``x = Lx`` under the full contact law of Appendix A (:mod:`granpipe.box.model`) and
the nominal time step ``Δt = t_c/50``:

*crystal*
    The hexagonal lattice of :func:`crystal_positions` (orientation A,
    rows horizontal, row fit ``inset`` 19/19 or ``spanning`` 20/19), each site displaced by
    a uniform random amount of at most ``crystal_noise`` (this breaks the exact mirror
    symmetry and nothing else), relaxed under gravity for ``crystal_relax_time``.
*random*
    Random sequential addition at area fraction ``random_packing_fraction`` in a tall
    rectangle above the plate, then fall and settle until the kinetic energy per disk is
    below ``settle_kinetic_energy`` (checked every 0.25 t0) or ``settle_max_time`` passes.

:func:`prepare` returns a :class:`Prepared` with positions, velocities and spins and the
bookkeeping the init file stores (settling time, whether it settled, bulk ψ6).

Placements, before any dynamics (:func:`crystal_positions`, :func:`random_positions`).
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
plate at a given area fraction (:func:`random_positions`), then the fall and settling.
"""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..engine import FlatWalls, Simulation
from . import model

__all__ = [
    "Prepared",
    "prepare",
    "box_simulation",
    "disk_arrays",
    "bulk_psi6",
    "crystal_row_lengths",
    "crystal_positions",
    "random_positions",
    "ROW_SPACING",
]


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


@dataclass
class Prepared:
    """A settled initial state.

    Attributes
    ----------
    positions : (N, 2) float64 [σ]
    velocities : (N, 2) float64 [σ/t0]
    spins : (N,) float64 [1/t0]
    settle_time : float [t0]
        Simulated time of the fall/relaxation.
    settled : bool
        Whether the kinetic-energy criterion was met.
    kinetic_energy : float [mgσ]
        Per disk, at the end.
    steps : int
        Time steps run.
    wall_seconds : float
    history : dict of arrays
        ``time`` [t0] and ``kinetic_energy`` [mgσ per disk] at each check.
    """

    positions: np.ndarray
    velocities: np.ndarray
    spins: np.ndarray
    settle_time: float
    settled: bool
    kinetic_energy: float
    steps: int
    wall_seconds: float
    history: dict = field(default_factory=dict)


def disk_arrays(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Radii (σ/2) and masses (m) of ``n`` identical disks."""
    return np.full(n, 0.5 * model.DIAMETER), np.full(n, model.MASS)


def box_simulation(physics: Mapping, dt: float, walls: FlatWalls) -> Simulation:
    """A :class:`granpipe.engine.Simulation` of the box model with the given plate motion."""
    return Simulation(
        law=model.box_law(physics),
        dt=float(dt),
        gravity=(0.0, -model.G),
        flat_walls=walls,
        parallel=False,
    )


def _settle(sim, state, n: int, max_time: float, ke_per_disk: float | None, log, label):
    """Run in chunks of 0.25 t0 until KE/N < ke_per_disk (if given) or max_time passes."""
    chunk = max(1, round(0.25 / sim.dt))
    steps = 0
    times, kes = [], []
    settled = False
    start = _time.perf_counter()
    last_log = start
    t_begin = state.time
    while True:
        sim.run(state, chunk)
        steps += chunk
        ke = state.kinetic_energy() / n
        times.append(state.time)
        kes.append(ke)
        if ke_per_disk is not None and ke < ke_per_disk:
            settled = True
            break
        if state.time - t_begin >= max_time:
            break
        now = _time.perf_counter()
        if log is not None and now - last_log > 30.0:
            last_log = now
            log(
                f"{label}: t = {state.time - t_begin:.2f} of at most {max_time:g} t0, "
                f"KE/N = {ke:.3e} mgσ, elapsed {now - start:.0f} s"
            )
    if ke_per_disk is None:
        settled = True
    return steps, settled, {"time": np.asarray(times), "kinetic_energy": np.asarray(kes)}


def prepare(
    physics: Mapping,
    init_cfg: Mapping,
    n: int,
    kind: str,
    rng: np.random.Generator,
    log: Callable[[str], None] | None = None,
) -> Prepared:
    """Prepare a ``crystal`` or ``random`` initial state of ``n`` disks.

    Parameters
    ----------
    physics, init_cfg : mapping
        The ``box.physics`` and ``box.init`` config sections.
    n : int
        N = N_l Lx.
    kind : {"crystal", "random"}
    rng : numpy.random.Generator
        The replica's stream (:func:`granpipe.seeds.replica_rng`).
    log : callable, optional
        Receives progress lines (every ~30 s wall).

    Raises
    ------
    SimulationError
        If the engine reports a bad state (the caller adds study/point/replica/seed).
    """
    lx = float(physics["Lx"])
    if kind == "crystal":
        pos = crystal_positions(n, lx, init_cfg["crystal_rows"])
        noise = float(init_cfg["crystal_noise"])
        if noise > 0:
            pos = pos + rng.uniform(-noise, noise, size=pos.shape)
            # keep the noisy lattice inside the walls and on the plate
            pos[:, 0] = np.clip(pos[:, 0], 0.5, lx - 0.5)
            pos[:, 1] = np.maximum(pos[:, 1], 0.5)
        max_time = float(init_cfg["crystal_relax_time"])
        threshold = None
    elif kind == "random":
        pos = random_positions(n, lx, float(init_cfg["random_packing_fraction"]), rng)
        max_time = float(init_cfg["settle_max_time"])
        threshold = float(init_cfg["settle_kinetic_energy"])
    else:
        raise ValueError(f"kind must be 'crystal' or 'random', got {kind!r}")
    radii, masses = disk_arrays(n)
    sim = box_simulation(physics, model.nominal_dt(physics), model.flat_walls(physics))
    start = _time.perf_counter()
    state = sim.new_state(pos, radii, masses)
    if max_time > 0:
        steps, settled, history = _settle(sim, state, n, max_time, threshold, log, kind)
    else:
        steps, settled, history = 0, True, {"time": np.zeros(0), "kinetic_energy": np.zeros(0)}
    return Prepared(
        positions=state.positions.copy(),
        velocities=state.velocities.copy(),
        spins=state.spins.copy(),
        settle_time=float(state.time),
        settled=bool(settled),
        kinetic_energy=float(state.kinetic_energy() / n),
        steps=int(steps),
        wall_seconds=_time.perf_counter() - start,
        history=history,
    )


def bulk_psi6(positions: np.ndarray, lx: float, r_max: float = 1.2, depth: float = 2.0) -> float:
    """Mean |ψ6| of disks more than ``depth`` σ from the side walls, the plate and the free
    surface (:func:`granpipe.box.measures.crystal_check`); NaN if none qualifies."""
    from .measures import crystal_check

    return crystal_check(positions, lx, r_max=r_max, depth=depth).psi6
