"""Throughput of the drum study: seconds per replica and ns per mobile-particle step.

Runs the real drum (736 mobile + 150 wall disks) of one point of a config's ``drum``
section: the start-up (placement and fall, or settling), then ``--seconds`` of rotation
with and without the tangent dynamics, and prints the cost per step and per mobile
particle-step, the projected cost of one replica of that config (start-up as measured;
tangent dynamics over the alignment, onset and decay windows; no waiting for a
continuous avalanche), and the paper's 70,000 pairs in core-hours. ``--full`` also
runs one whole replica through the protocol and prints its measured cost.

    .venv/bin/python benchmarks/drum.py [--configfile config/config.yaml] [--seconds 2]
        [--point NAME] [--full]

Times are CPU time of the process (one thread: NUMBA_NUM_THREADS=1), so other jobs on the
machine inflate them less than wall time; compare figures from one run.
"""

from __future__ import annotations

import argparse
import time

import engine as engine_bench  # benchmarks/engine.py, beside this file
import numpy as np
import yaml

from granpipe.drum.layout import filled, point_sections, steps
from granpipe.drum.model import DrumModel
from granpipe.drum.preparation import prepare
from granpipe.drum.protocol import (
    initial_tangent,
    replica_streams,
    run_replica,
)

PAPER_PAIRS = 70_000


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configfile", default="config/config.yaml")
    ap.add_argument("--point", default=None, help="parameter point (default: the reference)")
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated rotation per mode")
    ap.add_argument("--replica", type=int, default=0)
    ap.add_argument("--full", action="store_true", help="also run one whole replica")
    args = ap.parse_args(argv)
    points = point_sections(filled(yaml.safe_load(open(args.configfile))["drum"]))
    sec = points[args.point] if args.point else next(iter(points.values()))
    st = steps(sec)
    model = DrumModel.from_physics(sec["physics"])
    print(f"point {args.point or next(iter(points))}")

    sim = model.simulation(model.omega)
    place, tangent_rng, _ = replica_streams(sec, args.replica)
    start = prepare(model, sec, st, place)
    ns_start = start.wall_time / max(1, start.n_steps * model.n_mobile) * 1e9
    print(
        f"start-up ({sec['protocol']['startup']}): {start.settle_time:.2f} s simulated "
        f"({start.n_steps} steps) in {start.wall_time:.1f} s wall: {ns_start:.0f} ns per "
        "mobile particle-step"
    )
    n = max(st.block, int(round(args.seconds / st.dt_s / st.block)) * st.block)
    rates = {}
    for tangent in (False, True):
        state = model.new_state(sim, start.positions, start.velocities,
                                wall_angle=start.wall_angle)  # fmt: skip
        if tangent:
            dr, dv = initial_tangent(model.n_mobile, tangent_rng, 0.1)
            z = np.zeros((model.geom.n_wall, 2))
            sim.set_tangent(state, np.concatenate([dr, z]), np.concatenate([dv, z]))
        sim.run(state, st.block, stride=st.block, tangent=tangent)  # warm
        t = time.process_time()
        sim.run(state, n, stride=st.block, tangent=tangent)
        wall = time.process_time() - t
        rates[tangent] = wall / n
        print(
            f"rotation {'with' if tangent else 'without'} tangent: {n} steps in {wall:.2f} s CPU: "
            f"{wall / n * 1e6:.1f} us per step, "
            f"{wall / n / model.n_mobile * 1e9:.1f} ns per mobile particle-step"
        )
    tangent_steps = st.alignment + st.onset + st.decay
    replica = start.wall_time + tangent_steps * rates[True]
    print(
        f"one replica: start-up {start.wall_time:.1f} s + {tangent_steps} steps with tangent "
        f"x {rates[True] * 1e6:.1f} us = {replica:.1f} s; {PAPER_PAIRS} pairs: "
        f"{replica * PAPER_PAIRS / 3600:.0f} core-hours "
        f"(+{st.chunk * rates[False]:.2f} s per chunk of waiting for a continuous avalanche)"
    )
    if args.full:
        t = time.process_time()
        ds = run_replica(sec, args.replica, snapshots=False)
        cpu = time.process_time() - t
        wall = float(ds["wall_time"].values[0])
        steps_run = int(ds["n_steps"].values[0])
        ns = cpu / steps_run / model.n_mobile * 1e9
        print(
            f"whole replica {args.replica}: {steps_run} steps in {cpu:.1f} s CPU ({wall:.1f} s "
            f"wall), {ns:.1f} ns per mobile particle-step, "
            f"{ns / (rates[True] / model.n_mobile * 1e9):.2f}x the rotation with tangent; "
            f"decay window from {float(ds['decay_start'].values[0]):.1f} s; "
            f"{PAPER_PAIRS} pairs: {cpu * PAPER_PAIRS / 3600:.0f} core-hours"
        )
        # the engine benchmark's settled pile with tangent dynamics, in the same process
        bsim, bstate = engine_bench.drum_system()
        bsim.random_tangent(bstate, np.random.default_rng(1))
        bsim.run(bstate, 35, stride=35, tangent=True)
        med = engine_bench.timed(bsim, bstate, 14_000, 5, 736, tangent=True)[0]
        print(
            f"benchmarks/engine.py drum tangent here: {med:.1f} ns per mobile particle-step; "
            f"the whole replica costs {ns / med:.2f}x that"
        )


if __name__ == "__main__":
    main()
