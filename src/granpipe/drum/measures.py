"""What a replica records, and the labelled run file of a batch (stage ``runs``).

A run file ``runs/<point>/batch_<b>.nc`` holds, for each replica of the batch:

==================  =========================  ========  =====================================
variable            dims                       units     meaning
==================  =========================  ========  =====================================
``lambda_onset``    (replica, time_onset)      1/t0      block mean of λ(t), onset window
``speed_onset``     (replica, time_onset)      d_s/t0    block mean of V(t) = sqrt(Σ|v_i|²)
``lambda_decay``    (replica, time_decay)      1/t0      same, decay window
``speed_decay``     (replica, time_decay)      d_s/t0
``seed``            (replica,)                 1         63-bit seed of the replica's stream
``settled``         (replica,)                 1         1 if the settling criterion was met
``settle_time``     (replica,)                 s         time the fall and settling took
``continuous``      (replica,)                 1         1 if the avalanche became continuous
``continuous_time`` (replica,)                 s         when it did, after t = 0 (NaN if not)
``decay_start``     (replica,)                 s         start of the decay window after t = 0
``wall_time``       (replica,)                 s         wall-clock cost of the replica
``n_steps``         (replica,)                 1         steps integrated (settling included)
==================  =========================  ========  =====================================

Coordinates: ``time_onset``/``time_decay`` [t0], the centre of each block of
``block_steps`` steps after the start of the window (a block mean of λ covers
exactly [kBΔt, (k+1)BΔt]); ``seconds_onset``/``seconds_decay`` the same in seconds.

The first replica of each batch also stores Fig. 2-style snapshots:
``snapshot_position``/``snapshot_velocity`` (snapshot, particle, xy),
``wall_position`` (snapshot, wall, xy), ``diameter`` (particle), ``wall_diameter``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import xarray as xr

if TYPE_CHECKING:
    from .protocol import Steps

__all__ = ["ReplicaRecord", "Snapshot", "time_coords", "batch_dataset"]


@dataclass
class Snapshot:
    """Positions and velocities of the mobile and wall disks at one instant.

    positions, velocities : (N, 2) float64 [d_s], [d_s/t0]
    wall_positions : (n, 2) float64 [d_s]
    label : str; description : str
    """

    positions: np.ndarray
    velocities: np.ndarray
    wall_positions: np.ndarray
    label: str
    description: str = ""


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
    ds.attrs.update(
        dt=steps.dt,
        dt_s=steps.dt_s,
        t0_s=steps.dt_s / steps.dt,
        block_steps=steps.block,
        stop_time_s=steps.decay_rotating * steps.dt_s,
        pre_rotation_steps=steps.pre_rotation,
    )
    return ds
