"""summary.csv rows, atomic merge-writes and the fits Dataset."""

import numpy as np
import pandas as pd
import pytest

from granpipe.analysis.bootstrap import FitResult
from granpipe.analysis.summary import (
    COLUMNS,
    read_summary,
    results_dataset,
    summary_frame,
    summary_row,
    write_summary,
)
from granpipe.io import read_dataset, write_dataset


def test_row_and_frame_columns_and_empties():
    df = summary_frame(
        [
            summary_row("drum", "onset_time", 2.6281, "s", 0.002, 2.62, 2.64, 70000, 2.628),
            {"study": "box", "quantity": "E_b_random", "value": 7.2, "unit": "1"},
        ]
    )
    assert list(df.columns) == COLUMNS
    assert pd.isna(df.loc[1, "fit_error"]) and pd.isna(df.loc[1, "n"])
    assert df.loc[0, "n"] == 70000
    with pytest.raises(ValueError, match="unknown"):
        summary_frame([{"study": "x", "quantity": "y", "value": 1, "colour": "red"}])


def test_write_merge_and_read_back(tmp_path):
    path = tmp_path / "fits" / "summary.csv"
    r = FitResult("onset_time", 2.6281234567891, 0.0021, "s", ci_low=2.62, ci_high=2.64, n=120)
    write_summary([r.to_row("drum", paper_value=2.628)], path)
    write_summary(
        [
            summary_row("drum", "onset_time", 2.7, "s", n=240),  # replaces
            summary_row("drum", "decay_lag", 3.1, "s"),
        ],
        path,
    )
    text = path.read_text().splitlines()
    assert text[0] == ",".join(COLUMNS)
    assert text[1] == "drum,decay_lag,3.1,s,,,,,"
    assert text[2] == "drum,onset_time,2.7,s,,,,240,"
    df = read_summary(path)
    assert len(df) == 2 and df["n"].dtype == "Int64"
    write_summary([r.to_row("drum")], path, merge=False)
    df = read_summary(path)
    assert len(df) == 1 and df.loc[0, "value"] == pytest.approx(2.628123457, rel=1e-10)
    assert not list(path.parent.glob(".*tmp"))  # atomic: no temporary left
    with pytest.raises(ValueError, match="duplicate"):
        write_summary([r.to_row("drum"), r.to_row("drum")], path)


def test_results_dataset_is_writable(tmp_path):
    r = FitResult(
        "sign_change_time",
        14.5,
        0.2,
        "s",
        14.1,
        14.9,
        0.9,
        n=70,
        n_resamples=1000,
        window=(10.0, 20.0),
        method="linear fit, zero crossing",
    )
    ds = results_dataset([r, FitResult("lag", 11.9, 0.2, "s")])
    write_dataset(ds, tmp_path / "fits.nc", config_subset={"window": [10, 20]})
    back = read_dataset(tmp_path / "fits.nc")
    assert float(back["sign_change_time"]) == 14.5
    assert back["sign_change_time"].attrs["n"] == 70
    np.testing.assert_array_equal(back["sign_change_time"].attrs["window"], [10.0, 20.0])
    assert np.isnan(float(back["lag_ci_low"]))


def test_regression_and_threshold_rows_fit_the_summary():
    from granpipe.analysis.regression import arrhenius_fit, segmented_fit
    from granpipe.box.fits import threshold_crossing

    x = np.log(np.geomspace(0.5, 20, 12))
    seg = segmented_fit(x, 1.0 + x + 1.2 * np.maximum(x - np.log(3.3), 0) + 0.01 * np.sin(7 * x), 1)
    rows = seg.summary_rows("box", "Tg_random", paper_breakpoints=[3.3])
    assert [r["quantity"] for r in rows] == [
        "Tg_random_breakpoint_1",
        "Tg_random_slope_1",
        "Tg_random_slope_2",
    ]
    assert rows[0]["value"] == pytest.approx(3.3, rel=0.05) and rows[0]["paper_value"] == 3.3
    assert rows[0]["ci_low"] < rows[0]["value"] < rows[0]["ci_high"]
    K = np.array([1.5, 2.0, 3.0, 4.0])
    arr = arrhenius_fit(K, 0.5 * np.exp(-7 / K), p_s_sem=0.01 * 0.5 * np.exp(-7 / K))
    th = threshold_crossing([1.0, 1.5, 2.0], [0.0, 0.5, 2.0], 1.0)
    df = summary_frame(
        rows + [arr.summary_row("box", "E_b_random", 7.0), th.summary_row("box", "G")]
    )
    assert df.loc[3, "value"] == pytest.approx(7.0) and df.loc[3, "n"] == 4
    assert (df.loc[4, "ci_low"], df.loc[4, "ci_high"]) == (1.5, 2.0)  # the bracket
    assert pd.isna(df.loc[4, "fit_error"])
