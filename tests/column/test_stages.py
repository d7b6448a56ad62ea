"""The column's CLI stages end to end on a tiny configuration (runs → figures)."""

import json
import re
import shutil

import numpy as np
import pandas as pd
import pytest
from click.testing import CliRunner

from granpipe.column.cli import cli
from granpipe.io import config_hash, read_dataset

SMALL = {
    "N": 3,
    "m": 1.0,
    "r": 1.0,
    "g": 980.67,
    "stiffness_factor": 8.0,
    "e": 0.09,
    "a": 1.06,
    "Gamma": 3.8476,
    "T": 0.6,
}
UNITS = {"length": "m", "time": "s", "fig2_length": "cm", "fig2_time": "s"}
GENERIC = {
    "N": 4,
    "m": 0.001,
    "r": 0.005,
    "g": 9.81,
    "stiffness_factor": 50.0,
    "e": 0.09,
    "a": 0.005,
    "tap_duration": 0.05,
    "T": 0.3,
}


def _run(args):
    res = CliRunner().invoke(cli, args, catch_exceptions=False)
    assert res.exit_code == 0, res.output
    return res


def test_stage_pipeline(tmp_path):
    j = json.dumps
    traj = tmp_path / "runs" / "trajectories_N3.nc"
    traj_params = {"sets": {"N3": SMALL}, "n_taps": 1, "record_dt": 0.01, "step_factor": 0.2}
    _run(
        [
            "trajectories",
            "--params",
            j(traj_params),
            "--set",
            "N3",
            "--out",
            str(traj),
        ]
    )
    relax = [tmp_path / "runs" / f"relax_{b}.nc" for b in range(2)]
    rp = {"physics": GENERIC, "n_taps": 3, "batch_size": 2, "perturbation": 1.0, "step_factor": 0.2}
    for b, path in enumerate(relax):
        _run(["relaxation", "--params", j(rp), "--batch", str(b), "--out", str(path)])
    chaos = []
    cp = {
        "physics": GENERIC,
        "n_replicas": 2,
        "transient_taps": 1,
        "taps": 2,
        "perturbation": 1.0,
        "twin_epsilon": 1e-9,
        "plain": True,
        "step_factor": 0.2,
        "return_max_period": 1,
        "return_taps": 2,
        "return_tolerance": 1e-6,
    }
    for a in (0.0002, 0.005):
        path = tmp_path / "runs" / f"chaos_{a}.nc"
        _run(["chaos", "--params", j(cp), "--a", str(a), "--T", "0.3", "--out", str(path)])
        chaos.append(path)
    contp = {
        "physics": SMALL,
        "n_taps": 1,
        "lw_refinement": 2,
        "bsr_refinement": 2,
        "bsr_derived_refinement": 2,
        "record_dt": 0.01,
        "sigma_width": 0.01,
        "bsr_kernel_width": 1.0,
        "step_factor": 0.2,
        "convergence": {
            "t_end": 0.2,
            "lw_refinements": [2, 4, 8],
            "bsr_refinements": [2, 4, 8],
            "bsr_t_end": 0.05,
            "bsr_derived_refinements": [2, 4, 8],
            "sigma_widths": [0.01, 0.001],
            "sigma_scan_refinement": 2,
        },
    }
    comp, conv = tmp_path / "runs" / "continuum.nc", tmp_path / "runs" / "convergence.nc"
    _run(["continuum", "--params", j(contp), "--out", str(comp)])
    _run(["convergence", "--params", j(contp), "--out", str(conv)])
    ens_r, ens_c = tmp_path / "ensemble" / "relaxation.nc", tmp_path / "ensemble" / "chaos.nc"
    # what each stage is asked for: the config hashes of the files it reads
    relax_params = {"kind": "relaxation", "runs_config_hash": config_hash(rp)}
    points = {
        f"a={a:g},T=0.3": config_hash({**cp, "physics": {**GENERIC, "a": a, "T": 0.3}})
        for a in (0.0002, 0.005)
    }
    chaos_params = {"confidence": 0.95, "points": points}
    inputs = {
        "relaxation": config_hash(relax_params), "chaos": config_hash(chaos_params),
        "continuum": config_hash(contp), "convergence": config_hash(contp),
    }  # fmt: skip
    _run(
        [
            "ensemble",
            "--params",
            j(relax_params),
            "--kind",
            "relaxation",
            "--out",
            str(ens_r),
            *map(str, relax),
        ]
    )
    _run(
        [
            "ensemble",
            "--params",
            j(chaos_params),
            "--kind",
            "chaos",
            "--out",
            str(ens_c),
            *map(str, chaos),
        ]
    )
    summary = tmp_path / "fits" / "summary.csv"
    note = tmp_path / "fits" / "note.md"
    _run(
        [
            "fits",
            "--params",
            j({"n_boot": 20, "units": UNITS, "inputs": inputs}),
            "--relaxation",
            str(ens_r),
            "--chaos",
            str(ens_c),
            "--continuum",
            str(comp),
            "--convergence",
            str(conv),
            "--out-csv",
            str(summary),
            "--out-nc",
            str(tmp_path / "fits" / "fits.nc"),
            "--out-note",
            str(note),
        ]
    )
    _run(
        [
            "figures",
            "--params",
            j(
                {
                    "units": UNITS,
                    "inputs": {**inputs, "trajectories": {"N3": config_hash(traj_params)}},
                }
            ),
            "--trajectories",
            str(traj),
            "--continuum",
            str(comp),
            "--relaxation",
            str(ens_r),
            "--chaos",
            str(ens_c),
            "--convergence",
            str(conv),
            "--outdir",
            str(tmp_path / "figures"),
        ]
    )

    df = pd.read_csv(summary)
    assert list(df.columns) == [
        "study",
        "quantity",
        "value",
        "unit",
        "fit_error",
        "ci_low",
        "ci_high",
        "n",
        "paper_value",
    ]
    rows = {
        "relaxed_density",
        "bsr_collapse_time[top=free]",
        *(
            f"continuum_{v}[model={m},top={t}]"
            for v in ("rms_positions", "relative_displacements", "observed_order_finest")
            for m in ("longwave", "bsr", "bsr_derived")
            for t in ("hybrid", "free")
        ),
    }
    rows |= {
        "return_period[a=0.0002,T=0.3]",
        "return_periodic_fraction[a=0.005,T=0.3]",
        "return_period_longest[T=0.3]",
    }
    assert rows <= set(df.quantity)
    val = df.set_index("quantity")["value"]
    # the printed Eq. (35) changes its wave speed with the unit system; the chain's is 1
    assert val["printed_eq35_wave_speed[units=cgs]"] == pytest.approx(np.sqrt(31 / 6), rel=1e-9)
    assert val["printed_eq35_wave_speed[units=SI]"] == pytest.approx(np.sqrt(7 / 6 + 4e-4))
    m = read_dataset(ens_c)
    assert m.sizes == {"a": 2, "T": 1, "period": 2}  # periods 0 (none) and 1
    # replicas are reproducible from their seeds: the same batch gives the same numbers
    again = tmp_path / "again.nc"
    _run(["relaxation", "--params", j(rp), "--batch", "1", "--out", str(again)])
    assert np.array_equal(
        read_dataset(again)["height"].values, read_dataset(relax[1])["height"].values
    )
    r = read_dataset(ens_r)
    assert int(r["count"].max()) == 4 and r.attrs["config_yaml"]
    assert "Theorem 1 against the data: periods growing with a before chaos:" in note.read_text()
    for k in range(1, 7):
        assert list((tmp_path / "figures").glob(f"fig{k}_*.png"))
        assert list((tmp_path / "figures").glob(f"fig{k}_*.pdf"))

    # aggregation refuses files that do not belong together, naming the file
    def refused(args, match):
        res = CliRunner().invoke(cli, args)
        assert res.exit_code != 0
        assert re.search(match, str(res.exception) + res.output), (res.exception, res.output)

    copied = tmp_path / "runs" / "batch_0000.nc"
    shutil.copy(relax[1], copied)  # a valid batch 1 under batch 0's name
    ens_args = ["ensemble", "--params", j(relax_params), "--kind", "relaxation", "--out"]
    refused([*ens_args, str(tmp_path / "x.nc"), str(copied)], r"batch_0000\.nc holds batch 1")
    refused([*ens_args, str(tmp_path / "x.nc"), str(relax[0]), str(relax[0])], "appears twice")
    refused([*ens_args, str(tmp_path / "x.nc"), str(chaos[0])], r"chaos_.*kind = 'chaos'")
    # batches of another column (every one of them): refused naming both hashes
    other = {**relax_params, "runs_config_hash": config_hash({**rp, "n_taps": 4})}
    refused(["ensemble", "--params", j(other), "--kind", "relaxation", "--out",
             str(tmp_path / "x.nc"), *map(str, relax)],
            rf"relax_0\.nc was computed from another configuration \(config hash "
            rf"{config_hash(rp)[:12]}\).*\({other['runs_config_hash'][:12]}\)")  # fmt: skip
    chaos_args = ["ensemble", "--params", j(chaos_params), "--kind", "chaos", "--out",
                  str(tmp_path / "y.nc")]  # fmt: skip
    refused([*chaos_args, str(chaos[0]), str(chaos[0])], "appears twice")
    refused([*chaos_args, str(chaos[0])], r"no file of the chaos point\(s\) a=0\.005,T=0\.3")
    renamed = tmp_path / "runs" / "a=0.1,T=0.3.nc"
    shutil.copy(chaos[0], renamed)
    refused([*chaos_args, str(renamed)], r"a=0\.1,T=0\.3\.nc holds the point a=0\.0002,T=0\.3, not")
    garbage = tmp_path / "runs" / "broken.nc"
    garbage.write_bytes(b"not a netCDF file")
    refused([*chaos_args, str(garbage)], r"cannot read .*broken\.nc")
    fits_args = [
        "fits",
        "--params",
        j({"n_boot": 20, "units": UNITS, "inputs": inputs}),
        "--relaxation",
        str(ens_r),
    ]
    fits_args += ["--chaos", str(ens_c), "--out-csv", str(tmp_path / "s.csv")]
    fits_args += ["--out-nc", str(tmp_path / "f.nc"), "--out-note", str(tmp_path / "n.md")]
    swapped = ["--continuum", str(conv), "--convergence", str(comp)]
    refused([*fits_args, *swapped], r"convergence\.nc is not the expected input: attribute kind")


def test_relaxation_ensemble_streams_to_the_pooled_moments():
    """Batches merged one at a time (a generator) give the moments of all replicas pooled."""
    import xarray as xr

    from granpipe.column.measures import relaxation_ensemble

    rng = np.random.default_rng(3)
    sizes = (3, 1, 4)
    data = [rng.normal(1.0, 0.1, (n, 6)) for n in sizes]
    data[2][1, 4] = np.nan  # a replica that stopped early

    def batches():
        for x in data:
            yield xr.Dataset(
                {"density": (("replica", "tap"), x), "height": (("replica", "tap"), 2 * x)},
                coords={"tap": np.arange(6)},
            )

    ens = relaxation_ensemble(batches())
    pooled = np.concatenate(data)
    for name, k in (("density", 1), ("height", 2)):
        np.testing.assert_allclose(ens[f"{name}_mean"], np.nanmean(k * pooled, axis=0), rtol=1e-13)
        np.testing.assert_allclose(ens[f"{name}_std"], np.nanstd(k * pooled, axis=0, ddof=1),
                                   rtol=1e-12)  # fmt: skip
    np.testing.assert_array_equal(ens["count"], np.isfinite(pooled).sum(axis=0))
    np.testing.assert_array_equal(ens["density_replicas"], pooled)
