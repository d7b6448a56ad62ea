"""A drum replica replayed frame by frame: the run's snapshots bit for bit in both recorded
windows, spins under static friction, the command and its refusals."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from granpipe.drum import trajectory as drum_traj
from granpipe.drum.layout import filled, point_names, trajectory_params
from granpipe.drum.protocol import run_replica, tiny_section


@pytest.fixture(scope="module")
def run(tiny):
    return run_replica(tiny, 1)


def _same_state(frame, run, k):
    n = run.sizes["particle"]
    np.testing.assert_array_equal(np.column_stack([frame.x.values, frame.y.values])[:n],
                                  run["snapshot_position"].values[k])  # fmt: skip
    np.testing.assert_array_equal(np.column_stack([frame.vx.values, frame.vy.values])[:n],
                                  run["snapshot_velocity"].values[k])  # fmt: skip
    np.testing.assert_array_equal(frame.du.values[:n], run["snapshot_du"].values[k])


def test_the_frames_are_the_runs_states_in_both_windows(tiny, run):
    """The onset window's first frame is the run's snapshot at t = 0; its last (0.6 s, where
    this replica's decay window starts) and the decay window's first are the snapshot at
    the start of the decay window."""
    onset_s = tiny["protocol"]["onset_window_s"]
    assert float(run["decay_start"].values[0]) == pytest.approx(onset_s, abs=1e-4)
    on = drum_traj.trajectory(tiny, 1, (0.0, onset_s), 0.1)
    assert on.sizes["frame"] == 7 and on.attrs["window"] == "onset"
    _same_state(on.isel(frame=0), run, 0)
    _same_state(on.isel(frame=-1), run, 1)
    de = drum_traj.trajectory(tiny, 1, (0.0, 0.3), 0.1, part="decay")
    _same_state(de.isel(frame=0), run, 1)
    # the drum turns, then stops abruptly 0.2 s into the decay window
    assert np.all(np.diff(on["phase"].values) > 0)
    assert de["phase"].values[-1] == de["phase"].values[-2]
    assert "spin" not in on and np.isnan(on["local_lyapunov"].values[0])


def test_spins_under_static_friction():
    sec = tiny_section({"physics": {"friction": "static"}})
    sec["ensemble"].update(n_replicas=1)
    sec = filled(sec)
    ds = drum_traj.trajectory(sec, 0, (0.0, 0.1), 0.05)
    assert ds["spin"].attrs["units"] == "rad/t0" and np.any(ds["spin"].values[-1] != 0)


def test_the_command_writes_a_window_and_refuses_bad_requests(tiny, tmp_path, monkeypatch):
    from granpipe.drum.cli import cli

    params = json.dumps(trajectory_params(tiny, point_names(tiny)[0]))

    def call(*extra):
        args = ["trajectory", "--params", params, "--replica", "1", "--every", "0.1",
                "--out", str(tmp_path / "d.xyz"), "--format", "extxyz", *extra]  # fmt: skip
        return CliRunner().invoke(cli, args, standalone_mode=False)

    ok = call("--start", "0", "--end", "0.3", "--part", "decay")
    assert ok.exception is None, ok.output
    assert (tmp_path / "d.xyz").read_text().count("Properties=") == 4

    def never(*a, **k):
        raise AssertionError("integrated")

    monkeypatch.setattr(drum_traj, "prepare", never)
    for extra, option, words in (
        (("--start", "0", "--end", "0.7"), "--end", "outside the recorded time 0 .. 0.6"),
        (("--start", "0", "--end", "0.3", "--replica", "2"), "--replica", "outside"),
        (("--start", "0", "--end", "0.3", "--part", "wait"), "--part", "wait"),
        (("--start", "0", "--end", "0.3", "--every", "1e-5"), "--every", "below the time step"),
    ):
        bad = call(*extra)
        text = bad.exception.format_message()
        assert option in text and words in text and "\n" not in text
