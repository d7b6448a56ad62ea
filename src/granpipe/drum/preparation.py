"""Initial states of the drum study (stage ``init``; Sec. II.2, docs/drum.md "Start-up").

**Placement** (:func:`random_placement`): random non-overlapping placement of the mobile
disks inside the drum.

"We place the N non-wall disks randomly inside the drum and allow them to fall
to the bottom": random sequential addition, uniform over the free disk of the
drum, rejecting any trial that overlaps a disk already placed or the wall. At
the paper's filling (~24 % of the free area) a trial is accepted after a few
attempts, so placement costs milliseconds.

**Start-up** (:func:`prepare`): after the placement, the fall in the turning drum
(``paper`` start-up, :func:`fall`) or settling to rest in a still drum (``settled``,
:func:`settle`), as :mod:`granpipe.drum.protocol` describes step by step; the
:class:`Start` it returns is what the init file holds.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .layout import load

if TYPE_CHECKING:
    from .layout import Steps
    from .model import DrumModel

__all__ = ["random_placement", "min_gap", "Start", "fall", "settle", "prepare"]


def random_placement(
    diameters: np.ndarray,
    inner_radius: float,
    rng: np.random.Generator,
    *,
    gap: float = 0.05,
    max_attempts: int = 100_000,
) -> np.ndarray:
    """Positions of disks placed uniformly at random without overlap.

    Parameters
    ----------
    diameters : (N,) float64 [d_s]
        Disk diameters d_i.
    inner_radius : float [d_s]
        Radius of the free disk (R − d_w/2): a disk of diameter d is kept within
        ``inner_radius − d/2 − gap`` of the axis.
    rng : numpy.random.Generator
        The replica's stream; the result depends on it only.
    gap : float [d_s]
        Minimum clearance between two disks and between a disk and the wall,
        so that the fall starts with no contact at all.
    max_attempts : int
        Trials per disk before giving up (``RuntimeError``: the drum is too full).

    Returns
    -------
    (N, 2) float64 [d_s], centred on the drum axis. Disks are placed in a random
    order (so neither species is favoured for the free space).
    """
    d = np.asarray(diameters, dtype=np.float64)
    n = len(d)
    pos = np.full((n, 2), np.nan)
    placed = np.zeros(n, dtype=bool)
    for i in rng.permutation(n):
        rmax = inner_radius - d[i] / 2.0 - gap
        if rmax <= 0:
            raise RuntimeError(f"disk {i} (d={d[i]}) does not fit in the drum")
        for _ in range(max_attempts):
            r = rmax * np.sqrt(rng.random())
            phi = 2.0 * np.pi * rng.random()
            trial = np.array([r * np.cos(phi), r * np.sin(phi)])
            others = pos[placed]
            if len(others):
                dist = np.hypot(*(others - trial).T)
                if np.any(dist < (d[placed] + d[i]) / 2.0 + gap):
                    continue
            pos[i] = trial
            placed[i] = True
            break
        else:
            raise RuntimeError(
                f"random placement failed after {max_attempts} attempts for disk {i}: "
                "the drum is too full for random sequential addition"
            )
    return pos


def min_gap(positions: np.ndarray, diameters: np.ndarray) -> float:
    """Smallest surface-to-surface distance between two disks [d_s] (negative = overlap)."""
    p = np.asarray(positions, dtype=np.float64)
    d = np.asarray(diameters, dtype=np.float64)
    diff = p[:, None, :] - p[None, :, :]
    dist = np.hypot(diff[..., 0], diff[..., 1])
    gap = dist - (d[:, None] + d[None, :]) / 2.0
    np.fill_diagonal(gap, np.inf)
    return float(gap.min())


# ------------- start-ups: placement, then fall (paper) or settling (settled)
@dataclass
class Start:
    """Where the stage ``runs`` starts a replica (the content of the init file).

    Attributes
    ----------
    positions, velocities : (N, 2) float64 [d_s], [d_s/t0] of the mobile disks
    wall_angle : float [rad]
        Clockwise angle the drum has turned since the placement (0 for the settled
        start-up, whose drum starts turning here).
    settled : bool
        The settling criterion was met (always true for the paper start-up, which has
        none).
    settle_time : float [s]
        Duration of the fall (and settling) before this state.
    n_steps : int; wall_time : float [s]
        Cost of preparing it.
    spins : (N,) float64 [rad/t0] or None
        Static friction only: the mobile disks' angular velocities.
    shear : ((K, 2) int64, (K,) float64 [d_s]) or None
        Static friction only: the stretched tangential springs, as disk pairs (wall disks
        numbered after the N mobile ones) and their shear history
        (:meth:`granpipe.engine.State.shear_history`).
    """

    positions: np.ndarray
    velocities: np.ndarray
    wall_angle: float
    settled: bool
    settle_time: float
    n_steps: int
    wall_time: float
    spins: np.ndarray | None = None
    shear: tuple[np.ndarray, np.ndarray] | None = None


def _placement(model: DrumModel, protocol: Mapping, rng) -> np.ndarray:
    gap = float(protocol["placement_gap"])
    return random_placement(model.diameters, model.geom.inner_radius, rng, gap=gap)


def fall(
    model: DrumModel,
    st: Steps,
    positions: np.ndarray,
    *,
    on_chunk: Callable[[int, float], None] | None = None,
) -> Start:
    """The paper start-up: disks at rest at ``positions`` fall while the drum turns.

    Runs ``st.pre_rotation − st.alignment`` steps (forward dynamics only, no cap), so that
    the stage ``runs`` reaches t = 0 exactly ``pre_rotation_deg`` after the placement.
    """
    t_wall = time.perf_counter()
    sim = model.simulation(model.omega)
    state = model.new_state(sim, positions, np.zeros_like(positions))
    n_fall = st.pre_rotation - st.alignment
    done = 0
    while done < n_fall:
        n = min(st.chunk, n_fall - done)
        sim.run(state, n)
        done += n
        if on_chunk is not None:
            on_chunk(done, (done - st.pre_rotation) * st.dt_s)
    return Start(
        **model.start_arrays(state),
        wall_angle=model.omega * n_fall * st.dt,
        settled=True,
        settle_time=n_fall * st.dt_s,
        n_steps=n_fall,
        wall_time=time.perf_counter() - t_wall,
    )


def settle(
    model: DrumModel,
    st: Steps,
    settle_cfg: Mapping,
    positions: np.ndarray,
    *,
    on_chunk: Callable[[int, float], None] | None = None,
) -> Start:
    """The settled start-up: disks at ``positions`` fall and settle with the drum at rest."""
    t_wall = time.perf_counter()
    pos = np.asarray(positions, np.float64)
    sim = model.simulation(0.0)
    state = model.new_state(sim, pos, np.zeros_like(pos))
    threshold = float(settle_cfg["speed_threshold"])
    vmax = float(settle_cfg["max_speed"])
    n_mob = model.n_mobile
    history: list[np.ndarray] = []
    done = 0
    settled = False
    while done < st.settle_max:
        n = min(st.chunk, st.settle_max - done)
        for _ in range(n // st.block):
            rec = sim.run(state, st.block, stride=st.block)
            history.append(model.rms_speed(rec.global_speed))
            # Free fall from the top of the drum would hit the pile at ~10 sqrt(g d_s):
            # this start-up caps the speeds instead.
            vel = state.velocities[:n_mob]
            speed = np.hypot(vel[:, 0], vel[:, 1])
            fast = speed > vmax
            if fast.any():
                vel[fast] *= (vmax / speed[fast])[:, None]
                sim.refresh(state)
        done += n
        if on_chunk is not None:
            on_chunk(done, done * st.dt_s)
        if done >= st.settle_min:
            tail = np.concatenate(history[-st.settle_hold :])
            if len(tail) >= st.settle_hold and np.all(tail < threshold):
                settled = True
                break
    return Start(
        **model.start_arrays(state),
        wall_angle=0.0,
        settled=settled,
        settle_time=done * st.dt_s,
        n_steps=done,
        wall_time=time.perf_counter() - t_wall,
    )


def prepare(model: DrumModel, section: Mapping, st: Steps, rng, *, on_chunk=None) -> Start:
    """Placement and the section's start-up (stage ``init``) from the placement stream."""
    sec = load(section)
    pos = _placement(model, sec["protocol"], rng)
    if sec["protocol"]["startup"] == "settled":
        return settle(model, st, sec["settle"], pos, on_chunk=on_chunk)
    return fall(model, st, pos, on_chunk=on_chunk)
