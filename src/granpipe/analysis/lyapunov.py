"""Where the chaos lives: the per-disk size of the Lyapunov (tangent) vector and its
spatial correlation with the disks' speeds.

|δu_i| = sqrt(|δr_i|² + |δv_i|²) in reduced units, and the Pearson correlation
C(|δu|, |v|) over the mobile disks at one instant: the quantity Banigan et al. (Nature
Phys. 9, 288 (2013), the drum paper's Ref. [20]) measured in the shear cell and Wang &
Zhang (Sci. Rep. 5, 8128 (2015), its Ref. [22]) in a real drum (slightly larger near
unjamming than near jamming). The drum records it at every sample of the pile
(docs/drum.md), the shear cell at every network sample (docs/shear.md). Plain numpy.
"""

from __future__ import annotations

import numpy as np

__all__ = ["lyapunov_vector_magnitude", "speed_lyapunov_correlation"]


def lyapunov_vector_magnitude(
    tangent_r: np.ndarray, tangent_v: np.ndarray, relative: bool = False
) -> np.ndarray:
    """|δu_i| = sqrt(|δr_i|² + |δv_i|²) per disk, reduced units (``relative``: over the
    largest, the vector's scale being arbitrary).

    ``tangent_r`` (N, 2) [d_s] and ``tangent_v`` (N, 2) [d_s/t0]: the position and
    velocity parts of the Lyapunov (tangent) vector. Returns (N,) float.
    """
    dr = np.asarray(tangent_r, dtype=float)
    dv = np.asarray(tangent_v, dtype=float)
    du = np.sqrt(np.sum(dr * dr, axis=-1) + np.sum(dv * dv, axis=-1))
    return du / max(float(du.max(initial=0.0)), 1e-300) if relative else du


def speed_lyapunov_correlation(
    velocities: np.ndarray, tangent_r: np.ndarray, tangent_v: np.ndarray, mobile: np.ndarray
) -> float:
    """Pearson correlation C(|δu|, |v|) over the mobile disks.

    Parameters
    ----------
    velocities : (N, 2) float
        Disk velocities [d_s/t0].
    tangent_r, tangent_v : (N, 2) float
        The Lyapunov vector's parts, as in :func:`lyapunov_vector_magnitude`.
    mobile : (N,) bool
        Only these disks enter.

    Returns
    -------
    float in [−1, 1]; NaN with fewer than 3 mobile disks or if |v| or |δu| takes a
    single value over them (zero spread).
    """
    mob = np.asarray(mobile, dtype=bool)
    if np.count_nonzero(mob) < 3:
        return float("nan")
    speed = np.hypot(*np.asarray(velocities, dtype=float)[mob].T)
    du = lyapunov_vector_magnitude(np.asarray(tangent_r)[mob], np.asarray(tangent_v)[mob])
    if np.ptp(speed) == 0 or np.ptp(du) == 0:
        return float("nan")
    return float(np.clip(np.corrcoef(speed, du)[0, 1], -1.0, 1.0))
