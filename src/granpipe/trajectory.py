"""Trajectories of one replica for watching the dynamics: the frame schedule and its
checks, the recorder a study's protocol calls instead of ``Simulation.run`` when it is
replayed, and the writers (extended XYZ through ASE for OVITO, VTK ``.vtu`` frames with a
``.pvd`` index through meshio for ParaView).

A study's ``trajectory(params, replica, window, every)`` (e.g.
:func:`granpipe.shear.trajectory.trajectory`) replays one replica from its seed through
the study's own ``run_replica`` with a :class:`FrameRecorder` as its ``on_frame`` hook:
the recorder splits the protocol's runs at the frame steps (a run split into pieces is
bit-identical to the run in one piece), captures each frame and stops the replay at the
window's end (:class:`FramesComplete`). With no hook a protocol runs as it always did.

The dataset (dims ``frame``, ``disk``; wall disks included, flagged by ``wall``):

* per frame and disk: ``x``, ``y`` [d_s], ``radius`` [d_s], ``vx``, ``vy`` [d_s/t0],
  ``spin`` [rad/t0] (laws with spin), ``wall`` (1 for a wall disk), ``contacts`` (at the
  last force evaluation, walls included), ``du`` (|δu_i| of the tangent vector over its
  largest among the mobile disks, where the protocol integrates one);
* per frame: ``time`` [s] (the study's clock: seconds after its record's start),
  ``local_lyapunov`` [1/t0] and ``global_speed`` [d_s/t0] (means over the frame interval
  ending at the frame, the steps of the record's blocks: λ(t) over the non-rattlers, V =
  sqrt(Σ|v_i|²) over the mobile disks; NaN at a frame on the record's start),
  ``phase`` [rad] (the drive's phase, where the study has a drive).
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr

from .analysis.lyapunov import lyapunov_vector_magnitude
from .errors import ConfigError, WriteError

__all__ = [
    "FORMATS",
    "MAX_VALUES",
    "FramesComplete",
    "TrajectoryError",
    "Schedule",
    "FrameRecorder",
    "check_replica",
    "check_format",
    "write_trajectory",
    "write_extxyz",
    "write_vtu",
    "replay_to_file",
    "check_movie_file",
    "movie_window",
]

FORMATS = ("extxyz", "vtu", "mp4", "gif")
"""The file formats :func:`write_trajectory` writes (the movies:
:func:`granpipe.figures.movie.write_movie`)."""

MAX_VALUES = 100_000_000
"""Largest trajectory, in values (frames × disks × per-disk fields): 0.8 GB of float64."""

PER_DISK_FIELDS = 10
"""Per-disk values of a frame the budget counts (x, y, radius, vx, vy, spin, wall,
contacts, du and a spare)."""


class TrajectoryError(ConfigError):
    """A trajectory request refused before anything is integrated; ``option`` names the
    command-line option it concerns (``replica``, ``start``, ``end``, ``every``,
    ``format``, ``out``)."""

    def __init__(self, option: str, message: str):
        super().__init__(message)
        self.option = option


class FramesComplete(Exception):
    """Raised by :class:`FrameRecorder` once the window's last frame is captured: the
    replay stops there, nothing after the window is integrated."""


def check_replica(replica: int, n_replicas: int) -> int:
    """``replica`` as an int, refused unless it lies in the point's ensemble 0 … n−1."""
    r = int(replica)
    if not 0 <= r < int(n_replicas):
        raise TrajectoryError("replica", f"replica {r} is outside the point's ensemble "
                              f"(replicas 0 .. {int(n_replicas) - 1})")  # fmt: skip
    return r


def check_format(fmt: str) -> str:
    """``fmt`` if it is one of :data:`FORMATS`, else refused."""
    if fmt not in FORMATS:
        raise TrajectoryError("format", f"format {fmt!r} is not one of {', '.join(FORMATS)}")
    return fmt


@dataclass(frozen=True)
class Schedule:
    """The frames of a window, in engine steps after the record's start.

    Parameters
    ----------
    steps : (F,) int64
        Frame steps after the record's start (t = 0 of the study's clock).
    every : int
        Steps between frames.
    dt : float [s, or the study's time unit]
        One engine step.
    """

    steps: np.ndarray
    every: int
    dt: float

    @classmethod
    def build(cls, window, every_s: float, dt_s: float, record_s: float, n_disks: int,
              unit: str = "s"):  # fmt: skip
        """The frames ``start, start + every, …`` up to ``end`` (in ``unit`` after the record's
        start, rounded to whole steps), refused before anything runs if the window lies
        outside ``[0, record_s]`` or is empty, ``every_s`` is below one step ``dt_s``, or
        frames × disks × :data:`PER_DISK_FIELDS` exceeds :data:`MAX_VALUES`."""
        try:
            start, end = (float(w) for w in window)
        except (TypeError, ValueError):
            msg = f"window must be (start_s, end_s), got {window!r}"
            raise TrajectoryError("start", msg) from None
        every = float(every_s)
        for name, v in (("start", start), ("end", end), ("every", every)):
            if not math.isfinite(v):
                raise TrajectoryError(name, f"{name} must be a finite number, got {v}")
        tol = 0.5 * dt_s
        if start < -tol or start > record_s + tol:
            raise TrajectoryError("start", f"start {start:g} {unit} is outside the recorded time "
                                  f"0 .. {record_s:g} {unit}")  # fmt: skip
        if end > record_s + tol or end < -tol:
            raise TrajectoryError("end", f"end {end:g} {unit} is outside the recorded time "
                                  f"0 .. {record_s:g} {unit}")  # fmt: skip
        if end < start:
            raise TrajectoryError("end", f"end {end:g} {unit} is before start {start:g} {unit}")
        if every < dt_s * (1 - 1e-9):
            raise TrajectoryError("every", f"frame interval {every:g} {unit} is below the time "
                                  f"step {dt_s:g} {unit}")  # fmt: skip
        n_rec = round(record_s / dt_s)
        first = min(max(round(start / dt_s), 0), n_rec)
        last = min(max(round(end / dt_s), 0), n_rec)
        step = max(1, round(every / dt_s))
        n_frames = (last - first) // step + 1
        values = n_frames * int(n_disks) * PER_DISK_FIELDS
        if values > MAX_VALUES:
            raise TrajectoryError("every", f"{n_frames} frames × {int(n_disks)} disks × "
                                  f"{PER_DISK_FIELDS} fields = {values:.3g} values exceed the "
                                  f"bound {MAX_VALUES:.0e}: a longer interval or a shorter "
                                  "window")  # fmt: skip
        return cls(first + step * np.arange(n_frames, dtype=np.int64), step, float(dt_s))


class FrameRecorder:
    """The ``on_frame`` hook of a protocol's ``run_replica``: call :meth:`start` at the
    record's start (t = 0 of the study's clock) and :meth:`run` instead of
    ``sim.run`` for every run of the record. It runs the same steps, split at the frames
    and at the start of the first frame's interval, captures each frame, and raises
    :class:`FramesComplete` after the last.

    Parameters
    ----------
    schedule : Schedule
    t0_s : float [s]
        The reduced time unit in seconds.
    mobile : (N,) bool
        Mobile disks (the others are walls).
    phase : callable(State) -> float, optional
        The drive's phase [rad] at a state.
    tangent : bool
        Whether the protocol integrates a tangent vector (``du`` is recorded then).
    spin : bool
        Whether the contact law has spin (``spin`` is recorded then).
    extras : mapping, optional
        ``{name: (callable(State) -> float, units, long name)}``: more per-frame values.
    length_unit, time_unit : str
        The study's length unit and the unit of ``time`` and of the schedule's step (the
        box: ``sigma`` and ``t0``; ``t0_s`` None then).
    """

    def __init__(self, schedule: Schedule, t0_s: float | None, mobile, phase=None,
                 tangent=True, spin=False, extras=None, length_unit="d_s",
                 time_unit="s"):  # fmt: skip
        self.schedule = schedule
        self.t0_s = None if t0_s is None else float(t0_s)
        self.mobile = np.asarray(mobile, bool)
        self.phase = phase
        self.tangent = bool(tangent)
        self.spin = bool(spin)
        self.extras = dict(extras or {})
        self.length_unit, self.time_unit = str(length_unit), str(time_unit)
        self.frames: list[dict] = []
        self.step = None
        self._acc = None  # sums of λ·count, count, V·steps, steps since the interval began

    def start(self, state) -> None:
        """Mark the record's start; a frame at step 0 is captured here."""
        self.step = 0
        self._next = 0
        self._begin = int(self.schedule.steps[0]) - self.schedule.every
        if self._begin <= 0:
            self._acc = [0.0, 0, 0.0, 0]
        self._frames_at(state)

    def _frames_at(self, state) -> None:
        steps = self.schedule.steps
        while self._next < len(steps) and steps[self._next] == self.step:
            self._capture(state)
            self._next += 1
            self._acc = [0.0, 0, 0.0, 0]
        if self._next == len(steps):
            raise FramesComplete

    def _capture(self, state) -> None:
        acc = self._acc
        lam = acc[0] / acc[1] if acc is not None and acc[1] else math.nan
        speed = acc[2] / acc[3] if acc is not None and acc[3] else math.nan
        vel = state.velocities
        frame = {
            "time": self.step * self.schedule.dt,
            "global_speed": speed,
            "x": state.positions[:, 0].copy(),
            "y": state.positions[:, 1].copy(),
            "radius": state.radii.copy(),
            "vx": vel[:, 0].copy(),
            "vy": vel[:, 1].copy(),
            "contacts": state.contacts.astype(np.int32),
        }
        if self.spin:
            frame["spin"] = state.spins.copy()
        if self.tangent and state.has_tangent:
            dr, dv = state.tangent_stored
            du = np.zeros(len(self.mobile))
            du[self.mobile] = lyapunov_vector_magnitude(dr[self.mobile], dv[self.mobile],
                                                        relative=True)  # fmt: skip
            frame["du"] = du
        if self.tangent:
            frame["local_lyapunov"] = lam
        if self.phase is not None:
            frame["phase"] = float(self.phase(state))
        for name, (fn, _, _) in self.extras.items():
            frame[name] = float(fn(state))
        self.frames.append(frame)

    def run(self, sim, state, n_steps, *, stride=0, tangent=False):
        """``sim.run(state, n_steps, stride=stride, tangent=tangent)`` in pieces, the frames
        captured between them. Returns a Record of the protocol's shape filled with NaN
        (a replay's records are not the run's: only its frames are)."""
        from .engine.simulation import Record

        n_steps = int(n_steps)
        if self.step is None:
            raise RuntimeError("FrameRecorder.start was not called at the record's start")
        end = self.step + n_steps
        while self.step < end:
            cuts = [end, int(self.schedule.steps[self._next])]
            if self._begin > self.step:
                cuts.append(self._begin)
            piece = min(c for c in cuts if c > self.step)
            n = piece - self.step
            if self._acc is None:
                sim.run(state, n, tangent=tangent)
            else:
                rec = sim.run(state, n, stride=n, tangent=tangent)
                if tangent:
                    c = int(rec.lyapunov_count[0])
                    if c:
                        self._acc[0] += float(rec.local_lyapunov[0]) * c
                        self._acc[1] += c
                self._acc[2] += float(rec.global_speed[0]) * n
                self._acc[3] += n
            self.step = piece
            if piece == self._begin:
                self._acc = [0.0, 0, 0.0, 0]
            self._frames_at(state)
        blocks = n_steps // stride if stride else 0
        nan = np.full(blocks, np.nan)
        return Record(time=nan, global_speed=nan, local_lyapunov=nan if tangent else None,
                      lyapunov_count=np.zeros(blocks, np.int64) if tangent else None,
                      stride=stride)  # fmt: skip

    def dataset(self, attrs: Mapping | None = None) -> xr.Dataset:
        """The frames as a dataset (module docstring); ``attrs`` added to its attributes."""
        fr = self.frames
        if not fr:
            raise RuntimeError("no frame was captured")
        L, T = self.length_unit, self.time_unit
        spec = {  # name: (per disk?, units, long name)
            "time": (False, T, "time after the record's start"),
            "local_lyapunov": (False, "1/t0", "mean of the local Lyapunov exponent λ(t) over "
                               "the frame interval ending at the frame"),
            "global_speed": (False, f"{L}/t0", "mean of V(t) = sqrt(Σ|v_i|²) over the frame "
                             "interval ending at the frame"),
            "phase": (False, "rad", "the drive's phase"),
            "x": (True, L, "centre, x"),
            "y": (True, L, "centre, y"),
            "radius": (True, L, "radius"),
            "vx": (True, f"{L}/t0", "velocity, x"),
            "vy": (True, f"{L}/t0", "velocity, y"),
            "spin": (True, "rad/t0", "angular velocity (counter-clockwise > 0)"),
            "contacts": (True, "1", "contacts at the last force evaluation, walls included"),
            "du": (True, "1", "|δu_i| of the tangent vector over its largest (mobile disks)"),
            **{k: (False, u, ln) for k, (_, u, ln) in self.extras.items()},
        }  # fmt: skip
        data = {}
        for name, (disk, units, long) in spec.items():
            if name not in fr[0]:
                continue
            dims = ("frame", "disk") if disk else ("frame",)
            data[name] = (dims, np.stack([f[name] for f in fr]) if disk
                          else np.array([f[name] for f in fr]),
                          {"units": units, "long_name": long})  # fmt: skip
        n = len(self.mobile)
        data["wall"] = ("disk", (~self.mobile).astype(np.int8),
                        {"units": "1", "long_name": "1 for a wall disk"})  # fmt: skip
        ds = xr.Dataset(data, coords={"frame": ("frame", np.arange(len(fr))),
                                      "disk": ("disk", np.arange(n))})  # fmt: skip
        ds.attrs.update(
            length_unit=L,
            time_unit=T,
            dt=self.schedule.dt,
            every=self.schedule.every * self.schedule.dt,
            **(attrs or {}),
        )
        if self.t0_s is not None:
            ds.attrs["t0_s"] = self.t0_s
        return ds


# -- writers ----------------------------------------------------------------------------


def _target(path) -> Path:
    p = Path(path)
    folder = p.parent if str(p.parent) else Path(".")
    if not (folder.is_dir() and os.access(folder, os.W_OK)):
        raise WriteError(f"cannot write {p}: folder {folder} does not exist or is not writable")
    return p


def _info(ds: xr.Dataset, k: int) -> dict:
    """The frame's per-frame values and the units, for a comment line."""
    info = {"frame": int(k)}
    units = []
    for name in ds.data_vars:
        if ds[name].dims == ("frame",):
            info[name] = float(ds[name].values[k])
            units.append(f"{name} {ds[name].attrs['units']}")
    L = ds.attrs["length_unit"]
    units += [f"length {L}", f"velocity {L}/t0", "spin rad/t0"]
    info["units"] = ", ".join(units)
    if "t0_s" in ds.attrs:
        info["t0_s"] = float(ds.attrs["t0_s"])
    for key in ("study", "point", "replica", "seed", "window"):
        if key in ds.attrs:
            info[key] = ds.attrs[key]
    return info


def write_extxyz(ds: xr.Dataset, path) -> Path:
    """Every frame of ``ds`` into one extended-XYZ file (ASE), z = 0: species H for mobile
    disks and He for wall disks; per-atom arrays ``radius``, ``velo`` (N, 3), ``spin``,
    ``wall``, ``contacts``, ``du`` as present; the frame's time, λ, V, phase and the units
    in its comment line."""
    import ase
    import ase.io

    p = _target(path)
    wall = ds["wall"].values.astype(bool)
    symbols = np.where(wall, "He", "H")
    images = []
    for k in range(ds.sizes["frame"]):
        f = ds.isel(frame=k)
        pos = np.column_stack([f["x"].values, f["y"].values, np.zeros(len(wall))])
        atoms = ase.Atoms(symbols=list(symbols), positions=pos, pbc=False)
        atoms.new_array("radius", f["radius"].values.astype(float))
        atoms.new_array("velo", np.column_stack([f["vx"].values, f["vy"].values,
                                                 np.zeros(len(wall))]))  # fmt: skip
        atoms.new_array("wall", wall.astype(np.int64))
        for name in ("spin", "contacts", "du"):
            if name in f:
                v = f[name].values
                atoms.new_array(name, v.astype(np.int64 if name == "contacts" else float))
        atoms.info.update(_info(ds, k))
        images.append(atoms)
    try:
        ase.io.write(p, images, format="extxyz")
    except OSError as exc:
        raise WriteError(f"cannot write {p}: {exc.strerror or exc}") from None
    return p


def write_vtu(ds: xr.Dataset, path) -> Path:
    """One ``.vtu`` per frame (meshio; vertices at the centres, z = 0, point data
    ``radius``, ``velocity`` (N, 3), ``spin``, ``wall``, ``contacts``, ``du``) in the folder
    ``<stem>_frames`` beside ``path``, and ``path`` itself a ``.pvd`` index giving each
    frame's time (ParaView reads it as a time series)."""
    import meshio

    p = _target(path)
    folder = p.parent / f"{p.stem}_frames"
    folder.mkdir(exist_ok=True)
    wall = ds["wall"].values.astype(np.int32)
    n = len(wall)
    cells = [("vertex", np.arange(n, dtype=np.int64)[:, None])]
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for k in range(ds.sizes["frame"]):
        f = ds.isel(frame=k)
        pts = np.column_stack([f["x"].values, f["y"].values, np.zeros(n)])
        data = {"radius": f["radius"].values.astype(float),
                "velocity": np.column_stack([f["vx"].values, f["vy"].values, np.zeros(n)]),
                "wall": wall}  # fmt: skip
        for name in ("spin", "contacts", "du"):
            if name in f:
                v = f[name].values
                data[name] = v.astype(np.int32 if name == "contacts" else float)
        name = f"frame_{k:05d}.vtu"
        try:
            meshio.write(folder / name, meshio.Mesh(pts, cells, point_data=data), file_format="vtu")
        except OSError as exc:
            raise WriteError(f"cannot write {folder / name}: {exc.strerror or exc}") from None
        ET.SubElement(coll, "DataSet", timestep=repr(float(ds["time"].values[k])), group="",
                      part="0", file=f"{folder.name}/{name}")  # fmt: skip
    ET.indent(root)
    try:
        ET.ElementTree(root).write(p, xml_declaration=True, encoding="utf-8")
    except OSError as exc:
        raise WriteError(f"cannot write {p}: {exc.strerror or exc}") from None
    return p


def write_trajectory(ds: xr.Dataset, path, fmt: str, fps: float = 10.0) -> Path:
    """``ds`` written as ``fmt`` (one of :data:`FORMATS`) to ``path``; a movie at ``fps``
    frames per second (an ``mp4`` without ffmpeg at hand becomes a GIF: the path written
    is returned)."""
    if check_format(fmt) in ("mp4", "gif"):
        from .figures.movie import movie_suffix, write_movie

        p = _target(path).with_suffix(f".{fmt}")
        if fmt == "mp4" and movie_suffix() == ".gif":
            p = p.with_suffix(".gif")
        return write_movie(ds, p, fps)
    writer: Callable = {"extxyz": write_extxyz, "vtu": write_vtu}[fmt]
    return writer(ds, path)


def check_movie_file(path, option: str = "format") -> Path:
    """``path`` if it names a movie this machine can write: a ``.mp4`` (ffmpeg found by
    imageio-ffmpeg) or a ``.gif``; else refused naming ``option``, before anything runs
    (a workflow's movie is written under exactly the name its rule expects)."""
    from .figures.movie import movie_suffix

    p = Path(path)
    if p.suffix not in (".mp4", ".gif"):
        raise TrajectoryError(option, f"a movie is a .mp4 or a .gif file, not {p.name}")
    if p.suffix == ".mp4" and movie_suffix() == ".gif":
        raise TrajectoryError(option, "format mp4 needs ffmpeg (the imageio-ffmpeg wheel "
                              "ships it) and none was found: choose gif")  # fmt: skip
    return p


def movie_window(centre: float, before: float, after: float, lo: float, hi: float):
    """The window ``(centre − before, centre + after)`` moved inside the record ``[lo, hi]``
    keeping its length where the record is long enough (cut to the record where not).

    Returns (start, end) in the units of the arguments.
    """
    length = float(before) + float(after)
    start = float(centre) - float(before)
    start = min(max(start, lo), max(hi - length, lo))
    return start, min(start + length, hi)


def replay_to_file(replay: Callable, params: Mapping, replica: int, window, every: float,
                   fmt: str, out, fps: float = 10.0) -> tuple[Path, xr.Dataset]:  # fmt: skip
    """A study's ``trajectory`` function ``replay(params, replica, window, every)`` written
    to ``out`` as ``fmt``: the format and the folder are checked first, the replay checks
    replica, window, interval and budget before it integrates."""
    check_format(fmt)
    p = Path(out)
    folder = p.parent if str(p.parent) else Path(".")
    if not (folder.is_dir() and os.access(folder, os.W_OK)):
        raise TrajectoryError("out", f"cannot write into {folder}")
    ds = replay(params, replica, window, every)
    return write_trajectory(ds, p, fmt, fps), ds
