"""init → runs → ensemble → fits → figures through the stage functions, on a tiny drum."""

import re

import numpy as np
import pandas as pd
import pytest

from granpipe.analysis.summary import COLUMNS
from granpipe.drum.layout import COMPARISON_FIGURES, FIGURES, point_names, rule_params
from granpipe.drum.stages import (
    ensemble_stage,
    figures_stage,
    fits_stage,
    init_stage,
    runs_stage,
    summary_stage,
)
from granpipe.errors import RunFileError
from granpipe.io import read_dataset

# three tiny-drum replicas: many resamples have no crossing, as expected
pytestmark = pytest.mark.filterwarnings("ignore:.*bootstrap resamples gave no value")

TINY_FITS = {
    "moving_average_s": 0.05,
    "onset_vertex_window_s": [0.05, 0.55],
    "onset_zero_window_s": [0.1, 0.5],
    "decay_zero_window_s": [0.25, 0.55],
    "vertex_search_s": [0.05, 0.55],
    "bootstrap_resamples": 50,
}


@pytest.fixture(scope="module")
def pipeline(tiny, tmp_path_factory):
    """Both start-ups and both friction laws of the tiny drum (three points), three
    batches of one, through every stage."""
    tmp = tmp_path_factory.mktemp("pipe")
    sec = {**tiny, "protocol": {**tiny["protocol"], "startup": ["paper", "settled"]},
           "physics": {**tiny["physics"], "friction": ["viscous", "static"]},
           "ensemble": {**tiny["ensemble"], "batch_size": 1, "n_replicas": 3,
                        "exclude_flagged": False},
           "fits": {**tiny["fits"], **TINY_FITS}}  # fmt: skip
    params = rule_params(sec)
    fits = []
    for name in point_names(sec):
        runs = []
        for b in (0, 1, 2):
            init, run = tmp / name / f"init_{b}.nc", tmp / name / f"batch_{b:04d}.nc"
            init_stage(params["sim"][name], b, init)
            runs_stage(params["sim"][name], b, init, run)
            runs.append(run)
        ensemble_stage(params["ensemble"][name], runs, tmp / "ensemble" / f"{name}.nc")
        fits_stage(params["fits"][name], tmp / "ensemble" / f"{name}.nc", runs,
                   tmp / "fits" / f"{name}.nc")  # fmt: skip
        fits.append(tmp / "fits" / f"{name}.nc")
    summary_stage(fits, tmp / "summary.csv")
    names = point_names(sec)
    paths = figures_stage(
        {**params["figures"], "figures": {"dpi": 50}},
        [tmp / "ensemble" / f"{n}.nc" for n in names], fits,
        tmp / names[0] / "batch_0000.nc", tmp / "figures",
    )  # fmt: skip
    return tmp, paths, names, params, sec


def test_ensemble_counts_every_replica(pipeline):
    tmp, _, names, _, _ = pipeline
    ens = read_dataset(tmp / "ensemble" / f"{names[0]}.nc")
    assert ens.attrs["n_replicas"] == 3
    assert (ens["lambda_onset_count"].values == 3).all()
    assert ens.attrs["stage"] == "ensemble"


def test_summary_rows_have_the_design_columns(pipeline):
    tmp, _, _, _, _ = pipeline
    table = pd.read_csv(tmp / "summary.csv")
    assert list(table.columns) == COLUMNS
    assert set(table["study"]) == {"drum"}
    names = set(table["quantity"])
    for q in ("onset_time", "onset_sign_change_time", "onset_lag", "decay_sign_change_time",
              "decay_lag", "onset_time_auto", "decay_lag_auto"):  # fmt: skip
        assert q in names
        assert q + "[startup=settled]" in names  # the other points' rows, labelled
        assert q + "[friction=static]" in names
    rows = table.set_index("quantity")
    row = rows.loc["onset_time_auto"]
    assert row["paper_value"] == 2.628 and row["unit"] == "s" and row["n"] == 3
    # the paper's numbers stand beside the reference point's rows only
    assert np.isnan(rows.loc["onset_time_auto[startup=settled]", "paper_value"])
    for q in ("onset_curvature", "onset_valid_fraction", "onset_startup_excess"):
        assert q in names


def test_fits_file_holds_values_and_curves(pipeline):
    tmp, _, names, _, _ = pipeline
    fits = read_dataset(tmp / "fits" / f"{names[0]}.nc")
    assert fits["onset_time"].attrs["units"] == "s"
    # a refused onset says why, in the file
    if not np.isfinite(fits["onset_time"].values):
        assert fits["onset_time"].attrs["note"]
    assert fits["lambda_bar_onset"].dims == ("time_onset",)
    assert "onset_time_ci_low" in fits and "fit_lambda_decay_config" in fits


def test_every_figure_in_png_and_pdf(pipeline):
    tmp, paths, _, _, _ = pipeline
    names = sorted(p.name for p in paths)
    figs = {**FIGURES, **COMPARISON_FIGURES}
    expected = sorted(f"fig{k}_{n}.{e}" for k, n in figs.items() for e in ("png", "pdf"))
    assert names == expected
    for p in paths:
        assert p.stat().st_size > 1000
        head = p.read_bytes()[:4]
        assert head == (b"\x89PNG" if p.suffix == ".png" else b"%PDF")


def test_runs_path_fills_the_section_once_and_hands_it_down_frozen(tiny, tmp_path, monkeypatch):
    from granpipe.drum import layout, protocol

    sec = {**tiny, "ensemble": {**tiny["ensemble"], "batch_size": 1, "n_replicas": 1}}
    params = rule_params(sec)["sim"][point_names(sec)[0]]
    init = tmp_path / "init_0.nc"
    init_stage(params, 0, init)

    fills, seen = [], []
    read = layout._schema
    monkeypatch.setattr(layout, "_schema", lambda *a: fills.append(a) or read(*a))
    run_batch = protocol.run_batch

    def spy(section, *args, **kwargs):
        seen.append(section)
        with pytest.raises(TypeError):
            section["protocol"]["chunk_s"] = 1.0
        return run_batch(section, *args, **kwargs)

    monkeypatch.setattr(protocol, "run_batch", spy)
    runs_stage(params, 0, init, tmp_path / "batch_0000.nc")
    assert len(fills) == 1  # the stage's load of --params, nothing below it
    assert len(seen) == 1 and isinstance(seen[0], layout.FrozenSection)
    assert read_dataset(tmp_path / "batch_0000.nc").sizes["replica"] == 1


def test_a_point_folder_swapped_for_another_points_is_refused_naming_both(pipeline, tmp_path):
    """Every run file of the settled point copied into the reference point's folder: the
    files agree with each other, but not with the point the stages were asked for."""
    tmp, _, names, params, _ = pipeline
    ref, other = names[0], names[1]
    swapped = tmp_path / ref
    swapped.mkdir()
    for b in (0, 1, 2):
        (swapped / f"batch_{b:04d}.nc").write_bytes(
            (tmp / other / f"batch_{b:04d}.nc").read_bytes()
        )
    runs = sorted(swapped.glob("batch_*.nc"))
    both = rf"belongs to point '{re.escape(other)}', not to '{re.escape(ref)}'"
    with pytest.raises(RunFileError, match=both):
        ensemble_stage(params["ensemble"][ref], runs, tmp_path / "ensemble.nc")
    with pytest.raises(RunFileError, match=both):
        fits_stage(params["fits"][ref], tmp / "ensemble" / f"{ref}.nc", runs, tmp_path / "f.nc")
    # the other point's ensemble under the reference point's name
    with pytest.raises(RunFileError, match=both):
        own = [tmp / ref / f"batch_{b:04d}.nc" for b in (0, 1, 2)]
        fits_stage(params["fits"][ref], tmp / "ensemble" / f"{other}.nc", own, tmp_path / "f.nc")
    # an init file of the other point
    with pytest.raises(RunFileError, match=both):
        runs_stage(params["sim"][ref], 0, tmp / other / "init_0.nc", tmp_path / "r.nc")
    assert not list(tmp_path.glob("*.nc"))
    # a fits file of a point the summary is not given, copied over the reference's
    fits = tmp_path / "fits"
    fits.mkdir()
    (fits / f"{ref}.nc").write_bytes((tmp / "fits" / f"{names[2]}.nc").read_bytes())
    with pytest.raises(RunFileError, match=rf"of point {re.escape(names[2])}, not of"):
        summary_stage([fits / f"{ref}.nc", tmp / "fits" / f"{other}.nc"], fits / "s.csv")
    assert not (fits / "s.csv").exists()


def test_restamp_reuses_files_whose_physics_a_point_has(pipeline, tmp_path):
    """The documented way to reuse results under new point names: files are written to the
    point's folder with its name and hash, data untouched, and the stages accept them;
    a file whose physics no point of the config has is refused naming it."""
    from granpipe.drum.stages import restamp_stage

    tmp, _, names, params, sec = pipeline
    ref = names[0]
    old = [tmp / ref / "init_0.nc", tmp / ref / "batch_0000.nc"]
    written = restamp_stage(sec, old, tmp_path)
    assert written == [tmp_path / "init" / ref / "batch_0000.nc",
                       tmp_path / "runs" / ref / "batch_0000.nc"]  # fmt: skip
    for src, dest in zip(old, written, strict=True):
        a, b = read_dataset(src), read_dataset(dest)
        assert b.attrs["point"] == ref and b.attrs["config_hash"] == a.attrs["config_hash"]
        assert str(src) in b.attrs["restamped_from"]
        for name in a.data_vars:
            assert np.array_equal(a[name].values, b[name].values, equal_nan=a[name].dtype.kind
                                  == "f")  # fmt: skip
    ensemble_stage(params["ensemble"][ref], written[1:], tmp_path / "e.nc")
    with pytest.raises(RunFileError, match="which exists: remove it first"):
        restamp_stage(sec, old[:1], tmp_path)
    # only the reference start-up: the settled point's files have no point here
    paper = {**sec, "protocol": {**sec["protocol"], "startup": "paper"}}
    with pytest.raises(RunFileError, match=rf"{re.escape(names[1])}.*no point of this config"):
        restamp_stage(paper, [tmp / names[1] / "batch_0000.nc"], tmp_path / "other")
    assert not (tmp_path / "other").exists()


@pytest.mark.parametrize("part", ["onset", "decay"])
def test_the_movie_replays_the_reference_point_around_its_event(pipeline, part):
    import imageio.v2 as imageio

    from granpipe.drum.layout import movie_file, movie_input, movie_params
    from granpipe.drum.trajectory import movie_stage

    tmp, _, names, _, sec = pipeline
    sec = {**sec, "movie": {"format": "gif", "before_s": 0.1, "after_s": 0.1, "every_s": 0.05}}
    assert movie_input(sec) == f"runs/{names[0]}/batch_0000.nc"
    out = tmp / movie_file(sec, part)
    out.parent.mkdir(exist_ok=True)
    path, frames = movie_stage(movie_params(sec), part, tmp / names[0] / "batch_0000.nc", out)
    assert frames == 5 and len(imageio.mimread(path)) == 5
    with pytest.raises(RunFileError, match=names[1]):  # another point's run file
        movie_stage(movie_params(sec), part, tmp / names[1] / "batch_0000.nc", out)
