"""The box study's stages as file-to-file functions (the CLI calls these; rules call the CLI).

    init      prepared state of (N_l, init, walls, replica) -> init/<state>/replica_r.nc
    runs      one part of one point and replica              -> runs/<point>/replica_r.part_p.nc
    ensemble  all runs of a point -> detection, T_g, p_s, ψ  -> ensemble/<point>.nc
    fits      all points -> thresholds, segmented T_g*, E_b  -> fits/*.nc, fits/summary.csv
    figures   Figures 1, 3, 4, 5 and 6 (μ_w)                  -> figures/fig<k>_<name>.{png,pdf}

Seeds: a replica's stream is ``replica_rng("box", seed_physics, replica)`` with
``seed_physics = {physics without the walls' keys, init, N_l, init kind}``
(:func:`seed_physics`): the wall settings of one replica (side-wall friction, drive and
torque) share their random numbers (lattice noise, placement), so that they compare like
with like. The run itself
is deterministic given its initial state. Blow-ups are re-raised with the study, point,
replica and seed.
"""

from __future__ import annotations

import math
import sys
import time as _time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import SimulationError
from ..io import RunFileError, config_hash, expect_input, read_dataset, write_dataset
from ..seeds import replica_rng, replica_seed
from . import layout, model, preparation, protocol
from .layout import ensemble_params, figures_params, fits_params, runs_params

__all__ = [
    "runs_params",
    "ensemble_params",
    "fits_params",
    "figures_params",
    "seed_physics",
    "init_stage",
    "runs_stage",
    "read_point_runs",
    "log_to_stderr",
]


def log_to_stderr(text: str) -> None:
    print(f"[{_time.strftime('%H:%M:%S')}] {text}", file=sys.stderr, flush=True)


WALL_KEYS = ("mu_side_walls", "side_walls", "wall_torque")
"""Physics keys of a point's wall setting (:class:`granpipe.box.layout.Walls`), left out of
the seed."""


def seed_physics(params: Mapping, n_l: int, kind: str) -> dict:
    """The mapping that defines a replica's random stream (physics but the walls' keys,
    and preparation)."""
    return {
        "physics": {k: v for k, v in params["physics"].items() if k not in WALL_KEYS},
        "init": dict(params["init"]),
        "N_l": int(n_l),
        "init_kind": kind,
    }


def walls_of(physics: Mapping) -> layout.Walls:
    """The wall setting of a point's (or a prepared state's) physics."""
    return layout.Walls(
        float(physics["mu_side_walls"]),
        str(physics.get("side_walls", "shaken")),
        str(physics.get("wall_torque", "lever")),
    )


def _var(dims, data, units, long_name, **attrs):
    return (dims, data, {"units": units, "long_name": long_name, **attrs})


def n_disks(physics: Mapping, n_l: int) -> int:
    """N = N_l Lx (rounded to the nearest integer)."""
    return int(round(int(n_l) * float(physics["Lx"])))


# --------------------------------------------------------------------------- init
def init_stage(
    params: Mapping,
    n_l: int,
    kind: str,
    replica: int,
    out: str | Path,
    log: Callable[[str], None] | None = log_to_stderr,
) -> Path:
    """Prepare and write one initial state (``params`` = ``{physics, init}``; the side
    walls' drive, which the plate at rest does not feel, is not part of it)."""
    params = {**params, "physics": layout.preparation_physics(params["physics"])}
    physics, init_cfg = params["physics"], params["init"]
    n = n_disks(physics, n_l)
    sp = seed_physics(params, n_l, kind)
    seed = replica_seed("box", sp, replica)
    rng = replica_rng("box", sp, replica)
    walls = walls_of(physics)
    state = layout.state_name(n_l, kind, walls)
    label = f"init {state} replica {replica}"
    if log:
        log(f"{label}: N = {n}, seed = {seed}")
    try:
        prep = preparation.prepare(physics, init_cfg, n, kind, rng, log=log)
    except SimulationError as exc:
        raise exc.with_context(study="box", point=state, replica=replica, seed=seed) from exc
    from .measures import crystal_check, local_order

    lo = local_order(prep.positions)
    psi6 = crystal_check(prep.positions, float(physics["Lx"]), local=lo).psi6
    if log:
        log(
            f"{label}: settled={prep.settled} after {prep.settle_time:.2f} t0 "
            f"({prep.steps} steps, {prep.wall_seconds:.1f} s wall, "
            f"{1e9 * prep.wall_seconds / max(prep.steps * n, 1):.0f} ns per particle-step), "
            f"KE/N = {prep.kinetic_energy:.2e}, bulk |psi6| = {psi6:.4f}"
        )
    ds = xr.Dataset(
        {
            "positions": _var(("particle", "xy"), prep.positions, "sigma", "disk centre (x, z)"),
            "velocities": _var(("particle", "xy"), prep.velocities, "sigma/t0", "disk velocity"),
            "spins": _var(("particle",), prep.spins, "1/t0", "angular velocity (ccw > 0)"),
            "psi6_abs": _var(("particle",), np.abs(lo["psi6"]), "1", "|psi6| bond order"),
            "psi4_abs": _var(("particle",), np.abs(lo["psi4"]), "1", "|psi4| bond order"),
            "order": _var(
                ("particle",), lo["order"], "1", "local order: 0 disordered, 1 hexagonal, 2 square"
            ),
            "settle_history_ke": _var(
                ("check",), prep.history["kinetic_energy"], "m*g*sigma", "kinetic energy per disk"
            ),
        },
        coords={
            "check": _var(("check",), prep.history["time"], "t0", "time of the settling check"),
        },
        attrs={
            "study": "box",
            "stage": "init",
            "state": state,
            "N_l": int(n_l),
            "N": n,
            "init": kind,
            "mu_w": walls.mu_w,
            "wall_torque": walls.wall_torque,
            "replica": int(replica),
            "seed": str(seed),
            "settled": int(prep.settled),
            "settle_time": prep.settle_time,
            "kinetic_energy_per_disk": prep.kinetic_energy,
            "bulk_psi6": psi6,
            "steps": prep.steps,
            "wall_seconds": prep.wall_seconds,
            "crystal_rows": str(params["init"]["crystal_rows"]) if kind == "crystal" else "",
        },
    )
    return write_dataset(ds, out, config_subset=params, seeds=[seed])


# --------------------------------------------------------------------------- runs
def _engine_vars(arrays: Mapping[str, np.ndarray]) -> dict:
    out = {}
    for key, val in arrays.items():
        a = np.asarray(val)
        if a.dtype == bool:
            a = a.astype(np.int8)
        dims = tuple(f"engine_{key}_d{i}" for i in range(a.ndim))
        out[f"engine_{key}"] = _var(dims, a, "1", f"engine state '{key}' (for continuation)")
    return out


def _engine_arrays(ds: xr.Dataset) -> dict:
    names = [name for name in ds.data_vars if name.startswith("engine_")]
    return {name[len("engine_") :]: ds[name].values for name in names}


def runs_stage(
    params: Mapping,
    n_l: int,
    gamma: float,
    kind: str,
    replica: int,
    part: int,
    init_file: str | Path,
    out: str | Path,
    previous: str | Path | None = None,
    log: Callable[[str], None] | None = log_to_stderr,
) -> Path:
    """Run one part of a point and replica and write it (``params`` from :func:`runs_params`)."""
    physics, proto = params["physics"], params["protocol"]
    p0, p1 = (int(v) for v in params["part_periods"])
    periods = range(p0, p1)
    walls = walls_of(physics)
    point = layout.point_name(n_l, gamma, kind, walls)
    if part > 0 and previous is None:
        raise RunFileError(f"part {part} needs --previous (the run file of part {part - 1})")
    init_ds = read_dataset(init_file)
    # the prepared state of this point's (N_l, init, walls, replica), from this physics
    expect_input(
        init_ds, init_file, study="box", stage="init",
        config_hash=config_hash(
            {"physics": layout.preparation_physics(physics), "init": params["init"]}
        ),
        state=layout.state_name(n_l, kind, walls), replica=int(replica),
    )  # fmt: skip
    seed = int(init_ds.attrs["seed"])
    label = f"runs {point} replica {replica} part {part}"
    kwargs = {}
    if part == 0:
        kwargs.update(
            start_positions=init_ds["positions"].values,
            start_velocities=init_ds["velocities"].values,
            start_spins=init_ds["spins"].values,
        )
    else:
        prev = read_dataset(previous)
        expect_input(
            prev, previous, study="box", stage="runs", point=point,
            config_hash=config_hash(layout.previous_part_params(params)),
            replica=int(replica), part=part - 1, seed=seed,
        )  # fmt: skip
        kwargs.update(previous_state=_engine_arrays(prev), tracers=prev["tracer_index"].values)
    n = int(init_ds.sizes["particle"])
    if log:
        log(f"{label}: N = {n}, periods {p0}..{p1 - 1}, seed {seed}")
    try:
        res = protocol.run_part(
            physics, proto, gamma, part, periods, log=log, label=label, **kwargs
        )
    except SimulationError as exc:
        raise exc.with_context(study="box", point=point, replica=replica, seed=seed) from exc
    if log:
        log(
            f"{label}: done, {res.steps} steps in {res.wall_seconds:.1f} s "
            f"({res.ns_per_particle_step:.0f} ns per particle-step, dt = {res.dt:.6e} t0, "
            f"{res.steps_per_period} steps per period)"
        )
    n_k = int(proto["phases_per_period"])
    data = {
        "time": _var(("period", "phase"), res.time, "t0", "time of the sample"),
        "z_plate": _var(("period", "phase"), res.z_plate, "sigma", "plate height z_b(k)"),
        "z_tracers": _var(
            ("period", "phase", "tracer"), res.z_tracers, "sigma", "tracer heights z_j^i(k)"
        ),
        "bed_gap": _var(
            ("period", "phase"),
            res.bed_gap,
            "sigma",
            "gap under the bed: lowest disk bottom minus plate height",
        ),  # fmt: skip
        "plate_contacts": _var(
            ("period", "phase"), res.plate_contacts, "1", "disks touching the plate"
        ),
        "T_g": _var(
            ("period", "phase"),
            res.granular_temperature,
            "m*g*sigma",
            "instantaneous granular temperature (Eq. 2 without the time average)",
        ),  # fmt: skip
        "z_cm": _var(("period", "phase"), res.z_cm, "sigma", "bed centre-of-mass height"),
        "vz_cm": _var(("period", "phase"), res.vz_cm, "sigma/t0", "bed centre-of-mass velocity"),
        "positions": _var(
            ("frame", "particle", "xy"),
            res.cycle_positions,
            "sigma",
            "disk centres at the start of periods (frame f = start of measured period p0 + f)",
        ),  # fmt: skip
        "tracer_index": _var(("tracer",), res.tracers, "1", "indices of the tracer disks"),
    }
    coords = {}
    if res.phase_positions.shape[1]:
        n_s = res.phase_positions.shape[1] + 1
        data["phase_positions"] = _var(
            ("period", "slip_phase", "particle", "xy"),
            res.phase_positions,
            "sigma",
            "disk centres at the other slip phases of each measured period",
        )  # fmt: skip
        coords["slip_phase"] = _var(
            ("slip_phase",), np.arange(1, n_s) / n_s, "1", "phase of the cycle of the frames"
        )
    if res.ramp_positions is not None:
        data["positions_ramp_end"] = _var(
            ("particle", "xy"),
            res.ramp_positions,
            "sigma",
            f"disk centres when the start-up ramp has ended (t = {res.ramp_time:.6g} t0)",
        )  # fmt: skip
    if res.transient is not None:
        tr = res.transient
        units = {
            "time": ("t0", "time"),
            "z_plate": ("sigma", "plate height"),
            "v_plate": ("sigma/t0", "plate velocity"),
            "z_cm": ("sigma", "bed centre-of-mass height"),
            "vz_cm": ("sigma/t0", "bed centre-of-mass velocity"),
            "bed_gap": ("sigma", "gap under the bed"),
            "T_g": ("m*g*sigma", "instantaneous granular temperature"),
            "max_vz": ("sigma/t0", "largest upward disk velocity"),
            "plate_contacts": ("1", "disks touching the plate"),
        }
        for key, (u, ln) in units.items():
            data[f"transient_{key}"] = _var(("transient_sample",), tr[key], u, f"transient: {ln}")
    data.update(_engine_vars(res.final_state))
    ds = xr.Dataset(
        data,
        coords={
            "period": _var(("period",), res.periods, "1", "measured period index j"),
            "phase": _var(("phase",), np.arange(n_k) / n_k, "1", "phase k/N_k of the cycle"),
            "frame": _var(("frame",), np.arange(p0, p1 + 1), "1", "measured period at frame"),
            **coords,
        },
        attrs={
            "study": "box",
            "stage": "runs",
            "point": point,
            "N_l": int(n_l),
            "N": n,
            "Gamma": float(gamma),
            "K_m": float(gamma) ** 2,
            "init": kind,
            "mu_w": walls.mu_w,
            "side_walls": walls.side_walls,
            "wall_torque": walls.wall_torque,
            "replica": int(replica),
            "part": int(part),
            "seed": str(seed),
            "amplitude": res.drive.amplitude,
            "omega": res.drive.omega,
            "drive_phase": res.drive.phase,
            "ramp_time": res.drive.ramp_time,
            "z0": res.drive.z0,
            "dt": res.dt,
            "steps_per_period": res.steps_per_period,
            "steps": res.steps,
            "wall_seconds": res.wall_seconds,
            "ns_per_particle_step": res.ns_per_particle_step,
        },
    )
    return write_dataset(ds, out, config_subset=params, seeds=[seed])


def read_point_runs(files: Sequence[str | Path], params: Mapping) -> dict[int, list[xr.Dataset]]:
    """Run files of one point grouped by replica, each list in part order.

    ``params`` is the ensemble stage's config subset for one point
    (:func:`granpipe.box.layout.ensemble_params`): every file must be a box run file of
    ``params["point"]`` whose config hash is that of its part
    (``params["runs_config_hashes"][part]``), and the files must hold each replica
    ``0 .. params["replicas"] - 1`` and part once. Raises RunFileError naming the file.
    """
    point, hashes = params["point"], params["runs_config_hashes"]
    by_rep: dict[int, list[xr.Dataset]] = {}
    where: dict[tuple[int, int], str] = {}
    for f in files:
        ds = read_dataset(f)
        expect_input(ds, f, study="box", stage="runs", point=point)
        part = int(ds.attrs["part"])
        if not 0 <= part < len(hashes):
            raise RunFileError(f"{f} holds part {part}; {point} has parts 0..{len(hashes) - 1}")
        expect_input(ds, f, study="box", stage="runs", point=point, config_hash=hashes[part])
        key = (int(ds.attrs["replica"]), part)
        if key in where:
            raise RunFileError(f"replica {key[0]} part {key[1]} appears twice: {where[key]}, {f}")
        where[key] = str(f)
        ds = ds.drop_vars([v for v in ds.data_vars if v.startswith("engine_")])
        by_rep.setdefault(key[0], []).append(ds)
    want = {(r, p) for r in range(int(params["replicas"])) for p in range(len(hashes))}
    missing = sorted(want - set(where))
    if missing or set(where) - want:
        raise RunFileError(
            f"{point}: the run files hold (replica, part) {sorted(where)}, expected {sorted(want)}"
        )
    for parts in by_rep.values():
        parts.sort(key=lambda d: int(d.attrs["part"]))
    return by_rep


# ----------------------------------------------------------------------- ensemble
def ensemble_stage(
    params: Mapping,
    run_files: Sequence[str | Path],
    out: str | Path,
    log: Callable[[str], None] | None = log_to_stderr,
) -> Path:
    """Measures of one point from all its run files (every replica, every part)."""
    from . import measures

    by_rep = read_point_runs(run_files, params)
    runs = {r: measures.concat_parts(parts) for r, parts in by_rep.items()}
    ds = measures.point_dataset(
        runs, params["detection"], params["slips"], params["order"], float(params["Lx"])
    )
    seeds = sorted({int(p[0].attrs["seed"]) for p in by_rep.values()})
    if log:
        log(
            f"ensemble {ds.attrs['point']}: s_c = {float(ds.s_c):.3f}, s_b = {float(ds.s_b):.4f}, "
            f"detachment = {float(ds.detachment_fraction):.3f}, T_g* = {float(ds.T_g):.3e}, "
            f"p_s = {float(ds.p_s):.3e} ({int(ds.n_slips)}/{int(ds.n_trials)}), "
            f"psi6 start = {float(ds.psi6_start):.3f}, "
            f"{ds.attrs['ns_per_particle_step']:.0f} ns per particle-step"
        )
    return write_dataset(ds, out, config_subset=params, seeds=seeds)


# --------------------------------------------------------------------------- fits
def fit_n_l(fits_cfg: Mapping, n_ls) -> int:
    """The linear density whose fits the figures draw (``fits.N_l`` or the largest)."""
    n_ls = sorted({int(n) for n in n_ls})
    want = fits_cfg.get("N_l")
    return int(want) if want is not None and int(want) in n_ls else n_ls[-1]


def figure_reading(points, fits_cfg: Mapping, figure: int) -> str:
    """The subtitle of Fig. 3, 4, 5 or 7: the record its points hold and the readings of the
    paper the criteria and fits take (``fits.*``; docs/box.md)."""

    def span(values) -> str:
        v = sorted({int(x) for x in values})
        return f"{v[0]}" if len(v) == 1 else f"{v[0]}-{v[-1]}"

    record = (
        f"record: {span(points['measured_periods'])} measured periods, "
        f"{span(points['replicas'])} replica(s) per point"
    )
    if figure == 3:
        return (
            f"{record}; convection by Eq. (B2) over the whole record (and over its first n "
            "cycles: convection_<n>periods), rolls by the wall-to-centre displacement score"
        )
    if figure == 7:
        return (
            f"{record}; onsets by Eq. (B2) and by the roll criterion over the first n "
            "measured periods (fits.onset_records) and over the whole record"
        )
    if figure == 4:
        which = fits_cfg.get("temperature_points", "bouncing")
        return f"{record}; T_g* regions fitted over the {which} points (fits.temperature_points)"
    weights = fits_cfg.get("slip_weights", "unweighted")
    labels = fits_cfg.get("crystal_points", "initialisation")
    each = fits_cfg.get("slip_replicas", "pooled")
    regions = fits_cfg.get("crystal_regions", "temperature")
    return (
        f"{record}; slips between cycle starts; Arrhenius fits {weights} "
        f"(fits.slip_weights) over replicas {each} (fits.slip_replicas), crystal points "
        f"by {labels} (fits.crystal_points), its A2/B split at the {regions} reading "
        "(fits.crystal_regions)"
    )


def figure_walls(points) -> layout.Walls:
    """The walls Figures 1 and 3–5 draw: Table I's side-wall friction with the whole box
    shaken (lever torque first) if the grid has it, else the first setting of the table
    (``points``: the points table, columns mu_w, side_walls, wall_torque)."""
    from .fits import WALL_COLUMNS, is_paper_walls

    settings = [
        layout.Walls(float(m), str(s), str(t))
        for m, s, t in points[list(WALL_COLUMNS)].drop_duplicates().itertuples(index=False)
    ]
    paper = [w for w in settings if is_paper_walls(w)]
    paper.sort(key=lambda w: layout.WALL_TORQUES.index(w.wall_torque))
    return (paper or settings)[0]


def select_walls(df, walls: layout.Walls):
    """The rows of a fits table (columns mu_w, side_walls, wall_torque) with ``walls``."""
    return df[
        np.isclose(df["mu_w"].to_numpy(float), walls.mu_w)
        & (df["side_walls"] == walls.side_walls)
        & (df["wall_torque"] == walls.wall_torque)
    ]


def _check_inputs(files: Sequence[str | Path], expected: Mapping[str, str], stage: str,
                  key: str, every: bool) -> None:  # fmt: skip
    """Check that each file is a box ``stage`` file of one of the ``expected`` names (its
    attribute ``key``: ``point`` or ``state``) with that name's config hash; with
    ``every``, each name exactly once. RunFileError names the file (and the other file
    of a duplicate, or the names missing)."""
    from ..io import open_input

    seen: dict[str, str] = {}
    for f in files:
        with open_input(f) as ds:
            attrs = dict(ds.attrs)
        expect_input(attrs, f, study="box", stage=stage)
        name = str(attrs.get(key))
        if name not in expected:
            raise RunFileError(
                f"{f} holds {key} {name!r}, which this stage was not asked for "
                f"(expected one of: {', '.join(expected)})"
            )
        expect_input(attrs, f, study="box", stage=stage, config_hash=expected[name])
        if every and name in seen:
            raise RunFileError(f"{key} {name} appears twice: in {seen[name]} and in {f}")
        seen[name] = str(f)
    missing = [n for n in expected if n not in seen]
    if every and missing:
        raise RunFileError(f"no {stage} file of {key}(s) {', '.join(missing)}")


def fits_stage(
    params: Mapping,
    ensemble_files: Sequence[str | Path],
    out_dir: str | Path,
    log: Callable[[str], None] | None = log_to_stderr,
) -> list[Path]:
    """Thresholds, T_g* regions and Arrhenius barriers; ``fits/*.nc`` and ``summary.csv``."""
    import warnings

    from ..analysis.summary import write_summary
    from . import fits

    out_dir = Path(out_dir)
    _check_inputs(ensemble_files, params["points"], "ensemble", "point", every=True)
    fcfg = params["fits"]
    table = fits.points_table(
        ensemble_files, params["detection"], fcfg.get("crystal_points", "initialisation"),
        records=fcfg.get("onset_records", ()), slip_windows=fcfg.get("slip_windows", ()),
    )  # fmt: skip
    ths = fits.thresholds_table(table, params["detection"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        tfits = fits.temperature_fits(table, params["fits"], params["detection"])
        bends = fits.slip_bends(table, tfits, params["fits"])
        sfits = fits.slip_fits(table, tfits, params["fits"], fits.convection_onsets(ths), bends)
    datasets = fits.fits_datasets(table, ths, tfits, sfits, bends)
    written = []
    for name, ds in datasets.items():
        written.append(
            write_dataset(
                ds, out_dir / f"{name}.nc", config_subset=params, study="box", stage="fits"
            )
        )
    rows = fits.summary_rows(table, ths, tfits, sfits, bends)
    written.append(write_summary(rows, out_dir / "summary.csv", merge=False))
    written.append(write_summary(fits.cost_rows(table), out_dir / "costs.csv", merge=False))
    if log:
        for r in rows:
            log(
                f"{r['quantity']} = {r['value']:.4g} [{r.get('ci_low', math.nan):.4g}, "
                f"{r.get('ci_high', math.nan):.4g}]"
                + (f" (paper {r['paper_value']})" if r.get("paper_value") is not None else "")
            )
    return written


def load_fits(fits_dir: str | Path):
    """(points, thresholds, temperature, slips) DataFrames from ``fits/*.nc``; the points
    carry ``fitted``, whether the fits use them (their ``used`` column,
    :func:`~granpipe.box.fits.used_mask`)."""
    import pandas as pd

    fits_dir = Path(fits_dir)
    phase = read_dataset(fits_dir / "phase_diagram.nc")
    pcols = [d for d in phase.data_vars if phase[d].dims == ("point",)]
    points = pd.DataFrame({c: phase[c].values for c in pcols})
    for c in ("init", "point", "side_walls", "wall_torque"):
        points[c] = phase[c].values.astype(str)
    points["fitted"] = points["used"].astype(bool)
    tcols = [d for d in phase.data_vars if phase[d].dims == ("threshold",)]
    ths = pd.DataFrame({c.removeprefix("threshold_"): phase[c].values for c in tcols})
    for c in ("init", "criterion", "status", "side_walls", "wall_torque"):
        ths[c] = phase[f"threshold_{c}"].values.astype(str)

    def rows(name):
        ds = read_dataset(fits_dir / f"{name}.nc")
        cols = ("value", "se", "ci_low", "ci_high", "N_l", "mu_w")
        df = pd.DataFrame({c: ds[c].values for c in cols})
        for c in ("init", "name", "side_walls", "wall_torque", "note"):
            df[c] = ds[c].values.astype(str)
        df["index"] = ds["index"].values.astype(int)
        df["N_l"] = df["N_l"].astype(int)
        return df

    return points, ths, rows("temperature"), rows("slips")


# ------------------------------------------------------------------------- figures
def figures_stage(
    params: Mapping,
    fits_dir: str | Path,
    init_files: Sequence[str | Path],
    ensemble_files: Sequence[str | Path],
    out_dir: str | Path,
    log: Callable[[str], None] | None = log_to_stderr,
) -> list[Path]:
    """Figures 1, 3, 4, 5 and 7 at one wall setting (:func:`figure_walls`) and Fig. 6, the
    thresholds against the walls (PNG and PDF)."""
    from ..figures import box as figs
    from ..figures import save_figure
    from .fits import PAPER

    out_dir = Path(out_dir)
    _check_inputs(ensemble_files, params["points"], "ensemble", "point", every=True)
    _check_inputs(init_files, params["states"], "init", "state", every=False)
    points, ths, temp, slips = load_fits(fits_dir)
    all_ths = ths
    walls = figure_walls(points)
    points, ths, temp, slips = (select_walls(df, walls) for df in (points, ths, temp, slips))
    n_fit = fit_n_l(params["fits"], points["N_l"])
    written = []
    # Fig. 1: initial states of the largest N_l (replica 0), then the same starts at the
    # beginning of the measurement at the largest Γ without convection.
    n_big = int(points["N_l"].max())
    inits = {}
    for f in init_files:
        ds = read_dataset(f)
        a = ds.attrs
        if (
            int(a["N_l"]) == n_big
            and int(a["replica"]) == 0
            and a["state"] == layout.state_name(n_big, a["init"], walls)
        ):
            inits[a["init"]] = ds
    panels = []
    for kind in ("crystal", "random"):
        if kind in inits:
            ds = inits[kind]
            panels.append(
                {
                    "title": f"{kind} start, N_l = {n_big}, μ_w = {walls.mu_w:g}\nbulk |ψ6| = "
                    f"{float(ds.attrs['bulk_psi6']):.3f}",
                    "positions": ds["positions"].values,
                    "order": ds["order"].values,
                }
            )
    by_point = {Path(f).stem: f for f in ensemble_files}
    for kind in ("crystal", "random"):
        sel = points[(points["init"] == kind) & (points["N_l"] == n_big)]
        calm = sel[sel["convection"] == 0]
        if sel.empty:
            continue
        row = (calm if not calm.empty else sel).sort_values("Gamma").iloc[-1]
        f = by_point.get(row["point"])
        if f is None:
            continue
        ds = read_dataset(f)
        panels.append(
            {
                "title": f"{kind}, Γ = {row['Gamma']:g}: measurement start\nbulk |ψ6| = "
                f"{float(ds['psi6_start']):.3f}, {int(ds['dislocations_start'])} defects",
                "positions": ds["positions_start"].values,
                "order": ds["order_start"].values,
                "z_plate": float(np.min(ds["positions_start"].values[:, 1])) - 0.5,
            }
        )
    if panels:
        fig = figs.fig1_snapshots(panels, float(params["Lx"]))
        written += save_figure(fig, Path(out_dir) / layout.FIGURES[1])
    fcfg = params["fits"]
    fig3 = figs.fig3_phase_diagram(points, ths, reading=figure_reading(points, fcfg, 3))
    written += save_figure(fig3, Path(out_dir) / layout.FIGURES[3])
    fig4 = figs.fig4_granular_temperature(
        points, temp, n_fit, reading=figure_reading(points, fcfg, 4)
    )
    written += save_figure(fig4, Path(out_dir) / layout.FIGURES[4])
    fig5 = figs.fig5_slip_probability(
        points, slips, temp, n_fit, reading=figure_reading(points, fcfg, 5)
    )
    written += save_figure(fig5, Path(out_dir) / layout.FIGURES[5])
    paper_onset = math.sqrt(PAPER["K_m_break_random"])
    paper_lines = {
        "paper: bouncing just above Γ = 1": PAPER["Gamma_bouncing"],
        "paper: random-start convection, K_m ≈ 3.3": paper_onset,
    }
    written += save_figure(figs.fig6_walls(all_ths, paper_lines), Path(out_dir) / layout.FIGURES[6])
    fig7 = figs.fig7_onset_record(points, ths, paper_onset, reading=figure_reading(points, fcfg, 7))
    written += save_figure(fig7, Path(out_dir) / layout.FIGURES[7])
    if log:
        log("figures: " + ", ".join(str(p) for p in written))
    return written


_ = model
