"""Where a step spends its time: each pass of the step loop timed on its own.

The public hook is :meth:`granpipe.engine.Simulation.profile_passes`. For any law it times
the passes of :mod:`granpipe.engine.passes` as the step runs them: the gather, the law's
rows and the scatter, forward and with the tangent vector, the flat walls, the per-disk
kicks, and a list rebuild. Each runs ``nrep`` times in a jitted loop on one replica's
storage as it stands, with ``dt = 0`` where a pass would advance something (the work is
the same and the state does not move), and keeps the best of ``repeats`` loops (a shared
machine's noise only adds time). Returned figures are seconds per call;
``benchmarks/engine_passes.py`` prints them per particle and per listed pair.
"""

from __future__ import annotations

import time

import numpy as np

from granpipe._jit import njit
from granpipe.engine import layout as L
from granpipe.engine import passes as P
from granpipe.engine.neighbours import rebuild
from granpipe.engine.walls import has_flat

__all__ = ["profile_passes"]


@njit
def _gather(nrep, law, mode, st, npairs):
    for _ in range(nrep):
        P.gather(law, mode, st[0], st[1], st[5], st[13], npairs)


@njit
def _law(nrep, law, mode, st, npairs):
    pair_c, buf = st[6], st[13]
    c = 0
    for _ in range(nrep):
        c += P.law_rows(
            law, mode, buf, pair_c[L.P_SUM], pair_c[L.P_LIM], pair_c[L.P_MEFF], pair_c[L.P_DIFF],
            buf[L.B_XI], buf[L.B_DXI], st[14], st[15], npairs, 0.0,
        )[0]  # fmt: skip
    return c


@njit
def _scatter(nrep, law, mode, st):
    for _ in range(nrep):
        P.scatter(law, mode, st[0], st[1], st[4], st[5], st[13])


@njit
def _walls(nrep, laws, mode, st, fw, skin, info):
    # the near-wall list as the step finds it (built once, with the neighbour list)
    vec, sca, ivec, clock, counters = st[0], st[1], st[2], st[18], st[19]
    c = 0
    for _ in range(nrep):
        c += P.flat_walls(
            laws[1], laws[0], mode, vec, sca, ivec, fw, 0.0, 0.0, 0.0, False, info, 0,
            (skin, clock, counters),
        )  # fmt: skip
    return c


@njit
def _kicks(nrep, law, mode, st):
    vec, sca, ivec = st[0], st[1], st[2]
    for _ in range(nrep):
        P.kick_drift(law, vec, sca, 0.0, 1e300, True, True)
        if P.tangent_on(mode):
            P.tangent_kicks(law, vec, sca, ivec, 0.0, 1)


@njit
def _rebuild(nrep, law, st, skin):
    for _ in range(nrep):
        rebuild(st[0], st[1], st[2], skin, st, False, False)


def _best(fn, args, nrep, repeats):
    fn(2, *args)  # compile / warm
    best = np.inf
    for _ in range(max(1, int(repeats))):
        t = time.thread_time()
        fn(nrep, *args)
        best = min(best, time.thread_time() - t)
    return best / nrep


def profile_passes(laws, fw, skin, storage, repeats: int = 5, nrep: int = 2000) -> dict:
    """Seconds per call of each pass, on replica 0 of ``storage`` (the storage tuple of
    :data:`granpipe.engine.layout.STORAGE`, changed by the loops: pass a copy), with
    ``n_pairs`` and ``n_particles``.

    ``laws`` are the leaves' parameters at pairs and flat walls, ``fw`` the flat walls'
    parameters (:meth:`granpipe.engine.Simulation.profile_passes` supplies both).
    """
    st = tuple(a[0] for a in storage)
    law = laws[0]
    npairs = int(st[19][L.N_PAIRS])
    out = {"n_pairs": npairs, "n_particles": int(st[0].shape[1])}
    info = np.zeros(4, dtype=np.int64)
    # the law's rows advance copies of the histories (rows L.B_XI, L.B_DXI)
    st[13][L.B_XI, :npairs] = st[7][:npairs]
    st[13][L.B_DXI, :npairs] = st[8][:npairs]
    for mode, tag in ((P.FORWARD, "forward"), (P.TANGENT, "tangent")):
        out[f"gather.{tag}"] = _best(_gather, (law, mode, st, npairs), nrep, repeats)
        out[f"law.{tag}"] = _best(_law, (law, mode, st, npairs), nrep, repeats)
        out[f"scatter.{tag}"] = _best(_scatter, (law, mode, st), nrep, repeats)
        out[f"kicks.{tag}"] = _best(_kicks, (law, mode, st), nrep, repeats)
        if has_flat(fw):
            args = (laws, mode, st, fw, float(skin), info)
            out[f"flat_walls.{tag}"] = _best(_walls, args, nrep, repeats)
    out["rebuild"] = _best(_rebuild, (law, st, float(skin)), max(1, nrep // 50), repeats)
    return out
