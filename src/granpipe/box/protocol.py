"""The vibrated-box protocol of one parameter point (docs/box.md "Drive", Appendix B).

One run of a point ``(N_l, Γ, init)`` and replica, in order:

1. Start from the prepared state (:mod:`granpipe.box.preparation`), bed resting on the plate
   at ``z = 0``, time ``t = 0``. Shear histories of the settled packing are not carried
   into the run (the drive starts from positions, velocities and spins).
2. Drive the plate, ``z_b(t) = z0 + A r(t) sin(ωt + φ)`` with ``A = Γ g/ω²``
   (:func:`granpipe.box.model.drive_for`). Smooth start (docs/box.md, hazard (i)): with
   ``start_phase = sine`` and a ramp ``r(t) = min(t/t_ramp, 1)`` the plate velocity is
   continuous (zero) at ``t = 0`` and grows linearly; with ``start_phase = bottom``
   (``φ = -π/2``) the plate starts at rest at its lowest point.
3. Transient: until the drive phase ``ωt + φ`` reaches ``2π n_transient`` (ramp included);
   sampled at the same phases as the measurement (bed centre of mass, plate, gap, T_g)
   so that launch speeds can be read (hazard (ii)).
4. Measured periods ``j``, each starting at drive phase ``2π(n_transient + j)`` (plate at
   mid-height moving up, the cycle start of Eq. (1)). At ``N_k`` equally spaced phases
   ``k`` per period: tracer heights ``z_j^i(k)`` (Eqs. B1, B3), plate height ``z_b(k)``,
   gap under the bed, disks touching the plate, instantaneous granular temperature
   (Eq. 2), bed centre of mass. At every cycle start, all positions (float32), for slips
   (Sec. V) and ψ6/ψ4, and with ``slip_phases`` = n_s > 1 also at the phases
   k = m N_k/n_s, m = 1 … n_s − 1 (slips seen at other phases of the cycle). Tracers: the
   row closest to mid-height of the bed at the start of the measurement
   (:func:`granpipe.box.measures.select_tracers`).
5. All positions once more when the start-up ramp has ended (the first transient sample
   at t ≥ t_ramp; t = 0 without a ramp), for the crystal check of start-up damage.

A long run is a chain of *parts* (``periods_per_part`` periods each); part ``p``
continues from the engine state saved at the end of part ``p - 1`` (shear histories and
neighbour list included), so a chained run is bit-identical to an unchained one.

Time step: :func:`granpipe.box.model.steps_per_period` (Δt = t_c/50 rounded down so that
every sampling phase falls on a step).
"""

from __future__ import annotations

import functools
import math
import time as _time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..engine import FlatWalls, State
from . import model
from .measures import granular_temperature, select_tracers
from .preparation import box_simulation, disk_arrays

__all__ = [
    "PartResult",
    "run_part",
    "state_arrays",
    "Progress",
]


# ----------------------------------------------------------------- engine state I/O


def state_arrays(state) -> dict[str, np.ndarray]:
    """Everything the engine needs to continue ``state`` exactly (``State.to_arrays``)."""
    return state.to_arrays()


# ----------------------------------------------------------------------- progress
class Progress:
    """Progress lines every ``every`` seconds of wall time: period k of n, t, elapsed, ETA."""

    def __init__(self, log: Callable[[str], None] | None, total_steps: int, label: str,
                 every: float = 30.0):  # fmt: skip
        self.log = log
        self.total = max(int(total_steps), 1)
        self.label = label
        self.every = every
        self.start = _time.perf_counter()
        self.last = self.start
        self.done = 0

    def update(self, steps: int, text: str, sim_time: float) -> None:
        self.done += steps
        now = _time.perf_counter()
        if self.log is None or now - self.last < self.every:
            return
        self.last = now
        elapsed = now - self.start
        eta = elapsed * (self.total - self.done) / max(self.done, 1)
        self.log(
            f"{self.label}: {text}, t = {sim_time:.2f} t0, elapsed {elapsed:.0f} s, "
            f"remaining ~{eta:.0f} s"
        )


# -------------------------------------------------------------------------- a part
@dataclass
class PartResult:
    """What one part of a run recorded (arrays; :mod:`granpipe.box.stages` labels them).

    Shapes: P periods in the part, N_k phases, N_t tracers, N disks, S transient samples.
    """

    periods: np.ndarray  # (P,) measured-period indices
    time: np.ndarray  # (P, N_k) [t0]
    z_plate: np.ndarray  # (P, N_k) [σ]
    z_tracers: np.ndarray  # (P, N_k, N_t) [σ]
    bed_gap: np.ndarray  # (P, N_k) [σ]
    plate_contacts: np.ndarray  # (P, N_k) int
    granular_temperature: np.ndarray  # (P, N_k) [mgσ]
    z_cm: np.ndarray  # (P, N_k) [σ]
    vz_cm: np.ndarray  # (P, N_k) [σ/t0]
    cycle_positions: np.ndarray  # (P + 1, N, 2) float32 [σ], starts of periods j..j+P
    phase_positions: np.ndarray  # (P, n_s - 1, N, 2) float32 [σ], the other slip phases
    tracers: np.ndarray  # (N_t,) int
    final_state: dict  # engine arrays at the end of the part
    transient: dict | None  # part 0: (S,) arrays time, z_plate, v_plate, z_cm, vz_cm, ...
    dt: float
    steps_per_period: int
    steps: int
    wall_seconds: float
    drive: model.Drive
    ramp_positions: np.ndarray | None = None  # part 0: (N, 2) [σ] when the ramp has ended
    ramp_time: float = math.nan  # [t0], time of ``ramp_positions``
    extra: dict = field(default_factory=dict)

    @property
    def ns_per_particle_step(self) -> float:
        n = self.cycle_positions.shape[1]
        return 1e9 * self.wall_seconds / max(self.steps * n, 1)


def _sample(state, walls: FlatWalls, t: float):
    """(z_b, positions view, velocities view, gap, plate contacts, T_g, z_cm, vz_cm)."""
    pos = state.positions
    vel = state.velocities
    zb = float(walls.height(t))
    zmin_bottom = pos[:, 1] - 0.5 * model.DIAMETER
    gap = float(zmin_bottom.min() - zb)
    contacts = int(np.count_nonzero(zmin_bottom < zb))
    tg = float(granular_temperature(vel, model.MASS))
    return zb, pos, vel, gap, contacts, tg, float(pos[:, 1].mean()), float(vel[:, 1].mean())


def run_part(
    physics: Mapping,
    protocol: Mapping,
    gamma: float,
    part: int,
    periods: range,
    *,
    start_positions: np.ndarray | None = None,
    start_velocities: np.ndarray | None = None,
    start_spins: np.ndarray | None = None,
    previous_state: Mapping | None = None,
    tracers: np.ndarray | None = None,
    log: Callable[[str], None] | None = None,
    label: str = "box",
    on_frame=None,
) -> PartResult:
    """Run one part of a point's protocol.

    Parameters
    ----------
    physics, protocol : mapping
        ``box.physics`` and ``box.protocol`` (only ``start_phase``, ``ramp_periods``,
        ``transient_periods``, ``phases_per_period``, ``slip_phases`` are read here).
    gamma : float
        Γ = Aω²/g.
    part : int
        0 starts from ``start_*`` (the prepared state at t = 0) and runs the transient;
        ``p > 0`` continues from ``previous_state`` (engine arrays of part ``p - 1``) with
        the tracers of part ``p - 1``.
    periods : range
        Measured-period indices of this part (consecutive).
    log : callable, optional
        Receives progress lines (every ~30 s wall).
    on_frame : optional
        None in a run; a replay's :class:`granpipe.trajectory.FrameRecorder`, started at
        the part's first step and running its steps in place of ``sim.run``
        (:func:`granpipe.box.trajectory.trajectory`).

    Raises
    ------
    SimulationError
        From the engine, unchanged (the caller adds study/point/replica/seed).
    """
    n_k = int(protocol["phases_per_period"])
    n_s = int(protocol.get("slip_phases", 1))
    if n_k % n_s:
        raise ValueError(f"slip_phases = {n_s} does not divide phases_per_period = {n_k}")
    slip_k = {m * n_k // n_s: m - 1 for m in range(1, n_s)}  # phase k -> index m - 1
    steps_per, dt = model.steps_per_period(physics, n_k)
    chunk = steps_per // n_k
    drive = model.drive_for(physics, protocol, gamma)
    walls = model.flat_walls(physics, drive)
    sim = box_simulation(physics, dt, walls)
    n_tr = int(protocol["transient_periods"])
    # measurement start: drive phase 2π n_tr, i.e. t_m = (2π n_tr - φ)/ω = whole steps
    offset_steps = round(-drive.phase / (2.0 * math.pi) * steps_per)
    transient_steps = n_tr * steps_per + offset_steps
    if transient_steps < 0:
        raise ValueError("the measurement cannot start before t = 0")
    n_periods = len(periods)
    start = _time.perf_counter()

    if part == 0:
        if start_positions is None:
            raise ValueError("part 0 needs the prepared state")
        n = start_positions.shape[0]
        radii, masses = disk_arrays(n)
        state = sim.new_state(
            start_positions, radii, masses, velocities=start_velocities, spins=start_spins
        )
    else:
        if previous_state is None or tracers is None:
            raise ValueError(f"part {part} needs the previous part's state and tracers")
        state = State.from_arrays(dict(previous_state))
        n = state.positions.shape[0]
        if len(tracers) and int(np.max(tracers)) >= n:
            raise ValueError(f"the previous part's state holds {n} disks, fewer than its tracers")
        expected = (n_tr + periods[0]) * steps_per + offset_steps
        have = round(state.time / dt)
        if have != expected:
            raise ValueError(
                f"previous part ends at step {have}, part {part} starts at step {expected}"
            )

    run = sim.run
    if on_frame is not None:
        on_frame.start(state)
        run = functools.partial(on_frame.run, sim)
    total = (transient_steps if part == 0 else 0) + n_periods * steps_per
    progress = Progress(log, total, label)

    transient = None
    ramp_positions, ramp_time = None, math.nan
    if part == 0 and transient_steps == 0:
        ramp_positions, ramp_time = state.positions.copy(), state.time
    if part == 0 and transient_steps > 0:
        n_samples = -(-transient_steps // chunk)
        tr = {
            k: np.empty(n_samples + 1)
            for k in ("time", "z_plate", "v_plate", "z_cm", "vz_cm", "bed_gap", "T_g",
                      "max_vz")
        }  # fmt: skip
        tr["plate_contacts"] = np.empty(n_samples + 1, dtype=np.int64)
        done = 0
        for s in range(n_samples + 1):
            t = state.time
            zb, pos, vel, gap, cont, tg, zcm, vzcm = _sample(state, walls, t)
            tr["time"][s] = t
            tr["z_plate"][s] = zb
            tr["v_plate"][s] = float(walls.velocity(t))
            tr["z_cm"][s] = zcm
            tr["vz_cm"][s] = vzcm
            tr["bed_gap"][s] = gap
            tr["T_g"][s] = tg
            tr["max_vz"][s] = float(vel[:, 1].max())
            tr["plate_contacts"][s] = cont
            if ramp_positions is None and (t >= drive.ramp_time or s == n_samples):
                ramp_positions, ramp_time = pos.copy(), t
            if s == n_samples:
                break
            steps = min(chunk, transient_steps - done)
            run(state, steps)
            done += steps
            text = f"transient period {done / steps_per:.1f} of {transient_steps / steps_per:.2f}"
            progress.update(steps, text, state.time)
        transient = tr

    # the tracer row at the start of the measurement
    if tracers is None:
        tracers = select_tracers(state.positions)
    tracers = np.asarray(tracers, dtype=np.int64)
    n_t = tracers.size

    time_ = np.empty((n_periods, n_k))
    z_plate = np.empty((n_periods, n_k))
    z_tr = np.empty((n_periods, n_k, n_t))
    gap_ = np.empty((n_periods, n_k))
    cont_ = np.empty((n_periods, n_k), dtype=np.int64)
    tg_ = np.empty((n_periods, n_k))
    zcm_ = np.empty((n_periods, n_k))
    vzcm_ = np.empty((n_periods, n_k))
    frames = np.empty((n_periods + 1, n, 2), dtype=np.float32)
    phase_frames = np.empty((n_periods, n_s - 1, n, 2), dtype=np.float32)
    for j in range(n_periods):
        for k in range(n_k):
            t = state.time
            zb, pos, vel, gap, cont, tg, zcm, vzcm = _sample(state, walls, t)
            if k == 0:
                frames[j] = pos
            elif k in slip_k:
                phase_frames[j, slip_k[k]] = pos
            time_[j, k] = t
            z_plate[j, k] = zb
            z_tr[j, k] = pos[tracers, 1]
            gap_[j, k] = gap
            cont_[j, k] = cont
            tg_[j, k] = tg
            zcm_[j, k] = zcm
            vzcm_[j, k] = vzcm
            run(state, chunk)
            progress.update(
                chunk, f"period {periods[j] + 1} of {periods[-1] + 1} (part {part})", state.time
            )
    frames[n_periods] = state.positions
    wall = _time.perf_counter() - start
    return PartResult(
        periods=np.asarray(list(periods), dtype=np.int64),
        time=time_,
        z_plate=z_plate,
        z_tracers=z_tr,
        bed_gap=gap_,
        plate_contacts=cont_,
        granular_temperature=tg_,
        z_cm=zcm_,
        vz_cm=vzcm_,
        cycle_positions=frames,
        phase_positions=phase_frames,
        tracers=tracers,
        final_state=state_arrays(state),
        transient=transient,
        dt=dt,
        steps_per_period=steps_per,
        steps=total,
        wall_seconds=wall,
        drive=drive,
        ramp_positions=ramp_positions,
        ramp_time=ramp_time,
    )
