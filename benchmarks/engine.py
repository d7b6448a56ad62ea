"""Engine throughput: ns per particle-step on the drum and box systems (docs/drum.md, docs/box.md).

    .venv/bin/python benchmarks/engine.py [--repeats 5] [--quick]

Systems (one replica, one thread, compiled code loaded from numba's cache first):

* drum: 736 mobile + 150 wall disks (docs/drum.md), a pile settled with the drum at rest,
  then turning clockwise at Omega = 2.4417e-4; forward only, and with the tangent
  dynamics (lambda and V recorded in 4 ms blocks). ns per *mobile* particle-step. With
  the tangent dynamics also under the static-friction law (spin and shear history;
  docs/drum.md, "Static friction"), through the same passes.
* box: N = 1200 disks (sigma = 1, m = 1) in Lx = 20 with the Table I law, dt = t_c/50;
  driven at Gamma = 2 (A = 2, omega = 1) after six periods of transient, timed over
  whole drive periods; and at rest as a dense hexagonal crystal on the bottom.

Each figure is the median over ``--repeats`` timed chunks of the same run, in CPU time
of the (single) computing thread — wall time on a quiet machine, but not inflated when
other jobs share the cores (the wall/CPU ratio is printed beside it); the contact
and neighbour-list statistics of the timed steps are printed beside it. Settled
starting states are cached in the system temp folder (delete the ``granpipe_bench_*``
files to rebuild them). The last line is one JSON object:
``{"drum_forward_ns", "drum_tangent_ns", "static_friction_tangent_ns", "box_driven_ns",
"box_dense_ns"}`` (medians).

For scale: LAMMPS GRANULAR on one core of a 2-core machine takes about
110 (drum), 38 (driven box) and 100 (dense crystal) ns per particle-step. On a shared
virtual machine, other guests' load shows as CPU time too (``steal``): compare versions
by interleaved runs. ``benchmarks/engine_passes.py`` breaks a step down by pass;
docs/engine_performance.md records the figures and what bounds them.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

# One BLAS thread, as `make bench` sets, before numpy loads OpenBLAS: the idle thread pools
# of numpy's and scipy's OpenBLAS slowed the dense box from 37 to 52 ns per particle-step
# on a 2-vCPU machine (docs/engine_performance.md, round 5).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numba
import numpy as np

# the systems are built with the tests' geometry helpers (tests/engine/geometry.py)
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from granpipe.engine import BoxLaw, DrumLaw

DRUM_PARAMS = {"k_n": 565.97, "gamma_n": 8.7308, "gamma_t": 6.8927, "mu": 0.44}
DRUM_LAW = DrumLaw(**DRUM_PARAMS)
DT_DRUM = 1.14368e-3
OMEGA_DRUM = -2.4417e-4
BOX_PARAMS = {"kappa_n": 1e6, "kappa_t": 1e4, "gamma_n": 100.0, "gamma_t": 100.0, "mu": 0.6}
BOX_LAW = BoxLaw(**BOX_PARAMS)
DT_BOX = BOX_LAW.contact_time(0.5) / 50
LX = 20.0
N_BOX = 1200
CACHE = Path(tempfile.gettempdir())


def _api(pkg):
    """The engine of package ``pkg`` (``granpipe``, or an older revision's renamed copy,
    ``benchmarks/engine_ab.py``) and the tests' geometry helpers, so that every revision
    is timed on the same states."""
    return importlib.import_module(f"{pkg}.engine"), importlib.import_module(
        "tests.engine.geometry"
    )


def drum_system(skin=None, pkg="granpipe"):
    E, G = _api(pkg)
    ring, radius = G.ring_of_disks(150, 1.3846)
    diam = np.where(np.arange(736) % 2 == 0, 1.0, 1.1667)
    radii = np.r_[diam / 2, np.full(150, 1.3846 / 2)]
    masses = np.r_[diam**2, np.ones(150)]
    is_wall = np.arange(886) >= 736
    law = E.DrumLaw(**DRUM_PARAMS)
    sim = E.Simulation(law, dt=DT_DRUM, wall_disks=E.WallDisks(omega=0.0), skin=skin)
    path = CACHE / "granpipe_bench_drum_pile.npz"
    if path.exists():
        saved = np.load(path)
        pos, vel = saved["pos"], saved["vel"]
    else:
        rng = np.random.default_rng(2016)
        inner = G.random_disks_in_circle(rng, diam / 2, radius - 1.3846 / 2, y_max=0.0)
        state = sim.new_state(np.vstack([inner, ring]), radii, masses, is_wall=is_wall)
        t = time.perf_counter()
        for _ in range(60):
            sim.run(state, 5000)
            if state.kinetic_energy() / 736 < 1e-6:
                break
        print(
            f"settled the drum pile: t = {state.time:.0f}, KE/N = "
            f"{state.kinetic_energy() / 736:.1e} in {time.perf_counter() - t:.0f} s"
        )
        pos, vel = state.positions.copy(), state.velocities.copy()
        np.savez(path, pos=pos, vel=vel)
    sim = sim.replace(wall_disks=E.WallDisks(omega=OMEGA_DRUM))
    state = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall)
    return sim, state


def box_crystal(skin=None, pkg="granpipe"):
    E, G = _api(pkg)
    pos = G.hexagonal_rows(N_BOX, 1.0, LX, bottom=0.0)
    flat = E.FlatWalls(x_left=0.0, x_right=LX, bottom=True, z0=0.0)
    sim = E.Simulation(E.BoxLaw(**BOX_PARAMS), dt=DT_BOX, flat_walls=flat, skin=skin)
    path = CACHE / "granpipe_bench_box_crystal_v2.npz"
    n = len(pos)
    if path.exists():
        saved = np.load(path)
        state = sim.new_state(
            saved["pos"],
            np.full(n, 0.5),
            np.ones(n),
            velocities=saved["vel"],
            spins=saved["spin"],
        )
    else:
        # rows of 20 and 19 touching; let gravity compress the 60 layers and the
        # compression waves die out
        state = sim.new_state(pos, np.full(n, 0.5), np.ones(n))
        for _ in range(40):
            sim.run(state, 5000)
            if state.max_speed() < 1e-6:
                break
        np.savez(path, pos=state.positions, vel=state.velocities, spin=state.spins)
    return sim, state


def box_driven(skin=None, quick=False, pkg="granpipe"):
    E, _ = _api(pkg)
    sim0, crystal = box_crystal(skin, pkg)
    flat = E.FlatWalls(
        x_left=0.0, x_right=LX, bottom=True, z0=0.0, amplitude=2.0, omega=1.0, phase=-math.pi / 2
    )
    sim = sim0.replace(flat_walls=flat)
    period = int(round(2 * math.pi / DT_BOX))
    path = CACHE / f"granpipe_bench_box_driven_v2_{period}.npz"
    n = crystal.n
    if path.exists():
        saved = np.load(path)
        state = sim.new_state(
            saved["pos"],
            np.full(n, 0.5),
            np.ones(n),
            velocities=saved["vel"],
            spins=saved["spin"],
            time=float(saved["t"]),
        )
    else:
        # the plate starts at its lowest point at rest (hazard (i)); six periods of transient
        # (hazard (iv): the bed re-condenses after 3-6 periods)
        state = sim.new_state(
            crystal.positions - [0.0, 2.0],
            np.full(n, 0.5),
            np.ones(n),
            velocities=crystal.velocities,
        )
        sim.run(state, 1 if quick else 6 * period)
        np.savez(path, pos=state.positions, vel=state.velocities, spin=state.spins, t=state.time)
    return sim, state, period


def static_friction(sim, state, pkg="granpipe"):
    """The drum pile of ``state`` under the static-friction law (spin, shear history; the
    spins start at rest) of package ``pkg``: ``(simulation, state)``."""
    E, _ = _api(pkg)
    ssim = sim.replace(law=E.StaticFrictionLaw(**DRUM_PARAMS))
    sstate = ssim.new_state(
        state.positions, state.radii, state.masses, velocities=state.velocities,
        spins=np.zeros(state.n), is_wall=state.is_wall,
    )  # fmt: skip
    return ssim, sstate


def timed(sim, state, steps, repeats, n_particles, tangent=False):
    """Median ns per particle-step over ``repeats`` chunks; statistics of the timed steps.

    Times are the CPU time of the calling thread (the serial kernel runs in it), which
    equals wall time on a quiet machine and is not inflated by other processes; the
    wall/CPU ratio is printed as a load indicator.
    """
    per = []
    wall = 0.0
    cpu = 0.0
    state.reset_counters()
    for _ in range(repeats):
        t = time.thread_time()
        w = time.perf_counter()
        if tangent:
            sim.run(state, steps, stride=35, tangent=True)
        else:
            sim.run(state, steps)
        wall += time.perf_counter() - w
        dt = time.thread_time() - t
        cpu += dt
        per.append(dt / (steps * n_particles) * 1e9)
    st = state.neighbour_stats()
    stats = {
        "contacts_per_particle": 2 * st["mean_contacts"] / state.n,
        "pairs_per_particle": st["pairs"] / state.n,
        "steps_per_rebuild": st["steps_run"] / max(st["rebuilds"], 1),
        "wall_over_cpu": wall / cpu,
    }
    return float(np.median(per)), per, stats


def report(name, med, per, stats):
    runs = " ".join(f"{p:.1f}" for p in per)
    print(
        f"{name:14s} {med:7.2f} ns/particle-step  (runs: {runs})  "
        f"contacts/particle {stats['contacts_per_particle']:.2f}, list pairs/particle "
        f"{stats['pairs_per_particle']:.2f}, steps/rebuild {stats['steps_per_rebuild']:.0f}, "
        f"wall/cpu {stats['wall_over_cpu']:.2f}"
    )


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="short chunks (smoke test)")
    ap.add_argument("--skin", type=float, default=None, help="Verlet skin (default: engine's)")
    args = ap.parse_args(argv)
    numba.set_num_threads(1)
    out = {}

    sim, state = drum_system(args.skin)
    steps = 500 if args.quick else 20_000
    sim.run(state, 35)  # load compiled code
    med, per, stats = timed(sim, state, steps, args.repeats, 736)
    report("drum forward", med, per, stats)
    out["drum_forward_ns"] = med
    sim.random_tangent(state, np.random.default_rng(1))
    sim.run(state, 35, stride=35, tangent=True)
    steps = 350 if args.quick else 14_000
    med, per, stats = timed(sim, state, steps, args.repeats, 736, tangent=True)
    report("drum tangent", med, per, stats)
    out["drum_tangent_ns"] = med
    ssim, sstate = static_friction(sim, state)
    ssim.random_tangent(sstate, np.random.default_rng(1))
    ssim.run(sstate, 35, stride=35, tangent=True)
    med, per, stats = timed(ssim, sstate, steps, args.repeats, 736, tangent=True)
    report("static fric. t.", med, per, stats)
    out["static_friction_tangent_ns"] = med

    sim, state, period = box_driven(args.skin, args.quick)
    sim.run(state, 10)
    steps = 1000 if args.quick else period
    med, per, stats = timed(sim, state, steps, max(2, args.repeats // 2), N_BOX)
    report("box driven", med, per, stats)
    out["box_driven_ns"] = med

    sim, state = box_crystal(args.skin)
    sim.run(state, 10)
    steps = 1000 if args.quick else 20_000
    med, per, stats = timed(sim, state, steps, args.repeats, N_BOX)
    report("box dense", med, per, stats)
    out["box_dense_ns"] = med
    print(json.dumps({k: round(v, 2) for k, v in out.items()}))


if __name__ == "__main__":
    main()
