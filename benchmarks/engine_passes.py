"""Where an engine step spends its time: each pass of the step loop timed on its own.

    .venv/bin/python benchmarks/engine_passes.py [--repeats 5]

Runs on the same settled states as ``benchmarks/engine.py`` (drum pile of docs/drum.md,
rotating; dense box crystal of docs/box.md) and times, in a jitted loop, each pass the step
loop of :mod:`granpipe.engine.kernels` makes: the gather of relative coordinates, the
contact law over the listed pairs, the scatter of pair forces onto disks (and the fused
four-lane pass that does all three, used with the tangent vector), the flat-wall
contacts, the per-disk kicks, and a list rebuild. Figures are the best of ``--repeats``
chunks (the machine's noise only adds time), in ns per particle and ns per listed pair;
the passes of one step add up to a little less than the whole step of engine.py (the
remainder is wall motion, bookkeeping and the step loop itself). The last line is one
JSON object ``{"<system>.<pass>": ns per particle}``.

These are internal kernels: the script is a profile for the engine's developers, not an
example of the public API.
"""

from __future__ import annotations

import argparse
import json
import os
import time

# One BLAS thread, as `make bench` sets, before numpy loads OpenBLAS: the idle thread pools
# of numpy's and scipy's OpenBLAS slowed the dense box from 37 to 52 ns per particle-step
# on a 2-vCPU machine (docs/engine_performance.md, round 5).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numba
import numpy as np
from engine import box_crystal, drum_system

from granpipe._jit import njit
from granpipe.engine import kernels as K

N_DRUM_MOBILE = 736


@njit
def _gather(nrep, vec, sca, pair_ij, buf, npairs, mode):
    for _ in range(nrep):
        K._gather(vec, sca, pair_ij, buf, npairs, mode)


@njit
def _drum_law(nrep, buf, pair_c, touch, law, npairs, tangent):
    c = 0
    for _ in range(nrep):
        if tangent:
            c += K._drum_pairs_tangent(buf, pair_c[K.P_SUM], pair_c[K.P_LIM], touch, law, npairs)[0]
        else:
            c += K._drum_pairs(buf, pair_c[K.P_SUM], pair_c[K.P_LIM], touch, law, npairs)[0]
    return c


@njit
def _box_law(nrep, buf, pair_c, xi, touch, law, npairs):
    c = 0
    for _ in range(nrep):
        c += K._box_pairs(
            buf,
            pair_c[K.P_SUM],
            pair_c[K.P_LIM],
            pair_c[K.P_MEFF],
            pair_c[K.P_DIFF],
            xi,
            touch,
            law,
            0.0,
            npairs,
        )[0]
    return c


@njit
def _fused(nrep, vec, pair_ij, pair_c, buf, touch, law, npairs, tangent, pc):
    c = 0
    for _ in range(nrep):
        c += K._drum_pair_pass(vec, pair_ij, pair_c, buf, touch, law, npairs, tangent, pc)[0]
    return c


@njit
def _scatter(nrep, vec, sca, ivec, pair_start, pair_ij, buf, touch, tangent, torques):
    for _ in range(nrep):
        K._scatter(vec, sca, ivec, pair_start, pair_ij, buf, touch, tangent, torques, False)


@njit
def _recount(nrep, vec, sca, ivec, pair_start, pair_ij, buf, touch):
    for _ in range(nrep):
        K._scatter(vec, sca, ivec, pair_start, pair_ij, buf, touch, False, False, True)


@njit
def _kicks(nrep, vec, sca, ivec, spin_on, tangent):
    # dt = 0: the state does not move, the work is the same
    for _ in range(nrep):
        K._kick_drift(vec, sca, 0.0, 1e300, spin_on, True, True)
        if tangent:
            K._tangent_pass(vec, sca, ivec, 0.0, 1)


@njit
def _box_walls(nrep, vec, sca, ivec, law, fw, info, skin, clock, counters):
    # the near-wall list as the step finds it (built once, with the neighbour list)
    for _ in range(nrep):
        K._flat_walls(
            1,
            vec,
            sca,
            ivec,
            law,
            fw,
            0.0,
            0.0,
            False,
            0.0,
            False,
            info,
            0,
            (skin, clock, counters),
        )


@njit
def _rebuild(nrep, vec, sca, ivec, skin, pair_start, pair_ij, pair_c, cc, cs, clock, counters):
    for _ in range(nrep):
        K._rebuild(vec, sca, ivec, skin, pair_start, pair_ij, pair_c, cc, cs, clock, counters)


def _best(fn, args, nrep, repeats):
    fn(2, *args)  # compile / warm
    best = np.inf
    for _ in range(repeats):
        t = time.thread_time()
        fn(nrep, *args)
        best = min(best, time.thread_time() - t)
    return best / nrep


def _row(out, system, name, sec, n_particles, npairs):
    per_particle = sec * 1e9 / n_particles
    per_pair = sec * 1e9 / npairs
    print(f"{system:6s} {name:16s} {per_particle:7.2f} ns/particle  {per_pair:6.2f} ns/pair")
    out[f"{system}.{name}"] = round(per_particle, 2)


def _storage(state):
    s = state._s
    return {k: (v[0] if isinstance(v, np.ndarray) and v.ndim > 0 else v) for k, v in s.items()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    numba.set_num_threads(1)
    out = {}
    rep = args.repeats

    sim, state = drum_system()
    sim.random_tangent(state, np.random.default_rng(1))
    sim.run(state, 700, stride=35, tangent=True)
    g, law, wd, fw = sim._params()
    s = _storage(state)
    vec, sca, ivec, buf, touch = s["vec"], s["sca"], s["ivec"], s["buf"], s["touch"]
    pair_ij, pair_c, pair_start = s["pair_ij"], s["pair_c"], s["pair_start"]
    npairs = int(s["counters"][K.N_PAIRS])
    n = N_DRUM_MOBILE
    print(f"drum: {npairs} listed pairs, {npairs / n:.2f} per mobile disk")
    nrep = 5000
    for tangent in (False, True):
        tag = "tangent" if tangent else "forward"
        sec = _best(_gather, (vec, sca, pair_ij, buf, npairs, int(tangent)), nrep, rep)
        _row(out, "drum", f"gather.{tag}", sec, n, npairs)
        sec = _best(_drum_law, (buf, pair_c, touch, law, npairs, tangent), nrep, rep)
        _row(out, "drum", f"law.{tag}", sec, n, npairs)
        sec = _best(
            _scatter, (vec, sca, ivec, pair_start, pair_ij, buf, touch, tangent, False), nrep, rep
        )
        _row(out, "drum", f"scatter.{tag}", sec, n, npairs)
        # gather + law + scatter in one four-lane pass (used by the engine with tangent)
        pc = ivec[K.PAIR_CONTACTS].copy()
        fused = (vec, pair_ij, pair_c, buf, touch, law, npairs, tangent, pc)
        sec = _best(_fused, fused, nrep, rep)
        _row(out, "drum", f"fused_pass.{tag}", sec, n, npairs)
        sec = _best(_kicks, (vec, sca, ivec, False, tangent), nrep, rep)
        _row(out, "drum", f"kicks.{tag}", sec, n, npairs)
    sec = _best(_recount, (vec, sca, ivec, pair_start, pair_ij, buf, touch), nrep, rep)
    _row(out, "drum", "scatter+recount", sec, n, npairs)
    cc, cs, clock, counters = s["cell_count"], s["cell_start"], s["clock"], s["counters"]
    sec = _best(
        _rebuild,
        (vec, sca, ivec, s["skin"], pair_start, pair_ij, pair_c, cc, cs, clock, counters),
        100,
        rep,
    )
    _row(out, "drum", "rebuild", sec, n, npairs)

    sim, state = box_crystal()
    sim.run(state, 10)
    g, law, wd, fw = sim._params()
    s = _storage(state)
    vec, sca, ivec, buf, touch = s["vec"], s["sca"], s["ivec"], s["buf"], s["touch"]
    pair_ij, pair_c, pair_start = s["pair_ij"], s["pair_c"], s["pair_start"]
    npairs = int(s["counters"][K.N_PAIRS])
    n = vec.shape[1]
    xi = s["pair_xi"].copy()
    print(f"box crystal: {npairs} listed pairs, {npairs / n:.2f} per disk")
    sec = _best(_gather, (vec, sca, pair_ij, buf, npairs, 2), nrep, rep)
    _row(out, "box", "gather", sec, n, npairs)
    sec = _best(_box_law, (buf, pair_c, xi, touch, law, npairs), nrep, rep)
    _row(out, "box", "law", sec, n, npairs)
    sec = _best(_scatter, (vec, sca, ivec, pair_start, pair_ij, buf, touch, False, True), nrep, rep)
    _row(out, "box", "scatter", sec, n, npairs)
    walls = (vec, sca, ivec, law, fw, s["info"], float(s["skin"]), s["clock"], s["counters"])
    sec = _best(_box_walls, walls, nrep, rep)
    _row(out, "box", "flat_walls", sec, n, npairs)
    sec = _best(_kicks, (vec, sca, ivec, True, False), nrep, rep)
    _row(out, "box", "kicks", sec, n, npairs)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
