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
from .layout import load, movie_sim_params, point_name, steps
from .model import DrumModel
from .preparation import prepare
from .protocol import replica_streams, run_protocol

__all__ = ["WINDOWS", "trajectory", "schedule", "movie_stage"]

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


def movie_stage(params: Mapping, part: str, run_file, out) -> tuple:
    """The report's drum movie of the recorded window ``part`` (docs/watching.md): replica
    ``movie.replica`` of the point of ``params`` (:func:`granpipe.drum.layout.movie_params`;
    null: the first replica of ``run_file`` with the event) replayed from
    ``movie.before_s`` before to ``movie.after_s`` after its pile's onset of sustained flow
    (``onset``) or its flow's stop (``decay``), found in ``run_file`` by the fits'
    detector (:func:`granpipe.drum.fits.load_pile`; the window's middle without one), a
    frame every ``movie.every_s``, written to ``out`` (.mp4 or .gif) at ``movie.fps``.
    ``run_file`` is checked against the point's runs config hash.

    Returns (path written, frames).
    """
    from ..io import check_run_files, config_hash
    from ..trajectory import check_movie_file, movie_window, write_trajectory
    from .fits import load_pile

    sec = load(params)
    mv = sec["movie"]
    path = check_movie_file(out)
    if part not in WINDOWS:
        raise TrajectoryError("windows", f"window {part!r} is not one of {', '.join(WINDOWS)}")
    labels = check_run_files([run_file], study="drum", point=point_name(sec),
                             config_hash=config_hash(movie_sim_params(sec)))  # fmt: skip
    pile = load_pile([run_file], sec["fits"], exclude_flagged=False)  # any replica may be shown
    if pile is None:
        raise TrajectoryError("windows", f"{run_file} holds no pile samples")
    reps = np.asarray(pile.events["replica"], np.int64)
    times = np.asarray(pile.events["flow_onset" if part == "onset" else "flow_stop"], float)
    if mv["replica"] is None:
        found = np.flatnonzero(np.isfinite(times))
        replica = int(reps[found[0]] if len(found) else reps[0])
    else:
        replica = check_replica(mv["replica"], sec["ensemble"]["n_replicas"])
        if replica not in reps:
            raise TrajectoryError("replica", f"{run_file} holds replicas "
                                  f"{labels[0]['replicas']}, not {replica}")  # fmt: skip
    st = steps(sec)
    record = (st.onset if part == "onset" else st.decay) * st.dt_s
    t = times[reps == replica][0]
    centre = float(t) if np.isfinite(t) else 0.5 * record
    window = movie_window(centre, float(mv["before_s"]), float(mv["after_s"]), 0.0, record)
    traj = trajectory(sec, replica, window, float(mv["every_s"]), part)
    return write_trajectory(traj, path, path.suffix[1:], float(mv["fps"])), traj.sizes["frame"]
