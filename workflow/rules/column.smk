# column study (SPEC.md §2): runs -> ensemble -> fits -> figures (no init stage: the start is
# the closed-form equilibrium of Eq. 27, perturbed per replica inside the runs).
# Rules only call `granpipe column <stage>`; params carry the exact config subset each rule
# depends on, so an edit reruns what it touches: a figure-1 column reruns its trajectory;
# relaxation physics/n_taps/batch_size/perturbation rerun the relaxation batches, n_replicas
# only adds batches; chaos physics and settings rerun the points, the grids add or drop
# points; confidence -> chaos map onwards; n_boot/units -> fits and figures.


import shlex


def _column_cfg():
    return config.get("column", {})


COLUMN = _column_cfg()
COLUMN_STEP = COLUMN.get("integrator", {}).get("step_factor", 0.1)
COLUMN_UNITS = {
    "length": "m", "time": "s", "fig2_length": "cm", "fig2_time": "s",
    **COLUMN.get("units", {}),
}


def column_sets():
    sets = COLUMN["figure1"]["sets"] if enabled("column") else {}
    return sorted(sets, key=lambda name: (sets[name]["N"], name))


def column_relaxation_batches():
    r = COLUMN["relaxation"]
    return batch_ids(r.get("n_replicas", 8), r.get("batch_size", 4))


def column_chaos_points():
    c = COLUMN["chaos"]
    return [f"a={a:g},T={t:g}" for a in c["amplitudes"] for t in c["periods"]]


def column_relaxation_params():
    r = COLUMN["relaxation"]
    return {
        "physics": r["physics"],
        "n_taps": r.get("n_taps", 100),
        "batch_size": r.get("batch_size", 4),
        "perturbation": r.get("perturbation", 1.0),
        "step_factor": COLUMN_STEP,
    }


def column_chaos_params():
    c = COLUMN["chaos"]
    keys = ("n_replicas", "transient_taps", "taps", "perturbation", "twin_epsilon", "plain")
    defaults = (4, 3, 15, 1.0, 1.0e-9, True)
    return {
        "physics": c["physics"],
        **{k: c.get(k, v) for k, v in zip(keys, defaults)},
        "step_factor": COLUMN_STEP,
    }


def column_continuum_params(with_convergence=False):
    c = COLUMN["continuum"]
    p = {
        "physics": c["physics"],
        "viscosity": c.get("viscosity", "dissipative"),
        "step_factor": COLUMN_STEP,
    }
    if with_convergence:
        p["convergence"] = {
            "t_end": 1.0, "lw_refinements": [2, 4, 8, 16, 32, 64],
            "bsr_refinements": [2, 4, 8, 16, 32], "bsr_t_end": 0.1,
            **c.get("convergence", {}),
        }
    else:
        p.update({k: c.get(k, v) for k, v in
                  (("n_taps", 4), ("lw_dz", 0.25), ("bsr_dz", 0.25), ("record_dt", 0.01))})
    return p


wildcard_constraints:
    column_batch=r"\d{4}",
    column_set=r"[A-Za-z0-9_]+",
    column_a=r"[0-9.e+-]+",
    column_T=r"[0-9.e+-]+",


rule column_trajectories:
    """Fig. 1 data: y_i(t) of one figure-1 column over the configured taps."""
    output:
        out("column", "runs", "trajectories_{column_set}.nc"),
    params:
        json=lambda w: as_json({
            "sets": {w.column_set: COLUMN["figure1"]["sets"][w.column_set]},
            "n_taps": COLUMN["figure1"].get("n_taps", 4),
            "record_dt": COLUMN["figure1"].get("record_dt", 0.001),
            "step_factor": COLUMN_STEP,
        }),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "trajectories_{column_set}.log"),
    threads: 1
    resources:
        runtime=5,
        mem_mb=1000,
    group:
        "column_small"
    shell:
        "granpipe column trajectories --params {params.json:q} --set {wildcards.column_set}"
        " --out {output:q} > {log:q} 2>&1"


rule column_relaxation:
    """Density relaxation: one batch of perturbed starts over many taps."""
    output:
        out("column", "runs", "relaxation", "batch_{column_batch}.nc"),
    params:
        json=lambda w: as_json(column_relaxation_params()),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "relaxation_{column_batch}.log"),
    threads: 1
    resources:
        runtime=lambda w: int(5 + 0.01 * column_relaxation_params()["n_taps"]
                              * column_relaxation_params()["batch_size"]),
        mem_mb=1000,
    shell:
        "granpipe column relaxation --params {params.json:q} --batch {wildcards.column_batch}"
        " --out {output:q} > {log:q} 2>&1"


rule column_chaos:
    """One (a, T) point of the chaos map: ensemble of largest Lyapunov exponents."""
    output:
        out("column", "runs", "chaos", "a={column_a},T={column_T}.nc"),
    params:
        json=lambda w: as_json(column_chaos_params()),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "chaos_a={column_a},T={column_T}.log"),
    threads: 1
    resources:
        runtime=lambda w: int(5 + 0.05 * column_chaos_params()["n_replicas"]
                              * column_chaos_params()["taps"]),
        mem_mb=1000,
    group:
        "column_chaos"
    shell:
        "granpipe column chaos --params {params.json:q} --a {wildcards.column_a}"
        " --T {wildcards.column_T} --out {output:q} > {log:q} 2>&1"


rule column_continuum:
    """Fig. 2 data: discrete column, long-wave and BSR solutions, their distances."""
    output:
        out("column", "runs", "continuum.nc"),
    params:
        json=lambda w: as_json(column_continuum_params()),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "continuum.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    shell:
        "granpipe column continuum --params {params.json:q} --out {output:q} > {log:q} 2>&1"


rule column_convergence:
    """Both continuum solvers under grid refinement on the Fig. 2 problem."""
    output:
        out("column", "runs", "convergence.nc"),
    params:
        json=lambda w: as_json(column_continuum_params(with_convergence=True)),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "runs", "convergence.log"),
    threads: 1
    resources:
        runtime=20,
        mem_mb=2000,
    shell:
        "granpipe column convergence --params {params.json:q} --out {output:q} > {log:q} 2>&1"


rule column_ensemble_relaxation:
    """Relaxation batches -> per-tap mean, spread, standard error, count."""
    input:
        lambda w: [out("column", "runs", "relaxation", f"batch_{b}.nc")
                   for b in column_relaxation_batches()],
    output:
        out("column", "ensemble", "relaxation.nc"),
    params:
        json=lambda w: as_json({"kind": "relaxation"}),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "ensemble", "relaxation.log"),
    threads: 1
    resources:
        runtime=5,
        mem_mb=2000,
    shell:
        "granpipe column ensemble --params {params.json:q} --kind relaxation"
        " --out {output:q} {input:q} > {log:q} 2>&1"


rule column_ensemble_chaos:
    """Chaos points -> the (a, T) map with t-intervals and the chaotic/regular flags."""
    input:
        lambda w: [out("column", "runs", "chaos", f"{pt}.nc") for pt in column_chaos_points()],
    output:
        out("column", "ensemble", "chaos_map.nc"),
    params:
        json=lambda w: as_json({"confidence": COLUMN["chaos"].get("confidence", 0.95)}),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "ensemble", "chaos_map.log"),
    threads: 1
    resources:
        runtime=5,
        mem_mb=2000,
    shell:
        "granpipe column ensemble --params {params.json:q} --kind chaos"
        " --out {output:q} {input:q} > {log:q} 2>&1"


rule column_fits:
    """Relaxation fit, chaos thresholds and the Theorem 1 note, continuum distances."""
    input:
        relaxation=rules.column_ensemble_relaxation.output[0],
        chaos=rules.column_ensemble_chaos.output[0],
        continuum=rules.column_continuum.output[0],
        convergence=rules.column_convergence.output[0],
    output:
        nc=out("column", "fits", "column_fits.nc"),
        summary=out("column", "fits", "summary.csv"),
        note=report(
            out("column", "fits", "theorem1_and_continuum.md"),
            category="column",
            caption="../report/column_note.rst",
        ),
    params:
        json=lambda w: as_json({
            "n_boot": COLUMN["relaxation"].get("n_boot", 1000),
            "units": COLUMN_UNITS,
        }),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "fits.log"),
    threads: 1
    resources:
        runtime=5,
        mem_mb=2000,
    shell:
        "granpipe column fits --params {params.json:q} --relaxation {input.relaxation:q}"
        " --chaos {input.chaos:q} --continuum {input.continuum:q}"
        " --convergence {input.convergence:q} --out-csv {output.summary:q}"
        " --out-nc {output.nc:q} --out-note {output.note:q} > {log:q} 2>&1"


COLUMN_FIGURES = (
    ("fig1_trajectories", "Paper Fig. 1: particle trajectories of the tapped columns."),
    ("fig2_continuum", "Paper Fig. 2: L-W and BSR beside the discrete column."),
    ("fig3_density_relaxation", "Density relaxation against tap number."),
    ("fig4_chaos_map", "Largest Lyapunov exponent over (a, T)."),
    ("fig5_continuum_convergence", "Continuum solvers under refinement."),
    ("fig6_lyapunov_estimates", "Saltation tangent vs twins vs plain variational."),
)


rule column_figures:
    """Figures 1-6 (PNG for the report, PDF beside them)."""
    input:
        trajectories=lambda w: [out("column", "runs", f"trajectories_{s}.nc")
                                for s in column_sets()],
        continuum=rules.column_continuum.output[0],
        relaxation=rules.column_ensemble_relaxation.output[0],
        chaos=rules.column_ensemble_chaos.output[0],
        convergence=rules.column_convergence.output[0],
    output:
        png=[report(out("column", "figures", f"{name}.png"), category="column",
                    caption=f"../report/column_{name.split('_')[0]}.rst")
             for name, _ in COLUMN_FIGURES],
        pdf=[out("column", "figures", f"{name}.pdf") for name, _ in COLUMN_FIGURES],
    params:
        json=lambda w: as_json({"units": COLUMN_UNITS}),
        outdir=lambda w, output: str(Path(output.png[0]).parent),
        traj=lambda w, input: " ".join(f"--trajectories {shlex.quote(p)}" for p in input.trajectories),
    conda:
        "../envs/granpipe.yaml"
    log:
        log_path("column", "figures.log"),
    threads: 1
    resources:
        runtime=10,
        mem_mb=2000,
    shell:
        "granpipe column figures --params {params.json:q} {params.traj}"
        " --continuum {input.continuum:q} --relaxation {input.relaxation:q}"
        " --chaos {input.chaos:q} --convergence {input.convergence:q}"
        " --outdir {params.outdir:q} > {log:q} 2>&1"


if enabled("column"):
    register_targets(
        "column",
        lambda: [
            *rules.column_figures.output,
            rules.column_fits.output.summary,
            rules.column_fits.output.note,
        ],
    )
