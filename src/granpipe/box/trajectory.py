"""One box replica replayed frame by frame, for watching
(docs/watching.md): :func:`trajectory` prepares the replica's initial state from its seed as the
init stage does and runs :func:`granpipe.box.protocol.run_part` over the whole protocol
(transient and every measured period in one part: the same bits as the chained parts)
with a :class:`granpipe.trajectory.FrameRecorder` as its hook, and stops at the window's
end. Units: σ, t0 = sqrt(σ/g); times in t0 from the drive's start.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..seeds import replica_rng, replica_seed
from ..trajectory import FrameRecorder, FramesComplete, Schedule, check_replica
from . import layout, model, preparation
from .protocol import run_part
from .stages import n_disks, seed_physics

__all__ = ["trajectory", "schedule", "movie_stage"]


def _recorded_t0(params: Mapping) -> tuple[float, float]:
    """(Δt, the protocol's recorded time) [t0]: from the drive's start to the end of the
    last measured period."""
    proto = params["protocol"]
    drive = model.drive_for(params["physics"], proto, float(params["Gamma"]))
    steps_per, dt = model.steps_per_period(params["physics"], int(proto["phases_per_period"]))
    offset = round(-drive.phase / (2.0 * math.pi) * steps_per)
    total = (int(proto["transient_periods"]) + int(proto["measured_periods"])) * steps_per
    return dt, (total + offset) * dt


def schedule(params: Mapping, replica: int, window, every: float) -> Schedule:
    """The frames of ``window`` = (start, end) [t0 from the drive's start] every ``every``
    t0, checked before anything runs: replica in 0 … ``replicas`` − 1, the window within
    the transient and the measured periods, ``every`` at least Δt, the frame budget."""
    check_replica(replica, params["replicas"])
    dt, record = _recorded_t0(params)
    n = n_disks(params["physics"], int(params["N_l"]))
    return Schedule.build(window, every, dt, record, n, unit="t0")


def trajectory(params: Mapping, replica: int, window, every: float) -> xr.Dataset:
    """Replica ``replica`` of the point of ``params``
    (:func:`granpipe.box.layout.trajectory_params`) over ``window`` = (start, end) [t0 from
    the drive's start], a frame every ``every`` t0 (rounded to whole steps).

    Returns the dataset of :mod:`granpipe.trajectory` (dims ``frame``, ``disk``; every disk
    mobile: the box's walls are lines) with ``spin``, ``phase`` = ωt + φ of the drive
    [rad] and ``z_plate`` the plate's height [σ]; no tangent vector (the box integrates
    none: no ``du``, no λ). Lengths σ, times t0.
    """
    sched = schedule(params, replica, window, every)
    physics, proto = params["physics"], params["protocol"]
    n_l, kind = int(params["N_l"]), str(params["init_kind"])
    prep_params = {"physics": layout.preparation_physics(physics), "init": params["init"]}
    sp = seed_physics(prep_params, n_l, kind)
    n = n_disks(physics, n_l)
    prep = preparation.prepare(prep_params["physics"], params["init"], n, kind,
                               replica_rng("box", sp, int(replica)))  # fmt: skip
    gamma = float(params["Gamma"])
    drive = model.drive_for(physics, proto, gamma)
    walls = model.flat_walls(physics, drive)
    extras = {"z_plate": (lambda state: walls.height(state.time), "sigma", "plate height")}
    rec = FrameRecorder(sched, None, np.ones(n, bool),
                        phase=lambda state: drive.omega * state.time + drive.phase,
                        tangent=False, spin=True, extras=extras, length_unit="sigma",
                        time_unit="t0")  # fmt: skip
    try:
        run_part(physics, proto, gamma, 0, range(int(proto["measured_periods"])),
                 start_positions=prep.positions, start_velocities=prep.velocities,
                 start_spins=prep.spins, on_frame=rec)  # fmt: skip
    except FramesComplete:
        pass
    walls_ = layout.Walls(float(physics["mu_side_walls"]), str(physics["side_walls"]),
                          str(physics["wall_torque"]))  # fmt: skip
    return rec.dataset({
        "study": "box", "point": layout.point_name(n_l, gamma, kind, walls_),
        "replica": int(replica), "seed": replica_seed("box", sp, int(replica)),
        "phase": "drive phase ωt + φ of z_b(t) = z0 + A r(t) sin(ωt + φ) [rad]",
        "speed_reference": "bed",  # a movie colours the speed relative to the bed's mean
    })  # fmt: skip


def movie_stage(params: Mapping, out) -> tuple:
    """The report's box movie (docs/watching.md): replica ``movie.replica`` of the point of
    ``params`` (:func:`granpipe.box.layout.movie_params`) over the last ``movie.periods``
    periods of its record, ``movie.frames_per_period`` frames per period, written to
    ``out`` (.mp4 or .gif) at ``movie.fps``.

    Returns (path written, frames).
    """
    from ..trajectory import check_movie_file, movie_window, write_trajectory

    mv = params["movie"]
    path = check_movie_file(out)
    check_replica(mv["replica"], params["replicas"])
    _, record = _recorded_t0(params)
    phases = int(params["protocol"]["phases_per_period"])
    steps_per, dt = model.steps_per_period(params["physics"], phases)
    period = steps_per * dt
    window = movie_window(record, int(mv["periods"]) * period, 0.0, 0.0, record)
    every = period / int(mv["frames_per_period"])
    traj = trajectory(params, int(mv["replica"]), window, max(every, dt))
    return write_trajectory(traj, path, path.suffix[1:], float(mv["fps"])), traj.sizes["frame"]
