"""Walls with prescribed motion: rotating wall disks (drum) and flat lines (box).

Walls act on disks through the same contact law as disk pairs, with infinite mass
on the wall side (docs/drum.md, docs/box.md; docs/architecture.md, "The engine").

* :class:`WallDisks` — the disks flagged ``is_wall`` form one rigid body turning
  about ``centre`` at angular velocity ``omega`` (counter-clockwise positive; the
  drum of docs/drum.md turns clockwise, ``omega = -2.4417e-4``), which switches
  abruptly to ``omega_after`` at ``t_switch`` (the drum stop). The rotation angle
  is part of the state, so the motion can be redefined between chunks of a run
  without a jump.
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
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from granpipe._jit import njit
from granpipe.errors import ConfigError

__all__ = ["WallDisks", "FlatWalls", "bottom_height", "bottom_velocity", "wall_velocity",
           "wall_torque_factor"]


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
