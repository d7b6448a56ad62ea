"""Throughput of the drum study: seconds per replica and ns per particle-step.

Runs the real drum (736 mobile + 150 wall disks) of a config's ``drum`` section:
placement and settling, then ``--seconds`` of rotation with and without the tangent
dynamics, and prints the cost per step and per mobile-particle step, and the
projected cost of one replica of that config (settling as measured, the rotation
before t = 0, the onset and decay windows; no waiting for a continuous avalanche).

    .venv/bin/python benchmarks/drum.py [--configfile config/config.yaml] [--seconds 2]

Numbers depend on the machine and on what else runs; run it on a quiet machine.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import yaml

from granpipe.drum.protocol import DrumModel, initial_tangent, replica_streams, settle
from granpipe.drum.settings import filled, steps


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configfile", default="config/config.yaml")
    ap.add_argument("--seconds", type=float, default=2.0, help="simulated rotation per mode")
    ap.add_argument("--replica", type=int, default=0)
    args = ap.parse_args(argv)
    sec = filled(yaml.safe_load(open(args.configfile))["drum"])
    st = steps(sec)
    model = DrumModel.from_section(sec)
    place, tangent_rng, _ = replica_streams(sec, args.replica)

    # warm-up: compile (or load from cache) outside the timings
    sim = model.simulation(sec["physics"]["omega"])
    pos = np.zeros((model.n_mobile, 2))
    t = time.perf_counter()
    pile = settle(model, st, {**sec["settle"], "max_time_s": 0.01, "min_time_s": 0.0}, place)
    print(f"warm-up (compile or cache load): {time.perf_counter() - t:.1f} s")

    place, tangent_rng, _ = replica_streams(sec, args.replica)
    pile = settle(model, st, sec["settle"], place)
    ns_settle = pile.wall_time / (pile.n_steps * model.n_mobile) * 1e9
    print(
        f"settling: {pile.settle_time:.2f} s simulated ({pile.n_steps} steps) in "
        f"{pile.wall_time:.1f} s wall: {ns_settle:.0f} ns per particle-step "
        f"(settled={pile.settled})"
    )
    n = max(st.block, int(round(args.seconds / st.dt_s / st.block)) * st.block)
    rates = {}
    for tangent in (False, True):
        state = model.new_state(sim, pile.positions, pile.velocities)
        pos = state.positions
        if tangent:
            dr, dv = initial_tangent(model.n_mobile, tangent_rng, 0.1)
            z = np.zeros((model.geom.n_wall, 2))
            sim.set_tangent(state, np.concatenate([dr, z]), np.concatenate([dv, z]))
        sim.run(state, st.block, stride=st.block, tangent=tangent)  # warm
        t = time.perf_counter()
        sim.run(state, n, stride=st.block, tangent=tangent)
        wall = time.perf_counter() - t
        rates[tangent] = wall / n
        print(
            f"rotation {'with' if tangent else 'without'} tangent: {n} steps in {wall:.2f} s: "
            f"{wall / n * 1e6:.1f} us per step, "
            f"{wall / n / model.n_mobile * 1e9:.0f} ns per particle-step "
            f"({wall / n / (model.n_mobile + model.geom.n_wall) * 1e9:.0f} counting wall disks)"
        )
    del pos
    protocol_steps = st.pre_rotation + st.onset + st.decay
    replica = pile.wall_time + protocol_steps * rates[True]
    print(
        f"one replica of {args.configfile}: settling {pile.wall_time:.0f} s + "
        f"{protocol_steps} protocol steps x {rates[True] * 1e6:.1f} us = {replica:.0f} s "
        f"(+{st.chunk * rates[True]:.1f} s per extra chunk of waiting)"
    )


if __name__ == "__main__":
    main()
