import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import xarray as xr

from granpipe import io


def labelled(n=5):
    t = np.linspace(0.0, 1.0, n)
    return xr.Dataset(
        {
            "global_speed": (
                ("replica", "time"),
                np.random.default_rng(0).random((2, n)),
                {"units": "d_s/t0", "long_name": "global speed V(t)"},
            )
        },
        coords={
            "replica": ("replica", [0, 1], {"units": "1", "long_name": "replica index"}),
            "time": ("time", t, {"units": "t0", "long_name": "time"}),
        },
    )


def test_round_trip_keeps_data_units_and_provenance(tmp_path):
    ds = labelled()
    cfg = {"physics": {"dt": 1.14368e-3}, "record": {"block": 4e-3}}
    path = io.write_dataset(
        ds, tmp_path / "a.nc", config_subset=cfg, seeds=[11, 2**62], study="drum"
    )
    back = io.read_dataset(path)
    xr.testing.assert_identical(back.drop_attrs(), ds.drop_attrs())
    assert back.global_speed.attrs["units"] == "d_s/t0"
    assert back.time.attrs["long_name"] == "time"
    assert io.config_from_attrs(back) == cfg
    assert back.attrs["seeds"] == f"11 {2**62}"
    assert back.attrs["study"] == "drum"
    for key in ("granpipe_version", "git_commit", "config_hash", "created"):
        assert back.attrs[key]


def test_unlabelled_variable_is_refused(tmp_path):
    ds = labelled()
    ds["bare"] = ("time", np.zeros(ds.sizes["time"]))
    with pytest.raises(ValueError, match="bare.units"):
        io.write_dataset(ds, tmp_path / "b.nc")
    assert not (tmp_path / "b.nc").exists()


def test_exception_before_rename_leaves_nothing(tmp_path):
    target = tmp_path / "c.nc"
    with pytest.raises(RuntimeError), io.atomic_path(target) as tmp:
        tmp.write_text("partial")
        raise RuntimeError("job died")
    assert not target.exists()
    assert list(tmp_path.iterdir()) == []


def test_old_file_survives_failed_rewrite(tmp_path):
    target = tmp_path / "d.nc"
    io.write_dataset(labelled(), target)
    before = target.read_bytes()
    with pytest.raises(RuntimeError), io.atomic_path(target):
        raise RuntimeError("interrupted")
    assert target.read_bytes() == before


def test_sigkill_before_rename_leaves_nothing_under_final_name(tmp_path):
    # A real process killed (SIGKILL) after the data is written but before the rename.
    script = textwrap.dedent(
        f"""
        import os, signal
        import numpy as np, xarray as xr
        from granpipe import io
        os.replace = lambda *a: os.kill(os.getpid(), signal.SIGKILL)
        ds = xr.Dataset({{"x": ("i", np.arange(10.0), {{"units": "1", "long_name": "x"}})}})
        io.write_dataset(ds, {str(tmp_path / "e.nc")!r})
        """
    )
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True)
    assert proc.returncode == -signal.SIGKILL
    assert not (tmp_path / "e.nc").exists()
    assert all(p.name.startswith(".e.nc.") for p in tmp_path.iterdir())


def test_git_commit_is_reported():
    commit = io.git_commit()
    assert commit == "unknown" or len(commit.split("-")[0]) == 40
    os.environ["GRANPIPE_GIT_COMMIT"] = "abc"
    try:
        assert io.git_commit() == "abc"
    finally:
        del os.environ["GRANPIPE_GIT_COMMIT"]


def test_a_killed_attempts_temporary_file_goes_with_the_next_write(tmp_path):
    stale = tmp_path / ".batch_0000.nc.abc123.tmp"
    other = tmp_path / ".batch_0001.nc.abc123.tmp"  # another file's: left alone
    stale.write_bytes(b"partial")
    other.write_bytes(b"partial")
    io.write_dataset(labelled(), tmp_path / "batch_0000.nc")
    assert not stale.exists() and other.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == [other.name, "batch_0000.nc"]


def _run_file(path, batch, replicas, cfg):
    ds = labelled().assign_coords(
        replica=("replica", replicas, {"units": "1", "long_name": "replica"})
    )
    return io.write_dataset(ds, path, config_subset=cfg, study="drum", stage="runs",
                            batch=batch)  # fmt: skip


def test_run_files_that_do_not_belong_together_are_refused_naming_the_file(tmp_path):
    cfg = {"physics": {"dt": 1e-3}}
    a = _run_file(tmp_path / "batch_0000.nc", 0, [0, 1], cfg)
    b = _run_file(tmp_path / "batch_0001.nc", 1, [2, 3], cfg)
    info = io.check_run_files([a, b], study="drum")
    assert [i["replicas"] for i in info] == [[0, 1], [2, 3]]
    # batch 1 copied over batch 0: the name and the content disagree
    copied = tmp_path / "copy" / "batch_0000.nc"
    copied.parent.mkdir()
    copied.write_bytes(b.read_bytes())
    with pytest.raises(io.RunFileError, match=r"batch_0000\.nc holds batch 1"):
        io.check_run_files([copied, b], study="drum")
    # the same replicas twice under other names
    twice = tmp_path / "twice.nc"
    twice.write_bytes(b.read_bytes())
    with pytest.raises(io.RunFileError, match=r"replica 2 appears twice.*twice\.nc"):
        io.check_run_files([a, b, twice], study="drum")
    # another point's physics
    c = _run_file(tmp_path / "other" / "batch_0002.nc", 2, [4, 5], {"physics": {"dt": 2e-3}})
    with pytest.raises(io.RunFileError, match=r"batch_0002\.nc was computed with another"):
        io.check_run_files([a, c], study="drum")
    # not a runs file, and not a netCDF file at all
    with pytest.raises(io.RunFileError, match="not a box runs file"):
        io.check_run_files([a], study="box")
    junk = tmp_path / "batch_0003.nc"
    junk.write_text("not netCDF")
    with pytest.raises(io.RunFileError, match=r"cannot read .*batch_0003\.nc"):
        io.check_run_files([a, junk], study="drum")
    with pytest.raises(io.RunFileError, match=r"cannot read .*batch_0003\.nc"):
        io.read_dataset(junk)
