"""The issue-3 reference measured here: LAMMPS GRANULAR beside the engine, chunk by chunk.

    make bench-reference            # installs Debian's LAMMPS, then runs this script
    .venv/bin/python benchmarks/lammps_reference.py [--rounds 24] [--periods 2]
        [--systems df,dt,st,bd,bc]

Issue 3 sets its targets against LAMMPS (GRANULAR package, Debian's build, one core) on
the systems of ``benchmarks/engine.py``: ~110 ns per particle-step for the drum, ~38 for
the driven box, ~100 for the dense crystal, on "a 2-core machine like ours". On a shared
virtual machine the speed of a core changes by 1.3-1.5x for seconds to minutes
(docs/engine_performance.md), so an engine median taken at one moment and a reference
taken at another do not compare. This script runs both in one process and one thread:
Debian's ``liblammps`` through its own Python module (``python3-lammps``, ctypes) on the
same settled states as ``benchmarks/engine.py``, and the engine on its copy of them,
alternating short chunks (LAMMPS then engine, then engine then LAMMPS, ...). Each chunk
is timed in CPU time of the thread, as ``engine.py`` does.

The LAMMPS systems follow the engine's (same disks, positions, velocities, time step,
gravity, skin and rebuild criterion: a rebuild once some disk moved half the skin):

* drum: ``pair_style granular`` with ``hooke k_n gamma_n``, ``damping velocity`` (not
  scaled by mass) and ``tangential linear_nohistory gamma_t/gamma_n mu`` (viscous,
  capped at Coulomb): the drum law of docs/drum.md. The 150 wall disks turn with ``fix move
  rotate`` at Omega; wall-wall pairs are excluded from the list. LAMMPS integrates spins
  too (``nve/sphere``), which the drum law has not; ns per *mobile* disk, as engine.py.
* static-friction drum (``st``): the same pile under the static-friction law
  (docs/drum.md, "Static friction"), with the tangent vector in the engine; LAMMPS'
  ``tangential linear_history k_t gamma_t/gamma_n mu`` is the same Cundall-Strack spring
  with its dashpot. It prices the richer law in both codes, so that the engine's
  static/viscous cost ratio can be set beside LAMMPS' own; its printed target is 1.3
  times the drum-with-tangent one.
* box: ``pair_style gran/hooke/history kappa_n kappa_t gamma_n gamma_t mu 1``: normal
  spring, m_eff-scaled dashpots, tangential spring with shear history capped at
  Coulomb (the box law of docs/box.md, and LAMMPS' fastest granular style: ``granular``
  with the same model took 159 against 118 ns on the crystal), disks with I = m a²/2
  (``disc``); side walls and bottom by ``fix wall/gran`` with the same law. The driven
  bottom moves as ``wiggle y A 2pi/omega``, i.e. ``A sin(omega tau)``: the engine's state
  is first advanced a quarter period, to where its plate ``z0 + A sin(omega t - pi/2)``
  is at ``z0`` moving up, so both start there and each round times the same phase of the
  period in both codes. The crystal sits on a fixed bottom. Shear histories start at
  zero in LAMMPS.

Printed per system: median ns per particle-step of each code over the rounds, and the
ratio engine/LAMMPS: the median of the per-round ratios for the steady states; for the
driven box, whose rounds are the phases of a drive period (``--periods`` periods), the
period mean (:func:`_ratio`). Issue 3's box targets are that ratio (<= 1/5); its drum
targets are absolute (12 and 25 ns against LAMMPS' 110), so the ratio times the issue's
reference figure (``at_reference``) is what the engine's figure would be on the machine
where LAMMPS took the reference time. Also printed: steps per list rebuild of both codes,
the global speed V of the mobile disks after the timed steps (the same physics in both),
and the process/thread CPU-time ratio (1.000: each ran in the one thread timed). The
last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

# one thread for everything, LAMMPS' OpenMP runtime included (it reads OMP_NUM_THREADS)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import engine as bench
import numba
import numpy as np

# Debian's python3-lammps installs into the system interpreter's dist-packages; the module
# is pure Python over ctypes, so any CPython can load it from there
DEBIAN_DIST = "/usr/lib/python3/dist-packages"

# LAMMPS on the reference machine (ns per particle-step) and the targets
REFERENCE_NS = {"df": 110.0, "dt": 110.0, "st": 110.0, "bd": 38.0, "bc": 100.0}
TARGET_NS = {"df": 12.0, "dt": 25.0, "st": 32.5, "bd": 7.6, "bc": 20.0}
NAMES = {"df": "drum forward", "dt": "drum tangent", "st": "static fric.", "bd": "box driven"}
NAMES["bc"] = "box dense"
SYSTEMS = tuple(NAMES)


def _lammps():
    if DEBIAN_DIST not in sys.path:
        sys.path.append(DEBIAN_DIST)
    try:
        from lammps import lammps
    except ImportError as err:
        raise SystemExit(
            f"LAMMPS' Python module not found ({err}); run `make bench-reference`, which "
            "installs Debian's lammps, python3-lammps and liblammps-dev"
        ) from None
    lmp = lammps(cmdargs=["-log", "none", "-screen", "none", "-nocite"])
    if "GRANULAR" not in lmp.installed_packages:
        raise SystemExit("this LAMMPS build has no GRANULAR package")
    return lmp


def _write_data(path, pos, vel, spin, diam, mass, types, box):
    """A LAMMPS ``atom_style sphere`` data file (z = 0). This LAMMPS turns a density into a
    mass by the sphere's volume in 2d too, so the density column is ``mass / (pi d³/6)``."""
    n = len(pos)
    dens = mass / (math.pi * diam**3 / 6.0)
    lines = [
        "granpipe state",
        "",
        f"{n} atoms",
        f"{int(types.max())} atom types",
        f"{box[0]} {box[1]} xlo xhi",
        f"{box[2]} {box[3]} ylo yhi",
        "-0.5 0.5 zlo zhi",
        "",
        "Atoms # sphere",
        "",
    ]
    lines += [
        f"{i + 1} {types[i]} {diam[i]:.17g} {dens[i]:.17g} {pos[i, 0]:.17g} {pos[i, 1]:.17g} 0.0"
        for i in range(n)
    ]
    lines += ["", "Velocities", ""]
    lines += [f"{i + 1} {vel[i, 0]:.17g} {vel[i, 1]:.17g} 0 0 0 {spin[i]:.17g}" for i in range(n)]
    Path(path).write_text("\n".join(lines) + "\n")


def _common(dt, skin, data):
    return [
        "units lj",
        "dimension 2",
        "atom_style sphere",
        "boundary f m p",
        "comm_modify vel yes",
        f"read_data {data}",
        f"neighbor {skin:.17g} bin",
        "neigh_modify delay 0 every 1 check yes",
        f"timestep {dt:.17g}",
        "thermo 1000000000",
    ]


def drum_lammps(lmp, sim, state, tmp):
    """The drum pile of ``state`` in ``lmp``: mobile disks type 1, wall disks type 2."""
    law = sim.law
    mob = np.asarray(state.mobile)
    pos, vel = np.asarray(state.positions), np.asarray(state.velocities)
    diam = 2.0 * np.asarray(state.radii)
    mass = np.where(mob, np.asarray(state.masses), 1.0)
    types = np.where(mob, 1, 2)
    half = float(np.abs(pos).max() + diam.max() + 1.0)
    data = Path(tmp) / "drum.data"
    _write_data(data, pos, vel, np.zeros(len(pos)), diam, mass, types, (-half, half) * 2)
    omega = sim.wall_disks.omega
    cx, cy = sim.wall_disks.centre
    period = 2.0 * math.pi / abs(omega)
    axis = "0 0 1" if omega > 0 else "0 0 -1"
    cmds = _common(sim.dt, state.skin, data)
    if law.has_history:  # the static-friction law: a tangential spring
        tangential = f"linear_history {law.k_tangential:.17g}"
    else:
        tangential = "linear_nohistory"
    cmds += [
        "group mobile type 1",
        "group wall type 2",
        "neigh_modify exclude type 2 2",
        "pair_style granular",
        f"pair_coeff * * hooke {law.k_n:.17g} {law.gamma_n:.17g} tangential {tangential} "
        f"{law.gamma_t / law.gamma_n:.17g} {law.mu:.17g} damping velocity",
        "fix integrate mobile nve/sphere disc",
        f"fix turn wall move rotate {cx:.17g} {cy:.17g} 0.0 {axis} {period:.17g}",
        f"fix gravity mobile gravity {-sim.gravity[1]:.17g} vector 0 -1 0",
        "fix plane all enforce2d",
    ]
    for c in cmds:
        lmp.command(c)
    _check_masses(lmp, mass, mob)
    return int(mob.sum())


def box_lammps(lmp, sim, state, tmp):
    """The box of ``state`` in ``lmp``; a driven bottom starts at ``z0`` moving up."""
    law = sim.law
    fw = sim.flat_walls
    pos, vel = np.asarray(state.positions), np.asarray(state.velocities)
    n = len(pos)
    diam = 2.0 * np.asarray(state.radii)
    mass = np.asarray(state.masses)
    data = Path(tmp) / "box.data"
    top = float(pos[:, 1].max() + 10.0)
    box = (fw.x_left, fw.x_right, fw.z0 - fw.amplitude - 1.0, top)
    _write_data(data, pos, vel, np.asarray(state.spins), diam, mass, np.ones(n, int), box)
    coeffs = f"{law.kappa_n:.17g} {law.kappa_t:.17g} {law.gamma_n:.17g} {law.gamma_t:.17g}"
    wall_law = f"hooke/history {coeffs} {law.mu:.17g} 1"
    cmds = _common(sim.dt, state.skin, data)
    cmds += [
        f"pair_style gran/{wall_law}",
        "pair_coeff * *",
        "fix integrate all nve/sphere disc",
        f"fix gravity all gravity {-sim.gravity[1]:.17g} vector 0 -1 0",
        f"fix sides all wall/gran {wall_law} xplane {fw.x_left:.17g} {fw.x_right:.17g}",
    ]
    bottom = f"fix bottom all wall/gran {wall_law} yplane {fw.z0:.17g} NULL"
    if fw.amplitude != 0.0:
        bottom += f" wiggle y {fw.amplitude:.17g} {2.0 * math.pi / fw.omega:.17g}"
    cmds += [bottom, "fix plane all enforce2d"]
    for c in cmds:
        lmp.command(c)
    _check_masses(lmp, mass, np.ones(n, bool))
    return n


def _check_masses(lmp, mass, mob):
    """LAMMPS' per-atom masses of the disks ``mob`` are ``mass`` (the engine's; all disks),
    which checks the density convention of read_data."""
    lmp.command("run 0")
    got = np.empty(len(mob))
    got[lmp.numpy.extract_atom("id") - 1] = lmp.numpy.extract_atom("rmass")
    if not np.allclose(got[mob], mass[mob], rtol=1e-12):
        raise SystemExit("LAMMPS masses differ from the engine's: check the density column")


def systems(which, rounds, tmp):
    """``{key: (engine chunk, LAMMPS chunk, particles)}``; each chunk runs ``steps`` steps."""
    out = {}
    for key in [k for k in ("df", "dt", "st") if k in which]:
        sim, st = bench.drum_system()
        kw = {}
        if key == "st":
            sim, st = bench.static_friction(sim, st)
        if key != "df":  # LAMMPS has no tangent dynamics: its drum is the same either way
            sim.random_tangent(st, np.random.default_rng(1))
            kw = {"stride": 35, "tangent": True}
        lmp = _lammps()
        n = drum_lammps(lmp, sim, st, tmp)
        steps = 2_100  # a multiple of the tangent run's block stride 35
        out[key] = (_engine_chunk(sim, st, steps, kw), _lammps_chunk(lmp, steps), n)
    if "bd" in which:
        sim, st, period = bench.box_driven()
        sim.run(st, period // 4)  # to the phase where wiggle's sine starts
        lmp = _lammps()
        n = box_lammps(lmp, sim, st, tmp)
        steps = period // rounds
        out["bd"] = (_engine_chunk(sim, st, steps, {}), _lammps_chunk(lmp, steps), n)
    if "bc" in which:
        sim, st = bench.box_crystal()
        lmp = _lammps()
        n = box_lammps(lmp, sim, st, tmp)
        steps = 4_000
        out["bc"] = (_engine_chunk(sim, st, steps, {}), _lammps_chunk(lmp, steps), n)
    return out


class _Chunk:
    """``steps`` steps of one code, timed in CPU time of the thread (``run()``, seconds per
    step); also the CPU time of the whole process (other threads), list rebuilds, and the
    global speed ``V`` of the mobile disks (``speed()``: both codes run the same physics)."""

    def __init__(self, step, rebuilds, speed, steps):
        self.step, self.rebuilds, self.speed, self.steps = step, rebuilds, speed, steps
        self.thread = self.process = 0.0
        self.start = rebuilds()
        self.n_steps = 0

    def run(self):
        t, p = time.thread_time(), time.process_time()
        self.step(self.steps)
        dt = time.thread_time() - t
        self.thread += dt
        self.process += time.process_time() - p
        self.n_steps += self.steps
        return dt / self.steps

    def steps_per_rebuild(self):
        return self.n_steps / max(self.rebuilds() - self.start, 1)


def _engine_chunk(sim, state, steps, kw):
    sim.run(state, 35, **kw)  # compiled code loaded
    state.reset_counters()
    return _Chunk(
        lambda k: sim.run(state, k, **kw),
        lambda: state.neighbour_stats()["rebuilds"],
        state.global_speed,
        steps,
    )


def _lammps_chunk(lmp, steps):
    lmp.command("run 35")  # set up once (as many steps as the engine's first call)

    def speed():
        v = lmp.numpy.extract_atom("v")[:, :2]
        mobile = lmp.numpy.extract_atom("type") == 1
        return float(np.sqrt((v[mobile] ** 2).sum()))

    return _Chunk(
        lambda k: lmp.command(f"run {k} pre no post no"),
        lambda: int(lmp.get_thermo("nbuild")),
        speed,
        steps,
    )


def _ratio(a, b, per_period):
    """engine/LAMMPS from chunk times ``a``, ``b`` (ns), ``per_period`` chunks a period.

    A steady state: the median of the per-round ratios. The driven box: its chunks are the
    phases of a period, whose ratios differ (0.1-0.5), so the period-mean ratio weights
    each phase's ratio (median over periods) by LAMMPS' time for it, taken as the fastest
    over periods so that the host's load in one round does not set the weights.
    """
    r = (a / b).reshape(-1, per_period)
    if r.shape[1] == r.size:
        return float(np.median(r))
    w = b.reshape(r.shape).min(axis=0)
    return float((np.median(r, axis=0) * w).sum() / w.sum())


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=24, help="chunks per system (per period)")
    ap.add_argument("--periods", type=int, default=2, help="drive periods of the driven box")
    ap.add_argument("--systems", default=",".join(SYSTEMS))
    args = ap.parse_args(argv)
    which = args.systems.split(",")
    if bad := set(which) - set(SYSTEMS):
        ap.error(f"unknown systems {sorted(bad)}; choose from {','.join(SYSTEMS)}")
    numba.set_num_threads(1)
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        chunks = systems(which, args.rounds, tmp)
        for key in which:
            ours, theirs, n = chunks[key]
            t_ours, t_lmp = [], []
            for r in range(args.rounds * (args.periods if key == "bd" else 1)):
                order = (ours, theirs) if r % 2 == 0 else (theirs, ours)
                for chunk in order:
                    ns = chunk.run() / n * 1e9
                    (t_ours if chunk is ours else t_lmp).append(ns)
            a, b = np.array(t_ours), np.array(t_lmp)
            ratio = _ratio(a, b, args.rounds if key == "bd" else len(a))
            at_ref = ratio * REFERENCE_NS[key]
            print(
                f"{NAMES[key]:13s} engine {np.median(a):6.2f} (fastest {a.min():6.2f})  LAMMPS "
                f"{np.median(b):7.2f} (fastest {b.min():7.2f}) ns/particle-step  ratio "
                f"{ratio:.4f} (rounds {(a / b).min():.4f}-{(a / b).max():.4f})  at the "
                f"reference {at_ref:5.2f} ns (target {TARGET_NS[key]})",
                flush=True,
            )
            print(
                f"{'':13s} steps per list rebuild: engine {ours.steps_per_rebuild():.0f}, LAMMPS "
                f"{theirs.steps_per_rebuild():.0f}; V at the end: engine {ours.speed():.4g}, "
                f"LAMMPS {theirs.speed():.4g}; process/thread CPU time: engine "
                f"{ours.process / ours.thread:.3f}, LAMMPS {theirs.process / theirs.thread:.3f}",
                flush=True,
            )
            out[key] = {
                "engine_ns": round(float(np.median(a)), 2),
                "lammps_ns": round(float(np.median(b)), 2),
                "ratio": round(ratio, 4),
                "at_reference_ns": round(at_ref, 2),
            }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
