"""Config subsets and file names of the column workflow (used by workflow/rules/column.smk).

Each ``*_params`` function returns exactly the config subset one rule depends on (schema
defaults filled), so Snakemake's parameter trigger reruns only what an edit touches;
:func:`rule_params` gathers them per rule, as the rule file reads them.
"""

from __future__ import annotations

from collections.abc import Mapping

__all__ = [
    "check",
    "FIGURES",
    "step_factor",
    "units",
    "figure_sets",
    "trajectory_params",
    "relaxation_batches",
    "n_relaxation_batches",
    "relaxation_params",
    "chaos_points",
    "chaos_params",
    "chaos_point_params",
    "continuum_params",
    "ensemble_params",
    "input_hashes",
    "fits_params",
    "figures_params",
    "rule_params",
]

FIGURES = (
    "fig1_trajectories",
    "fig2_continuum",
    "fig3_density_relaxation",
    "fig4_chaos_map",
    "fig5_continuum_convergence",
    "fig6_lyapunov_estimates",
)


def check(cfg: Mapping) -> None:
    """Cross-key checks of a ``column`` section before any job runs (ConfigError names
    the key): every column physical (:func:`_check_columns`), each refinement of the
    convergence study a multiple of the one before, so that the coarse nodes lie on every
    finer grid, and the return-map window of the chaos points inside the measured taps,
    holding every phase of the longest period twice."""
    from ..errors import ConfigError

    _check_columns(cfg)
    chaos = cfg.get("chaos", {})
    p_max = int(chaos.get("return_max_period", 6))
    window = int(chaos.get("return_taps", 12))
    taps = int(chaos.get("taps", 15))
    if window > taps:
        raise ConfigError(
            f"config key 'column.chaos.return_taps' = {window} exceeds 'column.chaos.taps' = "
            f"{taps}: the return-map states are those at the end of the measured taps"
        )
    if window < 2 * p_max:
        raise ConfigError(
            f"config key 'column.chaos.return_max_period' = {p_max} needs "
            f"'column.chaos.return_taps' >= {2 * p_max} (got {window}): the window must hold "
            "every phase of the longest period at least twice"
        )

    cont = cfg.get("continuum", {})
    conv = cont.get("convergence", {})
    for key in ("lw_refinements", "bsr_refinements", "bsr_derived_refinements"):
        ks = [int(k) for k in conv.get(key, [])]
        for a, b in zip(ks[:-1], ks[1:], strict=False):
            if b <= a or b % a:
                raise ConfigError(
                    f"config key 'column.continuum.convergence.{key}' = {ks}: each entry must "
                    "be a multiple of the one before (nested grids)"
                )


MIN_RELAXATION_N = 20
"""The fewest particles of the relaxation column: the generic set of docs/column.md
("N ≥ 20"); a shorter column has no bulk whose density relaxes."""

BYTES_PER_PARTICLE = 1024
"""A generous bound on a column job's memory per particle (state, RK4 stages, tangent
vectors, return-map states), besides 16 bytes per particle and recorded sample."""


def _check_columns(cfg: Mapping) -> None:
    """Every physics block makes a column (:class:`granpipe.column.model.ColumnParams`:
    a period longer than the tap, Eq. 2; an equilibrium stack, Eq. 28: K > N m g / r,
    i.e. ``stiffness_factor`` > 1), the chaos grid's periods too; the relaxation column
    has at least :data:`MIN_RELAXATION_N` particles; the plan and each job's memory fit
    (ConfigError names the key and the constraint)."""
    from ..config import check_memory, check_plan
    from ..errors import ConfigError
    from .model import equilibrium_positions, physics

    def column(key, phys, samples=0):
        check_memory(f"{key}.N", phys["N"], int(phys["N"]) * (BYTES_PER_PARTICLE + 16 * samples))
        try:
            equilibrium_positions(physics(phys))
        except ConfigError as exc:
            raise ConfigError(f"config key '{key}': {exc}") from None

    # the plan first, counted rather than listed: a grid or a batch count too large to plan
    # is refused before anything loops over it
    runs, chaos = cfg["relaxation"], cfg["chaos"]
    n_batches = n_relaxation_batches(cfg)
    n_chaos = len(chaos["amplitudes"]) * len(chaos["periods"])
    key, remedy = (
        ("column.relaxation.n_replicas", "raise 'column.relaxation.batch_size'")
        if n_batches >= n_chaos
        else ("column.chaos.amplitudes", "list fewer amplitudes or periods in the chaos grid")
    )
    check_plan(key, len(cfg["figure1"]["sets"]) + n_batches + n_chaos + 2, remedy)
    fig1 = cfg["figure1"]
    for name, phys in fig1["sets"].items():
        samples = int(fig1.get("n_taps", 4) * phys["T"] / fig1.get("record_dt", 0.001)) + 1
        column(f"column.figure1.sets.{name}", phys, samples)
    relax = runs["physics"]
    column("column.relaxation.physics", relax)
    # each replica's samples, (n_taps, N), and the batch's heights and densities per tap
    taps = int(runs.get("n_taps", 100)) + 1
    need = 16 * taps * (int(relax["N"]) + 2 * int(runs.get("batch_size", 4)))
    check_memory("column.relaxation.n_taps", runs.get("n_taps", 100), need)
    if int(relax["N"]) < MIN_RELAXATION_N:
        raise ConfigError(
            f"config key 'column.relaxation.physics.N' = {relax['N']}: the relaxation column "
            f"needs N >= {MIN_RELAXATION_N} (the generic set, docs/column.md)"
        )
    for a in chaos["amplitudes"]:
        for t in chaos["periods"]:
            column("column.chaos.periods", {**chaos["physics"], "a": a, "T": t})
    cont = cfg["continuum"]
    conv = cont.get("convergence", {})
    finest = max([int(cont.get(k, 16)) for k in ("lw_refinement", "bsr_refinement")]
                 + [int(k) for k in conv.get("lw_refinements", [64])])  # fmt: skip
    samples = int(cont.get("n_taps", 4) * cont["physics"]["T"] / cont.get("record_dt", 0.01)) + 1
    column("column.continuum.physics", cont["physics"], samples * finest)


def step_factor(cfg: Mapping) -> float:
    return float(cfg.get("integrator", {}).get("step_factor", 0.1))


def units(cfg: Mapping) -> dict:
    return {
        "length": "m",
        "time": "s",
        "fig2_length": "cm",
        "fig2_time": "s",
        **cfg.get("units", {}),
    }


def figure_sets(cfg: Mapping) -> list[str]:
    """Names of the figure-1 columns, ordered by N (the paper: N = 5 left, N = 10 right)."""
    sets = cfg["figure1"]["sets"]
    return sorted(sets, key=lambda name: (sets[name]["N"], name))


def trajectory_params(cfg: Mapping, name: str) -> dict:
    f = cfg["figure1"]
    return {
        "sets": {name: f["sets"][name]},
        "n_taps": f.get("n_taps", 4),
        "record_dt": f.get("record_dt", 0.001),
        "step_factor": step_factor(cfg),
    }


def n_relaxation_batches(cfg: Mapping) -> int:
    """Whole batches covering n_replicas (batches are always full)."""
    r = cfg["relaxation"]
    return -(-int(r.get("n_replicas", 8)) // int(r.get("batch_size", 4)))


def relaxation_batches(cfg: Mapping) -> list[str]:
    """Batch ids 0000, 0001, … (:func:`n_relaxation_batches` of them)."""
    return [f"{b:04d}" for b in range(n_relaxation_batches(cfg))]


def relaxation_params(cfg: Mapping) -> dict:
    r = cfg["relaxation"]
    return {
        "physics": r["physics"],
        "n_taps": r.get("n_taps", 100),
        "batch_size": r.get("batch_size", 4),
        "perturbation": r.get("perturbation", 1.0),
        "step_factor": step_factor(cfg),
    }


def chaos_points(cfg: Mapping) -> list[str]:
    """Point names ``a=<a>,T=<T>`` of the chaos grid."""
    c = cfg["chaos"]
    return [f"a={a:g},T={t:g}" for a in c["amplitudes"] for t in c["periods"]]


def chaos_params(cfg: Mapping) -> dict:
    c = cfg["chaos"]
    defaults = {
        "n_replicas": 4,
        "transient_taps": 3,
        "taps": 15,
        "perturbation": 1.0,
        "twin_epsilon": 1.0e-9,
        "plain": True,
        "return_max_period": 6,
        "return_taps": 12,
        "return_tolerance": 1.0e-6,
    }
    return {
        "physics": c["physics"],
        **{k: c.get(k, v) for k, v in defaults.items()},
        "step_factor": step_factor(cfg),
    }


def continuum_params(cfg: Mapping, with_convergence: bool = False) -> dict:
    c = cfg["continuum"]
    p = {
        "physics": c["physics"],
        "sigma_width": c.get("sigma_width", 0.01),
        "bsr_kernel_width": c.get("bsr_kernel_width", 1.0),
        "step_factor": step_factor(cfg),
    }
    if with_convergence:
        p["convergence"] = {
            "t_end": 1.0,
            "lw_refinements": [2, 4, 8, 16, 32, 64],
            "bsr_refinements": [2, 4, 8, 16, 32],
            "bsr_t_end": 0.1,
            "bsr_derived_refinements": [2, 4, 8, 16, 32],
            "sigma_widths": [0.01, 0.001, 0.0001],
            "sigma_scan_refinement": 4,
            **c.get("convergence", {}),
        }
    else:
        defaults = {
            "n_taps": 4,
            "lw_refinement": 16,
            "bsr_refinement": 4,
            "bsr_derived_refinement": 8,
            "record_dt": 0.01,
        }
        p.update({k: c.get(k, v) for k, v in defaults.items()})
    return p


def chaos_point_params(cfg: Mapping, point: str) -> dict:
    """The config subset a chaos point's file records: :func:`chaos_params` with the
    point's a and T in its physics, as the rule passes them (the values of its name)."""
    a, t = (float(v.split("=")[1]) for v in point.split(","))
    p = chaos_params(cfg)
    return {**p, "physics": {**p["physics"], "a": a, "T": t}}


def ensemble_params(cfg: Mapping, kind: str) -> dict:
    """Config subset of an ensemble rule, with the config hashes of the files it reduces
    (each stage checks its inputs against them): the relaxation batches' for the
    relaxation (``runs_config_hash``), each point's and the interval's confidence for the
    chaos map (``points``: name -> hash)."""
    from ..io import config_hash

    if kind == "relaxation":
        return {"kind": "relaxation", "runs_config_hash": config_hash(relaxation_params(cfg))}
    if kind == "chaos":
        return {
            "confidence": cfg["chaos"].get("confidence", 0.95),
            "points": {pt: config_hash(chaos_point_params(cfg, pt)) for pt in chaos_points(cfg)},
        }
    raise ValueError(f"kind must be 'relaxation' or 'chaos', got {kind!r}")


def input_hashes(cfg: Mapping, trajectories: bool = False) -> dict:
    """The config hashes of the files the fits (and, with ``trajectories``, the figures)
    read: the two ensembles, the continuum comparison and convergence runs, and each
    figure-1 column's trajectories (by name)."""
    from ..io import config_hash

    out = {
        "relaxation": config_hash(ensemble_params(cfg, "relaxation")),
        "chaos": config_hash(ensemble_params(cfg, "chaos")),
        "continuum": config_hash(continuum_params(cfg)),
        "convergence": config_hash(continuum_params(cfg, True)),
    }
    if trajectories:
        out["trajectories"] = {
            name: config_hash(trajectory_params(cfg, name)) for name in figure_sets(cfg)
        }
    return out


def fits_params(cfg: Mapping) -> dict:
    """Config subset of the fits rule: the bootstrap, the unit names and the config hashes
    of its inputs (:func:`input_hashes`)."""
    return {
        "n_boot": cfg["relaxation"].get("n_boot", 1000),
        "units": units(cfg),
        "inputs": input_hashes(cfg),
    }


def figures_params(cfg: Mapping) -> dict:
    """Config subset of the figures rule: the unit names and the config hashes of its
    inputs."""
    return {"units": units(cfg), "inputs": input_hashes(cfg, trajectories=True)}


def rule_params(cfg: Mapping) -> dict[str, dict]:
    """The config subset each column rule depends on (its ``params:``).

    Keys are the rules' names without ``column_``: ``trajectories`` (a subset per
    figure-1 column, by name), ``relaxation``, ``chaos``, ``continuum``, ``convergence``,
    ``ensemble_relaxation``, ``ensemble_chaos``, ``fits`` and ``figures``.
    """
    return {
        "trajectories": {name: trajectory_params(cfg, name) for name in figure_sets(cfg)},
        "relaxation": relaxation_params(cfg),
        "chaos": chaos_params(cfg),
        "continuum": continuum_params(cfg),
        "convergence": continuum_params(cfg, True),
        "ensemble_relaxation": ensemble_params(cfg, "relaxation"),
        "ensemble_chaos": ensemble_params(cfg, "chaos"),
        "fits": fits_params(cfg),
        "figures": figures_params(cfg),
    }


def run_files(cfg: Mapping) -> list[str]:
    """Every simulation output a config section asks for, relative to
    ``results/<scale>/column/`` (what ``granpipe status`` counts; column.smk writes these)."""
    return [
        *(f"runs/trajectories_{s}.nc" for s in figure_sets(cfg)),
        *(f"runs/relaxation/batch_{b}.nc" for b in relaxation_batches(cfg)),
        *(f"runs/chaos/{pt}.nc" for pt in chaos_points(cfg)),
        "runs/continuum.nc",
        "runs/convergence.nc",
    ]
