"""Walls with prescribed motion: rotating wall disks (drum) and flat lines (box).

Walls act on disks through the same contact law as disk pairs, with infinite mass
on the wall side (docs/drum.md, docs/box.md; docs/architecture.md, "The engine").

* :class:`WallDisks` — the disks flagged ``is_wall`` turn about ``centre`` at their rate
  (``new_state(wall_rate=...)``, default 1; the shear cell's still ring: 0) times
  ``omega`` (counter-clockwise positive; the drum turns clockwise), which switches to
  ``omega_after`` at ``t_switch`` (the drum stop). The angle is part of the state, so the
  motion can be redefined between chunks of a run without a jump.
* :class:`FlatWalls` — vertical lines ``x = x_left`` and ``x = x_right`` and a
  horizontal bottom at ``y = z_b(t) = z0 + A r(t) sin(omega t + phase)``, with an
  optional linear amplitude ramp ``r(t) = clip((t - ramp_start)/ramp_time, 0, 1)``
  (docs/box.md, hazard (i): start smoothly with a phase offset, e.g. ``phase = -pi/2``
  starts at the bottom turning point, and/or a ramp). The vertical axis is the
  second coordinate; the box paper's ``z`` is our ``y``. With ``shaken_sides`` the
  side walls move vertically with the bottom (the whole box is driven, docs/box.md,
  "Which walls move"): an infinite vertical line keeps its place, but a disk touching
  it slides against a wall moving at ``dz_b/dt``. With ``wall_torque = False`` the
  walls' tangential force exerts no torque on the disk (the ``sigma_j = 0`` reading of
  the box paper's Eq. A4 for a flat wall).

Timing inside a step (velocity Verlet, forces at ``t_{n+1}`` from positions at
``t_{n+1}`` and half-step velocities): walls take their positions at ``t_{n+1}``
and their velocities at ``t_{n+1/2}``, matching the disks' half-step velocities.

The kernels here know no contact law: they move the walls, and tell which disks touch
a flat wall (:func:`near_walls`, :func:`wall_candidates`) and where (:func:`wall_gap`,
:func:`wall_normal`); the contact forces are the passes' (:mod:`granpipe.engine.passes`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from granpipe._jit import njit
from granpipe.engine import layout as L
from granpipe.errors import ConfigError

__all__ = ["WallDisks", "FlatWalls", "NO_FLAT_WALLS", "NO_WALL_DISKS", "bottom_height"]
__all__ += ["bottom_velocity", "bottom", "wall_velocity", "wall_torque_factor", "wall_omega"]
__all__ += ["time_now", "place_wall_disks", "advance_walls", "has_flat", "wall_gap"]
__all__ += ["wall_normal", "near_walls", "wall_candidates"]


@dataclass(frozen=True)
class WallDisks:
    """Rigid rotation of the disks flagged as walls.

    Parameters
    ----------
    centre : (2,) float [length]
        Rotation centre (must not change during a run).
    omega : float [rad/time]
        Angular velocity before ``t_switch`` (counter-clockwise positive).
    omega_after : float [rad/time]
        Angular velocity from ``t_switch`` on (default: ``omega``, no switch).
    t_switch : float [time]
        Time of the switch (default: never).
    """

    centre: tuple[float, float] = (0.0, 0.0)
    omega: float = 0.0
    omega_after: float | None = None
    t_switch: float = math.inf

    def __post_init__(self):
        for name in ("omega", "t_switch"):
            if math.isnan(float(getattr(self, name))):
                raise ConfigError(f"WallDisks.{name} is NaN")
        if len(self.centre) != 2:
            raise ConfigError("WallDisks.centre must have 2 components")

    def params(self) -> np.ndarray:
        """``[cx, cy, omega, omega_after, t_switch]`` for the kernels."""
        after = self.omega if self.omega_after is None else self.omega_after
        return np.array(
            [self.centre[0], self.centre[1], self.omega, after, self.t_switch], dtype=np.float64
        )


@dataclass(frozen=True)
class FlatWalls:
    """Flat line walls: left, right (vertical) and a driven bottom.

    Parameters
    ----------
    x_left, x_right : float or None [length]
        Positions of the vertical walls (None: no such wall).
    bottom : bool
        Whether the bottom wall exists.
    z0 : float [length]
        Mean height of the bottom.
    amplitude : float [length]
        Drive amplitude ``A`` (``Gamma = A omega² / g``).
    omega : float [rad/time]
        Drive angular frequency.
    phase : float [rad]
        Phase ``phi`` of ``sin(omega t + phi)``.
    ramp_start, ramp_time : float [time]
        Linear amplitude ramp from 0 at ``ramp_start`` to ``A`` at
        ``ramp_start + ramp_time`` (``ramp_time = 0``: no ramp).
    shaken_sides : bool
        The side walls move vertically with the bottom (velocity ``dz_b/dt``); False:
        they stand still and only the bottom is driven.
    wall_torque : bool
        The walls' tangential force exerts a torque on the disk (lever from the disk's
        centre to the contact point); False: it acts on the disk's centre only.
    """

    x_left: float | None = None
    x_right: float | None = None
    bottom: bool = True
    z0: float = 0.0
    amplitude: float = 0.0
    omega: float = 0.0
    phase: float = 0.0
    ramp_start: float = 0.0
    ramp_time: float = 0.0
    shaken_sides: bool = False
    wall_torque: bool = True

    def __post_init__(self):
        if self.x_left is not None and self.x_right is not None and self.x_right <= self.x_left:
            raise ConfigError("FlatWalls: x_right must exceed x_left")
        if self.ramp_time < 0:
            raise ConfigError("FlatWalls.ramp_time must be >= 0")

    def params(self) -> np.ndarray:
        """Kernel parameter vector (see :func:`bottom_height`)."""
        return np.array(
            [
                0.0 if self.x_left is None else 1.0,
                0.0 if self.x_left is None else self.x_left,
                0.0 if self.x_right is None else 1.0,
                0.0 if self.x_right is None else self.x_right,
                1.0 if self.bottom else 0.0,
                self.z0,
                self.amplitude,
                self.omega,
                self.phase,
                self.ramp_start,
                self.ramp_time,
                1.0 if self.shaken_sides else 0.0,
                1.0 if self.wall_torque else 0.0,
            ],
            dtype=np.float64,
        )

    def height(self, t):
        """Bottom height ``z_b(t)`` (vectorised over ``t``)."""
        p = self.params()
        return np.vectorize(lambda s: bottom_height(p, s))(t)

    def velocity(self, t):
        """Bottom velocity ``dz_b/dt`` (vectorised over ``t``)."""
        p = self.params()
        return np.vectorize(lambda s: bottom_velocity(p, s))(t)


NO_FLAT_WALLS = FlatWalls(bottom=False).params()
NO_WALL_DISKS = np.array([0.0, 0.0, 0.0, 0.0, np.inf])


@njit
def _ramp(fw, t):
    if fw[10] <= 0.0:
        return 1.0, 0.0
    s = (t - fw[9]) / fw[10]
    if s <= 0.0:
        return 0.0, 0.0
    if s >= 1.0:
        return 1.0, 0.0
    return s, 1.0 / fw[10]


@njit
def bottom_height(fw, t):
    """``z_b(t) = z0 + A r(t) sin(omega t + phase)`` for flat-wall parameters ``fw``."""
    r, _ = _ramp(fw, t)
    return fw[5] + fw[6] * r * math.sin(fw[7] * t + fw[8])


@njit
def bottom_velocity(fw, t):
    """``dz_b/dt = A [r(t) omega cos(omega t + phase) + r'(t) sin(omega t + phase)]``."""
    r, dr = _ramp(fw, t)
    arg = fw[7] * t + fw[8]
    return fw[6] * (r * fw[7] * math.cos(arg) + dr * math.sin(arg))


@njit
def wall_velocity(fw, w, vb):
    """Vertical velocity of flat wall ``w`` (0 left, 1 right, 2 bottom) when the bottom
    moves at ``vb``: the bottom's, and the side walls' if they are shaken with it."""
    return vb if (w == 2 or fw[11] != 0.0) else 0.0


@njit
def wall_torque_factor(fw):
    """1 if the walls' tangential force exerts a torque on the disk, else 0."""
    return fw[12]


@njit
def wall_omega(wd, t):
    """Angular velocity of the wall disks at time ``t``."""
    return wd[2] if t < wd[4] else wd[3]


@njit
def time_now(clock, counters, dt):
    """Time of a replica's state: its origin plus its steps."""
    return clock[L.T_ORIGIN] + counters[L.STEP] * dt


@njit
def bottom(fw, t):
    """Height and velocity of the flat bottom at time ``t`` (0, 0 without one)."""
    if fw[4] == 0.0:
        return 0.0, 0.0
    return bottom_height(fw, t), bottom_velocity(fw, t)


@njit
def has_flat(fw):
    """Whether there is any flat wall."""
    return fw[0] != 0.0 or fw[2] != 0.0 or fw[4] != 0.0


# --------------------------------------------------------------------------- wall disks


@njit
def place_wall_disks(vec, sca, walls, n_walls, wd, theta, omega):
    """Place each wall disk at angle ``rate theta`` with velocity ``rate omega x (r - c)``
    and spin ``rate omega`` (its rate: ``sca[WALL_RATE]``)."""
    pos = vec[L.POS]
    vel = vec[L.VEL]
    ref = vec[L.WALL_REF]
    spin = sca[L.SPIN]
    cx, cy = wd[0], wd[1]
    c1, s1 = math.cos(theta), math.sin(theta)
    for m in range(n_walls):
        i = walls[m]
        f = sca[L.WALL_RATE, i]
        c, s = (c1, s1) if f == 1.0 else (math.cos(f * theta), math.sin(f * theta))
        w = f * omega
        rx = ref[i, 0]
        ry = ref[i, 1]
        x = cx + c * rx - s * ry
        y = cy + s * rx + c * ry
        pos[i, 0] = x
        pos[i, 1] = y
        vel[i, 0] = -w * (y - cy)
        vel[i, 1] = w * (x - cx)
        spin[i] = w


@njit
def advance_walls(vec, sca, walls, wd, fw, clock, counters, dt, half_skin):
    """Move the walls over the step that starts now; returns (wall disks moved far enough
    for a list rebuild, z_b at the step's end, v_b at its middle)."""
    t0 = time_now(clock, counters, dt)
    t1 = clock[L.T_ORIGIN] + (counters[L.STEP] + 1) * dt
    moved = False
    n_walls = counters[L.N_WALLS]
    if n_walls > 0:
        omega = wall_omega(wd, t0 + 0.5 * dt)
        if omega != 0.0 or clock[L.LAST_OMEGA] != 0.0:
            clock[L.THETA] += omega * dt
            place_wall_disks(vec, sca, walls, n_walls, wd, clock[L.THETA], omega)
            clock[L.LAST_OMEGA] = omega
            # a wall disk at distance R and rate f has moved by at most
            # |f| R |theta - theta_build| (WALL_RMAX: the largest |f| R)
            moved = clock[L.WALL_RMAX] * abs(clock[L.THETA] - clock[L.THETA_BUILD]) > half_skin
    zb = 0.0
    vb = 0.0
    if fw[4] != 0.0:
        zb = bottom_height(fw, t1)
        vb = bottom_velocity(fw, t0 + 0.5 * dt)
        if abs(zb - clock[L.ZB_NEAR]) > half_skin:
            counters[L.NEAR_WALLS] = -1
    return moved, zb, vb


# --------------------------------------------------------------------------- flat walls


@njit
def wall_gap(w, pos, i, fw, zb):
    """Distance from disk ``i``'s centre to flat wall ``w`` (0 left, 1 right, 2 bottom)."""
    if w == 0:
        return pos[i, 0] - fw[1]
    if w == 1:
        return fw[3] - pos[i, 0]
    return pos[i, 1] - zb


@njit
def wall_normal(w):
    """Unit normal of flat wall ``w`` pointing into the box."""
    return (1.0 if w == 0 else (-1.0 if w == 1 else 0.0)), (1.0 if w == 2 else 0.0)


@njit
def _limits(fw, zb):
    big = 1e300
    return (
        fw[1] if fw[0] != 0.0 else -big,
        fw[3] if fw[2] != 0.0 else big,
        zb if fw[4] != 0.0 else -big,
    )


@njit
def near_walls(vec, sca, ivec, fw, zb, skin, reset, clock, counters):
    """List in ``ivec[L.CELL_ITEMS]`` the mobile disks within ``2 skin`` of touching a flat
    wall (ascending); with ``reset`` (laws with history), zero the wall shear histories
    and their perturbations of the others.

    The list is rebuilt with the neighbour list and when the bottom has moved more than
    ``skin/2`` since: until then a disk has moved at most ``skin`` from where it was
    listed (each less than ``skin/2`` from its place at the list build) and the bottom at
    most ``skin/2``, so a disk not listed cannot touch a wall, and its history is zero.
    """
    pos = vec[L.POS]
    mob = vec[L.MOB2]
    radius = sca[L.RADIUS]
    near = ivec[L.CELL_ITEMS]
    x_left, x_right, z_bottom = _limits(fw, zb)
    margin = 2.0 * skin
    m = 0
    for i in range(radius.shape[0]):
        x = pos[i, 0]
        y = pos[i, 1]
        a = radius[i] + margin
        if mob[i, 0] != 0.0 and (x - x_left <= a or x_right - x <= a or y - z_bottom <= a):
            near[m] = i
            m += 1
        elif reset:
            for w in range(3):
                sca[L.XI_LEFT + w, i] = 0.0
                sca[L.T_XI_LEFT + w, i] = 0.0
    counters[L.NEAR_WALLS] = m
    clock[L.ZB_NEAR] = zb


@njit
def wall_candidates(vec, sca, ivec, fw, zb, skin, reset, tangent, clock, counters, out, info,
                    step):  # fmt: skip
    """Disks of the near-wall list (:func:`near_walls`, rebuilt here when stale) touching
    at least one flat wall, listed in ``out``; returns how many, or -1 (recorded in
    ``info``) if one overlaps a wall by more than the bound (``clock[OVERLAP_FRAC]``
    times its radius).

    One pass for all three walls (an absent wall sits at infinity). With ``reset`` (laws
    with history), the shear history against each wall of the listed disks not touching
    it is zeroed, and with ``tangent`` its perturbation too. Most disks touch no wall,
    so the branch is well predicted and the contact loop only sees the touching disks.
    Flat arguments: with the storage as named bundles the drum with tangent and the driven
    box ran 4-10 % slower (docs/engine_performance.md, round 13).
    """
    if counters[L.NEAR_WALLS] < 0:
        near_walls(vec, sca, ivec, fw, zb, skin, reset, clock, counters)
    p = vec[L.POS].reshape(vec[L.POS].size)
    radius = sca[L.RADIUS]
    near = ivec[L.CELL_ITEMS]
    xi_l, xi_r, xi_b = sca[L.XI_LEFT], sca[L.XI_RIGHT], sca[L.XI_BOTTOM]
    dxi_l, dxi_r, dxi_b = sca[L.T_XI_LEFT], sca[L.T_XI_RIGHT], sca[L.T_XI_BOTTOM]
    x_left, x_right, z_bottom = _limits(fw, zb)
    frac = clock[L.OVERLAP_FRAC]
    m = 0
    for q in range(counters[L.NEAR_WALLS]):
        i = near[q]
        x = p[2 * i]
        y = p[2 * i + 1]
        a = radius[i]
        t_l = x - x_left <= a
        t_r = x_right - x <= a
        t_b = y - z_bottom <= a
        if reset:
            xi_l[i] = xi_l[i] if t_l else 0.0
            xi_r[i] = xi_r[i] if t_r else 0.0
            xi_b[i] = xi_b[i] if t_b else 0.0
        if reset and tangent:
            dxi_l[i] = dxi_l[i] if t_l else 0.0
            dxi_r[i] = dxi_r[i] if t_r else 0.0
            dxi_b[i] = dxi_b[i] if t_b else 0.0
        if t_l | t_r | t_b:
            pos = vec[L.POS]
            for w in range(3):
                if fw[2 * w] != 0.0 and a - wall_gap(w, pos, i, fw, zb) > frac * a:
                    info[0] = L.DEEP_OVERLAP
                    info[1] = i
                    info[2] = -1 - w
                    info[3] = step
                    return -1
            out[m] = i
            m += 1
    return m
