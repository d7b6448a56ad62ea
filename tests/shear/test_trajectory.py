"""A shear replica replayed frame by frame: the run's states bit for bit, the files read back,
and every bad request refused before anything is integrated."""

import json
import re
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


def test_extxyz_reads_back_through_ovitos_own_importer(replay, tmp_path):
    """OVITO maps pos, radius and velo to its Position, Radius and Velocity properties,
    keeps the other per-atom columns under their names and the frame's values on the
    comment line (its ``Comment`` attribute)."""
    ovito_io = pytest.importorskip("ovito.io")

    ds, _ = replay
    path = traj.write_trajectory(ds, tmp_path / "t.xyz", "extxyz")
    pipeline = ovito_io.import_file(str(path))
    assert pipeline.source.num_frames == ds.sizes["frame"]
    for k in (0, ds.sizes["frame"] - 1):
        data, f = pipeline.compute(k), ds.isel(frame=k)
        p = data.particles
        xy, v = np.column_stack([f.x.values, f.y.values]), np.column_stack([f.vx, f.vy])
        np.testing.assert_allclose(np.asarray(p.positions)[:, :2], xy, atol=5e-9)
        np.testing.assert_allclose(np.asarray(p["Radius"]), f.radius.values, atol=5e-9)
        np.testing.assert_allclose(np.asarray(p["Velocity"])[:, :2], v, atol=5e-9)
        np.testing.assert_allclose(np.asarray(p["du"]), f.du.values, atol=5e-9)
        np.testing.assert_array_equal(np.asarray(p["contacts"]), f.contacts.values)
        np.testing.assert_array_equal(np.asarray(p["wall"]), ds["wall"].values)
        comment = data.attributes["Comment"]
        time = float(re.search(r"\btime=(\S+)", comment)[1])
        assert time == pytest.approx(float(f.time), abs=5e-9) and "units=" in comment


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


@pytest.fixture(scope="module")
def movie_setup(tmp_path_factory):
    """A point's run file (one replica per batch) and the movie's params."""
    from granpipe.shear.stages import runs_stage
    from tests.shear.conftest import shear_section

    cfg = shear_section(
        physics={"phi": [0.82], "n_inner": 12, "n_outer": 30},
        preparation={"growth_stages": 10, "growth_s": 0.4, "steady_s": 0.4},
        protocol={"record_s": 0.4, "tangent_alignment_s": 0.1, "sample_s": 0.02},
        ensemble={"n_replicas": 2, "batch_size": 1},
        events={"min_changes": 1, "quiet_s": 0.02},
        movie={"replica": 1, "before_s": 0.1, "after_s": 0.1, "every_s": 0.02},
    )
    run = tmp_path_factory.mktemp("shear_movie") / "batch_0001.nc"
    runs_stage(layout.runs_params(cfg, "phi=0.82"), 1, run)
    return cfg, run


def test_the_movie_shows_the_window_around_the_replicas_first_event(movie_setup, tmp_path):
    import imageio.v2 as imageio

    from granpipe.io import read_dataset
    from granpipe.shear.fits import event_times

    cfg, run = movie_setup
    params = layout.movie_params(cfg)
    assert layout.movie_point(cfg) == "phi=0.82" and layout.movie_input(cfg).endswith("0001.nc")
    path, frames = shear_traj.movie_stage(params, run, tmp_path / "m.gif")
    times = event_times(read_dataset(run), params["events"])[0]
    first = times[times >= 0.1]
    centre = first[0] if len(first) else 0.2
    lo, hi = traj.movie_window(centre, 0.1, 0.1, 0.0, 0.4)
    assert frames == round((hi - lo) / 0.02) + 1 == 11
    assert len(imageio.mimread(path)) == frames


def test_the_movie_refuses_a_run_file_of_other_physics(movie_setup, tmp_path):
    from granpipe.io import RunFileError

    cfg, run = movie_setup
    params = layout.movie_params(cfg)
    params["runs_config_hash"] = "0" * 16
    with pytest.raises(RunFileError, match="config"):
        shear_traj.movie_stage(params, run, tmp_path / "m.gif")
    assert not list(tmp_path.iterdir())
