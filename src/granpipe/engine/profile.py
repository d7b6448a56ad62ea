"""Where a step spends its time: each pass of a law's step loop timed on its own.

The public hook is :meth:`granpipe.engine.Simulation.profile_passes`; it asks the law's
:class:`~granpipe.engine.contract.Kernels` for its ``profile`` function, one of
:func:`drum_passes`, :func:`box_passes` (the drum and box laws' own passes) or
:func:`generic_passes` (any law on the generic reference passes). Each runs a pass
``nrep`` times in a jitted loop on a state as it stands, with ``dt = 0`` where a pass
would advance something (the work is the same and the state does not move), and keeps
the best of ``repeats`` loops (a shared machine's noise only adds time). Returned
figures are seconds per call; ``benchmarks/engine_passes.py`` prints them per particle
and per listed pair.
"""

from __future__ import annotations

import time

import numpy as np

from granpipe._jit import njit
from granpipe.engine import generic as G
from granpipe.engine import kernels as K

__all__ = ["drum_passes", "box_passes", "generic_passes"]


# --------------------------------------------------------------------------- loops
@njit
def _gather(nrep, vec, sca, pair_ij, buf, npairs, mode):
    for _ in range(nrep):
        K._gather(vec, sca, pair_ij, buf, npairs, mode)


@njit
def _drum_law(nrep, buf, pair_c, touch, law, npairs):
    c = 0
    for _ in range(nrep):
        c += K._drum_pairs(buf, pair_c[K.P_SUM], pair_c[K.P_LIM], touch, law, npairs)[0]
    return c


@njit
def _box_law(nrep, buf, pair_c, xi, touch, law, npairs):
    c = 0
    for _ in range(nrep):
        c += K._box_pairs(
            buf, pair_c[K.P_SUM], pair_c[K.P_LIM], pair_c[K.P_MEFF], pair_c[K.P_DIFF], xi,
            touch, law, 0.0, npairs,
        )[0]  # fmt: skip
    return c


@njit
def _fused(nrep, vec, pair_ij, pair_c, buf, touch, law, npairs, tangent, pc):
    c = 0
    for _ in range(nrep):
        c += K._drum_pair_pass(vec, pair_ij, pair_c, buf, touch, law, npairs, tangent, pc)[0]
    return c


@njit
def _scatter(nrep, vec, sca, ivec, pair_start, pair_ij, buf, touch, torques, recount):
    for _ in range(nrep):
        K._scatter(vec, sca, ivec, pair_start, pair_ij, buf, touch, torques, recount)


@njit
def _kicks(nrep, vec, sca, ivec, spin_on, tangent):
    for _ in range(nrep):
        K._kick_drift(vec, sca, 0.0, 1e300, spin_on, True, True)
        if tangent:
            K._tangent_pass(vec, sca, ivec, 0.0, 1)


@njit
def _box_walls(nrep, vec, sca, ivec, law, fw, info, skin, clock, counters):
    # the near-wall list as the step finds it (built once, with the neighbour list)
    for _ in range(nrep):
        K._flat_walls(
            1, vec, sca, ivec, law, fw, 0.0, 0.0, False, 0.0, False, info, 0,
            (skin, clock, counters),
        )  # fmt: skip


@njit
def _rebuild(nrep, vec, sca, ivec, skin, pair_start, pair_ij, pair_c, cc, cs, clock, counters):
    for _ in range(nrep):
        K._rebuild(vec, sca, ivec, skin, pair_start, pair_ij, pair_c, cc, cs, clock, counters)


@njit
def _generic_forces(nrep, law, st, mode, info, fw):
    (vec, sca, ivec, _w, _ps, pair_ij, pair_c, pair_xi, pair_dxi, _os, _oj, _ox, _od, _b,
     touch, _cc, _cs, _clock, counters) = st  # fmt: skip
    c = 0
    for _ in range(nrep):
        c += G._forces(
            law, vec, sca, ivec, pair_ij, pair_c, pair_xi, pair_dxi, touch, counters, 0.0,
            mode, info, 0, fw, 0.0, 0.0, 2.0,
        )  # fmt: skip
    return c


@njit
def _generic_kicks(nrep, st, tangent):
    vec, sca, ivec = st[0], st[1], st[2]
    for _ in range(nrep):
        G._kick_drift(vec, sca, ivec, 0.0, 1e300, tangent)
        G._final_kick(vec, sca, ivec, 0.0, tangent)
        if tangent:
            G._norms(vec, sca, ivec)


@njit
def _generic_rebuild(nrep, st, skin):
    vec, sca, ivec, clock, counters = st[0], st[1], st[2], st[17], st[18]
    for _ in range(nrep):
        G._rebuild_generic(vec, sca, ivec, skin, st, counters, clock)


# --------------------------------------------------------------------------- drivers
def _best(fn, args, nrep, repeats):
    fn(2, *args)  # compile / warm
    best = np.inf
    for _ in range(max(1, int(repeats))):
        t = time.thread_time()
        fn(nrep, *args)
        best = min(best, time.thread_time() - t)
    return best / nrep


def _one(state):
    """Replica 0 of a state's storage (arrays without the replica axis)."""
    s = state._s
    return {k: (v[0] if isinstance(v, np.ndarray) and v.ndim > 0 else v) for k, v in s.items()}


def _setup(sim, state):
    """``(law parameters, flat walls, replica 0's storage, {n_pairs, n_particles})``."""
    _g, law, _wd, fw = sim._params()
    s = _one(state)
    counts = {"n_pairs": int(s["counters"][K.N_PAIRS]), "n_particles": int(s["vec"].shape[1])}
    return law, fw, s, counts


def drum_passes(sim, state, repeats: int = 5, nrep: int = 5000) -> dict:
    """The drum law's passes: gather, law and scatter (forward), the fused four-lane pass
    (forward and with the tangent vector), the kicks and a list rebuild [s per call]."""
    law, fw, s, out = _setup(sim, state)
    vec, sca, ivec, buf, touch = s["vec"], s["sca"], s["ivec"], s["buf"], s["touch"]
    pair_ij, pair_c, pair_start, npairs = s["pair_ij"], s["pair_c"], s["pair_start"], out["n_pairs"]
    out["gather.forward"] = _best(_gather, (vec, sca, pair_ij, buf, npairs, 0), nrep, repeats)
    args = (buf, pair_c, touch, law, npairs)
    out["law.forward"] = _best(_drum_law, args, nrep, repeats)
    args = (vec, sca, ivec, pair_start, pair_ij, buf, touch, False, False)
    out["scatter.forward"] = _best(_scatter, args, nrep, repeats)
    args = (vec, sca, ivec, pair_start, pair_ij, buf, touch, False, True)
    out["scatter+recount"] = _best(_scatter, args, nrep, repeats)
    pc = ivec[K.PAIR_CONTACTS].copy()
    for tangent in (False, True):
        tag = "tangent" if tangent else "forward"
        args = (vec, pair_ij, pair_c, buf, touch, law, npairs, tangent, pc)
        out[f"fused_pass.{tag}"] = _best(_fused, args, nrep, repeats)
        out[f"kicks.{tag}"] = _best(_kicks, (vec, sca, ivec, False, tangent), nrep, repeats)
    cc, cs, clock, counters = s["cell_count"], s["cell_start"], s["clock"], s["counters"]
    args = (vec, sca, ivec, s["skin"], pair_start, pair_ij, pair_c, cc, cs, clock, counters)
    out["rebuild"] = _best(_rebuild, args, max(1, nrep // 50), repeats)
    return out


def box_passes(sim, state, repeats: int = 5, nrep: int = 5000) -> dict:
    """The box law's passes: gather (with spins), law, scatter (with torques), flat
    walls and kicks [s per call]."""
    law, fw, s, out = _setup(sim, state)
    vec, sca, ivec, buf, touch = s["vec"], s["sca"], s["ivec"], s["buf"], s["touch"]
    pair_ij, pair_c, pair_start, npairs = s["pair_ij"], s["pair_c"], s["pair_start"], out["n_pairs"]
    xi = s["pair_xi"].copy()
    out["gather"] = _best(_gather, (vec, sca, pair_ij, buf, npairs, 2), nrep, repeats)
    out["law"] = _best(_box_law, (buf, pair_c, xi, touch, law, npairs), nrep, repeats)
    args = (vec, sca, ivec, pair_start, pair_ij, buf, touch, True, False)
    out["scatter"] = _best(_scatter, args, nrep, repeats)
    args = (vec, sca, ivec, law, fw, s["info"], float(s["skin"]), s["clock"], s["counters"])
    out["flat_walls"] = _best(_box_walls, args, nrep, repeats)
    out["kicks"] = _best(_kicks, (vec, sca, ivec, True, False), nrep, repeats)
    return out


def generic_passes(sim, state, repeats: int = 5, nrep: int = 2000) -> dict:
    """The generic passes of any law: the pair pass (forward, with tangent), the per-disk
    kicks (forward, with tangent and norms) and a list rebuild [s per call]."""
    from granpipe.engine.simulation import _storage

    law, fw, _s, out = _setup(sim, state)
    st = tuple(a[0] for a in _storage(state._s))
    info = np.zeros(4, dtype=np.int64)
    for mode, tag in ((0, "forward"), (1, "tangent")):
        args = (law, st, mode, info, fw)
        out[f"pairs.{tag}"] = _best(_generic_forces, args, nrep, repeats)
        out[f"kicks.{tag}"] = _best(_generic_kicks, (st, mode == 1), nrep, repeats)
    out["rebuild"] = _best(_generic_rebuild, (st, float(state._s["skin"])), max(1, nrep // 50),
                           repeats)  # fmt: skip
    return out
