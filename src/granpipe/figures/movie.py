"""Movies of a replayed trajectory (:mod:`granpipe.trajectory`): the disks drawn to scale,
coloured by speed (relative to the mobile disks' mean velocity where the dataset's
``speed_reference`` attribute is ``bed``: the box) and, beside, by |δu_i| (by |spin|
where the study has no tangent vector), over a strip with time, λ̄ and V; MP4 through
imageio-ffmpeg, or a GIF (Pillow).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

__all__ = ["movie_suffix", "frame_figure", "write_movie"]

WIDTH_PX, HEIGHT_PX, DPI = 1280, 800, 100
"""Movie frame size (multiples of 16, what H.264 encoders take without resizing)."""


def movie_suffix() -> str:
    """``.mp4`` when imageio-ffmpeg finds an ffmpeg executable, else ``.gif``."""
    try:
        import imageio_ffmpeg

        imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError, OSError):
        return ".gif"
    return ".mp4"


def _right(ds: xr.Dataset):
    """(values (F, N), label, norm) of the right panel."""
    from matplotlib.colors import LogNorm, Normalize

    if "du" in ds:
        return ds["du"].values, "|δu_i| / max", LogNorm(1e-3, 1.0, clip=True)
    spin = np.abs(ds["spin"].values) if "spin" in ds else np.zeros(ds["x"].shape)
    top = float(np.percentile(spin, 99)) if spin.size else 1.0
    return spin, "|spin| [rad/t0]", Normalize(0.0, top if top > 0 else 1.0)


def frame_figure(ds: xr.Dataset):
    """A figure for the movie of ``ds`` and ``draw(k)``, which shows frame ``k`` on it.

    Returns ``(fig, draw)``; the figure is WIDTH_PX × HEIGHT_PX at DPI.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import EllipseCollection
    from matplotlib.colors import Normalize

    L = ds.attrs.get("length_unit", "d_s")
    T = ds.attrs.get("time_unit", "s")
    wall = ds["wall"].values.astype(bool)
    vx, vy = ds["vx"].values, ds["vy"].values
    speed_label = f"|v_i| [{L}/t0]"
    if ds.attrs.get("speed_reference") == "bed":  # the box: the bed's flight taken out
        vx = vx - vx[:, ~wall].mean(axis=1, keepdims=True)
        vy = vy - vy[:, ~wall].mean(axis=1, keepdims=True)
        speed_label = f"|v_i − ⟨v⟩| [{L}/t0]"
    speed = np.hypot(vx, vy)
    mob = speed[:, ~wall]
    top = float(np.percentile(mob, 99)) if mob.size else 1.0
    norms = [Normalize(0.0, top if top > 0 else 1.0)]
    right, right_label, right_norm = _right(ds)
    norms.append(right_norm)
    fig = plt.figure(figsize=(WIDTH_PX / DPI, HEIGHT_PX / DPI), dpi=DPI)
    grid = fig.add_gridspec(2, 2, height_ratios=[4, 1], hspace=0.25, wspace=0.15)
    x, y, r = ds["x"].values, ds["y"].values, ds["radius"].values
    pad = float(r.max())
    lims = (float(x.min()) - pad, float(x.max()) + pad, float(y.min()) - pad,
            float(y.max()) + pad)  # fmt: skip
    panels = []
    for col, (label, norm, cmap) in enumerate(
        ((speed_label, norms[0], "viridis"), (right_label, norms[1], "magma"))
    ):
        ax = fig.add_subplot(grid[0, col])
        ax.set_aspect("equal")
        ax.set_xlim(lims[0], lims[1])
        ax.set_ylim(lims[2], lims[3])
        ax.set_xticks([])
        ax.set_yticks([])
        coll = EllipseCollection(2 * r[0], 2 * r[0], np.zeros(len(wall)), units="xy",
                                 offsets=np.column_stack([x[0], y[0]]),
                                 offset_transform=ax.transData, edgecolors="none")  # fmt: skip
        ax.add_collection(coll)
        colours = ScalarMappable(norm, cmap)
        fig.colorbar(colours, ax=ax, shrink=0.8, label=label)
        panels.append((coll, colours))
    strip = fig.add_subplot(grid[1, :])
    t = ds["time"].values
    lines = []
    if "global_speed" in ds:
        lines += strip.plot(t, ds["global_speed"].values, color="C0", label=f"V [{L}/t0]")
    strip.set_xlabel(f"time [{T}]")
    if "local_lyapunov" in ds:
        twin = strip.twinx()
        lines += twin.plot(t, ds["local_lyapunov"].values, color="C3", label="λ̄ [1/t0]")
        twin.axhline(0.0, color="C3", lw=0.5, ls=":")
        twin.set_ylabel("λ̄ [1/t0]")
    strip.set_ylabel(f"V [{L}/t0]")
    if lines:
        strip.legend(lines, [ln.get_label() for ln in lines], loc="upper left", fontsize=8)
    cursor = strip.axvline(t[0], color="k", lw=1)
    title = fig.suptitle("")
    head = f"{ds.attrs.get('study', '')} {ds.attrs.get('point', '')}, replica " \
        f"{ds.attrs.get('replica', '')}"  # fmt: skip
    grey = np.array([0.6, 0.6, 0.6, 1.0])

    def draw(k: int) -> None:
        offsets = np.column_stack([x[k], y[k]])
        for (coll, colours), values in zip(panels, (speed[k], right[k]), strict=True):
            coll.set_offsets(offsets)
            coll.set_facecolor(np.where(wall[:, None], grey, colours.to_rgba(values)))
        cursor.set_xdata([t[k], t[k]])
        title.set_text(f"{head}: t = {t[k]:.3f} {T}")

    return fig, draw


def _frames(ds: xr.Dataset):
    """Every frame of ``ds`` drawn, as (H, W, 3) uint8 arrays."""
    import matplotlib.pyplot as plt

    fig, draw = frame_figure(ds)
    try:
        for k in range(ds.sizes["frame"]):
            draw(k)
            fig.canvas.draw()
            yield np.ascontiguousarray(np.asarray(fig.canvas.buffer_rgba())[..., :3])
    finally:
        plt.close(fig)


def _write_mp4(ds: xr.Dataset, tmp: Path, fps: float) -> None:
    import imageio_ffmpeg

    writer = imageio_ffmpeg.write_frames(str(tmp), (WIDTH_PX, HEIGHT_PX), fps=float(fps),
                                         codec="libx264", quality=7, macro_block_size=16,
                                         output_params=["-f", "mp4"])  # fmt: skip
    writer.send(None)
    try:
        for frame in _frames(ds):
            writer.send(frame)
    finally:
        writer.close()


def _write_gif(ds: xr.Dataset, tmp: Path, fps: float) -> None:
    from PIL import Image

    images = [Image.fromarray(f).quantize(colors=255) for f in _frames(ds)]
    images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:],
                   duration=round(1000.0 / float(fps)), loop=0)  # fmt: skip


def write_movie(ds: xr.Dataset, path, fps: float = 10.0) -> Path:
    """Every frame of ``ds`` as a movie at ``path``, written atomically
    (:func:`granpipe.io.atomic_path`): MP4 (H.264 through imageio-ffmpeg, which must find
    ffmpeg: :func:`movie_suffix`) for a ``.mp4`` path, a GIF (Pillow) for a ``.gif``
    path."""
    from ..io import atomic_path

    p = Path(path)
    if p.suffix not in (".mp4", ".gif"):
        raise ValueError(f"a movie is a .mp4 or a .gif file, not {p.name}")
    with atomic_path(p) as tmp:
        (_write_mp4 if p.suffix == ".mp4" else _write_gif)(ds, tmp, fps)
    return p
