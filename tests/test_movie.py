"""The report's movies: the window around an event, the movie file's checks, and writes
that leave nothing behind when they fail."""

import numpy as np
import pytest
import xarray as xr

from granpipe import trajectory as traj
from granpipe.figures import movie


def _frames(n_frames=3, n_disks=4) -> xr.Dataset:
    """A synthetic trajectory: disks on a row moving right, the last a wall disk."""
    t = np.arange(n_frames) * 0.1
    x = np.arange(n_disks)[None, :] + 0.5 * t[:, None]
    zeros = np.zeros((n_frames, n_disks))
    return xr.Dataset(
        {
            "x": (("frame", "disk"), x), "y": (("frame", "disk"), zeros),
            "radius": (("frame", "disk"), zeros + 0.5),
            "vx": (("frame", "disk"), zeros + 0.5), "vy": (("frame", "disk"), zeros),
            "du": (("frame", "disk"), zeros + 0.1),
            "wall": ("disk", (np.arange(n_disks) == n_disks - 1).astype(np.int8)),
            "time": ("frame", t), "global_speed": ("frame", np.ones(n_frames)),
            "local_lyapunov": ("frame", np.zeros(n_frames)),
        },
        attrs={"length_unit": "d_s", "time_unit": "s", "study": "test"},
    )  # fmt: skip


@pytest.mark.parametrize(
    "centre, expected",
    [
        (5.0, (4.0, 7.0)),  # inside the record
        (0.5, (0.0, 3.0)),  # moved to the record's start, its length kept
        (9.5, (7.0, 10.0)),  # moved to the record's end
    ],
)
def test_the_movie_window_keeps_its_length_inside_the_record(centre, expected):
    assert traj.movie_window(centre, 1.0, 2.0, 0.0, 10.0) == pytest.approx(expected)


def test_a_record_shorter_than_the_window_is_shown_whole():
    assert traj.movie_window(1.0, 1.0, 2.0, 0.0, 2.0) == pytest.approx((0.0, 2.0))


@pytest.mark.parametrize("name", ["m.avi", "m", "m.mp4.tmp"])
def test_a_movie_file_is_mp4_or_gif(name):
    with pytest.raises(traj.TrajectoryError, match="a .mp4 or a .gif") as err:
        traj.check_movie_file(name)
    assert err.value.option == "format"


def test_mp4_without_ffmpeg_is_refused_for_a_workflow_movie(monkeypatch):
    monkeypatch.setattr(movie, "movie_suffix", lambda: ".gif")
    with pytest.raises(traj.TrajectoryError, match="needs ffmpeg"):
        traj.check_movie_file("m.mp4")
    assert traj.check_movie_file("m.gif").suffix == ".gif"


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_the_movie_holds_every_frame(tmp_path, suffix):
    import imageio.v2 as imageio

    if suffix == ".mp4" and movie.movie_suffix() != ".mp4":
        pytest.skip("no ffmpeg on this machine")
    ds = _frames(5)
    path = movie.write_movie(ds, tmp_path / f"m{suffix}", fps=5)
    reader = imageio.get_reader(path)
    assert reader.count_frames() == 5 if suffix == ".mp4" else len(imageio.mimread(path)) == 5
    assert [p.name for p in tmp_path.iterdir()] == [f"m{suffix}"]  # no temporary left


@pytest.mark.parametrize("suffix", [".mp4", ".gif"])
def test_a_failed_movie_leaves_the_old_file_and_no_temporary(tmp_path, monkeypatch, suffix):
    if suffix == ".mp4" and movie.movie_suffix() != ".mp4":
        pytest.skip("no ffmpeg on this machine")
    target = tmp_path / f"m{suffix}"
    target.write_bytes(b"old")
    draw = movie.frame_figure

    def failing(ds):
        fig, inner = draw(ds)

        def draw_k(k):
            if k == 2:
                raise RuntimeError("interrupted")
            inner(k)

        return fig, draw_k

    monkeypatch.setattr(movie, "frame_figure", failing)
    with pytest.raises(RuntimeError, match="interrupted"):
        movie.write_movie(_frames(4), target)
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == [target.name]


def test_the_box_colours_speed_relative_to_the_bed():
    """Every mobile disk moves with the bed: relative to its mean the speeds are zero, so
    each mobile disk gets the colour of zero; absolute, the colour of the top speed."""
    import matplotlib.pyplot as plt

    ds = _frames(2)
    for reference, level in ((None, 1.0), ("bed", 0.0)):
        if reference:
            ds.attrs["speed_reference"] = reference
        fig, draw = movie.frame_figure(ds)
        draw(1)
        coll = fig.axes[0].collections[0]
        cmap = plt.get_cmap("viridis")
        np.testing.assert_allclose(coll.get_facecolor()[:3], [cmap(level)] * 3)
        plt.close(fig)
