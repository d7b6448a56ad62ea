"""One shear replica replayed frame by frame, for watching
(docs/watching.md): :func:`trajectory` runs :func:`granpipe.shear.protocol.run_replica` from the
replica's seed with a :class:`granpipe.trajectory.FrameRecorder` as its hook, so the
frames are the run's states, and stops at the window's end.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..seeds import replica_seed
from ..trajectory import (
    FrameRecorder,
    FramesComplete,
    Schedule,
    TrajectoryError,
    check_replica,
)
from .model import ShearCell
from .protocol import Steps, run_replica

__all__ = ["trajectory", "schedule", "movie_stage"]


def schedule(params: Mapping, replica: int, window, every: float) -> Schedule:
    """The frames of ``window`` = (start_s, end_s) [s after t = 0] every ``every`` s,
    checked against the point (replica in 0 … ``n_replicas`` − 1, the window within the
    record ``[0, record_s]``, ``every`` at least Δt, the frame budget) before anything
    runs; refusals are :class:`granpipe.trajectory.TrajectoryError`."""
    check_replica(replica, params["n_replicas"])
    st = Steps(params)
    cell = ShearCell.from_physics(params["physics"])
    n = cell.n_mobile + len(cell.walls)
    return Schedule.build(window, every, st.dt_s, st.n_samples * st.sample * st.dt_s, n)


def trajectory(params: Mapping, replica: int, window, every: float) -> xr.Dataset:
    """Replica ``replica`` of the point of ``params`` (the runs' subset and
    ``n_replicas``: :func:`granpipe.shear.layout.trajectory_params`) over ``window`` =
    (start_s, end_s), a frame every ``every`` s (rounded to whole steps).

    Returns the dataset of :mod:`granpipe.trajectory` (dims ``frame``, ``disk``: the N
    mobile disks, then the inner ring's and the outer ring's wall disks); ``phase`` is the
    inner ring's angle [rad], ``time`` seconds after t = 0 of the record, ``du`` |δu_i| of
    the run's tangent vector over its largest. Lengths d_s, times t0 = ``t0_s`` s.
    """
    sched = schedule(params, replica, window, every)
    cell = ShearCell.from_physics(params["physics"])
    n = cell.n_mobile
    mobile = np.arange(n + len(cell.walls)) < n
    rec = FrameRecorder(sched, float(params["physics"]["t0_s"]), mobile,
                        phase=lambda state: state.wall_angle, tangent=True)  # fmt: skip
    try:
        run_replica(params, int(replica), on_frame=rec)
    except FramesComplete:
        pass
    return rec.dataset({
        "study": "shear", "point": str(params.get("point", "")), "replica": int(replica),
        "seed": replica_seed("shear", params["physics"], int(replica)),
        "phase": "angle of the inner ring (turning counter-clockwise at Ω) [rad]",
    })  # fmt: skip


def movie_stage(params: Mapping, run_file, out) -> tuple:
    """The report's shear movie (docs/watching.md): replica ``movie.replica`` of the point
    replayed around its first event at least ``movie.before_s`` after the record's start
    (the record's middle if it has none), ``movie.before_s`` before to ``movie.after_s``
    after it, a frame every ``movie.every_s``, written to ``out`` (.mp4 or .gif) at
    ``movie.fps``. ``run_file`` is the batch holding the replica, checked against the
    runs' config hash; the events are the fits' detector (``events``).

    Returns (path written, frames).
    """
    from ..io import check_run_files, read_dataset
    from ..trajectory import check_movie_file, movie_window, write_trajectory
    from .fits import event_times

    mv = params["movie"]
    path = check_movie_file(out)
    replica = check_replica(mv["replica"], params["n_replicas"])
    check_run_files([run_file], study="shear", point=params["point"],
                    config_hash=params["runs_config_hash"],
                    variables=("network_changes",))  # fmt: skip
    ds = read_dataset(run_file)
    if replica not in ds["replica"].values:
        raise TrajectoryError("replica", f"{run_file} does not hold replica {replica}")
    row = int(np.flatnonzero(ds["replica"].values == replica)[0])
    times = event_times(ds, params["events"])[row]
    record = float(params["protocol"]["record_s"])
    before, after = float(mv["before_s"]), float(mv["after_s"])
    later = times[times >= before]
    centre = float(later[0]) if len(later) else 0.5 * record
    window = movie_window(centre, before, after, 0.0, record)
    traj = trajectory(params, replica, window, float(mv["every_s"]))
    return write_trajectory(traj, path, path.suffix[1:], float(mv["fps"])), traj.sizes["frame"]
