"""The column study's runs, step by step (docs/column.md): what each runs stage computes.

1. Trajectories y_i(t) of the figure-1 columns over four taps (paper Fig. 1).
2. Density relaxation: column height and mean linear density at 0.99T, 1.99T, … over
   many taps, for an ensemble of starts perturbed inside the stick band (generic set).
3. Chaos points: largest Lyapunov exponent at one tap amplitude a and period T, from
   the tangent dynamics with saltation, checked against twin trajectories and against the
   plain variational solution (no saltation), each point an ensemble; and, from the same
   runs, the period of the tap-to-tap return map (Theorem 1). The map over the (a, T)
   grid is reduced in :mod:`granpipe.column.measures`.
4. Continuum models against the discrete column (paper Fig. 2), and their convergence.

The column has no separate preparation: its start is the closed-form equilibrium of
Eq. (27) (:func:`granpipe.column.model.equilibrium_positions`), perturbed per replica
(:func:`perturbed_start`).

Every function returns an :class:`xarray.Dataset` whose variables carry ``units`` and
``long_name``; the CLI writes them with provenance (granpipe.io).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np
import xarray as xr

from ..errors import SimulationError
from ..seeds import replica_rng, replica_seed
from . import continuum as cont
from . import discrete as d
from .measures import return_period
from .model import ColumnParams, equilibrium_positions, physics

__all__ = [
    "perturbed_start",
    "trajectories",
    "relaxation_batch",
    "lyapunov_point",
    "continuum_comparison",
    "continuum_convergence",
    "STUDY",
]

STUDY = "column"


def perturbed_start(p: ColumnParams, rng: np.random.Generator, fraction: float) -> d.ColumnState:
    """Equilibrium start with every compression scaled by 1 + fraction·0.9·e·U(−1, 1).

    The force each contact must carry is unchanged, so with ``fraction <= 1`` every contact
    stays inside its hysteresis band [K(1−e)c, K(1+e)c]: the perturbed column is still
    exactly at rest (a stuck state), a different one for each replica.
    """
    y = equilibrium_positions(p)
    c = np.empty(p.N)
    c[0] = p.r - y[0]
    c[1:] = 2 * p.r - np.diff(y)
    c = c * (1.0 + fraction * 0.9 * p.e * rng.uniform(-1.0, 1.0, p.N))
    y = np.cumsum(np.concatenate([[p.r], np.full(p.N - 1, 2 * p.r)]) - c)
    return d.ColumnState(y)


# --------------------------------------------------------------------------- 1. Fig. 1
def trajectories(phys: Mapping, n_taps: int, record_dt: float, step_factor: float = 0.1):
    """y_i(t) of one column from the equilibrium start over ``n_taps`` taps (Fig. 1).

    Returns a Dataset with ``y`` (time, particle) [length], ``v`` [length/time],
    ``floor`` (time,) [length], ``height`` (time,) [length] = y_N + r − y0.
    """
    p = physics(phys)
    s = d.initial_state(p)
    out = d.simulate(
        p, s, n_taps, h=d.default_step(p, step_factor), record_dt=record_dt, sample_fracs=()
    )
    floor = cont.floor_position(p, out["t"])
    ds = xr.Dataset(
        {
            "y": (
                ("time", "particle"),
                out["y"],
                {"units": "length", "long_name": "particle height y_i"},
            ),
            "v": (
                ("time", "particle"),
                out["v"],
                {"units": "length/time", "long_name": "particle velocity"},
            ),
            "floor": ("time", floor, {"units": "length", "long_name": "floor height y0 (Eq. 2)"}),
            "height": (
                "time",
                out["y"][:, -1] + p.r - floor,
                {"units": "length", "long_name": "column height y_N + r - y0"},
            ),
        },
        coords={
            "time": ("time", out["t"], {"units": "time", "long_name": "time"}),
            "particle": (
                "particle",
                np.arange(1, p.N + 1),
                {"units": "1", "long_name": "particle index i"},
            ),
        },
        attrs={"stats": str(out["stats"]), "N": p.N, "T": p.T, "tap_duration": p.tap_duration},
    )
    return ds


# --------------------------------------------------------------------------- 2. relaxation
def relaxation_batch(
    phys: Mapping,
    replicas: Iterable[int],
    n_taps: int,
    perturbation: float,
    step_factor: float = 0.1,
    sample_frac: float = 0.99,
):
    """Column height and mean linear density at (k + 0.99)T for replicas of perturbed starts.

    Returns (replica, tap) ``height`` [length] = y_N + r (floor at rest at 0.99T) and
    ``density`` [mass/length] = N m / height, plus the rest values at tap 0.
    """
    p = physics(phys)
    replicas = list(replicas)
    H = np.full((len(replicas), n_taps + 1), np.nan)
    seeds = []
    for k, rep in enumerate(replicas):
        rng = replica_rng(STUDY, dict(phys), rep)
        seeds.append(replica_seed(STUDY, dict(phys), rep))
        s = perturbed_start(p, rng, perturbation)
        H[k, 0] = s.y[-1] + p.r
        try:
            out = d.simulate(
                p, s, n_taps, h=d.default_step(p, step_factor), sample_fracs=(sample_frac,)
            )
        except SimulationError as exc:
            raise exc.with_context(
                study=STUDY, stage="relaxation", replica=rep, seed=seeds[-1]
            ) from None
        H[k, 1:] = out["samples"][:, 0, -1] + p.r
    ds = xr.Dataset(
        {
            "height": (
                ("replica", "tap"),
                H,
                {"units": "length", "long_name": "column height y_N + r at (k + 0.99) T"},
            ),
            "density": (
                ("replica", "tap"),
                p.N * p.m / H,
                {"units": "mass/length", "long_name": "mean linear density N m / height"},
            ),
        },
        coords={
            "replica": (
                "replica",
                np.array(replicas),
                {"units": "1", "long_name": "replica index"},
            ),
            "tap": (
                "tap",
                np.arange(n_taps + 1),
                {"units": "1", "long_name": "taps completed (0 = start)"},
            ),
        },
        attrs={"sample_frac": sample_frac, "close_packed_density": p.m / (2 * p.r)},
    )
    return ds, seeds


# --------------------------------------------------------------------------- 3. chaos map
def _twin_lyapunov(p, base: d.ColumnState, twin_dir, n_taps, eps, h):
    """Benettin twin estimate: per-tap log growth of a twin at distance ε, renormalized."""
    sy, sv = d.tangent_scales(p)
    tw = base.copy()
    tw.y = base.y + eps * sy * twin_dir[: p.N]
    tw.v = base.v + eps * sv * twin_dir[p.N :]
    logs = np.full(n_taps, np.nan)
    for k in range(n_taps):
        d.simulate(p, base, 1, h=h, sample_fracs=())
        d.simulate(p, tw, 1, h=h, sample_fracs=())
        dist = math.sqrt(float(np.sum(((tw.y - base.y) / sy) ** 2 + ((tw.v - base.v) / sv) ** 2)))
        logs[k] = math.log(dist / eps)
        tw.y = base.y + (tw.y - base.y) * (eps / dist)
        tw.v = base.v + (tw.v - base.v) * (eps / dist)
        tw.modes = base.modes.copy()
        tw.period = base.period
    return logs


def lyapunov_point(
    phys: Mapping,
    replicas: Iterable[int],
    n_transient: int,
    n_taps: int,
    perturbation: float,
    twin_epsilon: float,
    plain: bool = True,
    step_factor: float = 0.1,
    return_max_period: int = 6,
    return_taps: int = 12,
    return_tolerance: float = 1e-6,
):
    """Largest Lyapunov exponent and return-map period at one (a, T), per replica.

    ``lambda_tap`` from the tangent dynamics with saltation (the estimate of the map),
    ``lambda_twin`` from twin trajectories (ε = ``twin_epsilon`` in the scaled norm), and
    ``lambda_plain`` from the variational equations without saltation. Exponents are per
    tap [1/tap]; divide by T for per unit time. A replica whose column breaks (the floor
    passes through a particle: the contact law is too soft for the tap) gives NaN and is
    counted in ``failed``.

    The same tangent run samples the state at the end of every measured tap, t = kT
    (positions, velocities, contact modes: the state the next tap starts from), and
    :func:`return_period` finds the smallest period p ≤ ``return_max_period`` of the
    tap-to-tap return map over the last ``return_taps`` of these states
    (``return_period``: p, 0 = none up to the maximum, −2 = undecided, −1 = the column
    broke), with the
    largest distance per lag (``return_distance``) and the fraction of those states at
    rest (``rest_fraction``). Sampling at t = kT adds no step: the exponents are the same
    bit for bit with or without it.
    """
    if not 1 <= return_taps <= n_taps:
        raise ValueError(f"return_taps = {return_taps} must be in [1, taps = {n_taps}]")
    if return_taps < 2 * return_max_period:
        raise ValueError(
            f"return_taps = {return_taps} must be at least 2 return_max_period"
            f" = {2 * return_max_period}"
        )
    p = physics(phys)
    h = d.default_step(p, step_factor)
    replicas = list(replicas)
    lam = np.full(len(replicas), np.nan)
    twin = np.full(len(replicas), np.nan)
    plain_l = np.full(len(replicas), np.nan)
    growth = np.full((len(replicas), n_taps), np.nan)
    failed = np.zeros(len(replicas), dtype=np.int64)
    period = np.full(len(replicas), -1, dtype=np.int64)
    rdist = np.full((len(replicas), return_max_period), np.nan)
    rest = np.full(len(replicas), np.nan)
    seeds = []
    for k, rep in enumerate(replicas):
        rng = replica_rng(STUDY, dict(phys), rep)
        seeds.append(replica_seed(STUDY, dict(phys), rep))
        try:
            s = perturbed_start(p, rng, perturbation)
            d.simulate(p, s, n_transient, h=h, sample_fracs=())
            start = s.copy()
            u = rng.standard_normal(2 * p.N)
            u /= np.linalg.norm(u)
            sy, sv = d.tangent_scales(p)
            s.dy, s.dv = u[: p.N] * sy, u[p.N :] * sv
            # states at the end of every tap (f = 1), the last return_taps of them
            out = d.simulate(p, s, n_taps, h=h, tangent=True, sample_fracs=(1.0,))
            ys = out["samples"][-return_taps:, 0]
            vs = out["samples_v"][-return_taps:, 0]
            ms = out["sample_modes"][-return_taps:, 0]
            x = np.concatenate([ys / sy, vs / sv], axis=1)
            period[k], rdist[k] = return_period(x, ms, return_max_period, return_tolerance)
            rest[k] = float(np.mean(np.all((vs == 0.0) & (ms == d.STICK), axis=1)))
            growth[k] = out["log_growth"]
            lam[k] = float(np.mean(out["log_growth"]))
            twin[k] = float(np.mean(_twin_lyapunov(p, start.copy(), u, n_taps, twin_epsilon, h)))
            if plain:
                s2 = start.copy()
                s2.dy, s2.dv = u[: p.N] * sy, u[p.N :] * sv
                out2 = d.simulate(
                    p, s2, n_taps, h=h, tangent=True, saltation=False, sample_fracs=()
                )
                plain_l[k] = float(np.mean(out2["log_growth"]))
        except SimulationError:
            failed[k] = 1
            period[k] = -1
    ds = xr.Dataset(
        {
            "lambda_tap": (
                "replica",
                lam,
                {
                    "units": "1/tap",
                    "long_name": "largest Lyapunov exponent, tangent with saltation",
                },
            ),
            "lambda_twin": (
                "replica",
                twin,
                {"units": "1/tap", "long_name": "largest Lyapunov exponent, twin trajectories"},
            ),
            "lambda_plain": (
                "replica",
                plain_l,
                {
                    "units": "1/tap",
                    "long_name": "largest Lyapunov exponent, variational without saltation",
                },
            ),
            "log_growth": (
                ("replica", "tap"),
                growth,
                {"units": "1", "long_name": "log growth of the tangent vector per tap"},
            ),
            "failed": (
                "replica",
                failed,
                {"units": "1", "long_name": "1 if the column broke (particle passed through)"},
            ),
            "return_period": (
                "replica",
                period,
                {
                    "units": "taps",
                    "long_name": "smallest period of the tap-to-tap return map "
                    f"(0: none up to {return_max_period}; -2: undecided; -1: column broke)",
                },
            ),
            "return_distance": (
                ("replica", "lag"),
                rdist,
                {
                    "units": "1",
                    "long_name": "largest scaled distance |x_(k+p) - x_k| over the return "
                    "window (norm sqrt(sum (dy/r)^2 + (dv/(omega_c r))^2))",
                },
            ),
            "rest_fraction": (
                "replica",
                rest,
                {
                    "units": "1",
                    "long_name": "fraction of the return-window states at rest "
                    "(all contacts stuck, all velocities zero)",
                },
            ),
        },
        coords={
            "replica": (
                "replica",
                np.array(replicas),
                {"units": "1", "long_name": "replica index"},
            ),
            "tap": ("tap", np.arange(n_taps), {"units": "1", "long_name": "measured tap"}),
            "lag": (
                "lag",
                np.arange(1, return_max_period + 1),
                {"units": "taps", "long_name": "lag p of the return-map distance"},
            ),
        },
        attrs={
            "a": p.a,
            "T": p.T,
            "N": p.N,
            "twin_epsilon": twin_epsilon,
            "return_max_period": return_max_period,
            "return_taps": return_taps,
            "return_tolerance": return_tolerance,
        },
    )
    return ds, seeds


# --------------------------------------------------------------------------- 4. continuum
CONTINUUM_MODELS = ("longwave", "bsr", "bsr_derived")
"""The continuum models compared: the derived long-wave model, BSR as printed (Eq. 45) and
the BSR derived from the force law of Eq. (24) (docs/column.md)."""

TOP_TREATMENTS = ("hybrid", "free")
"""``hybrid``: the continuum's top follows the discrete top (Section 4); ``free``: Φ = 0."""

SMOOTH_CHAIN = "smooth_chain"
"""The reference beside the continuum models: the discrete chain itself with the smooth
sign σ(W) = tanh(W/w_σ) the continuum models need (the derived BSR with the point-particle
kernel on the particles' own labels), so that a distance can be split into what the
smoothing of the sign costs and what the continuum limit costs."""

#: Models of the scan over the width w_σ of the smooth sign, in the order of its axis.
SIGMA_SCAN_MODELS = ("longwave", "bsr_derived", SMOOTH_CHAIN)

MODEL_NAMES = {
    "longwave": "long-wave (derived)",
    "bsr": "BSR (Eq. 45 as printed)",
    "bsr_derived": "BSR (derived)",
    SMOOTH_CHAIN: "chain with the smooth sign",
}


def _discrete_record(q, n_taps, record_dt, step_factor):
    s = d.initial_state(q)
    return d.simulate(
        q, s, n_taps, h=d.default_step(q, step_factor), record_dt=record_dt, sample_fracs=()
    )


def _discrete_top(q, disc):
    """(t, y_N + r, v_N) of a discrete record: the free top of the hybrid treatment."""
    return disc["t"], disc["y"][:, -1] + q.r, disc["v"][:, -1]


def _solve_continuum(model, q, t_end, refinement, top, record_dt, sigma_width,
                     kernel_width=cont.BSR_KERNEL_WIDTH):  # fmt: skip
    """Positions of the N particles in one continuum model, chain units: (t, (n_t, N), sol).

    L-W: y(z_i, t) at the centre labels z_i = i − 1/2; BSR as printed: tracers started at
    the discrete rest positions; derived BSR: its material at the centre labels.
    """
    dz = 1.0 / refinement
    if model == "longwave":
        sol = cont.solve_longwave(
            q, t_end, dz=dz, top=top, record_dt=record_dt, sigma_width=sigma_width
        )
        zi = np.arange(1, q.N + 1) - 0.5
        y = np.array([np.interp(zi, sol["z"], row) for row in sol["y"]])
    elif model == "bsr":
        sol = cont.solve_bsr(q, t_end, dz=dz, top=top, record_dt=record_dt)
        y = sol["tracers"]
    elif model == "bsr_derived":
        sol = cont.solve_bsr_derived(
            q, t_end, ds=dz, kernel_width=kernel_width, top=top, record_dt=record_dt,
            sigma_width=sigma_width,
        )  # fmt: skip
        y = sol["tracers"]
    else:
        raise ValueError(f"unknown continuum model {model!r}; known: {CONTINUUM_MODELS}")
    return sol["t"], y, sol


def _distance(model_y, disc_y):
    """RMS distances to the discrete column, in units of h (chain units in, numbers out).

    Returns (positions, displacements from each one's own rest state, displacements
    relative to the RMS displacement of the discrete column).
    """
    a = model_y - disc_y
    disp = (model_y - model_y[0]) - (disc_y - disc_y[0])
    ref = disc_y - disc_y[0]
    rms_disp = float(np.sqrt(np.mean(disp * disp)))
    return (
        float(np.sqrt(np.mean(a * a))),
        rms_disp,
        rms_disp / float(np.sqrt(np.mean(ref * ref))),
    )


def _on_records(disc, t, fine):
    idx = np.clip(np.round(t / fine).astype(int), 0, disc["t"].size - 1)
    return disc["y"][idx]


def continuum_comparison(
    phys: Mapping,
    n_taps: int,
    lw_refinement: int,
    bsr_refinement: int,
    record_dt: float,
    sigma_width: float = 0.01,
    step_factor: float = 0.1,
    bsr_derived_refinement: int = 8,
    bsr_kernel_width: float = cont.BSR_KERNEL_WIDTH,
):
    """Discrete column and the continuum models with the hybrid and the free top.

    Everything is computed in chain units (h, sqrt(m/K), m: docs/column.md); the
    physical column ``phys`` only sets the dimensionless numbers. ``record_dt`` is in the
    units of ``phys``. Returns (dataset on common records, distances per model and top).
    """
    p = physics(phys)
    q = cont.dimensionless(p)
    sc = cont.chain_scales(p)
    rec = record_dt / sc.time
    fine = min(rec, q.T / 1000)
    disc = _discrete_record(q, n_taps, fine, step_factor)
    top = _discrete_top(q, disc)
    t_end = n_taps * q.T
    runs = {}
    refinements = {
        "longwave": lw_refinement,
        "bsr": bsr_refinement,
        "bsr_derived": bsr_derived_refinement,
    }
    for model, k in refinements.items():
        for treat in TOP_TREATMENTS:
            runs[model, treat] = _solve_continuum(
                model, q, t_end, k, top if treat == "hybrid" else None, rec, sigma_width,
                bsr_kernel_width,
            )  # fmt: skip
    for treat in TOP_TREATMENTS:
        runs[SMOOTH_CHAIN, treat] = _solve_continuum(
            "bsr_derived", q, t_end, 1, top if treat == "hybrid" else None, rec, sigma_width, 0.0
        )
    t = runs["longwave", "hybrid"][0]
    yd = _on_records(disc, t, fine)
    lab = {"units": "h"}
    data = {
        "y_discrete": (("time", "particle"), yd, {**lab, "long_name": "discrete y_i / h"}),
        "floor": (
            "time",
            cont.floor_position(q, t),
            {**lab, "long_name": "floor height y0 / h"},
        ),
    }
    dist = {}
    for (model, treat), (_, y, _sol) in runs.items():
        # BSR as printed stops once it has collapsed; its tracers then rest on the floor
        yy = np.full_like(yd, np.nan)
        yy[: y.shape[0]] = y
        dist[model, treat] = _distance(yy, yd)
        data[f"y_{model}_{treat}"] = (
            ("time", "particle"),
            yy,
            {**lab, "long_name": f"{MODEL_NAMES[model]}, {treat} top: particle heights / h"},
        )
    lw = runs["longwave", "hybrid"][2]
    data["y_longwave_field"] = (
        ("time", "label"),
        lw["y"],
        {**lab, "long_name": "long-wave (derived), hybrid top: height y(z, t) / h"},
    )
    bd = runs["bsr_derived", "hybrid"][2]
    data["rho_bsr_derived"] = (
        ("time", "height"),
        bd["rho"][: t.size],
        {"units": "m/h", "long_name": "BSR (derived), hybrid top: linear density"},
    )
    attrs = {
        "length_scale": sc.length,
        "time_scale": sc.time,
        "G": q.g,
        "tap_amplitude": q.a,
        "tap_duration": q.tap_duration,
        "period": q.T,
        "lw_refinement": int(lw_refinement),
        "bsr_refinement": int(bsr_refinement),
        "bsr_derived_refinement": int(bsr_derived_refinement),
        "bsr_kernel_width": float(bsr_kernel_width),
        "sigma_width": float(sigma_width),
        "N": q.N,
    }
    for (model, treat), (pos, disp, rel) in dist.items():
        attrs[f"rms_positions_{model}_{treat}"] = pos
        attrs[f"rms_displacements_{model}_{treat}"] = disp
        attrs[f"relative_displacements_{model}_{treat}"] = rel
    for treat in TOP_TREATMENTS:
        attrs[f"bsr_collapse_time_{treat}"] = float(runs["bsr", treat][2]["collapse_time"])
        attrs[f"bsr_derived_min_spacing_{treat}"] = runs["bsr_derived", treat][2]["min_spacing"]
    ds = xr.Dataset(
        data,
        coords={
            "time": ("time", t, {"units": "sqrt(m/K)", "long_name": "time"}),
            "particle": (
                "particle",
                np.arange(1, q.N + 1),
                {"units": "1", "long_name": "particle index"},
            ),
            "label": ("label", lw["z"], {**lab, "long_name": "Lagrangian label z / h"}),
            "height": ("height", bd["z"], {**lab, "long_name": "Eulerian height z / h"}),
        },
        attrs=attrs,
    )
    return ds, {f"{m}_{t}": v for (m, t), v in dist.items()}


def continuum_convergence(
    phys: Mapping,
    t_end: float,
    lw_refinements: Iterable[int],
    bsr_refinements: Iterable[int],
    bsr_t_end: float,
    sigma_width: float = 0.01,
    step_factor: float = 0.1,
    bsr_derived_refinements: Iterable[int] = (2, 4, 8, 16),
    bsr_kernel_width: float = cont.BSR_KERNEL_WIDTH,
    sigma_widths: Iterable[float] = (),
    sigma_scan_refinement: int = 4,
):
    """Every model and both tops under grid refinement, in chain units.

    For each model, top treatment and refinement k (Δz = h/k): the RMS distances to the
    discrete column (:func:`_distance`) and the successive difference
    e_k = max over records and particles of |y(h/k) − y(h/2k)|, with observed orders
    log2(e_k / e_2k). ``t_end`` (L-W, derived BSR) and ``bsr_t_end`` (BSR as printed) are
    in the units of ``phys``; BSR as printed stops when it has collapsed.

    The scan over ``sigma_widths`` solves L-W and the derived BSR at h/``sigma_scan_
    refinement`` and the chain with the smooth sign (:data:`SMOOTH_CHAIN`) over ``t_end``
    for each width w_σ: the distance of the smooth-sign chain is what the smoothing alone
    costs, the rest of a model's distance is its continuum limit.
    """
    p = physics(phys)
    q = cont.dimensionless(p)
    sc = cont.chain_scales(p)
    fine = q.T / 1000
    ends = {"longwave": t_end / sc.time, "bsr": bsr_t_end / sc.time}
    ends["bsr_derived"] = ends["longwave"]
    disc = _discrete_record(q, max(1, math.ceil(max(ends.values()) / q.T)), fine, step_factor)
    top = _discrete_top(q, disc)
    ks = {"longwave": sorted(int(k) for k in lw_refinements)}
    ks["bsr"] = sorted(int(k) for k in bsr_refinements)
    ks["bsr_derived"] = sorted(int(k) for k in bsr_derived_refinements)
    n_k = max(len(v) for v in ks.values())
    shape = (len(CONTINUUM_MODELS), len(TOP_TREATMENTS), n_k)
    fields = {
        k: np.full(shape, np.nan)
        for k in ("rms_positions", "rms_displacements", "relative_displacements", "error")
    }
    refine = np.full((len(CONTINUUM_MODELS), n_k), -1, dtype=np.int64)
    orders = {}
    for i, model in enumerate(CONTINUUM_MODELS):
        rec = ends[model] / 100
        refine[i, : len(ks[model])] = ks[model]
        for j, treat in enumerate(TOP_TREATMENTS):
            ys = []
            for n, k in enumerate(ks[model]):
                t, y, _ = _solve_continuum(
                    model, q, ends[model], k, top if treat == "hybrid" else None, rec,
                    sigma_width, bsr_kernel_width,
                )  # fmt: skip
                yd = _on_records(disc, t, fine)
                yy = np.full((int(round(ends[model] / rec)) + 1, q.N), np.nan)
                yy[: y.shape[0]] = y[: yy.shape[0]]
                if y.shape[0] < yy.shape[0]:  # collapsed BSR: tracers rest on the floor
                    tt = np.arange(yy.shape[0]) * rec
                    yy[y.shape[0] :] = cont.floor_position(q, tt[y.shape[0] :])[:, None]
                    yd = _on_records(disc, tt, fine)
                else:
                    yd = yd[: yy.shape[0]]
                (
                    fields["rms_positions"][i, j, n],
                    fields["rms_displacements"][i, j, n],
                    fields["relative_displacements"][i, j, n],
                ) = _distance(yy, yd)
                ys.append(yy)
            err = [float(np.max(np.abs(a - b))) for a, b in zip(ys[:-1], ys[1:], strict=True)]
            fields["error"][i, j, : len(err)] = err
            e = np.asarray(err)
            with np.errstate(divide="ignore", invalid="ignore"):
                orders[model, treat] = np.log2(e[:-1] / e[1:])
    dims = ("model", "top", "level")
    names = {
        "rms_positions": ("h", "RMS distance of particle heights to the discrete column"),
        "rms_displacements": ("h", "RMS distance of displacements from rest"),
        "relative_displacements": (
            "1",
            "RMS distance of displacements / RMS displacement of the discrete column",
        ),
        "error": ("h", "max |y(h/k) - y(h/2k)| over records and particles"),
    }
    data = {
        k: (dims, v, {"units": names[k][0], "long_name": names[k][1]}) for k, v in fields.items()
    }
    data["refinement"] = (
        ("model", "level"),
        refine,
        {"units": "1", "long_name": "h / dz (-1: not run)"},
    )
    widths = [float(w) for w in sigma_widths]
    scan_models = SIGMA_SCAN_MODELS
    scan = np.full((len(scan_models), len(TOP_TREATMENTS), len(widths)), np.nan)
    rec = ends["longwave"] / 100
    for i, model in enumerate(scan_models):
        for j, treat in enumerate(TOP_TREATMENTS):
            for n, w in enumerate(widths):
                args = (model, sigma_scan_refinement, bsr_kernel_width)
                if model == SMOOTH_CHAIN:
                    args = ("bsr_derived", 1, 0.0)
                t, y, _ = _solve_continuum(
                    args[0], q, ends["longwave"], args[1], top if treat == "hybrid" else None,
                    rec, w, args[2],
                )  # fmt: skip
                scan[i, j, n] = _distance(y, _on_records(disc, t, fine)[: y.shape[0]])[2]
    data["sigma_scan_relative_displacements"] = (
        ("scan_model", "top", "sigma_width"),
        scan,
        {"units": "1", "long_name": "relative displacement distance against the width w_σ"},
    )
    attrs = {
        "t_end": ends["longwave"],
        "bsr_t_end": ends["bsr"],
        "sigma_width": sigma_width,
        "bsr_kernel_width": float(bsr_kernel_width),
        "sigma_scan_refinement": int(sigma_scan_refinement),
    }
    for (model, treat), o in orders.items():
        attrs[f"orders_{model}_{treat}"] = " ".join(f"{x:.3f}" for x in o)
    return xr.Dataset(
        data,
        coords={
            "model": (
                "model",
                list(CONTINUUM_MODELS),
                {"units": "1", "long_name": "continuum model"},
            ),
            "top": (
                "top",
                list(TOP_TREATMENTS),
                {"units": "1", "long_name": "top boundary treatment"},
            ),
            "level": ("level", np.arange(n_k), {"units": "1", "long_name": "refinement level"}),
            "scan_model": ("scan_model", list(scan_models), {"units": "1", "long_name": "model"}),
            "sigma_width": (
                "sigma_width",
                widths,
                {"units": "h sqrt(K/m)", "long_name": "width of the smooth sign"},
            ),
        },
        attrs=attrs,
    )
