"""What a replica records, and the labelled run file of a batch (stage ``runs``).

A run file ``runs/<point>/batch_<b>.nc`` holds, for each replica of the batch:

========================  ======================  ======  ===================================
variable                  dims                    units   meaning
========================  ======================  ======  ===================================
``lambda_onset``          (replica, time_onset)   1/t0    block mean of λ(t), onset window
``speed_onset``           (replica, time_onset)   d_s/t0  block mean of V(t) = sqrt(Σ|v_i|²)
``lambda_decay``          (replica, time_decay)   1/t0    same, decay window
``speed_decay``           (replica, time_decay)   d_s/t0
``seed``                  (replica,)              1       63-bit seed of the replica's stream
``settled``               (replica,)              1       1 if the settling criterion was met
``settle_time``           (replica,)              s       time the fall and settling took
``continuous``            (replica,)              1       1 if the avalanche became continuous
``continuous_time``       (replica,)              s       when it did, after t = 0 (NaN if not)
``decay_start``           (replica,)              s       start of the decay window after t = 0
``wall_time``             (replica,)              s       wall-clock cost of the replica
``n_steps``               (replica,)              1       steps integrated (settling included)
``tilt_onset``            (replica, pile_onset)   degree  tilt of the pile's surface
``centroid_angle_onset``  (replica, pile_onset)   degree  angle of the pile's mass centre
``rigid_speed_onset``     (replica, pile_onset)   d_s/t0  Ω sqrt(Σ r_i²): V of rigid rotation
``tilt_decay``, ...       (replica, pile_decay)           the same, decay window
========================  ======================  ======  ===================================

With ``protocol.disk_record`` (default), ``disk_du_onset`` (replica, pile_onset,
particle) [1] holds each mobile disk's |δu_i| over the largest and ``disk_speed_onset``
(replica, pile_onset, particle) [d_s/t0] its speed |v_i|, both float32, at the pile's
samples of the onset window (where each pile's avalanche starts: docs/drum.md, "Where
the avalanche starts").

``speed_lyapunov_correlation_onset`` (replica, pile_onset) and ``..._decay`` [1] hold the
correlation C(|δu_i|, |v_i|) over the mobile disks at the pile's samples (where the chaos
lives; :mod:`granpipe.analysis.lyapunov`).

The pile's state is sampled at t = 0 of each window and then every
``protocol.pile_sample_s`` (0.1 s) and at the window's end: an instantaneous value at
the end of a stretch of whole blocks, computed between two engine calls (the engine
records block means only; a run split at more places is bit-identical). Coordinates
``seconds_pile_onset``/``seconds_pile_decay`` [s] give the sample times. The rigid
speed uses the turning drum's Ω in both windows (after the stop too: a reference
speed, not the drum's).

Coordinates: ``time_onset``/``time_decay`` [t0], the centre of each block of
``block_steps`` steps after the start of the window (a block mean of λ covers
exactly [kBΔt, (k+1)BΔt]); ``seconds_onset``/``seconds_decay`` the same in seconds.

The first replica of each batch also stores Fig. 2-style snapshots:
``snapshot_position``/``snapshot_velocity`` (snapshot, particle, xy),
``wall_position`` (snapshot, wall, xy), ``diameter`` (particle), ``wall_diameter``, and
``snapshot_du`` (snapshot, particle): each disk's |δu_i| over the largest (NaN before the
tangent vector is set).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

from ..analysis.events import first_run
from ..analysis.lyapunov import speed_lyapunov_correlation

if TYPE_CHECKING:
    from .layout import Steps
    from .model import DrumModel

__all__ = [
    "ReplicaRecord",
    "Snapshot",
    "time_coords",
    "batch_dataset",
    "pile_state",
    "pile_sample",
    "SURFACE_COLUMN_WIDTH",
    "SURFACE_FRACTION",
    "coarse_blocks",
    "onset_events",
    "stop_events",
]

SURFACE_COLUMN_WIDTH = 2.0
"""Width of the columns whose highest disk marks the pile's surface [d_s]."""

SURFACE_FRACTION = 0.6
"""Fraction of the pile's width, about its middle, over which the surface is fitted
(the surface bends where it meets the wall)."""


def pile_state(positions, radii, masses=None) -> tuple[float, float]:
    """Tilt of the pile's free surface and angle of its centroid, in the drum's sense.

    The surface: the mobile disks' horizontal extent is cut, over its middle
    :data:`SURFACE_FRACTION`, into columns about :data:`SURFACE_COLUMN_WIDTH` wide; the
    top point (y + r) of the highest disk of each column is one surface point, and a
    least-squares line through them gives the slope s. The drum turns clockwise
    (paper Sec. II.2, Fig. 2(b)) and lifts the pile on its left (x < 0), so the tilt is
    −atan(s): positive when the surface rises toward the lifted side, as the drum's
    rotation makes it. The centroid angle is that of the mass centre (x_c, y_c) about
    the drum's axis from straight down, atan2(−x_c, −y_c): positive when the pile sits
    turned the drum's way. A pile turned rigidly by α with the drum gains α in both.

    Parameters
    ----------
    positions : (N, 2) float [d_s], mobile-disk centres, drum axis at the origin
    radii : (N,) float [d_s]
    masses : (N,) float [m_s], optional (default: equal)

    Returns
    -------
    tilt, centroid_angle : float [degree]; the tilt is NaN with fewer than two columns.
    """
    p = np.asarray(positions, dtype=np.float64)
    r = np.asarray(radii, dtype=np.float64)
    m = np.ones(len(p)) if masses is None else np.asarray(masses, dtype=np.float64)
    x, y = p[:, 0], p[:, 1]
    xc = float(np.dot(m, x) / m.sum())
    yc = float(np.dot(m, y) / m.sum())
    centroid = math.degrees(math.atan2(-xc, -yc))
    lo, hi = float(x.min()), float(x.max())
    half = 0.5 * SURFACE_FRACTION * (hi - lo)
    a, b = 0.5 * (lo + hi) - half, 0.5 * (lo + hi) + half
    n_col = int((b - a) // SURFACE_COLUMN_WIDTH)
    if n_col < 2:
        return math.nan, centroid
    col = np.floor((x - a) / (b - a) * n_col).astype(np.int64)
    inside = (col >= 0) & (col < n_col)
    col, top, xs = col[inside], (y + r)[inside], x[inside]
    order = np.lexsort((top, col))  # by column, highest last
    last = np.r_[col[order][1:] != col[order][:-1], True]
    sx, sy = xs[order][last], top[order][last]
    if len(sx) < 2:
        return math.nan, centroid
    slope = np.polyfit(sx, sy, 1)[0]
    return -math.degrees(math.atan(slope)), centroid


@dataclass
class Snapshot:
    """Positions and velocities of the mobile and wall disks at one instant.

    positions, velocities : (N, 2) float64 [d_s], [d_s/t0]
    wall_positions : (n, 2) float64 [d_s]
    label : str; description : str
    du : (N,) float64, |δu_i| over its largest (NaN without a tangent vector)
    """

    positions: np.ndarray
    velocities: np.ndarray
    wall_positions: np.ndarray
    label: str
    description: str = ""
    du: np.ndarray | None = None


@dataclass
class ReplicaRecord:
    """The recorded output of one replica (see the module docstring for units)."""

    replica: int
    seed: int
    lambda_onset: np.ndarray
    speed_onset: np.ndarray
    lambda_decay: np.ndarray
    speed_decay: np.ndarray
    settled: bool = True
    settle_time: float = np.nan
    continuous: bool = True
    continuous_time: float = np.nan
    decay_start: float = np.nan
    wall_time: float = np.nan
    n_steps: int = 0
    snapshots: list[Snapshot] = field(default_factory=list)
    pile_onset: np.ndarray | None = None
    """(S, 4): tilt [degree], centroid angle [degree], rigid speed [d_s/t0] and
    C(|δu|, |v|) per sample."""
    pile_seconds_onset: np.ndarray | None = None
    """(S,) [s] the samples' times after the start of the onset window."""
    pile_decay: np.ndarray | None = None
    pile_seconds_decay: np.ndarray | None = None
    disk_du_onset: np.ndarray | None = None
    """(S, N) float32: each mobile disk's |δu_i| over the largest at the onset window's
    pile samples (``protocol.disk_record``; None without)."""
    disk_speed_onset: np.ndarray | None = None
    """(S, N) float32 [d_s/t0]: each mobile disk's |v_i| at the same samples."""


def time_coords(n_blocks: int, steps: Steps, window: str) -> dict:
    """Coordinates ``time_<window>`` [t0] and ``seconds_<window>`` [s] of block centres."""
    k = np.arange(n_blocks, dtype=np.float64) + 0.5
    t = k * steps.block * steps.dt
    return {
        f"time_{window}": (
            f"time_{window}",
            t,
            {
                "units": "t0",
                "long_name": f"time after the start of the {window} window (block centre), "
                "t0 = sqrt(d_s/g)",
            },
        ),
        f"seconds_{window}": (
            f"time_{window}",
            k * steps.block * steps.dt_s,
            {"units": "s", "long_name": f"time after the start of the {window} window"},
        ),
    }


def batch_dataset(
    records: Sequence[ReplicaRecord],
    steps: Steps,
    diameters: np.ndarray,
    wall_diameter: float,
) -> xr.Dataset:
    """The run file of a batch: records stacked on ``replica`` (labelled, see module doc)."""
    if not records:
        raise ValueError("a batch needs at least one replica")
    n_on = max(len(r.lambda_onset) for r in records)
    n_de = max(len(r.lambda_decay) for r in records)

    def stack(attr, n):
        out = np.full((len(records), n), np.nan)
        for i, r in enumerate(records):
            x = np.asarray(getattr(r, attr), dtype=np.float64)
            out[i, : len(x)] = x
        return out

    coords = {
        "replica": (
            "replica",
            np.array([r.replica for r in records], dtype=np.int64),
            {"units": "1", "long_name": "replica index"},
        ),
        **time_coords(n_on, steps, "onset"),
        **time_coords(n_de, steps, "decay"),
    }
    lam = "local Lyapunov exponent λ, block mean over the disks with >= 2 contacts"
    spd = "global speed V = sqrt(sum_i |v_i|^2) of the mobile disks, block mean"
    ds = xr.Dataset(coords=coords)
    for w, n in (("onset", n_on), ("decay", n_de)):
        dims = ("replica", f"time_{w}")
        ds[f"lambda_{w}"] = (
            dims,
            stack(f"lambda_{w}", n),
            {"units": "1/t0", "long_name": f"{lam}, {w} window"},
        )
        ds[f"speed_{w}"] = (
            dims,
            stack(f"speed_{w}", n),
            {"units": "d_s/t0", "long_name": f"{spd}, {w} window"},
        )

    if all(r.pile_onset is not None for r in records):
        _pile_variables(ds, records)
    if all(r.disk_du_onset is not None for r in records) and "pile_onset" in ds.dims:
        _disk_variables(ds, records)

    def col(attr, dtype):
        return np.array([getattr(r, attr) for r in records], dtype=dtype)

    scalars = {
        "seed": (
            np.int64,
            "1",
            "seed of the replica's random stream (granpipe.seeds.replica_seed)",
        ),
        "settled": (
            np.int8,
            "1",
            "1 if the settling criterion was met before drum.settle.max_time_s",
        ),
        "settle_time": (np.float64, "s", "duration of the fall and settling"),
        "continuous": (
            np.int8,
            "1",
            "1 if the avalanche became continuous before drum.protocol.max_rotation_s",
        ),
        "continuous_time": (
            np.float64,
            "s",
            "time after t = 0 at which the avalanche was continuous",
        ),
        "decay_start": (
            np.float64,
            "s",
            "start of the decay window after t = 0 of the onset window",
        ),
        "wall_time": (np.float64, "s", "wall-clock cost of the replica (settling and protocol)"),
        "n_steps": (np.int64, "1", "time steps integrated for the replica"),
    }
    for name, (dtype, units, lname) in scalars.items():
        ds[name] = ("replica", col(name, dtype), {"units": units, "long_name": lname})
    snaps = records[0].snapshots
    if snaps:
        ds = ds.assign_coords(
            snapshot=(
                "snapshot",
                np.array([s.label for s in snaps], dtype=object).astype(str),
                {
                    "units": "1",
                    "long_name": f"instant of the snapshot (replica {records[0].replica})",
                    "descriptions": ";".join(s.description for s in snaps),
                },
            )
        )
        ds["snapshot_position"] = (
            ("snapshot", "particle", "xy"),
            np.stack([s.positions for s in snaps]),
            {"units": "d_s", "long_name": "mobile-disk centre (drum axis at the origin)"},
        )
        ds["snapshot_velocity"] = (
            ("snapshot", "particle", "xy"),
            np.stack([s.velocities for s in snaps]),
            {"units": "d_s/t0", "long_name": "mobile-disk velocity"},
        )
        if all(s.du is not None for s in snaps):
            ds["snapshot_du"] = (
                ("snapshot", "particle"),
                np.stack([s.du for s in snaps]),
                {"units": "1", "long_name": "|δu_i| of the Lyapunov vector over its largest"},
            )
        ds["wall_position"] = (
            ("snapshot", "wall", "xy"),
            np.stack([s.wall_positions for s in snaps]),
            {"units": "d_s", "long_name": "wall-disk centre"},
        )
        ds["diameter"] = (
            "particle",
            np.asarray(diameters, dtype=np.float64),
            {"units": "d_s", "long_name": "mobile-disk diameter"},
        )
        ds["wall_diameter"] = (
            (),
            float(wall_diameter),
            {"units": "d_s", "long_name": "wall-disk diameter"},
        )
    if "tilt_onset" in ds:
        ds.attrs.update(surface_column_width=SURFACE_COLUMN_WIDTH,
                        surface_fraction=SURFACE_FRACTION)  # fmt: skip
    ds.attrs.update(
        dt=steps.dt,
        dt_s=steps.dt_s,
        t0_s=steps.dt_s / steps.dt,
        block_steps=steps.block,
        stop_time_s=steps.decay_rotating * steps.dt_s,
        pre_rotation_steps=steps.pre_rotation,
    )
    return ds


_PILE = (
    ("tilt", "degree", "tilt of the pile's surface, in the drum's sense (linear fit of the "
     "column tops; granpipe.drum.measures.pile_state)"),
    ("centroid_angle", "degree", "angle of the pile's mass centre about the drum's axis from "
     "straight down, in the drum's sense"),
    ("rigid_speed", "d_s/t0", "Omega sqrt(sum_i r_i^2): V of the mobile disks turning rigidly "
     "at the drum's rate"),
    ("speed_lyapunov_correlation", "1", "Pearson correlation of |du_i| and |v_i| over the "
     "mobile disks (granpipe.analysis.lyapunov)"),
)  # fmt: skip


def _pile_variables(ds: xr.Dataset, records: Sequence[ReplicaRecord]) -> None:
    """The pile's sampled state of every replica, on ``pile_onset``/``pile_decay``."""
    for w in ("onset", "decay"):
        arrays = [getattr(r, f"pile_{w}") for r in records]
        longest = max(range(len(records)), key=lambda i: len(arrays[i]))
        n = len(arrays[longest])
        dim = f"pile_{w}"
        ds.coords[f"seconds_{dim}"] = (
            dim,
            np.asarray(getattr(records[longest], f"pile_seconds_{w}"), dtype=np.float64),
            {"units": "s", "long_name": f"time of the pile's sample after the start of the "
             f"{w} window"},
        )  # fmt: skip
        for k, (name, units, lname) in enumerate(_PILE):
            out = np.full((len(records), n), np.nan)
            for i, a in enumerate(arrays):
                out[i, : len(a)] = np.asarray(a, dtype=np.float64)[:, k]
            ds[f"{name}_{w}"] = (
                ("replica", dim),
                out,
                {"units": units, "long_name": f"{lname}, {w} window"},
            )


def _disk_variables(ds: xr.Dataset, records: Sequence[ReplicaRecord]) -> None:
    """Per-disk |δu_i| and |v_i| of every replica at the onset window's pile samples,
    (replica, pile_onset, particle) float32, NaN past a replica's last sample."""
    S, N = ds.sizes["pile_onset"], records[0].disk_du_onset.shape[1]
    for name, attr, units, lname in (
        ("disk_du_onset", "disk_du_onset", "1", "|δu_i| of the Lyapunov vector over its "
         "largest, per mobile disk at the pile's samples, onset window"),
        ("disk_speed_onset", "disk_speed_onset", "d_s/t0", "speed |v_i| per mobile disk at "
         "the pile's samples, onset window"),
    ):  # fmt: skip
        out = np.full((len(records), S, N), np.nan, np.float32)
        for i, r in enumerate(records):
            a = getattr(r, attr)
            out[i, : len(a)] = a
        ds[name] = (("replica", "pile_onset", "particle"), out,
                    {"units": units, "long_name": lname})  # fmt: skip


# ---------------------------------------------------------------- the pile's events
def coarse_blocks(seconds, Y, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Means over ``n`` consecutive stored blocks (a trailing part left out).

    Parameters
    ----------
    seconds : (T,) [s], centres of the stored blocks (uniform)
    Y : (..., T)
    n : int, stored blocks per coarse block

    Returns
    -------
    start : (J,) [s], start time of each coarse block; mean : (..., J)
    """
    seconds = np.asarray(seconds, dtype=np.float64)
    Y = np.asarray(Y, dtype=np.float64)
    n = max(1, int(n))
    J = Y.shape[-1] // n
    half = 0.5 * (seconds[1] - seconds[0]) if len(seconds) > 1 else 0.0
    start = seconds[: J * n : n] - half
    mean = Y[..., : J * n].reshape(Y.shape[:-1] + (J, n)).mean(axis=-1)
    return start, mean


def _speed_ratio(seconds, speed, pile_seconds, rigid, n):
    """(start (J,), V/V_rigid (R, J), block length [s]) over coarse blocks of n stored blocks,
    the rigid speed interpolated to each coarse block's middle."""
    start, V = coarse_blocks(seconds, np.atleast_2d(speed), n)
    length = n * (seconds[1] - seconds[0])
    rig = np.atleast_2d(np.asarray(rigid, dtype=np.float64))
    mid = start + 0.5 * length
    R = np.stack([np.interp(mid, pile_seconds, r) for r in rig])
    with np.errstate(invalid="ignore", divide="ignore"):
        return start, V / R, length


def onset_events(seconds, speed, pile_seconds, rigid, *, block: int, startup_excess: float,
                 startup_hold: int, burst_excess: float, flow_excess: float,
                 flow_hold: int) -> dict[str, np.ndarray]:  # fmt: skip
    """Per replica: the end of the start-up transient, the first burst, sustained flow.

    V (block means) is averaged over coarse blocks of ``block`` stored blocks (0.1 s by
    default) and compared with the rigid-rotation speed Ω sqrt(Σ r_i²) of the same
    moment (the paper's continuous avalanche, Sec. II.2, made a per-replica event):

    * **start-up end**: the first coarse block from which V/V_rigid stays at or below
      1 + ``startup_excess`` for ``startup_hold`` blocks — the fall's motion has died out
      and the pile turns with the drum (what the paper's V minimum in 1-4 s marks,
      Sec. III);
    * **first burst**: the first block at or after the start-up end with V/V_rigid above
      1 + ``burst_excess``;
    * **sustained flow**: the first block at or after the start-up end that starts
      ``flow_hold`` blocks all with V/V_rigid above 1 + ``flow_excess``.

    Parameters
    ----------
    seconds : (T,) [s], centres of the stored blocks; speed : (R, T) [d_s/t0]
    pile_seconds : (S,) [s]; rigid : (R, S) [d_s/t0], the pile's samples
    block, startup_hold, flow_hold : int, in stored / coarse blocks

    Returns
    -------
    ``{"startup_end", "first_burst", "flow_onset"}``: (R,) [s], the start of the event's
    coarse block after t = 0 of the window; NaN where the record holds none.
    """

    start, x, _ = _speed_ratio(seconds, speed, pile_seconds, rigid, block)
    finite = np.isfinite(x)
    end = first_run(finite & (x <= 1.0 + startup_excess), startup_hold)
    begin = np.where(end >= 0, end, x.shape[-1])
    burst = first_run(finite & (x > 1.0 + burst_excess), 1, begin)
    flow = first_run(finite & (x > 1.0 + flow_excess), flow_hold, begin)

    def at(i):
        return np.where(i >= 0, start[np.clip(i, 0, len(start) - 1)], np.nan)

    return {"startup_end": at(end), "first_burst": at(burst), "flow_onset": at(flow)}


def stop_events(seconds, speed, pile_seconds, rigid, *, block: int, stop_time: float,
                stop_fraction: float, hold: int) -> np.ndarray:  # fmt: skip
    """Per replica, when the pile stops flowing after the drum stops (decay window): the
    first coarse block starting at or after ``stop_time`` [s] from which V stays at or
    below ``stop_fraction`` times the rigid-rotation speed of the turning drum for
    ``hold`` blocks. (R,) [s], NaN where the record holds none. Arguments as
    :func:`onset_events`."""

    start, x, _ = _speed_ratio(seconds, speed, pile_seconds, rigid, block)
    begin = int(np.searchsorted(start, stop_time - 1e-9))
    i = first_run(np.isfinite(x) & (x <= stop_fraction), hold, begin)
    return np.where(i >= 0, start[np.clip(i, 0, len(start) - 1)], np.nan)


def pile_sample(model: DrumModel, state, omega: float) -> tuple[float, float, float, float]:
    """(tilt [degree], centroid angle [degree], rigid speed [d_s/t0], C(|δu|, |v|)) of the
    pile in an engine state (:func:`pile_state`,
    :meth:`~granpipe.drum.model.DrumModel.rigid_speed`,
    :func:`granpipe.analysis.lyapunov.speed_lyapunov_correlation`; NaN without a tangent
    vector)."""
    n = model.n_mobile
    tilt, centroid = pile_state(state.positions[:n], 0.5 * model.diameters, model.masses)
    corr = np.nan
    if state.has_tangent:
        dr, dv = state.tangent_stored
        corr = speed_lyapunov_correlation(state.velocities[:n], dr[:n], dv[:n], np.ones(n, bool))
    return tilt, centroid, model.rigid_speed(state, omega), corr
