"""A shear replica replayed frame by frame: the run's states bit for bit, the files read back,
and every bad request refused before anything is integrated."""

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest
from click.testing import CliRunner

from granpipe import trajectory as traj
from granpipe.shear import layout
from granpipe.shear import trajectory as shear_traj
from granpipe.shear.protocol import run_replica


@pytest.fixture(scope="module")
def params():
    from tests.shear.conftest import shear_section

    cfg = shear_section(
        physics={"phi": 0.82, "n_inner": 12, "n_outer": 30},
        preparation={"growth_stages": 10, "growth_s": 0.4, "steady_s": 0.4},
        protocol={"record_s": 0.4, "tangent_alignment_s": 0.1, "sample_s": 0.02},
        ensemble={"n_replicas": 2, "batch_size": 1},
    )
    return layout.trajectory_params(cfg, "phi=0.82")


@pytest.fixture(scope="module")
def replay(params):
    """Replica 1 over the record's last 0.1 s, a frame every 0.01 s, beside its run."""
    return shear_traj.trajectory(params, 1, (0.3, 0.4), 0.01), run_replica(params, 1)


def test_the_last_frame_is_the_runs_final_state_bit_for_bit(replay):
    ds, run = replay
    n = len(run["positions"])
    last = ds.isel(frame=-1)
    assert ds.sizes["frame"] == 11 and ds["wall"].values[:n].sum() == 0
    np.testing.assert_array_equal(np.column_stack([last.x.values, last.y.values])[:n],
                                  run["positions"])  # fmt: skip
    np.testing.assert_array_equal(np.hypot(last.vx.values, last.vy.values)[:n], run["v"])
    np.testing.assert_array_equal(last.du.values[:n], run["du"])
    assert float(last.time) == pytest.approx(0.4, abs=ds.attrs["dt"])
    assert np.all(np.isfinite(ds["local_lyapunov"])) and np.all(ds["global_speed"] > 0)
    assert np.all(np.diff(ds["phase"].values) > 0)  # the inner ring turns


def test_a_shorter_window_stops_early_on_the_same_states(params, replay):
    ds, _ = replay
    short = shear_traj.trajectory(params, 1, (0.3, 0.35), 0.01)
    assert short.sizes["frame"] == 6
    for name in ("x", "y", "vx", "vy", "du", "contacts", "local_lyapunov", "time"):
        np.testing.assert_array_equal(short[name].values, ds[name].values[:6])


def test_extxyz_reads_back_through_ase(replay, tmp_path):
    import ase.io

    ds, _ = replay
    path = traj.write_trajectory(ds, tmp_path / "t.xyz", "extxyz")
    images = ase.io.read(path, index=":")
    assert len(images) == ds.sizes["frame"]
    for k in (0, len(images) - 1):
        a, f = images[k], ds.isel(frame=k)
        # ASE writes reals with 8 decimals: equal to half a unit of the last place
        np.testing.assert_allclose(a.positions[:, 0], f.x.values, rtol=0, atol=5e-9)
        np.testing.assert_allclose(a.positions[:, 1], f.y.values, rtol=0, atol=5e-9)
        np.testing.assert_allclose(
            a.arrays["velo"][:, :2], np.column_stack([f.vx.values, f.vy.values]), atol=5e-9
        )
        np.testing.assert_allclose(a.arrays["radius"], f.radius.values, atol=5e-9)
        np.testing.assert_allclose(a.arrays["du"], f.du.values, atol=5e-9)
        np.testing.assert_array_equal(a.arrays["contacts"], f.contacts.values)
        np.testing.assert_array_equal(a.arrays["wall"], ds["wall"].values)
        assert a.info["time"] == float(f.time)
        assert a.info["local_lyapunov"] == float(f.local_lyapunov)
        assert "d_s" in a.info["units"]


def test_vtu_frames_and_pvd_read_back_through_meshio(replay, tmp_path):
    import meshio

    ds, _ = replay
    path = traj.write_trajectory(ds, tmp_path / "t.pvd", "vtu")
    sets = ET.parse(path).getroot().find("Collection").findall("DataSet")
    assert [float(s.get("timestep")) for s in sets] == list(ds["time"].values)
    for k, s in enumerate(sets):
        mesh, f = meshio.read(tmp_path / s.get("file")), ds.isel(frame=k)
        np.testing.assert_array_equal(mesh.points[:, 0], f.x.values)
        np.testing.assert_array_equal(mesh.points[:, 1], f.y.values)
        np.testing.assert_array_equal(mesh.point_data["velocity"][:, 1], f.vy.values)
        for name in ("radius", "du", "contacts"):
            np.testing.assert_array_equal(mesh.point_data[name], f[name].values)
        np.testing.assert_array_equal(mesh.point_data["wall"], ds["wall"].values)


def _invoke(params, tmp_path, **change):
    from granpipe.shear.cli import cli

    opts = {"replica": "1", "start": "0.3", "end": "0.4", "every": "0.01", "format": "extxyz",
            "out": str(tmp_path / "t.xyz"), **change}  # fmt: skip
    args = ["trajectory", "--params", json.dumps(params)]
    for k, v in opts.items():
        args += [f"--{k}", v]
    return CliRunner().invoke(cli, args, standalone_mode=False, catch_exceptions=True)


@pytest.mark.parametrize(
    "change, option, words",
    [
        ({"replica": "2"}, "--replica", "outside the point's ensemble"),
        ({"start": "-0.1"}, "--start", "outside the recorded time"),
        ({"end": "0.5"}, "--end", "outside the recorded time"),
        ({"start": "0.35", "end": "0.3"}, "--end", "before start"),
        ({"every": "1e-6"}, "--every", "below the time step"),
        ({"format": "pdb"}, "--format", "pdb"),
        ({"out": "/nonexistent/folder/t.xyz"}, "--out", "cannot write into"),
    ],
)
def test_bad_requests_are_refused_naming_the_option_before_integrating(
    params, tmp_path, monkeypatch, change, option, words
):
    def never(*a, **k):
        raise AssertionError("integrated")

    monkeypatch.setattr(shear_traj, "run_replica", never)
    call = _invoke(params, tmp_path, **change)
    assert call.exception is not None and not isinstance(call.exception, AssertionError)
    text = call.exception.format_message()
    assert option in text and words in text and "\n" not in text


def test_a_trajectory_too_large_is_refused_with_its_size(params, monkeypatch):
    monkeypatch.setattr(traj, "MAX_VALUES", 10_000)
    with pytest.raises(traj.TrajectoryError, match=r"11 frames × 108 disks .* 1\.19e\+04"):
        shear_traj.schedule(params, 1, (0.3, 0.4), 0.01)


def test_the_command_writes_the_replay(params, replay, tmp_path):
    call = _invoke(params, tmp_path, format="vtu", out=str(tmp_path / "t.pvd"))
    assert call.exception is None, call.output
    assert len(list((tmp_path / "t_frames").glob("frame_*.vtu"))) == replay[0].sizes["frame"]


@pytest.mark.parametrize("fmt", ["mp4", "gif"])
def test_a_movie_holds_every_frame(replay, tmp_path, fmt):
    import imageio.v2 as imageio

    ds, _ = replay
    path = traj.write_trajectory(ds, tmp_path / f"m.{fmt}", fmt, fps=10)
    assert path.suffix in (f".{fmt}", ".gif")
    if path.suffix == ".mp4":
        assert imageio.get_reader(path).count_frames() == ds.sizes["frame"]
    else:
        assert len(imageio.mimread(path)) == ds.sizes["frame"]
