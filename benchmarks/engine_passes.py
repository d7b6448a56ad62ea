"""Where an engine step spends its time: each pass of the step loop timed on its own.

    .venv/bin/python benchmarks/engine_passes.py [--repeats 5]

Runs on the same settled states as ``benchmarks/engine.py`` (drum pile of docs/drum.md,
rotating, with a tangent vector, under the drum law and under static friction; dense box
crystal of docs/box.md) through the engine's public hook
:meth:`granpipe.engine.Simulation.profile_passes`, which times each pass of the step loop
in a jitted loop: gather, the law's rows and scatter, forward and with the tangent
vector, the flat walls, the kicks and a list rebuild. Figures are the best of
``--repeats`` loops (the machine's noise only adds time), in ns per particle and ns per
listed pair; the passes of one step add up to a little less than the whole step of
engine.py (the remainder is wall motion, bookkeeping and the step loop itself). The last
line is one JSON object ``{"<system>.<pass>": ns per particle}``.
"""

from __future__ import annotations

import argparse
import json
import os

# One BLAS thread, as `make bench` sets, before numpy loads OpenBLAS: the idle thread pools
# of numpy's and scipy's OpenBLAS slowed the dense box from 37 to 52 ns per particle-step
# on a 2-vCPU machine (docs/engine_performance.md, round 5).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numba
import numpy as np
from engine import DT_DRUM, OMEGA_DRUM, box_crystal, drum_system

from granpipe.engine import Simulation, StaticFrictionLaw, WallDisks

N_DRUM_MOBILE = 736


def _rows(out, system, timings, n_particles):
    npairs = timings.pop("n_pairs")
    timings.pop("n_particles")
    for name, sec in timings.items():
        per_particle = sec * 1e9 / n_particles
        per_pair = sec * 1e9 / npairs
        print(f"{system:14s} {name:18s} {per_particle:7.2f} ns/particle  {per_pair:6.2f} ns/pair")
        out[f"{system}.{name}"] = round(per_particle, 2)


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
    pile = state.copy()
    t = sim.profile_passes(state, repeats=rep, nrep=5000)
    print(f"drum: {t['n_pairs']} listed pairs, {t['n_pairs'] / N_DRUM_MOBILE:.2f} per mobile disk")
    _rows(out, "drum", t, N_DRUM_MOBILE)

    # the same pile under static friction (spin, shear history)
    law = StaticFrictionLaw(565.97, 8.7308, 6.8927, 0.44)
    ssim = Simulation(law, dt=DT_DRUM, wall_disks=WallDisks(omega=OMEGA_DRUM))
    s = ssim.new_state(pile.positions, pile.radii, pile.masses, velocities=pile.velocities,
                       spins=np.zeros(pile.n), is_wall=pile.is_wall)  # fmt: skip
    ssim.random_tangent(s, np.random.default_rng(1))
    ssim.run(s, 700, tangent=True)
    _rows(out, "static", ssim.profile_passes(s, repeats=rep, nrep=5000), N_DRUM_MOBILE)

    sim, state = box_crystal()
    sim.run(state, 10)
    t = sim.profile_passes(state, repeats=rep, nrep=5000)
    print(
        f"box crystal: {t['n_pairs']} listed pairs, {t['n_pairs'] / t['n_particles']:.2f} per disk"
    )
    _rows(out, "box", t, t["n_particles"])
    print(json.dumps(out))


if __name__ == "__main__":
    main()
