"""Per-point measures of the box study: detection, temperature, slips, order.

The glue between run files and :mod:`granpipe.analysis.box`: concatenates the parts of
each replica, applies Appendix B (s_c, corrected s_b), the direct detachment measure,
Eq. (2) and the slip criterion of Sec. V, and pools the replicas of a point.

Pooling: T_g and p_s are averaged over all measured periods of all replicas, their
standard errors are those of the per-period values (periods treated as independent; a
bed's memory is a few periods, so the SEM is somewhat optimistic at few periods); s_c,
s_b and the detachment fraction are replica means (with the replica spread when R > 1).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
import xarray as xr

from ..analysis import box as ab

__all__ = ["ReplicaRun", "concat_parts", "point_dataset", "convergence"]


class ReplicaRun:
    """The parts of one replica joined along the measured periods.

    Attributes: ``z_tracers`` (P, N_k, N_t), ``z_plate``, ``bed_gap``, ``T_g``, ``z_cm``,
    ``vz_cm``, ``plate_contacts`` (P, N_k), ``frames`` (P + 1, N, 2) [σ],
    ``transient`` dict of (S,) arrays, ``attrs`` of part 0, ``wall_seconds`` and
    ``steps`` summed over parts.
    """

    def __init__(self, parts: Sequence[xr.Dataset]):
        first = parts[0]
        cat = {
            k: np.concatenate([p[k].values for p in parts], axis=0)
            for k in ("z_tracers", "z_plate", "bed_gap", "T_g", "z_cm", "vz_cm", "plate_contacts")
        }
        self.__dict__.update(cat)
        frames = [parts[0]["positions"].values]
        for p in parts[1:]:
            frames.append(p["positions"].values[1:])
        self.frames = np.concatenate(frames, axis=0).astype(np.float64)
        self.transient = {
            k[len("transient_") :]: first[k].values
            for k in first.data_vars
            if k.startswith("transient_")
        }
        self.attrs = dict(first.attrs)
        self.wall_seconds = float(sum(float(p.attrs["wall_seconds"]) for p in parts))
        self.steps = int(sum(int(p.attrs["steps"]) for p in parts))
        self.n = self.frames.shape[1]


def concat_parts(parts: Sequence[xr.Dataset]) -> ReplicaRun:
    return ReplicaRun(parts)


def _sem(values: np.ndarray) -> float:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.std(ddof=1) / math.sqrt(v.size)) if v.size > 1 else math.nan


def _var(dims, data, units, long_name):
    return (dims, data, {"units": units, "long_name": long_name})


def point_dataset(
    runs: Mapping[int, ReplicaRun],
    detection: Mapping,
    slips: Mapping,
    order: Mapping,
    lx: float,
) -> xr.Dataset:
    """Measures of one point from its replicas (``runs[r]``), as a labelled Dataset.

    Parameters
    ----------
    detection, slips, order : mapping
        The ``box.detection``, ``box.slips``, ``box.order`` config sections.
    lx : float [σ]
        Box width (for the bulk window of :func:`granpipe.analysis.box.crystal_check`).
    """
    reps = sorted(runs)
    R = len(reps)
    first = runs[reps[0]]
    amp_omega = float(first.attrs["amplitude"]) * float(first.attrs["omega"])
    per_rep: dict[str, list] = {
        k: []
        for k in (
            "s_c", "s_b", "s_b_printed", "detachment_fraction", "max_gap", "T_g", "T_g_sem",
            "p_s", "p_s_sem", "n_slips", "n_trials", "psi6_start", "psi6_end",
            "hexagonal_start", "hexagonal_end", "dislocations_start", "dislocations_end",
            "intact_start", "intact_end", "launch_ratio", "launch_ratio_disk",
            "plate_contact_fraction", "wall_seconds", "steps",
        )
    }  # fmt: skip
    s_k_all, s_j_all, tg_periods, ps_periods = [], [], [], []
    r_max = float(order["neighbour_cutoff"])
    for r in reps:
        run = runs[r]
        s_c, s_j = ab.convection_measure(run.z_tracers[:, 0, :])
        s_b, s_k = ab.bouncing_measure(run.z_tracers, run.z_plate)
        frac, _ = ab.detachment_fraction(run.bed_gap, tol=float(detection["detachment_gap"]))
        tg_p = run.T_g.mean(axis=1)
        sl = ab.slip_probability(
            run.frames,
            threshold=float(slips["displacement"]),
            min_count=int(slips["min_neighbours"]),
            r_max=float(slips["neighbour_cutoff"]),
            bulk_depth=float(slips["surface_depth"]),
        )
        lo0 = ab.local_order(run.frames[0], r_max=r_max, threshold=float(order["threshold"]))
        lo1 = ab.local_order(run.frames[-1], r_max=r_max, threshold=float(order["threshold"]))
        checks = {
            when: ab.crystal_check(
                frame, lx, r_max=r_max, threshold=float(order["threshold"]),
                min_psi6=float(order["crystal_min_psi6"]), local=lo,
            )
            for when, frame, lo in (("start", run.frames[0], lo0), ("end", run.frames[-1], lo1))
        }  # fmt: skip
        tr = run.transient
        per_rep["s_c"].append(s_c)
        per_rep["s_b"].append(s_b)
        per_rep["s_b_printed"].append(float(np.sqrt(np.mean(s_k**2))))
        per_rep["detachment_fraction"].append(frac)
        per_rep["max_gap"].append(float(run.bed_gap.max(axis=1).mean()))
        per_rep["T_g"].append(float(tg_p.mean()))
        per_rep["T_g_sem"].append(_sem(tg_p))
        per_rep["p_s"].append(sl.p_s)
        per_rep["p_s_sem"].append(sl.sem)
        per_rep["n_slips"].append(sl.n_slips)
        per_rep["n_trials"].append(sl.n_trials)
        for when, c in checks.items():
            per_rep[f"psi6_{when}"].append(c.psi6)
            per_rep[f"hexagonal_{when}"].append(c.hexagonal)
            per_rep[f"dislocations_{when}"].append(c.dislocations)
            per_rep[f"intact_{when}"].append(int(c.intact))
        if tr and amp_omega > 0:
            per_rep["launch_ratio"].append(float(np.max(tr["vz_cm"]) / amp_omega))
            per_rep["launch_ratio_disk"].append(float(np.max(tr["max_vz"]) / amp_omega))
        else:
            per_rep["launch_ratio"].append(math.nan)
            per_rep["launch_ratio_disk"].append(math.nan)
        per_rep["plate_contact_fraction"].append(float(np.mean(run.plate_contacts > 0)))
        per_rep["wall_seconds"].append(run.wall_seconds)
        per_rep["steps"].append(run.steps)
        s_k_all.append(s_k)
        s_j_all.append(s_j)
        tg_periods.append(tg_p)
        ps_periods.append(sl.per_period)
        if r == reps[0]:
            snap = {
                "positions_start": run.frames[0],
                "order_start": lo0["order"],
                "psi6_abs_start": np.abs(lo0["psi6"]),
                "positions_end": run.frames[-1],
                "order_end": lo1["order"],
                "psi6_abs_end": np.abs(lo1["psi6"]),
            }
    tg_all = np.concatenate(tg_periods)
    ps_all = np.concatenate(ps_periods)
    n_slips = int(np.sum(per_rep["n_slips"]))
    n_trials = int(np.sum(per_rep["n_trials"]))

    def mean(key):
        return float(np.nanmean(per_rep[key])) if np.isfinite(per_rep[key]).any() else math.nan

    s_c, s_b, frac = mean("s_c"), mean("s_b"), mean("detachment_fraction")
    units = {
        "s_c": ("sigma", "convection measure s_c (Eqs. B1-B2)"),
        "s_b": ("sigma", "bouncing measure s_b (spread of s(k) over phases, docs/box.md)"),
        "s_b_printed": ("sigma", "Eq. (B4) as printed: sqrt(mean_k s(k)^2)"),
        "detachment_fraction": ("1", "fraction of the cycle with a gap under the bed"),
        "max_gap": ("sigma", "mean over cycles of the largest gap under the bed"),
        "T_g": ("m*g*sigma", "granular temperature, time average (Eq. 2)"),
        "T_g_sem": ("m*g*sigma", "standard error of T_g over periods"),
        "p_s": ("1", "slip probability per period"),
        "p_s_sem": ("1", "standard error of p_s over periods"),
        "n_slips": ("1", "slips counted"),
        "n_trials": ("1", "bulk disk-periods examined"),
        "psi6_start": ("1", "bulk mean |psi6| at the start of the measurement"),
        "psi6_end": ("1", "bulk mean |psi6| at the end of the measurement"),
        "hexagonal_start": ("1", "fraction of bulk disks with hexagonal local order at start"),
        "hexagonal_end": ("1", "fraction of bulk disks with hexagonal local order at the end"),
        "dislocations_start": ("1", "bulk disks with other than 6 Delaunay neighbours at start"),
        "dislocations_end": ("1", "bulk disks with other than 6 Delaunay neighbours at the end"),
        "intact_start": ("1", "bulk |psi6| >= crystal_min_psi6 and no dislocation at start"),
        "intact_end": ("1", "bulk |psi6| >= crystal_min_psi6 and no dislocation at the end"),
        "launch_ratio": ("1", "largest bed centre-of-mass upward speed in transient / (A omega)"),
        "launch_ratio_disk": ("1", "largest disk upward speed in the transient / (A omega)"),
        "plate_contact_fraction": ("1", "fraction of samples with a disk on the plate"),
        "wall_seconds": ("s", "wall time of the runs"),
        "steps": ("1", "time steps run (transient included)"),
    }  # fmt: skip
    data = {
        f"{k}_replica": _var(("replica",), np.asarray(v), *units[k]) for k, v in per_rep.items()
    }
    n_periods = int(np.isfinite(tg_all).sum())
    data.update(
        {
            "s_c": _var((), s_c, *units["s_c"]),
            "s_b": _var((), s_b, *units["s_b"]),
            "s_b_printed": _var((), mean("s_b_printed"), *units["s_b_printed"]),
            "detachment_fraction": _var((), frac, *units["detachment_fraction"]),
            "max_gap": _var((), mean("max_gap"), *units["max_gap"]),
            "T_g": _var((), float(np.nanmean(tg_all)), *units["T_g"]),
            "T_g_sem": _var((), _sem(tg_all), *units["T_g_sem"]),
            "p_s": _var(
                (),
                float(np.nanmean(ps_all)) if np.isfinite(ps_all).any() else math.nan,
                *units["p_s"],
            ),  # fmt: skip
            "p_s_sem": _var((), _sem(ps_all), *units["p_s_sem"]),
            "n_slips": _var((), n_slips, *units["n_slips"]),
            "n_trials": _var((), n_trials, *units["n_trials"]),
            "psi6_start": _var((), mean("psi6_start"), *units["psi6_start"]),
            "psi6_end": _var((), mean("psi6_end"), *units["psi6_end"]),
            "hexagonal_start": _var((), mean("hexagonal_start"), *units["hexagonal_start"]),
            "hexagonal_end": _var((), mean("hexagonal_end"), *units["hexagonal_end"]),
            "dislocations_start": _var(
                (), mean("dislocations_start"), *units["dislocations_start"]
            ),
            "dislocations_end": _var((), mean("dislocations_end"), *units["dislocations_end"]),
            "launch_ratio": _var((), mean("launch_ratio"), *units["launch_ratio"]),
            "convection": _var(
                (), int(s_c > float(detection["convection_s_c"])), "1", "convection flag s_c > σ"
            ),
            "bouncing": _var(
                (), int(s_b > float(detection["bouncing_s_b"])), "1", "bouncing-bed flag s_b > σ/30"
            ),
            "detached": _var(
                (),
                int(frac > float(detection["detachment_fraction"])),
                "1",
                "bed leaves the plate (detachment fraction above the threshold)",
            ),  # fmt: skip
            "crystal_intact": _var(
                (),
                int(all(per_rep["intact_start"])),
                "1",
                "every replica's bulk at measurement start is a defect-free crystal: mean "
                "|psi6| >= crystal_min_psi6 and no disk with other than 6 Delaunay neighbours",
            ),  # fmt: skip
            "s_k": _var(("phase",), np.mean(s_k_all, axis=0), "sigma", "s(k) of Eq. (B3)"),
            "s_j": _var(
                ("replica", "period"), np.asarray(s_j_all), "sigma", "s_j of Eq. (B1) per cycle"
            ),
            "T_g_period": _var(
                ("replica", "period"), np.asarray(tg_periods), "m*g*sigma", "T_g per period"
            ),
            "p_s_period": _var(
                ("replica", "slip_period"), np.asarray(ps_periods), "1", "slip fraction per period"
            ),
            "positions_start": _var(
                ("particle", "xy"),
                snap["positions_start"],
                "sigma",
                "disk centres at the start of the measurement (replica 0)",
            ),  # fmt: skip
            "order_start": _var(
                ("particle",), snap["order_start"], "1", "local order at start (0 dis, 1 hex, 2 sq)"
            ),
            "psi6_abs_start": _var(("particle",), snap["psi6_abs_start"], "1", "|psi6| at start"),
            "positions_end": _var(
                ("particle", "xy"),
                snap["positions_end"],
                "sigma",
                "disk centres at the end of the measurement (replica 0)",
            ),  # fmt: skip
            "order_end": _var(
                ("particle",), snap["order_end"], "1", "local order at the end (0 dis, 1 hex, 2 sq)"
            ),
            "psi6_abs_end": _var(("particle",), snap["psi6_abs_end"], "1", "|psi6| at the end"),
        }
    )
    n_k = first.z_plate.shape[1]
    ds = xr.Dataset(
        data,
        coords={
            "replica": _var(("replica",), np.asarray(reps), "1", "replica index"),
            "phase": _var(("phase",), np.arange(n_k) / n_k, "1", "phase k/N_k of the cycle"),
        },
    )
    a = first.attrs
    ds.attrs.update(
        {
            "study": "box",
            "stage": "ensemble",
            "point": a["point"],
            "N_l": int(a["N_l"]),
            "N": int(a["N"]),
            "Gamma": float(a["Gamma"]),
            "K_m": float(a["Gamma"]) ** 2,
            "init": a["init"],
            "mu_w": float(a["mu_w"]),
            "replicas": R,
            "measured_periods": n_periods // max(R, 1),
            "wall_seconds": float(np.sum(per_rep["wall_seconds"])),
            "steps": int(np.sum(per_rep["steps"])),
            "ns_per_particle_step": 1e9
            * float(np.sum(per_rep["wall_seconds"]))
            / max(float(np.sum(per_rep["steps"])) * int(a["N"]), 1.0),
        }
    )
    return ds


def convergence(
    z_tracers: np.ndarray,
    z_plate: np.ndarray,
    T_g: np.ndarray,
    frames: np.ndarray,
    slips: Mapping,
    periods: Sequence[int],
) -> dict[str, np.ndarray]:
    """s_c, s_b, T_g* and p_s of one replica from its first P measured periods, for each P
    in ``periods`` (how many periods a point needs; docs/box.md, "Measured periods").

    Parameters are the record of a replica (:class:`ReplicaRun` attributes of the same
    names): ``z_tracers`` (P, N_k, N_t), ``z_plate`` and ``T_g`` (P, N_k), ``frames``
    (P + 1, N, 2). The same estimators as :func:`point_dataset` on the truncated record:
    s_c² the mean of s_j² over the first P cycles (Eq. B2), s_b from s(k) of the first P
    cycles, T_g* the mean of the per-period temperatures, p_s the mean of the per-period
    slip fractions.

    Returns a dict of (len(periods),) arrays ``P``, ``s_c``, ``s_b``, ``T_g``, ``p_s``.
    """
    P = np.asarray([int(p) for p in periods])
    n = z_tracers.shape[0]
    if P.min() < 1 or P.max() > n:
        raise ValueError(f"periods must lie in 1..{n}, got {P.min()}..{P.max()}")
    _, s_j = ab.convection_measure(z_tracers[:, 0, :])
    tg = np.asarray(T_g).mean(axis=1)
    sl = ab.slip_probability(
        np.asarray(frames[: P.max() + 1], dtype=np.float64),
        threshold=float(slips["displacement"]),
        min_count=int(slips["min_neighbours"]),
        r_max=float(slips["neighbour_cutoff"]),
        bulk_depth=float(slips["surface_depth"]),
    )
    out = {"P": P, "s_c": [], "s_b": [], "T_g": [], "p_s": []}
    for p in P:
        out["s_c"].append(float(np.sqrt(np.mean(s_j[:p] ** 2))))
        out["s_b"].append(ab.bouncing_measure(z_tracers[:p], z_plate[:p])[0])
        out["T_g"].append(float(tg[:p].mean()))
        per = sl.per_period[:p]
        out["p_s"].append(float(np.nanmean(per)) if np.isfinite(per).any() else math.nan)
    return {k: np.asarray(v) for k, v in out.items()}
