"""Initial states of the box study (paper Sec. III; docs/box.md "Initial states").

Both preparations run with the plate at rest at ``z = 0`` between side walls at ``x = 0``
and ``x = Lx`` under the full contact law of Appendix A (:mod:`granpipe.box.model`) and
the nominal time step ``Δt = t_c/50``:

*crystal*
    The hexagonal lattice of :func:`granpipe.box.lattice.crystal_positions` (orientation A,
    rows horizontal, row fit ``inset`` 19/19 or ``spanning`` 20/19), each site displaced by
    a uniform random amount of at most ``crystal_noise`` (this breaks the exact mirror
    symmetry and nothing else), relaxed under gravity for ``crystal_relax_time``.
*random*
    Random sequential addition at area fraction ``random_packing_fraction`` in a tall
    rectangle above the plate, then fall and settle until the kinetic energy per disk is
    below ``settle_kinetic_energy`` (checked every 0.25 t0) or ``settle_max_time`` passes.

:func:`prepare` returns a :class:`Prepared` with positions, velocities and spins and the
bookkeeping the init file stores (settling time, whether it settled, bulk ψ6).
"""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..engine import FlatWalls, Simulation
from . import lattice, model

__all__ = ["Prepared", "prepare", "box_simulation", "disk_arrays", "resting_walls", "bulk_psi6"]


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


def resting_walls(physics: Mapping) -> FlatWalls:
    """Side walls at 0 and Lx, plate at rest at z = 0."""
    return FlatWalls(x_left=0.0, x_right=float(physics["Lx"]), bottom=True, z0=0.0)


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
        pos = lattice.crystal_positions(n, lx, init_cfg["crystal_rows"])
        noise = float(init_cfg["crystal_noise"])
        if noise > 0:
            pos = pos + rng.uniform(-noise, noise, size=pos.shape)
            # keep the noisy lattice inside the walls and on the plate
            pos[:, 0] = np.clip(pos[:, 0], 0.5, lx - 0.5)
            pos[:, 1] = np.maximum(pos[:, 1], 0.5)
        max_time = float(init_cfg["crystal_relax_time"])
        threshold = None
    elif kind == "random":
        pos = lattice.random_positions(n, lx, float(init_cfg["random_packing_fraction"]), rng)
        max_time = float(init_cfg["settle_max_time"])
        threshold = float(init_cfg["settle_kinetic_energy"])
    else:
        raise ValueError(f"kind must be 'crystal' or 'random', got {kind!r}")
    radii, masses = disk_arrays(n)
    sim = box_simulation(physics, model.nominal_dt(physics), resting_walls(physics))
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
    surface (:func:`granpipe.analysis.box.crystal_check`); NaN if none qualifies."""
    from ..analysis import box as ab

    return ab.crystal_check(positions, lx, r_max=r_max, depth=depth).psi6
