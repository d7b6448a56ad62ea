"""sha256 of every output array of the column's discrete chain (a relaxation and a chaos point)
and of two short continuum runs; with --time, the median wall time of the discrete runs.

    PYTHONPATH=src .venv/bin/python benchmarks/column_hashes.py [--time]

A change meant to keep the results bit for bit must print the same hashes before and after.
"""

import hashlib
import sys
import time

import numpy as np

from granpipe.column import continuum as cont
from granpipe.column import discrete as d
from granpipe.column import protocol as pr
from granpipe.column.model import physics

RELAX = {
    "N": 20,
    "m": 0.001,
    "r": 0.005,
    "g": 9.81,
    "stiffness_factor": 50.0,
    "e": 0.09,
    "a": 0.01,
    "tap_duration": 0.05,
    "T": 1.0,
}
CHAOS = {**RELAX, "N": 10, "a": 0.005, "T": 0.15}


def h(x):
    a = np.ascontiguousarray(np.asarray(x))
    return hashlib.sha256(a.tobytes() + str(a.dtype).encode() + str(a.shape).encode()).hexdigest()[
        :16
    ]


def show(tag, out):
    for k in sorted(out):
        v = out[k]
        if isinstance(v, dict):
            print(f"{tag}.{k}: {v}")
        else:
            print(f"{tag}.{k}: {h(v)}")


def ds_show(tag, ds):
    for k in sorted(ds.data_vars):
        print(f"{tag}.{k}: {h(ds[k].values)}")


def state_show(tag, s):
    for k in ("y", "v", "dy", "dv", "modes"):
        print(f"{tag}.state.{k}: {h(getattr(s, k))}")


def relax_run():
    p = physics(RELAX)
    s = pr.perturbed_start(p, np.random.default_rng(1), 1.0)
    out = d.simulate(p, s, 3, record_dt=0.01, sample_fracs=(0.5, 0.99))
    return out, s


def chaos_run():
    p = physics(CHAOS)
    s = pr.perturbed_start(p, np.random.default_rng(2), 1.0)
    d.simulate(p, s, 1, sample_fracs=())
    s.dy[:] = p.r
    out = d.simulate(p, s, 3, tangent=True, sample_fracs=(1.0,))
    return out, s


def main():
    out, s = relax_run()
    show("relax", out)
    state_show("relax", s)
    out, s = chaos_run()
    show("chaos", out)
    state_show("chaos", s)
    ds, _ = pr.relaxation_batch(RELAX, [0, 1], 3, 1.0)
    ds_show("relaxation_batch", ds)
    res = pr.lyapunov_point(CHAOS, [0, 1], 1, 3, 1.0, 1e-9, return_max_period=1, return_taps=2)
    ds = res[0] if isinstance(res, tuple) else res
    ds_show("lyapunov_point", ds)
    q = cont.dimensionless(physics({**RELAX, "N": 10}))
    sol = cont.solve_longwave(q, 2.0, dz=0.5, record_dt=0.1)
    show("longwave", {k: v for k, v in sol.items() if isinstance(v, np.ndarray)})
    sol = cont.solve_bsr_derived(q, 2.0, ds=0.5, record_dt=0.1)
    show("bsr_derived", {k: v for k, v in sol.items() if isinstance(v, np.ndarray)})
    if "--time" in sys.argv:
        ts = []
        for _ in range(5):
            t0 = time.perf_counter()
            relax_run()
            chaos_run()
            ts.append(time.perf_counter() - t0)
        print(f"time median {np.median(ts):.4f} s  all {[round(x, 4) for x in ts]}")


if __name__ == "__main__":
    main()
