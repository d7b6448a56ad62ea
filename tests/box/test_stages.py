"""Every stage of the box study, file to file, on a tiny system (30 disks in Lx = 6).

The same functions the CLI calls: init -> runs (two chained parts) -> ensemble -> fits ->
figures, at two side-wall frictions; checks what each file must hold and that a stage
refuses a file that is not its input, not the physics (test_physics.py does that).
"""

import re

import numpy as np
import pandas as pd
import pytest

from granpipe.analysis.summary import COLUMNS, read_summary
from granpipe.box import layout, stages
from granpipe.io import RunFileError, config_from_attrs, read_dataset

W6 = layout.Walls(0.6, "shaken", "lever")
W0 = layout.Walls(0.0, "shaken", "lever")


@pytest.fixture(scope="module")
def pipeline(tmp_path_factory):
    from .conftest import SECTION

    sec = {**SECTION}
    sec["fits"] = {**SECTION["fits"], "breakpoints_random": 0, "breakpoints_crystal": 0}
    sec["grid"] = {**SECTION["grid"], "Gamma": [0.7, 1.4, 2.0], "mu_side_walls": [0.6, 0.0]}
    sec["protocol"] = {**SECTION["protocol"], "ramp_periods": 0.5, "transient_periods": 1}
    root = tmp_path_factory.mktemp("box")
    for n_l, init, walls in layout.init_states(sec):
        out = root / layout.init_file(n_l, init, walls, 0)
        stages.init_stage(layout.init_params(sec, walls), n_l, init, 0, out, log=None)
    for n_l, gamma, init, walls in layout.points(sec):
        for part in range(layout.n_parts(sec)):
            prev = root / layout.run_file(n_l, gamma, init, walls, 0, part - 1) if part else None
            stages.runs_stage(
                layout.runs_params(sec, part, walls), n_l, gamma, init, 0, part,
                root / layout.init_file(n_l, init, walls, 0),
                root / layout.run_file(n_l, gamma, init, walls, 0, part), previous=prev,
                log=None,
            )  # fmt: skip
        stages.ensemble_stage(
            layout.ensemble_params(sec, layout.point_name(n_l, gamma, init, walls)),
            [root / f for f in layout.point_run_files(sec, n_l, gamma, init, walls)],
            root / layout.ensemble_file(n_l, gamma, init, walls),
            log=None,
        )
    ens = [root / f for f in layout.ensemble_files(sec)]
    stages.fits_stage(layout.fits_params(sec), ens, root / "fits", log=None)
    stages.figures_stage(
        layout.figures_params(sec), root / "fits", [root / f for f in layout.init_files(sec)],
        ens, root / "figures", log=None,
    )  # fmt: skip
    return sec, root


def test_every_file_of_the_layout_exists(pipeline):
    sec, root = pipeline
    for rel in [
        *layout.init_files(sec), *layout.run_files(sec), *layout.ensemble_files(sec),
        *layout.fit_files(), *layout.figure_files("png"), *layout.figure_files("pdf"),
    ]:  # fmt: skip
        assert (root / rel).is_file(), rel


def test_run_files_chain_and_carry_their_config(pipeline):
    sec, root = pipeline
    p0 = read_dataset(root / layout.run_file(5, 2.0, "crystal", W6, 0, 0))
    p1 = read_dataset(root / layout.run_file(5, 2.0, "crystal", W6, 0, 1))
    assert config_from_attrs(p1) == layout.runs_params(sec, 1, W6)
    assert list(p0["period"].values) == [0] and list(p1["period"].values) == [1]
    np.testing.assert_array_equal(p0["positions"].values[-1], p1["positions"].values[0])
    np.testing.assert_array_equal(p0["tracer_index"].values, p1["tracer_index"].values)
    assert "transient_vz_cm" in p0 and "transient_vz_cm" not in p1
    n_k = sec["protocol"]["phases_per_period"]
    dt = float(p0.attrs["dt"])
    # samples at exact phases: N_k per period, a period apart between parts
    t0, t1 = p0["time"].values[0], p1["time"].values[0]
    np.testing.assert_allclose(np.diff(t0), 2 * np.pi / n_k, rtol=1e-9)
    assert t1[0] - t0[0] == pytest.approx(2 * np.pi, rel=1e-12)
    assert (t0[0] / dt) == pytest.approx(round(t0[0] / dt), abs=1e-6)


def test_ensemble_flags_and_fits_summary(pipeline):
    sec, root = pipeline
    calm = read_dataset(root / layout.ensemble_file(5, 0.7, "crystal", W6))
    wild = read_dataset(root / layout.ensemble_file(5, 2.0, "crystal", W6))
    assert float(wild.detachment_fraction) > float(calm.detachment_fraction)
    # μ = 0.6 side walls stir the bed even below Γ = 1 (docs/box.md, hazard (iii)); the driven bed
    # is still several times hotter (4.8x and 12x seen for two engine versions).
    assert float(wild.T_g) > 3 * float(calm.T_g)
    assert int(wild.bouncing) == 1 and calm.attrs["measured_periods"] == 2
    summary = read_summary(root / "fits" / "summary.csv")
    assert list(summary.columns) == COLUMNS
    q = set(summary["quantity"])
    for init in ("crystal", "random"):
        for mu_w in ("0.6", "0.0"):
            group = f"[N_l=5,init={init},mu_w={mu_w},walls=shaken,torque=lever]"
            # points are labelled by their start (fits.crystal_points: initialisation): every
            # group is fitted, whether or not the crystal check certified a crystal
            for crit in ("bouncing", "detachment", "convection", "rolls"):
                assert f"Gamma_{crit}{group}" in q
            assert f"E_b_all{group}" in q and f"E_b_all_weighted{group}" in q
            assert f"crystal_intact_points{group}" in q or init == "random"
    for point in (layout.point_name(*pt) for pt in layout.points(sec)):
        assert f"psi6_at_measurement_start[{point}]" in q
        assert f"dislocations_at_measurement_end[{point}]" in q
    points, ths, temp, slips = stages.load_fits(root / "fits")
    n_groups = len(ths.groupby(["init", "mu_w"]).groups)
    assert isinstance(points, pd.DataFrame) and len(points) == 12 and len(ths) == 4 * n_groups
    assert set(points["mu_w"]) == {0.0, 0.6} and n_groups >= 2
    # the T_g* fits take the bouncing points only (fits.temperature_points): here Γ = 2.0
    # alone, too few per group, so none is fitted: the rows are there, empty, with a note
    calm_points = points[points["Gamma"] == 0.7]
    assert (calm_points["detachment_fraction"] <= sec["detection"]["detachment_fraction"]).all()
    assert len(temp) and temp["value"].isna().all()
    assert temp["note"].str.startswith("T_g* fit refused on").all()


def test_wall_friction_points_share_random_numbers_but_not_physics(pipeline):
    sec, root = pipeline
    a = read_dataset(root / layout.init_file(5, "random", W6, 0))
    b = read_dataset(root / layout.init_file(5, "random", W0, 0))
    # the same placement (seed), settled between different walls
    assert a.attrs["seed"] == b.attrs["seed"] and a.attrs["mu_w"] != b.attrs["mu_w"]
    assert not np.array_equal(a["positions"].values, b["positions"].values)
    ra = read_dataset(root / layout.run_file(5, 2.0, "random", W6, 0, 0))
    rb = read_dataset(root / layout.run_file(5, 2.0, "random", W0, 0, 0))
    assert config_from_attrs(ra)["physics"]["mu_side_walls"] == 0.6
    assert config_from_attrs(rb)["physics"]["mu_side_walls"] == 0.0


def test_stages_refuse_files_that_are_not_their_inputs(pipeline, tmp_path):
    sec, root = pipeline
    other_walls = root / layout.init_file(5, "crystal", W0, 0)
    with pytest.raises(RunFileError, match="state"):
        stages.runs_stage(
            layout.runs_params(sec, 0, W6), 5, 2.0, "crystal", 0, 0, other_walls,
            tmp_path / "run.nc", log=None,
        )  # fmt: skip
    wrong_part = root / layout.run_file(5, 2.0, "crystal", W6, 0, 1)
    with pytest.raises(RunFileError, match="part"):
        stages.runs_stage(
            layout.runs_params(sec, 1, W6), 5, 2.0, "crystal", 0, 1,
            root / layout.init_file(5, "crystal", W6, 0), tmp_path / "run.nc",
            previous=wrong_part, log=None,
        )  # fmt: skip
    point = layout.point_name(5, 2.0, "crystal", W6)
    mixed = [
        root / layout.run_file(5, 2.0, "crystal", W6, 0, 0),
        root / layout.run_file(5, 1.4, "crystal", W6, 0, 1),
    ]
    with pytest.raises(RunFileError, match="point"):
        stages.ensemble_stage(
            layout.ensemble_params(sec, point), mixed, tmp_path / "e.nc", log=None
        )
    twice = [root / layout.run_file(5, 2.0, "crystal", W6, 0, 0)] * 2
    with pytest.raises(RunFileError, match="twice"):
        stages.ensemble_stage(
            layout.ensemble_params(sec, point), twice, tmp_path / "e.nc", log=None
        )
    assert not (tmp_path / "run.nc").exists() and not (tmp_path / "e.nc").exists()


def test_a_point_folder_swapped_for_another_points_is_refused_naming_both(pipeline, tmp_path):
    """Every run file of Γ = 2.0 copied into the Γ = 0.7 folder: the files agree with each
    other but not with the point the ensemble stage was asked for; the other point's
    ensemble under this point's name is refused by the fits and figures."""
    sec, root = pipeline
    want, other = (layout.point_name(5, g, "random", W6) for g in (0.7, 2.0))
    swapped = [tmp_path / "runs" / want / f"replica_0000.part_{p:03d}.nc" for p in range(2)]
    for p, dest in enumerate(swapped):
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_bytes((root / layout.run_file(5, 2.0, "random", W6, 0, p)).read_bytes())
    both = rf"belongs to point '{re.escape(other)}', not to '{re.escape(want)}'"
    with pytest.raises(RunFileError, match=both):
        stages.ensemble_stage(layout.ensemble_params(sec, want), swapped, tmp_path / "e.nc",
                              log=None)  # fmt: skip
    # the ensembles with one point's file under another's name: refused naming the point
    # twice (and the file) before any fit or duplicate summary row
    ens = [root / f for f in layout.ensemble_files(sec)]
    copied = tmp_path / "ensemble" / f"{want}.nc"
    copied.parent.mkdir()
    copied.write_bytes((root / layout.ensemble_file(5, 2.0, "random", W6)).read_bytes())
    ens = [copied if p.stem == want else p for p in ens]
    with pytest.raises(RunFileError, match=rf"point {re.escape(other)} appears twice"):
        stages.fits_stage(layout.fits_params(sec), ens, tmp_path / "fits", log=None)
    with pytest.raises(RunFileError, match=rf"point {re.escape(other)} appears twice"):
        stages.figures_stage(
            layout.figures_params(sec), root / "fits", [root / f for f in layout.init_files(sec)],
            ens, tmp_path / "figures", log=None,
        )  # fmt: skip
    assert not (tmp_path / "e.nc").exists() and not (tmp_path / "fits").exists()
    assert not (tmp_path / "figures").exists()


def test_a_grid_of_crystal_starts_only_fits(pipeline, tmp_path):
    """``grid.inits: [crystal]``: the fits and figures run on the crystal points alone, also
    when no crystal stayed intact (then no threshold is fitted, and the table says so)."""
    sec, root = pipeline
    crystal = {**sec, "grid": {**sec["grid"], "inits": ["crystal"]}}
    ens = [root / f for f in layout.ensemble_files(crystal)]
    assert ens and all("init=crystal" in p.name for p in ens)
    stages.fits_stage(layout.fits_params(crystal), ens, tmp_path / "fits", log=None)
    summary = read_summary(tmp_path / "fits" / "summary.csv")
    assert set(summary["quantity"]) >= {
        f"psi6_at_measurement_start[{layout.point_name(*pt)}]" for pt in layout.points(crystal)
    }
    assert not any("init=random" in q for q in summary["quantity"])
    intact = summary.set_index("quantity")["value"]
    for mu_w in ("0.6", "0.0"):
        group = f"[N_l=5,init=crystal,mu_w={mu_w},walls=shaken,torque=lever]"
        assert f"Gamma_bouncing{group}" in intact  # labelled by their start: always fitted
    only = {**crystal, "fits": {**crystal["fits"], "crystal_points": "intact"}}
    stages.fits_stage(layout.fits_params(only), ens, tmp_path / "intact", log=None)
    kept = read_summary(tmp_path / "intact" / "summary.csv").set_index("quantity")["value"]
    for mu_w in ("0.6", "0.0"):
        group = f"[N_l=5,init=crystal,mu_w={mu_w},walls=shaken,torque=lever]"
        assert (f"Gamma_bouncing{group}" in kept) == (kept[f"crystal_intact_points{group}"] > 0)
    paths = stages.figures_stage(
        layout.figures_params(crystal), tmp_path / "fits",
        [root / f for f in layout.init_files(crystal)], ens, tmp_path / "figures", log=None,
    )  # fmt: skip
    assert {p.name for p in paths} >= {f"{stem}.png" for stem in layout.FIGURES.values() if
                                        stem != "fig1_snapshots"}  # fmt: skip
    # no crystal intact at all: no group to fit, every table still has its columns
    from granpipe.box import fits

    table = fits.points_table(ens, sec["detection"]).assign(crystal_intact=0)
    table["used"] = fits.used_mask(table, "intact")
    ths = fits.thresholds_table(table, sec["detection"])
    assert ths.empty and list(ths.columns) == list(fits.THRESHOLD_COLUMNS)
    tfits = fits.temperature_fits(table, sec["fits"], sec["detection"])
    sfits = fits.slip_fits(table, tfits, sec["fits"])
    assert fits.fits_datasets(table, ths, tfits, sfits)["phase_diagram"].sizes["threshold"] == 0
    rows = fits.summary_rows(table, ths, tfits, sfits)
    assert {r["quantity"] for r in rows if r["quantity"].startswith("crystal_intact")} == {
        f"crystal_intact_points{when}[N_l=5,init=crystal,mu_w={m},walls=shaken,torque=lever]"
        for m in ("0.6", "0.0")
        for when in ("", "_ramp_end")
    }


def test_summary_holds_no_wall_clock_cost(pipeline):
    """The costs are in fits/costs.csv; summary.csv holds only what two runs of one config
    give alike."""
    _, root = pipeline
    summary = read_summary(root / "fits" / "summary.csv")
    costs = read_summary(root / "fits" / "costs.csv")
    assert not any("cost" in q for q in summary["quantity"])
    assert len(costs) and all(q.startswith("cost_ns_per_particle_step[") for q in costs["quantity"])
    assert (costs["value"] > 0).all() and set(costs["unit"]) == {"ns"}


def test_figures_say_what_record_and_which_reading_they_show():
    points = pd.DataFrame({"measured_periods": [8, 200], "replicas": [3, 3]})
    fig3 = stages.figure_reading(points, {}, 3)
    assert fig3.startswith("record: 8-200 measured periods, 3 replica(s) per point")
    assert "Eq. (B2)" in fig3 and "rolls" in fig3
    assert "over the all points" in stages.figure_reading(points, {"temperature_points": "all"}, 4)
    fig5 = stages.figure_reading(points, {"slip_weights": "weighted"}, 5)
    assert "fits weighted" in fig5 and "by initialisation" in fig5
