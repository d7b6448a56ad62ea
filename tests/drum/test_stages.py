"""init → runs → ensemble → fits → figures through the stage functions, on a tiny drum."""

import numpy as np
import pandas as pd
import pytest

from granpipe.analysis.summary import COLUMNS
from granpipe.drum.layout import FIGURES
from granpipe.drum.stages import (
    ensemble_stage,
    figures_stage,
    fits_stage,
    init_stage,
    runs_stage,
)
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
    tmp = tmp_path_factory.mktemp("pipe")
    sec = {**tiny, "ensemble": {**tiny["ensemble"], "batch_size": 1}}
    runs = []
    for b in (0, 1, 2):
        init_stage(sec, b, tmp / f"init_{b}.nc")
        runs_stage(sec, b, tmp / f"init_{b}.nc", tmp / f"run_{b}.nc")
        runs.append(tmp / f"run_{b}.nc")
    params = {"ensemble": {"exclude_flagged": False}, "fits": TINY_FITS}
    ensemble_stage(params, runs, tmp / "ensemble.nc")
    fits_stage(params, tmp / "ensemble.nc", runs, tmp / "fits.nc", tmp / "summary.csv")
    paths = figures_stage({"figures": {"dpi": 50}}, tmp / "ensemble.nc", tmp / "fits.nc",
                          runs[0], tmp / "figures")  # fmt: skip
    return tmp, paths


def test_ensemble_counts_every_replica(pipeline):
    tmp, _ = pipeline
    ens = read_dataset(tmp / "ensemble.nc")
    assert ens.attrs["n_replicas"] == 3
    assert (ens["lambda_onset_count"].values == 3).all()
    assert ens.attrs["stage"] == "ensemble"


def test_summary_rows_have_the_design_columns(pipeline):
    tmp, _ = pipeline
    table = pd.read_csv(tmp / "summary.csv")
    assert list(table.columns) == COLUMNS
    assert set(table["study"]) == {"drum"}
    names = set(table["quantity"])
    for q in ("onset_time", "onset_sign_change_time", "onset_lag", "decay_sign_change_time",
              "decay_lag", "onset_time_auto", "decay_lag_auto"):  # fmt: skip
        assert q in names
    row = table.set_index("quantity").loc["onset_time"]
    assert row["paper_value"] == 2.628 and row["unit"] == "s" and row["n"] == 3
    assert np.isfinite(row["value"]) and np.isfinite(row["fit_error"])


def test_fits_file_holds_values_and_curves(pipeline):
    tmp, _ = pipeline
    fits = read_dataset(tmp / "fits.nc")
    assert fits["onset_time"].attrs["units"] == "s"
    assert fits["lambda_bar_onset"].dims == ("time_onset",)
    assert "onset_time_ci_low" in fits and "fit_lambda_decay_config" in fits


def test_four_figures_in_png_and_pdf(pipeline):
    tmp, paths = pipeline
    names = sorted(p.name for p in paths)
    expected = sorted(f"fig{k}_{n}.{e}" for k, n in FIGURES.items() for e in ("png", "pdf"))
    assert names == expected
    for p in paths:
        assert p.stat().st_size > 1000
        head = p.read_bytes()[:4]
        assert head == (b"\x89PNG" if p.suffix == ".png" else b"%PDF")
