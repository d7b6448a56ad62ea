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


def _run_file(path, batch, replicas, cfg, point="N=1", n=5):
    ds = labelled(n).assign_coords(
        replica=("replica", replicas, {"units": "1", "long_name": "replica"})
    )
    return io.write_dataset(ds, path, config_subset=cfg, study="drum", stage="runs",
                            batch=batch, point=point)  # fmt: skip


def test_run_files_are_checked_against_what_the_stage_asks_for(tmp_path):
    cfg = {"physics": {"dt": 1e-3}}
    want = {"study": "drum", "point": "N=1", "config_hash": io.config_hash(cfg)}
    a = _run_file(tmp_path / "batch_0000.nc", 0, [0, 1], cfg)
    b = _run_file(tmp_path / "batch_0001.nc", 1, [2, 3], cfg)
    info = io.check_run_files([a, b], **want)
    assert [i["replicas"] for i in info] == [[0, 1], [2, 3]]
    # batch 1 copied over batch 0: the name and the content disagree
    copied = tmp_path / "copy" / "batch_0000.nc"
    copied.parent.mkdir()
    copied.write_bytes(b.read_bytes())
    with pytest.raises(io.RunFileError, match=r"batch_0000\.nc holds batch 1"):
        io.check_run_files([copied, b], **want)
    # the same replicas twice under other names
    twice = tmp_path / "twice.nc"
    twice.write_bytes(b.read_bytes())
    with pytest.raises(io.RunFileError, match=r"replica 2 appears twice.*twice\.nc"):
        io.check_run_files([a, b, twice], **want)
    # every file of another point: refused although they agree with each other, naming
    # the point each file holds and the one the stage was asked for
    other = {"physics": {"dt": 2e-3}}
    swapped = [
        _run_file(tmp_path / "other" / f"batch_{b:04d}.nc", b, [2 * b, 2 * b + 1], other, "N=2")
        for b in (0, 1)
    ]
    with pytest.raises(io.RunFileError, match=r"batch_0000\.nc belongs to point 'N=2', not to "
                       r"'N=1'"):  # fmt: skip
        io.check_run_files(swapped, **want)
    # the same point name, computed from another configuration: both hashes named
    stale = _run_file(tmp_path / "stale" / "batch_0000.nc", 0, [0, 1], other)
    with pytest.raises(
        io.RunFileError,
        match=rf"config hash {io.config_hash(other)[:12]}\).*\({io.config_hash(cfg)[:12]}\)",
    ):
        io.check_run_files([stale], **want)
    # not a runs file, and not a netCDF file at all
    with pytest.raises(io.RunFileError, match="not a box runs file"):
        io.check_run_files([a], **{**want, "study": "box"})
    junk = tmp_path / "batch_0003.nc"
    junk.write_text("not netCDF")
    with pytest.raises(io.RunFileError, match=r"cannot read .*batch_0003\.nc"):
        io.check_run_files([a, junk], **want)
    with pytest.raises(io.RunFileError, match=r"cannot read .*batch_0003\.nc"):
        io.read_dataset(junk)


def test_a_truncated_file_is_named_with_what_to_do(tmp_path):
    cfg = {"physics": {"dt": 1e-3}}
    path = _run_file(tmp_path / "batch_0000.nc", 0, [0, 1], cfg, n=100_000)
    size = path.stat().st_size
    with open(path, "r+b") as fh:
        fh.truncate(size // 2)
    for read in (
        lambda: io.read_dataset(path),
        lambda: io.check_run_files([path], study="drum", config_hash=io.config_hash(cfg)),
    ):
        with pytest.raises(io.RunFileError) as err:
            read()
        message = str(err.value)
        assert str(path) in message and "remove it and rerun" in message
        assert message.count(str(path)) == 1 and "\n" not in message
    missing = tmp_path / "missing.nc"
    with pytest.raises(io.RunFileError, match=r"missing\.nc: No such file or directory \(ENOENT\)"):
        io.read_dataset(missing)


@pytest.mark.parametrize("umask, mode", [(0o022, 0o644), (0o027, 0o640), (0o077, 0o600)])
def test_files_get_the_permissions_the_umask_gives(tmp_path, umask, mode):
    old = os.umask(umask)
    try:
        nc = io.write_dataset(labelled(), tmp_path / "a.nc")
        text = io.write_text("x\n", tmp_path / "b.csv")
    finally:
        os.umask(old)
    for path in (nc, text):
        assert path.stat().st_mode & 0o777 == mode, oct(path.stat().st_mode)


def test_a_file_size_limit_names_the_path_and_efbig(tmp_path):
    """A process under a file-size limit (RLIMIT_FSIZE) writing a file larger than the
    limit: one line naming the file and EFBIG, nothing under the final name."""
    target = tmp_path / "big.nc"
    script = textwrap.dedent(
        f"""
        import resource, sys
        import numpy as np, xarray as xr
        from granpipe import io
        ds = xr.Dataset({{"x": ("i", np.random.default_rng(0).random(200_000),
                                {{"units": "1", "long_name": "x"}})}})
        resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))
        try:
            io.write_dataset(ds, {str(target)!r})
        except io.WriteError as exc:
            print(exc)
            sys.exit(3)
        """
    )
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert proc.returncode == 3, proc.stderr
    assert f"cannot write {target}: File too large (EFBIG)" in proc.stdout
    assert not target.exists() and not list(tmp_path.iterdir())


@pytest.fixture
def small_tmpfs(tmp_path):
    """A 256 kB tmpfs (needs the right to mount: skipped elsewhere)."""
    mnt = tmp_path / "full"
    mnt.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=256k", "tmpfs", str(mnt)],
                          capture_output=True, text=True)  # fmt: skip
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.strip()}")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", str(mnt)], check=True)


def test_a_full_filesystem_names_the_path_and_enospc(small_tmpfs):
    ds = xr.Dataset(
        {"x": ("i", np.random.default_rng(0).random(100_000), {"units": "1", "long_name": "x"})}
    )
    target = small_tmpfs / "runs" / "batch_0000.nc"
    with pytest.raises(io.WriteError) as err:
        io.write_dataset(ds, target)
    assert str(err.value) == f"cannot write {target}: No space left on device (ENOSPC)"
    assert not target.exists() and not list(target.parent.iterdir())
    with pytest.raises(io.WriteError, match=r"summary\.csv: No space left on device \(ENOSPC\)"):
        io.write_text("x" * 400_000, small_tmpfs / "summary.csv")


def test_a_folder_without_write_permission_names_the_path_and_eacces(tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root writes through folder permissions")
    folder = tmp_path / "locked"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        with pytest.raises(io.WriteError, match=r"locked/a\.nc: Permission denied \(EACCES\)"):
            io.write_dataset(labelled(), folder / "a.nc")
    finally:
        folder.chmod(0o700)
