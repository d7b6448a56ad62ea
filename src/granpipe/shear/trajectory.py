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
from ..trajectory import FrameRecorder, FramesComplete, Schedule, check_replica
from .model import ShearCell
from .protocol import Steps, run_replica

__all__ = ["trajectory", "schedule"]


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
