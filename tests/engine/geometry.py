"""Geometric builders of the engine tests and benchmarks: a ring of wall disks, random
non-overlapping disks, a lattice (the studies place their own disks).
"""

from __future__ import annotations

import math

import numpy as np

from granpipe.errors import ConfigError

__all__ = ["ring_of_disks", "random_disks_in_circle", "random_disks_in_box", "hexagonal_rows"]


def ring_of_disks(n, diameter, centre=(0.0, 0.0), phase=0.0):
    """Centres of ``n`` disks on the vertices of a regular n-gon of side ``diameter``.

    Neighbouring disks touch (drum paper Sec. II.2: 150 wall disks of diameter
    1.3846 give a circumradius of 33.057).

    Returns
    -------
    positions : (n, 2) float64 [length]
    circumradius : float [length]
    """
    radius = diameter / (2.0 * math.sin(math.pi / n))
    ang = phase + 2.0 * math.pi * np.arange(n) / n
    pos = np.column_stack([np.cos(ang), np.sin(ang)]) * radius + np.asarray(centre, float)
    return pos, radius


def _place(rng, radii, sample, max_tries):
    """Random sequential placement: each disk tries up to ``max_tries`` candidate centres."""
    n = len(radii)
    pos = np.empty((n, 2))
    order = np.argsort(-np.asarray(radii), kind="stable")  # big disks first
    placed = []
    for k in order:
        for _ in range(max_tries):
            c = sample(radii[k])
            if placed:
                p = pos[placed]
                d2 = ((p - c) ** 2).sum(1)
                if np.any(d2 < (radii[placed] + radii[k]) ** 2):
                    continue
            pos[k] = c
            placed.append(k)
            break
        else:
            raise ConfigError(f"could not place disk {k} without overlap; too dense")
    return pos


def random_disks_in_circle(
    rng, radii, container_radius, centre=(0.0, 0.0), margin=0.0, max_tries=10_000, y_max=None
):
    """Non-overlapping disks placed uniformly at random inside a circle.

    Parameters
    ----------
    rng : numpy.random.Generator
    radii : (N,) float64 [length]
    container_radius : float [length]
        Disks lie entirely within ``container_radius - margin`` of ``centre``.
    y_max : float or None [length]
        If given, centres lie below ``centre[1] + y_max`` (e.g. a low pile that does
        not fall far).

    Returns
    -------
    (N, 2) float64 [length]
    """
    radii = np.asarray(radii, dtype=float)
    c0 = np.asarray(centre, float)

    def sample(a):
        rmax = container_radius - margin - a
        if rmax <= 0:
            raise ConfigError("container too small for the disks")
        while True:
            p = rng.uniform(-rmax, rmax, 2)
            if p @ p <= rmax * rmax and (y_max is None or p[1] <= y_max):
                return c0 + p

    return _place(rng, radii, sample, max_tries)


def random_disks_in_box(rng, radii, lower, upper, max_tries=10_000):
    """Non-overlapping disks placed uniformly at random inside the box [lower, upper].

    Returns
    -------
    (N, 2) float64 [length]
    """
    radii = np.asarray(radii, dtype=float)
    lo = np.asarray(lower, float)
    hi = np.asarray(upper, float)

    def sample(a):
        if np.any(hi - lo <= 2 * a):
            raise ConfigError("box too small for the disks")
        return rng.uniform(lo + a, hi - a)

    return _place(rng, radii, sample, max_tries)


def hexagonal_rows(n, diameter, width, bottom=0.0, x0=0.0):
    """``n`` disk centres in a hexagonal lattice with close-packed rows horizontal.

    Row ``k`` sits at height ``bottom + diameter/2 + k diameter sqrt(3)/2``; even rows
    start at ``x0 + diameter/2``, odd rows are shifted by half a diameter. A row holds
    as many disks as fit in ``width`` (so widths of 20 diameters give rows of 20 and 19).

    Returns
    -------
    (n, 2) float64 [length]
    """
    pos = []
    k = 0
    while len(pos) < n:
        shift = 0.5 * diameter * (k % 2)
        per_row = int(math.floor((width - shift) / diameter + 1e-9))
        y = bottom + 0.5 * diameter + k * diameter * math.sqrt(3.0) / 2.0
        for m in range(per_row):
            if len(pos) == n:
                break
            pos.append((x0 + shift + 0.5 * diameter + m * diameter, y))
        k += 1
    return np.array(pos)
