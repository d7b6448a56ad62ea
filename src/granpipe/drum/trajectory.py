"""One drum replica replayed frame by frame, for watching
(docs/watching.md): :func:`trajectory` prepares the replica from its seed and runs
:func:`granpipe.drum.protocol.run_protocol` with a
:class:`granpipe.trajectory.FrameRecorder` as its hook in one of the two recorded windows
(each with its own t = 0, as the run files keep them), and stops at the window's end.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..trajectory import (
    FrameRecorder,
    FramesComplete,
    Schedule,
    TrajectoryError,
    check_replica,
)
from .layout import load, point_name, steps
from .model import DrumModel
from .preparation import prepare
from .protocol import replica_streams, run_protocol

__all__ = ["WINDOWS", "trajectory", "schedule"]

WINDOWS = ("onset", "decay")
"""The drum's recorded windows, each timed from its own t = 0 (docs/drum.md)."""


def schedule(params: Mapping, replica: int, window, every: float, part: str = "onset"):
    """The frames of ``window`` = (start_s, end_s) [s after the part's t = 0] every
    ``every`` s, checked before anything runs: replica in 0 … ``ensemble.n_replicas`` − 1,
    ``part`` one of :data:`WINDOWS`, the window within ``[0, onset_window_s]`` or
    ``[0, decay_window_s]``, ``every`` at least Δt, the frame budget."""
    sec = load(params)
    check_replica(replica, sec["ensemble"]["n_replicas"])
    if part not in WINDOWS:
        raise TrajectoryError("part", f"part {part!r} is not one of {', '.join(WINDOWS)}")
    st = steps(sec)
    record = (st.onset if part == "onset" else st.decay) * st.dt_s
    model = DrumModel.from_physics(sec["physics"])
    return Schedule.build(window, every, st.dt_s, record, model.n_mobile + model.geom.n_wall)


def trajectory(params: Mapping, replica: int, window, every: float,
               part: str = "onset") -> xr.Dataset:  # fmt: skip
    """Replica ``replica`` of the point of ``params`` (a drum point's section, e.g.
    :func:`granpipe.drum.layout.trajectory_params`) over ``window`` = (start_s, end_s) of
    the recorded window ``part`` (``onset``: from the onset window's t = 0; ``decay``: from
    the decay window's, after the wait for a continuous avalanche), a frame every
    ``every`` s (rounded to whole steps).

    Returns the dataset of :mod:`granpipe.trajectory` (dims ``frame``, ``disk``: the N
    mobile disks, then the wall disks); ``phase`` is the angle the drum has turned
    clockwise since the placement [rad] (constant once it stops in the decay window),
    ``du`` |δu_i| of the run's tangent vector over its largest, ``spin`` under static
    friction. Lengths d_s, times t0 = ``physics.t0_s`` s.
    """
    sched = schedule(params, replica, window, every, part)
    sec = load(params)
    st = steps(sec)
    model = DrumModel.from_physics(sec["physics"])
    place, tangent, seed = replica_streams(sec, int(replica))
    start = prepare(model, sec, st, place)
    mobile = np.arange(model.n_mobile + model.geom.n_wall) < model.n_mobile
    rec = FrameRecorder(sched, float(sec["physics"]["t0_s"]), mobile,
                        phase=lambda state: start.wall_angle - state.wall_angle,
                        tangent=True, spin=model.static)  # fmt: skip
    try:
        run_protocol(model, st, sec["protocol"], start, tangent, replica=int(replica),
                     seed=seed, on_frame=rec, frame_window=part)  # fmt: skip
    except FramesComplete:
        pass
    return rec.dataset({
        "study": "drum", "point": point_name(sec), "replica": int(replica), "seed": seed,
        "window": part,
        "phase": "angle the drum has turned clockwise since the placement [rad]",
    })  # fmt: skip
