"""One replica of the shear cell, and a batch of them as a dataset (docs/shear.md).

1. Preparation (:func:`granpipe.shear.preparation.grow`): placement, growth to φ, steady
   shear for ``preparation.steady_s``.
2. Tangent vector: about ``protocol.tangent_fraction`` of the 4N components uniform in
   [−1, 1] (the drum paper's Sec. II.3, as the drum), evolved for
   ``protocol.tangent_alignment_s`` before t = 0 so that it points along the fastest
   growing direction.
3. Record ``protocol.record_s`` from t = 0: block means of λ(t) (rattlers excluded: the
   norm over disks with at least two contacts, as the drum) and V(t) over
   ``protocol.block_s``; every ``protocol.sample_s`` the neighbour network's changes
   since the sample before, the correlation C(|δu|, |v|) over the mobile disks
   (:mod:`granpipe.shear.measures`), the growth rate of the whole tangent vector over
   the sample (all mobile disks, rattlers included: the finite-time maximal exponent,
   docs/shear.md, "Two readings of λ"), the jamming measures (the contact number z of
   the non-rattlers in both readings, the normal springs' energy, the pressure on the
   outer ring and the torque on the inner one, the bulk |ψ6|; docs/shear.md, "The
   cell's jamming point") and, per disk, |δu_i| over its largest, |v_i| and the changed
   edges it is an end of (what the predictions of rearrangements read: docs/shear.md,
   "Predicting rearrangements"); nothing per step is stored; at the end a snapshot
   (positions, |δu_i|, |v_i|) for the figure of where the chaos lives.

A replica's stream is ``replica_rng("shear", physics, replica)`` with ``physics`` the
point's section: its first child places the disks, the second draws the tangent vector.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping

import numpy as np
import xarray as xr

from ..analysis.lyapunov import lyapunov_vector_magnitude, speed_lyapunov_correlation
from ..errors import SimulationError
from ..seeds import replica_rng, replica_seed
from .measures import (
    JAMMING,
    bulk_hexatic_order,
    contact_number,
    contact_pairs,
    edge_change_counts,
    elastic_measures,
    neighbour_edges,
    network_changes,
)
from .model import ShearCell
from .preparation import grow

__all__ = ["Steps", "run_replica", "run_batch"]


class Steps:
    """The protocol's times in engine steps (Δt = ``physics.dt`` t0); a sample is whole
    blocks."""

    def __init__(self, section: Mapping):
        ph, pr = section["physics"], section["protocol"]
        self.dt_s = float(ph["dt"]) * float(ph["t0_s"])
        self.block = max(1, round(float(pr["block_s"]) / self.dt_s))
        self.sample = self.block * max(1, round(float(pr["sample_s"]) / self.dt_s / self.block))
        self.n_samples = max(1, round(float(pr["record_s"]) / (self.sample * self.dt_s)))
        self.n_blocks = self.n_samples * self.sample // self.block
        self.align = round(float(pr["tangent_alignment_s"]) / self.dt_s)


def run_replica(section: Mapping, replica: int, log: Callable[[str], None] = lambda m: None,
                on_frame=None):  # fmt: skip
    """One replica at the section's point; returns a dict of its records (see module).

    ``on_frame``: None in a run; a replay's :class:`granpipe.trajectory.FrameRecorder`,
    started at t = 0 and running the record's steps in its place
    (:func:`granpipe.shear.trajectory.trajectory`)."""
    cell = ShearCell.from_physics(section["physics"])
    st = Steps(section)
    rng = replica_rng("shear", section["physics"], replica)
    place, tangent = rng.spawn(2)
    sim, state = grow(cell, section["preparation"], place)
    n = cell.n_mobile
    sim.random_tangent(state, tangent, float(section["protocol"]["tangent_fraction"]))
    sim.run(state, st.align, tangent=True)
    ev = section["events"]
    radii = np.r_[cell.diameters, np.full(len(cell.walls), cell.physics["d_wall"])] / 2
    mobile = np.arange(len(radii)) < n

    def edges():
        return neighbour_edges(state.positions, radii, mobile, float(ev["edge_cutoff"]))

    def log_norm():  # ln |du| over the mobile disks, at its true size (the engine rescales)
        dr, dv = state.tangent_stored
        return 0.5 * math.log(np.sum(dr[:n] ** 2) + np.sum(dv[:n] ** 2)) + (
            state.tangent_log2_scale * math.log(2.0)
        )

    lam = np.empty(st.n_blocks)
    speed = np.empty(st.n_blocks)
    changes = np.zeros(st.n_samples, dtype=np.int64)
    corr = np.empty(st.n_samples)
    lam_all = np.empty(st.n_samples)
    jam = {k: np.empty(st.n_samples) for k in JAMMING}
    disk_du = np.empty((st.n_samples, n), np.float32)
    disk_speed = np.empty((st.n_samples, n), np.float32)
    disk_changes = np.empty((st.n_samples, n), np.uint8)
    inner = np.r_[np.zeros(n, bool), cell.rate == 1.0]
    outer = np.r_[np.zeros(n, bool), cell.rate == 0.0]
    depth = float(section["protocol"]["bulk_depth"])
    before, ln_before = edges(), log_norm()
    per = st.sample // st.block
    run = sim.run
    if on_frame is not None:
        on_frame.start(state)
        run = functools.partial(on_frame.run, sim)
    for k in range(st.n_samples):
        rec = run(state, st.sample, stride=st.block, tangent=True)
        lam[k * per : (k + 1) * per] = rec.local_lyapunov
        speed[k * per : (k + 1) * per] = rec.global_speed
        after = edges()
        changes[k] = network_changes(before, after)
        disk_changes[k] = np.minimum(edge_change_counts(before, after, len(radii))[:n], 255)
        before = after
        dr, dv = state.tangent_stored
        corr[k] = speed_lyapunov_correlation(state.velocities, dr, dv, mobile)
        disk_du[k] = lyapunov_vector_magnitude(dr[:n], dv[:n], relative=True)
        disk_speed[k] = np.hypot(*state.velocities[:n].T)
        ln_after = log_norm()
        lam_all[k] = (ln_after - ln_before) / (st.sample * float(section["physics"]["dt"]))
        ln_before = ln_after
        pos = state.positions
        c = contact_pairs(pos, radii, mobile)
        for key, m in (("z_frictionless", 3), ("z_frictional", 2)):
            z, rattler = contact_number(c, mobile, m)
            jam[key][k] = z
            jam[key.replace("z_", "rattlers_")][k] = rattler.sum() / n
        el = elastic_measures(c, pos, float(cell.physics["k_n"]), inner, outer, cell.r_out)
        for key in ("energy", "pressure", "torque", "overlap"):
            jam[key][k] = el[key]
        jam["hexatic"][k] = bulk_hexatic_order(pos[:n], cell.r_in, cell.r_out, depth)
    dr, dv = state.tangent_stored
    du = lyapunov_vector_magnitude(dr[:n], dv[:n], relative=True)
    log(f"replica {replica}: N = {n}, {st.n_samples} samples, "
        f"{int((changes > 0).sum())} with network changes")  # fmt: skip
    return {
        "lam": lam, "speed": speed, "changes": changes, "corr": corr, "lam_all": lam_all,
        "positions": state.positions[:n].copy(), "du": du,
        "v": np.hypot(*state.velocities[:n].T), "diameters": cell.diameters,
        "disk_du": disk_du, "disk_speed": disk_speed, "disk_changes": disk_changes, **jam,
    }  # fmt: skip


def run_batch(section: Mapping, replicas, log: Callable[[str], None] = lambda m: None):
    """The replicas' records as one dataset (dims replica, time, sample, disk); a blow-up
    names replica, seed and step (SimulationError)."""
    out = []
    for r in replicas:
        try:
            out.append(run_replica(section, r, log))
        except SimulationError as exc:
            seed = replica_seed("shear", section["physics"], r)
            point = f"phi={float(section['physics']['phi']):g}"
            raise exc.with_context(study="shear", stage="runs", point=point, replica=int(r),
                                   seed=seed) from None  # fmt: skip
    st = Steps(section)
    rep, time, sample = ("replica",), ("replica", "time"), ("replica", "sample")
    spec = {  # name: (dims, record key, units, long name)
        "local_lyapunov": (time, "lam", "1/t0", "block mean of the local Lyapunov exponent λ(t)"),
        "global_speed": (time, "speed", "d_s/t0", "block mean of V(t) = sqrt(Σ|v_i|²)"),
        "network_changes": (sample, "changes", "1", "neighbour edges changed since the sample "
                            "before"),
        "speed_lyapunov_correlation": (sample, "corr", "1", "correlation of |δu_i| and |v_i| "
                                       "over the mobile disks"),
        "lyapunov_all": (sample, "lam_all", "1/t0", "growth rate of the whole tangent vector "
                         "(all mobile disks, rattlers included) over the sample"),
        **{f"jamming_{k}": (sample, k, u, ln) for k, (u, ln) in JAMMING.items()},
        "disk_du": (sample + ("disk",), "disk_du", "1", "|δu_i| over its largest at the sample"),
        "disk_speed": (sample + ("disk",), "disk_speed", "d_s/t0", "|v_i| at the sample"),
        "disk_changes": (sample + ("disk",), "disk_changes", "1", "neighbour edges of the disk "
                         "changed since the sample before (at most 255)"),
        "snapshot_positions": (rep + ("disk", "xy"), "positions", "d_s", "centres at the end"),
        "snapshot_du": (rep + ("disk",), "du", "1", "|δu_i| at the end over its largest"),
        "snapshot_speed": (rep + ("disk",), "v", "d_s/t0", "|v_i| at the end"),
    }  # fmt: skip
    ds = xr.Dataset(
        {k: (d, np.stack([o[key] for o in out]), {"units": u, "long_name": ln})
         for k, (d, key, u, ln) in spec.items()},
        coords={
            "replica": ("replica", np.asarray(list(replicas), np.int64),
                        {"units": "1", "long_name": "replica index"}),
            "time": ("time", (np.arange(st.n_blocks) + 0.5) * st.block * st.dt_s,
                     {"units": "s", "long_name": "block centre after t = 0"}),
            "sample": ("sample", (np.arange(st.n_samples) + 1) * st.sample * st.dt_s,
                       {"units": "s", "long_name": "sample time after t = 0"}),
        },
    )  # fmt: skip
    ds["diameter"] = ("disk", out[0]["diameters"], {"units": "d_s", "long_name": "diameter"})
    ds.attrs.update(block_s=st.block * st.dt_s, sample_s=st.sample * st.dt_s)
    return ds, [replica_seed("shear", section["physics"], r) for r in replicas]
