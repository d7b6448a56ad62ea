"""The shear stages file to file: every input checked against the stage's own params."""

import shutil

import pytest

from granpipe.io import RunFileError
from granpipe.shear import layout
from granpipe.shear.stages import figures_stage, fits_stage, runs_stage, summary_stage


@pytest.fixture(scope="module")
def two_points(tmp_path_factory):
    """The tiny cell at φ = 0.80 and 0.82, two batches of one replica each, and fits; a
    variant with larger disks at the same φ, three replicas."""
    from tests.shear.conftest import shear_section

    cfg = shear_section(
        physics={"phi": [0.8, 0.82], "n_inner": 12, "n_outer": 30},
        preparation={"growth_stages": 10, "growth_s": 0.4, "steady_s": 0.4},
        protocol={"record_s": 0.4, "tangent_alignment_s": 0.1},
        ensemble={"n_replicas": 2, "batch_size": 1},
        fits={"aligned_before_s": 0.1, "aligned_after_s": 0.1, "bootstrap_resamples": 50},
    )
    cfg["variants"] = {"big": {"physics": {"d_large": 1.4}, "ensemble": {"n_replicas": 3}}}
    root = tmp_path_factory.mktemp("shear")
    for point in layout.points(cfg):
        runs = [root / layout.run_file(point, b) for b in layout.batches(cfg, point)]
        for b, path in enumerate(runs):
            runs_stage(layout.runs_params(cfg, point), b, path)
        fits_stage(layout.fits_params(cfg, point), runs, root / layout.fits_file(point))
    return cfg, root


def test_fits_refuse_another_points_batches_and_missing_replicas(two_points):
    cfg, root = two_points
    a, b = layout.points(cfg, "")
    theirs = [root / layout.run_file(b, x) for x in layout.batches(cfg, b)]
    with pytest.raises(RunFileError, match="point"):
        fits_stage(layout.fits_params(cfg, a), theirs, root / "x.nc")
    ours = [root / layout.run_file(a, "0000")]
    with pytest.raises(RunFileError, match="replicas"):
        fits_stage(layout.fits_params(cfg, a), ours, root / "x.nc")
    assert not (root / "x.nc").exists()


def test_summary_and_figures_from_every_point_and_only_those(two_points, tmp_path):
    cfg, root = two_points
    fits = [root / layout.fits_file(p) for p in layout.points(cfg)]
    out = summary_stage(layout.summary_params(cfg), fits, tmp_path / "summary.csv")
    text = out.read_text()
    assert "lambda_mean[phi=0.8]" in text and "lambda_mean[phi=0.82]" in text
    assert "phi_lambda_zero" in text and "phi_lambda_all_zero" in text
    # the variant's points and its own transition rows, its files in a folder of its name
    assert "lambda_mean[big/phi=0.82]" in text and "phi_lambda_all_zero[big]" in text
    assert "phi_J_pressure[big]" in text and "phi_J_z_frictionless," in text
    assert (root / "runs" / "big" / "phi=0.82" / "batch_0002.nc").exists()
    paths = figures_stage(layout.figures_params(cfg), fits, tmp_path / "figures")
    assert sorted(p.name for p in paths) == sorted(
        f"{n}.{e}" for n in layout.FIGURES for e in ("png", "pdf"))  # fmt: skip
    # a point's fits copied over the other's name, or one point missing, is refused
    copy = tmp_path / "fits" / f"{layout.points(cfg)[1]}.nc"
    copy.parent.mkdir()
    big = tmp_path / "fits" / "big" / "phi=0.8.nc"  # the base's fits as the variant's
    big.parent.mkdir()
    shutil.copy(fits[0], big)
    with pytest.raises(RunFileError, match="holds the fits of phi=0.8, not of big/phi=0.8"):
        summary_stage(layout.summary_params(cfg), [*fits[1:], big], tmp_path / "s1.csv")
    shutil.copy(fits[0], copy)
    with pytest.raises(RunFileError, match="holds the fits of"):
        summary_stage(layout.summary_params(cfg), [fits[0], copy], tmp_path / "s2.csv")
    with pytest.raises(RunFileError, match="no fits file"):
        summary_stage(layout.summary_params(cfg), fits[:1], tmp_path / "s3.csv")


def test_files_an_earlier_granpipe_wrote_are_named_with_the_rule_to_rerun(two_points, tmp_path):
    """A run file without ``lyapunov_all`` and a fits file without its replica means (as
    granpipe wrote them before it recorded the whole tangent vector's rate) are refused by
    the stages that read them, naming the file, the variable and the rule to force."""
    from granpipe.io import read_dataset

    cfg, root = two_points
    a = layout.points(cfg)[0]
    runs = []
    for b in layout.batches(cfg, a):
        ds = read_dataset(root / layout.run_file(a, b)).drop_vars("lyapunov_all")
        runs.append(tmp_path / "runs" / f"batch_{b}.nc")
        runs[-1].parent.mkdir(exist_ok=True)
        ds.to_netcdf(runs[-1])
    with pytest.raises(RunFileError, match=r"no 'lyapunov_all'.*--forcerun shear_runs"):
        fits_stage(layout.fits_params(cfg, a), runs, tmp_path / "x.nc")
    old = tmp_path / "fits" / f"{a}.nc"
    old.parent.mkdir()
    read_dataset(root / layout.fits_file(a)).drop_vars("lambda_all_replica_mean").to_netcdf(old)
    params = {**layout.summary_params(cfg), "points": {a: layout.summary_params(cfg)["points"][a]}}
    with pytest.raises(RunFileError, match=r"no 'lambda_all_replica_mean'.*--forcerun shear_fits"):
        summary_stage(params, [old], tmp_path / "s.csv")
    assert not (tmp_path / "x.nc").exists() and not (tmp_path / "s.csv").exists()


def test_the_command_line_takes_every_stages_params_of_a_variants_point(two_points, tmp_path):
    """What the workflow passes for a variant's point (``big/phi=0.82``) is accepted by each
    command, and the command writes what the stage writes: the same replica, bit for bit."""
    import json

    from click.testing import CliRunner

    from granpipe.io import read_dataset
    from granpipe.shear.cli import cli

    cfg, root = two_points
    point = "big/phi=0.82"
    runs = tmp_path / "batch_0001.nc"
    call = CliRunner().invoke(cli, ["runs", "--params", json.dumps(layout.runs_params(cfg, point)),
                                    "--batch", "1", "--out", str(runs)])  # fmt: skip
    assert call.exit_code == 0, call.output
    mine, theirs = read_dataset(runs), read_dataset(root / layout.run_file(point, "0001"))
    assert (mine["lyapunov_all"].values == theirs["lyapunov_all"].values).all()
    fits = [str(root / layout.fits_file(p)) for p in layout.points(cfg)]
    for stage, params, where in (
        ("summary", layout.summary_params(cfg), ["--out", str(tmp_path / "summary.csv")]),
        ("figures", layout.figures_params(cfg), ["--out-dir", str(tmp_path / "figures")]),
    ):
        call = CliRunner().invoke(cli, [stage, "--params", json.dumps(params), *where, *fits])
        assert call.exit_code == 0, call.output
    assert "[big]" in (tmp_path / "summary.csv").read_text()
