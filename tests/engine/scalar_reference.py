"""Scalar passes of the drum law with the tangent vector, the reference the fused
four-lane pass (``kernels._drum_pair_pass``) is tested against bit for bit.

The engine runs the drum's tangent dynamics through the four-lane pass only; these
separate gather and scatter passes with the tangent rows exist for the test.
"""

import numpy as np

from granpipe._jit import njit
from granpipe.engine import kernels as K


@njit
def gather_tangent(vec, sca, pair_ij, buf, npairs):
    """``kernels._gather`` plus the tangent vector's differences ``du_i - du_j`` in rows
    ``B_E0`` .. ``B_E0 + 3`` (dx, dy, dvx, dvy) of every listed pair."""
    K._gather(vec, sca, pair_ij, buf, npairs, 0)
    tr = vec[K.T_POS]
    tv = vec[K.T_VEL]
    for k in range(npairs):
        i = pair_ij[K.PI, k]
        j = pair_ij[K.PJ, k]
        buf[K.B_E0, k] = tr[i, 0] - tr[j, 0]
        buf[K.B_E0 + 1, k] = tr[i, 1] - tr[j, 1]
        buf[K.B_E0 + 2, k] = tv[i, 0] - tv[j, 0]
        buf[K.B_E0 + 3, k] = tv[i, 1] - tv[j, 1]


@njit
def scatter_tangent(vec, pair_start, pair_ij, buf):
    """``kernels._scatter`` with the force perturbations (rows ``B_G0``, ``B_G1``) summed
    into ``T_FRC`` alongside the forces, in the same order: partners pair by pair,
    owners in a running sum added when their row ends."""
    f = K._flat(vec[K.FRC])
    mg = K._flat(vec[K.MG])
    tf = K._flat(vec[K.T_FRC])
    for k in range(f.shape[0]):
        f[k] = mg[k]
        tf[k] = 0.0
    n = pair_start.shape[0] - 1
    npairs = pair_start[n]
    if npairs == 0:
        return
    pi = pair_ij[K.PI]
    pj = pair_ij[K.PJ]
    two = np.uint32(2)
    one = np.uint32(1)
    prev = pi[0]
    ax = 0.0
    ay = 0.0
    bx = 0.0
    by = 0.0
    for k in range(npairs):
        i = pi[k]
        j2 = two * pj[k]
        a = buf[K.B_FX, k]
        b = buf[K.B_FY, k]
        c = buf[K.B_G0, k]
        d = buf[K.B_G1, k]
        f[j2] -= a
        f[j2 + one] -= b
        tf[j2] -= c
        tf[j2 + one] -= d
        if i != prev:
            p2 = two * prev
            f[p2] += ax
            f[p2 + one] += ay
            tf[p2] += bx
            tf[p2 + one] += by
            ax = 0.0
            ay = 0.0
            bx = 0.0
            by = 0.0
        ax += a
        ay += b
        bx += c
        by += d
        prev = i
    p2 = two * prev
    f[p2] += ax
    f[p2 + one] += ay
    tf[p2] += bx
    tf[p2 + one] += by
