"""A box replica replayed frame by frame: at the end of the measurement the state the
chained run parts saved, bit for bit; refusals before anything is integrated."""

import numpy as np
import pytest

from granpipe.box import layout
from granpipe.box import trajectory as box_traj
from granpipe.box.stages import init_stage, runs_stage
from granpipe.engine import State
from granpipe.errors import ConfigError
from granpipe.io import read_dataset
from granpipe.trajectory import TrajectoryError


@pytest.fixture
def point(section):
    n_l, gamma, kind, walls = layout.points(section)[0]
    return layout.point_name(n_l, gamma, kind, walls), (n_l, gamma, kind, walls)


def test_the_last_frame_is_the_state_the_chained_parts_end_in(section, point, tmp_path):
    name, (n_l, gamma, kind, walls) = point
    init = tmp_path / "init.nc"
    init_stage(layout.init_params(section, walls), n_l, kind, 0, init, log=None)
    previous = None
    for part in range(layout.n_parts(section)):
        out = tmp_path / f"part_{part}.nc"
        runs_stage(layout.runs_params(section, part, walls), n_l, gamma, kind, 0, part, init,
                   out, previous=previous, log=None)  # fmt: skip
        previous = out
    saved = read_dataset(previous)
    end = State.from_arrays({k[len("engine_") :]: saved[k].values
                             for k in saved.data_vars if k.startswith("engine_")})  # fmt: skip
    params = layout.trajectory_params(section, name)
    t_end = end.time
    ds = box_traj.trajectory(params, 0, (t_end, t_end), 1.0)  # one frame, at the end
    last = ds.isel(frame=-1)
    assert float(last.time) == pytest.approx(t_end, abs=1e-9)
    np.testing.assert_array_equal(np.column_stack([last.x.values, last.y.values]), end.positions)
    np.testing.assert_array_equal(np.column_stack([last.vx.values, last.vy.values]),
                                  end.velocities)  # fmt: skip
    np.testing.assert_array_equal(last.spin.values, end.spins)
    assert "du" not in ds and "local_lyapunov" not in ds and ds.attrs["length_unit"] == "sigma"
    assert float(last.phase) == pytest.approx(2 * np.pi * 4, abs=1e-3)  # 2 + 2 periods


def test_bad_requests_are_refused_before_the_preparation(section, point, monkeypatch):
    params = layout.trajectory_params(section, point[0])

    def never(*a, **k):
        raise AssertionError("integrated")

    monkeypatch.setattr(box_traj.preparation, "prepare", never)
    for args, option in (((1, (0, 1), 0.1), "replica"), ((0, (0, 30.0), 0.1), "end"),
                         ((0, (0, 1), 1e-6), "every")):  # fmt: skip
        with pytest.raises(TrajectoryError) as err:
            box_traj.trajectory(params, *args)
        assert err.value.option == option
        assert option == "replica" or " t0" in str(err.value)


def test_the_command_writes_vtu_frames_and_refuses_a_bad_replica(section, point, tmp_path):
    import json

    from click.testing import CliRunner

    from granpipe.box.cli import cli

    params = json.dumps(layout.trajectory_params(section, point[0]))

    def call(*extra):
        args = ["trajectory", "--params", params, "--start", "0", "--end", "1", "--every",
                "0.5", "--format", "vtu", "--out", str(tmp_path / "b.pvd"), *extra]  # fmt: skip
        return CliRunner().invoke(cli, args, standalone_mode=False)

    bad = call("--replica", "1")
    assert "--replica" in bad.exception.format_message()
    ok = call("--replica", "0")
    assert ok.exception is None, ok.output
    assert len(list((tmp_path / "b_frames").glob("*.vtu"))) == 3


def test_the_movie_shows_the_records_last_periods(section, point, tmp_path):
    import imageio.v2 as imageio

    section["movie"] = {"enabled": True, "format": "gif", "N_l": None, "Gamma": None,
                        "inits": ["random"], "replica": 0, "periods": 1,
                        "frames_per_period": 4, "fps": 5}  # fmt: skip
    layout.check(section)
    (name,) = layout.movie_points(section)
    assert name == layout.point_name(5, 2.0, "random", layout.wall_settings(section)[0])
    params = layout.movie_params(section, name)
    path, frames = box_traj.movie_stage(params, tmp_path / layout.movie_file(section, name)
                                        .replace("movie/", ""))  # fmt: skip
    assert frames == 5 and len(imageio.mimread(path)) == 5
    # no starts named: every start of the grid
    grid = {**section["grid"], "inits": ["crystal"]}
    section = {**section, "grid": grid, "movie": {**section["movie"], "inits": None}}
    layout.check(section)
    assert [p.split(",")[2] for p in layout.movie_points(section)] == ["init=crystal"]
    section["movie"]["Gamma"] = 1.0
    with pytest.raises(ConfigError, match="'box.movie.Gamma' = 1.0 is not in"):
        layout.check(section)
