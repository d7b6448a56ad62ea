"""Throughput of the column's kernels (printed, never asserted).

    .venv/bin/python benchmarks/column.py

Discrete column: wall time per tap, RK4 steps and located switches per tap, for the
figure-1 and generic sets at a few sizes, with and without the tangent dynamics; the
settling time of the figure-1 columns (why T = 1 s); the continuum solvers' time per
simulated second.
"""

import time

import numpy as np

from granpipe.column import continuum as cont
from granpipe.column import discrete as d
from granpipe.column.model import parameter_set


def per_tap(p, n=4, tangent=False):
    s = d.initial_state(p)
    if tangent:
        s.dy[:] = p.r
    t0 = time.perf_counter()
    out = d.simulate(p, s, n, tangent=tangent, sample_fracs=())
    el = (time.perf_counter() - t0) / n
    return el, out["stats"]["steps"] / n, out["stats"]["events"] / n


def settling(name):
    p = parameter_set(name, T=5.0)
    s = d.initial_state(p)
    out = d.simulate(p, s, 1, record_dt=1e-3, sample_fracs=())
    moving = np.any(out["v"] != 0, axis=1)
    return out["t"][moving][-1]


def main():
    per_tap(parameter_set("figure1_N5"), 1)  # load the compiled kernels
    print("discrete column (event-located RK4, h = 0.1/omega_max)")
    print(
        f"{'set':>22} {'N':>3} {'a':>8} {'T':>5} {'ms/tap':>8} {'steps/tap':>10}"
        f" {'switches/tap':>13}"
    )
    cases = [
        ("figure1_N5", {}),
        ("figure1_N10", {}),
        ("generic", {}),
        ("generic", {"N": 40}),
        ("generic", {"N": 10, "a": 0.002, "T": 0.15}),
        ("generic", {"N": 10, "a": 0.02}),
    ]
    for name, kw in cases:
        p = parameter_set(name, **kw)
        el, st, ev = per_tap(p)
        print(
            f"{name:>22} {p.N:>3} {p.a:>8.3g} {p.T:>5.3g} {1e3 * el:>8.2f} {st:>10.0f} {ev:>13.0f}"
        )
        if name == "generic" and not kw:
            elt, _, _ = per_tap(p, tangent=True)
            print(f"{'  + tangent':>22} {'':>3} {'':>8} {'':>5} {1e3 * elt:>8.2f}")
    for name in ("figure1_N5", "figure1_N10"):
        print(
            f"{name}: every contact stuck (full rest) {settling(name):.3f} s after the tap starts"
        )
    p = parameter_set("figure1_N10")
    s = d.initial_state(p)
    disc = d.simulate(p, s, 1, record_dt=1e-3, sample_fracs=())
    top = (disc["t"], disc["y"][:, -1] + p.r, disc["v"][:, -1])
    for k in (8, 32):
        t0 = time.perf_counter()
        cont.solve_longwave(p, 1.0, dz=p.h / k, top=top, record_dt=0.01)
        print(f"long-wave h/dz = {k:>3}: {time.perf_counter() - t0:.2f} s per simulated second")
    for k in (8, 16):
        t0 = time.perf_counter()
        out = cont.solve_bsr(p, 0.1, dz=p.h / k, top=top, record_dt=0.001)
        print(
            f"BSR h/dz = {k:>3}: {time.perf_counter() - t0:.2f} s to collapse at "
            f"t = {out['collapse_time']:.4f} s"
        )


if __name__ == "__main__":
    main()
