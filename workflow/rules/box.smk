# box study (docs/box.md): stages init -> runs -> ensemble -> fits -> figures.
# Rules only call `granpipe box <stage>`; params carry the exact config subset each stage
# depends on (granpipe.box.layout.*_params), so a config edit reruns exactly what it
# touches: physics/init -> everything (grid.mu_side_walls, physics.side_walls and
# physics.wall_torque: the points of each value; the side walls' drive is not part of the
# prepared states); protocol -> runs onwards (measured_periods only adds or drops whole
# parts); detection/slips/order -> ensemble onwards; fits -> fits, figures.
# Point lists come from granpipe.box.layout, the same functions `granpipe status` uses.

from granpipe.box import layout as box_layout

if "box" in config:
    BOX = config["box"]
    BOX_ENSEMBLE_FILES = [out("box", f) for f in box_layout.ensemble_files(BOX)]
    BOX_INIT_FILES = [out("box", f) for f in box_layout.init_files(BOX)]
    # a point's and a prepared state's folder names as wildcards (box_layout.point_name,
    # box_layout.state_name fill them)
    BOX_POINT = "N_l={box_nl},Gamma={box_gamma},init={box_init},mu_w={box_mu_w},walls={box_side},torque={box_torque}"
    BOX_STATE = "N_l={box_nl},init={box_init},mu_w={box_mu_w},torque={box_torque}"

    wildcard_constraints:
        box_nl=r"\d+",
        box_gamma=r"[0-9.]+(e[-+]?[0-9]+)?",
        box_init=r"crystal|random",
        # one wildcard per key: Snakemake's --target-jobs (how a cluster job names its
        # jobs) splits wildcards at commas, so no wildcard value may hold one
        box_mu_w=r"[0-9.]+(e[-+]?[0-9]+)?",
        box_side=r"shaken|still",
        box_torque=r"lever|none",
        box_rep=r"\d{4}",
        box_part=r"\d{3}",

    rule box_init:
        """Crystal (relaxed lattice) or random (placement, fall, settle) initial state."""
        output:
            out("box", "init", BOX_STATE, "replica_{box_rep}.nc"),
        params:
            json=lambda w: as_json(
                box_layout.init_params(BOX, box_layout.Walls.of_state(w))
            ),
        conda:
            "../envs/granpipe.yaml"
        log:
            log_path("box", "init", BOX_STATE, "replica_{box_rep}.log"),
        threads: 1
        resources:
            runtime=lambda w: box_layout.sim_minutes(BOX, int(w.box_nl), 0),
            mem_mb=BOX["resources"]["mem_mb"],
        group:
            "box_sim"
        shell:
            "granpipe box init --params {params.json:q} --N-l {wildcards.box_nl}"
            " --init {wildcards.box_init} --replica {wildcards.box_rep}"
            " --out {output:q} > {log:q} 2>&1"

    rule box_runs:
        """One part of a point: ramp and transient (part 0), measured periods, recording."""
        input:
            unpack(
                lambda w: {
                    k: out("box", v) for k, v in box_layout.run_inputs(BOX, w).items()
                }
            ),
        output:
            out(
                "box",
                "runs",
                BOX_POINT,
                "replica_{box_rep}.part_{box_part}.nc",
            ),
        params:
            json=lambda w: as_json(
                box_layout.runs_params(
                    BOX, int(w.box_part), box_layout.Walls.of_point(w)
                )
            ),
            previous=lambda w, input: (
                ["--previous", input.previous] if "previous" in input.keys() else []
            ),
        conda:
            "../envs/granpipe.yaml"
        log:
            log_path(
                "box",
                "runs",
                BOX_POINT,
                "replica_{box_rep}.part_{box_part}.log",
            ),
        threads: 1
        resources:
            runtime=lambda w: box_layout.sim_minutes(BOX, int(w.box_nl), int(w.box_part)),
            mem_mb=BOX["resources"]["mem_mb"],
        group:
            "box_sim"
        shell:
            "granpipe box runs --params {params.json:q} --N-l {wildcards.box_nl}"
            " --Gamma {wildcards.box_gamma} --init {wildcards.box_init}"
            " --replica {wildcards.box_rep} --part {wildcards.box_part}"
            " --init-file {input.init:q} {params.previous:q} --out {output:q} > {log:q} 2>&1"

    rule box_ensemble:
        """Detection (s_c, s_b, detachment), T_g, slips and ψ6 of one point."""
        input:
            runs=lambda w: [
                out("box", f)
                for f in box_layout.point_run_files(
                    BOX,
                    int(w.box_nl),
                    float(w.box_gamma),
                    w.box_init,
                    box_layout.Walls.of_point(w),
                )
            ],
        output:
            out("box", "ensemble", f"{BOX_POINT}.nc"),
        params:
            # from the wildcards, not the output: Snakemake leaves params derived from the
            # output out of its params trigger, so a detection edit would rerun nothing
            json=lambda w: as_json(box_layout.ensemble_params(BOX, BOX_POINT.format(**dict(w.items())))),
        conda:
            "../envs/granpipe.yaml"
        log:
            log_path("box", "ensemble", f"{BOX_POINT}.log"),
        threads: 1
        resources:
            runtime=10,
            mem_mb=2000,
        shell:
            "granpipe box ensemble --params {params.json:q} --out {output:q} {input.runs:q}"
            " > {log:q} 2>&1"

    rule box_fits:
        """Thresholds in Γ, segmented T_g* regions, Arrhenius barriers; summary.csv."""
        input:
            BOX_ENSEMBLE_FILES,
        output:
            *[out("box", f) for f in box_layout.fit_files() if f != "fits/summary.csv"],
            summary=report(
                out("box", "fits", "summary.csv"),
                category="box",
                subcategory="summary",
                caption="../report/box_summary.rst",
            ),
        params:
            json=lambda w: as_json(box_layout.fits_params(BOX)),
            outdir=lambda w: out("box", "fits"),
        conda:
            "../envs/granpipe.yaml"
        log:
            log_path("box", "fits.log"),
        threads: 1
        resources:
            runtime=15,
            mem_mb=2000,
        shell:
            "granpipe box fits --params {params.json:q} --out-dir {params.outdir:q}"
            " {input:q} > {log:q} 2>&1"

    rule box_figures:
        """Figures 1, 3, 4 and 5 of the paper and the thresholds against the side walls' friction
        (PNG for the report, PDF beside them)."""
        input:
            fits=rules.box_fits.output,
            init=BOX_INIT_FILES,
            ensemble=BOX_ENSEMBLE_FILES,
        output:
            fig1=report(
                out("box", "figures", "fig1_snapshots.png"),
                category="box",
                caption="../report/box_fig1.rst",
            ),
            fig3=report(
                out("box", "figures", "fig3_phase_diagram.png"),
                category="box",
                caption="../report/box_fig3.rst",
            ),
            fig4=report(
                out("box", "figures", "fig4_granular_temperature.png"),
                category="box",
                caption="../report/box_fig4.rst",
            ),
            fig5=report(
                out("box", "figures", "fig5_slip_probability.png"),
                category="box",
                caption="../report/box_fig5.rst",
            ),
            fig6=report(
                out("box", "figures", "fig6_walls.png"),
                category="box",
                caption="../report/box_fig6.rst",
            ),
            fig7=report(
                out("box", "figures", "fig7_onset_record.png"),
                category="box",
                caption="../report/box_fig7.rst",
            ),
            pdf=[out("box", f) for f in box_layout.figure_files("pdf")],
        params:
            json=lambda w: as_json(box_layout.figures_params(BOX)),
            fitsdir=lambda w: out("box", "fits"),
            outdir=lambda w: out("box", "figures"),
            inits=lambda w, input: [a for f in input.init for a in ("--init-file", f)],
        conda:
            "../envs/granpipe.yaml"
        log:
            log_path("box", "figures.log"),
        threads: 1
        resources:
            runtime=10,
            mem_mb=2000,
        shell:
            "granpipe box figures --params {params.json:q} --fits-dir {params.fitsdir:q}"
            " --out-dir {params.outdir:q} {params.inits:q} {input.ensemble:q} > {log:q} 2>&1"

    rule box_movie:
        """The report's movies: one replica over the last periods of its record, one per
        start (docs/watching.md)."""
        output:
            report(out("box", "movie", f"{BOX_POINT}.{BOX['movie']['format']}"),
                   category="box", subcategory="movie", caption="../report/box_movie.rst"),
        params:
            json=lambda w: as_json(box_layout.movie_params(BOX, BOX_POINT.format(**dict(w.items())))),
        conda:
            "../envs/granpipe.yaml"
        log:
            log_path("box", "movie", f"{BOX_POINT}.log"),
        threads: 1
        resources:
            runtime=lambda w: box_layout.sim_minutes(BOX, int(w.box_nl), 0)
            * (box_layout.n_parts(BOX) + 1),
            mem_mb=2000,
        shell:
            "granpipe box movie --params {params.json:q} --out {output:q} > {log:q} 2>&1"

    # run files are targets too: a plain rerun recomputes any that a killed job removed
    register_targets(
        "box",
        lambda: [
            *[out("box", box_layout.movie_file(BOX, p)) for p in box_layout.movie_points(BOX)
              if BOX["movie"]["enabled"]],
            *rules.box_figures.output,
            out("box", "fits", "summary.csv"),
            *[out("box", f) for f in box_layout.run_files(BOX)],
        ],
    )
