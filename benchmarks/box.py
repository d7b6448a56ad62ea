"""Box study throughput and start-up hazards (docs/box.md), printed, never asserted.

    .venv/bin/python benchmarks/box.py            # cost per particle-step, N = 200, 400
    .venv/bin/python benchmarks/box.py --hazards  # launch speeds and ψ6 at measurement start
    .venv/bin/python benchmarks/box.py --crystal [--gamma 1.2 2.4] [--n-l 20] [--jobs 2]
    .venv/bin/python benchmarks/box.py --convergence [--gamma 0.8 1.6 2.4 3.4] [--periods 100]

Cost: ns per particle-step of the box law with walls and a driven plate (Γ = 2, after
one period of drive), and the projected wall time of one default-scale point.

Hazards: for the crystal start (rows ``spanning`` 20/19 and ``inset`` 19/19) and the
random start, each start-up (Eq. (1) as printed: impulsive; ``sine`` with a 2-period
ramp; ``bottom`` turning point without ramp), with μ = 0.6 and frictionless side walls:
the largest bed centre-of-mass and disk upward speeds over the plate's top speed Aω,
and the bulk |ψ6| when the measurement begins after 6 periods.

Crystal: does the crystal start survive the start-up? For each preparation (row fit,
start phase, ramp and transient length in periods, side-wall friction μ_w, the side
walls shaken with the plate or still, the walls' torque) and Γ, the bed's largest
centre-of-mass launch speed over Aω in the transient and the
crystal check of docs/box.md (bulk |ψ6|, hexagonal fraction, dislocations = bulk disks
with other than six Delaunay neighbours) at the start of the measurement and after
``--periods`` more periods.

Convergence: s_c, s_b, T_g* and p_s of a point from its first P measured periods
(:func:`granpipe.box.measures.convergence`), both starts, the default protocol, μ_w = 0.6,
with the relative distance of each from its value at the longest record.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from granpipe.box import model, preparation, protocol

PHYSICS = dict(
    Lx=20.0, kappa_n=1e6, kappa_t=1e4, gamma_n=100.0, gamma_t=100.0, mu=0.6, mu_bottom=0.6,
    mu_side_walls=0.6, omega=1.0, steps_per_contact=50.0, side_walls="shaken",
    wall_torque="lever",
)  # fmt: skip
INIT = dict(
    crystal_rows="spanning", crystal_noise=1e-6, crystal_relax_time=1.0,
    random_packing_fraction=0.3, settle_kinetic_energy=1e-8, settle_max_time=60.0,
)  # fmt: skip


def cost(n_ls=(10, 20), gamma=2.0, steps=30000):
    from granpipe.box.preparation import box_simulation, disk_arrays

    proto = dict(start_phase="sine", ramp_periods=0.0, transient_periods=0, phases_per_period=64)
    drive = model.drive_for(PHYSICS, proto, gamma)
    steps_per, dt = model.steps_per_period(PHYSICS, 64)
    print(f"dt = {dt:.6e} t0, {steps_per} steps per period (t_c/dt = "
          f"{model.contact_time(PHYSICS) / dt:.3f})")  # fmt: skip
    for n_l in n_ls:
        n = 20 * n_l
        prep = preparation.prepare(PHYSICS, INIT, n, "crystal", np.random.default_rng(1))
        sim = box_simulation(PHYSICS, dt, model.flat_walls(PHYSICS, drive))
        radii, masses = disk_arrays(n)
        st = sim.new_state(prep.positions, radii, masses)
        sim.run(st, steps_per)  # one period of drive: the bed is bouncing
        t0 = time.perf_counter()
        sim.run(st, steps)
        el = time.perf_counter() - t0
        ns = 1e9 * el / (steps * n)
        per_period = ns * 1e-9 * n * steps_per
        print(
            f"N_l = {n_l:3d} (N = {n:5d}): {ns:6.1f} ns per particle-step, "
            f"{per_period:6.2f} s per period; a default point (6.25 + 8 periods): "
            f"{14.25 * per_period:6.0f} s"
        )


def hazards(gamma=1.5, n_l=10, transient=6, only=None):
    cases = [
        ("crystal", "spanning", "sine", 0.0, 0.6),
        ("crystal", "spanning", "sine", 2.0, 0.6),
        ("crystal", "spanning", "bottom", 0.0, 0.6),
        ("crystal", "inset", "sine", 2.0, 0.6),
        ("crystal", "spanning", "sine", 2.0, 0.0),
        ("random", "spanning", "sine", 2.0, 0.6),
        ("random", "spanning", "sine", 0.0, 0.6),
    ]
    if only:
        cases = [cases[i] for i in only]
    print(f"Γ = {gamma}, N_l = {n_l}, transient {transient} periods")
    print("start    rows      start_phase ramp mu_side | v_cm/Aω v_disk/Aω | psi6 prep  start")
    for kind, rows, phase, ramp, mu_side in cases:
        phys = {**PHYSICS, "mu_side_walls": mu_side}
        init = {**INIT, "crystal_rows": rows}
        prep = preparation.prepare(phys, init, 20 * n_l, kind, np.random.default_rng(3))
        proto = dict(
            start_phase=phase, ramp_periods=ramp, transient_periods=transient,
            phases_per_period=64,
        )  # fmt: skip
        res = protocol.run_part(
            phys, proto, gamma, 0, range(1), start_positions=prep.positions,
            start_velocities=prep.velocities, start_spins=prep.spins,
        )  # fmt: skip
        tr = res.transient
        aw = res.drive.amplitude * res.drive.omega
        print(
            f"{kind:8s} {rows:9s} {phase:11s} {ramp:4.1f} {mu_side:7.1f} | "
            f"{tr['vz_cm'].max() / aw:7.2f} {tr['max_vz'].max() / aw:9.2f} | "
            f"{preparation.bulk_psi6(prep.positions, 20.0):.3f} "
            f"{preparation.bulk_psi6(res.cycle_positions[0].astype(float), 20.0):.3f}"
        )


CRYSTAL_CASES = [
    # rows, start_phase, ramp, transient, mu_w, side walls, wall torque
    ("spanning", "sine", 2.0, 6, 0.6, "shaken", "lever"),
    ("spanning", "sine", 2.0, 6, 0.6, "shaken", "none"),
    ("spanning", "sine", 2.0, 6, 0.6, "still", "none"),
    ("spanning", "sine", 2.0, 6, 0.6, "still", "lever"),
    ("spanning", "sine", 6.0, 10, 0.6, "still", "lever"),
    ("spanning", "sine", 20.0, 24, 0.6, "still", "lever"),
    ("inset", "sine", 6.0, 10, 0.6, "still", "lever"),
    ("spanning", "bottom", 0.0, 6, 0.6, "still", "lever"),
    ("spanning", "sine", 2.0, 6, 0.4, "still", "lever"),
    ("spanning", "sine", 2.0, 6, 0.2, "still", "lever"),
    ("spanning", "sine", 2.0, 6, 0.0, "still", "lever"),
]


def _crystal_case(args):
    from granpipe.box import measures

    (rows, phase, ramp, transient, mu_w, side, torque), gamma, n_l, periods = args
    phys = {**PHYSICS, "mu_side_walls": mu_w, "side_walls": side, "wall_torque": torque}
    init = {**INIT, "crystal_rows": rows, "crystal_relax_time": 2.0}
    prep = preparation.prepare(phys, init, 20 * n_l, "crystal", np.random.default_rng(3))
    proto = dict(
        start_phase=phase, ramp_periods=ramp, transient_periods=transient, phases_per_period=8
    )  # fmt: skip
    res = protocol.run_part(
        phys, proto, gamma, 0, range(periods), start_positions=prep.positions,
        start_velocities=prep.velocities, start_spins=prep.spins,
    )  # fmt: skip
    checks = [
        measures.crystal_check(res.cycle_positions[i].astype(float), 20.0) for i in (0, periods)
    ]
    aw = res.drive.amplitude * res.drive.omega
    launch = float(res.transient["vz_cm"].max() / aw)
    return (rows, phase, ramp, transient, mu_w, side, torque, gamma, checks, launch,
            res.wall_seconds)  # fmt: skip


def crystal(gammas=(1.2, 2.4), n_l=20, periods=4, jobs=1, only=None):
    from concurrent.futures import ProcessPoolExecutor

    cases = CRYSTAL_CASES if not only else [CRYSTAL_CASES[i] for i in only]
    todo = [(c, g, n_l, periods) for g in gammas for c in cases]
    print(f"N_l = {n_l}; crystal check at measurement start and {periods} periods later")
    print("rows     phase  ramp  tr  mu_w sides  torque Gamma | v_cm/Aω | psi6  hex   disl "
          "intact | psi6  hex   disl intact | wall s")  # fmt: skip
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        for row in pool.map(_crystal_case, todo):
            rows, phase, ramp, tr, mu_w, side, torque, g, checks, launch, wall = row
            cols = " | ".join(
                f"{c.psi6:.3f} {c.hexagonal:.3f} {c.dislocations:4d} {str(c.intact):6s}"
                for c in checks
            )
            print(f"{rows:8s} {phase:6s} {ramp:4.0f} {tr:3d} {mu_w:5.2f} {side:6s} {torque:6s}"
                  f"{g:5.2f} | {launch:7.2f} | {cols} | {wall:5.0f}", flush=True)  # fmt: skip


def _convergence_case(args):
    from granpipe.box import measures

    kind, gamma, n_l, periods = args
    prep = preparation.prepare(PHYSICS, {**INIT, "crystal_relax_time": 2.0}, 20 * n_l, kind,
                           np.random.default_rng(3))  # fmt: skip
    proto = dict(start_phase="sine", ramp_periods=2.0, transient_periods=6, phases_per_period=64)
    res = protocol.run_part(
        PHYSICS, proto, gamma, 0, range(periods), start_positions=prep.positions,
        start_velocities=prep.velocities, start_spins=prep.spins,
    )  # fmt: skip
    slips = dict(displacement=0.2, min_neighbours=2, neighbour_cutoff=1.2, surface_depth=10.0)
    marks = [p for p in (5, 10, 20, 50, 100, 200, 500) if p < periods] + [periods]
    conv = measures.convergence(
        res.z_tracers, res.z_plate, res.granular_temperature, res.cycle_positions, slips, marks
    )
    return kind, gamma, conv


def convergence(gammas=(0.8, 1.6, 2.4, 3.4), n_l=20, periods=100, jobs=1):
    from concurrent.futures import ProcessPoolExecutor

    todo = [(k, g, n_l, periods) for g in gammas for k in ("random", "crystal")]
    print(f"N_l = {n_l}: measures from the first P periods; (x) = |x(P)/x({periods}) - 1|")
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        for kind, gamma, c in pool.map(_convergence_case, todo):
            print(f"{kind} Γ = {gamma}")
            for i, p in enumerate(c["P"]):
                cols = "  ".join(
                    f"{q} {c[q][i]:.4g} ({abs(c[q][i] / c[q][-1] - 1):.2f})"
                    if c[q][-1]
                    else f"{q} {c[q][i]:.4g}"
                    for q in ("s_c", "s_b", "T_g", "p_s")
                )
                print(f"  P = {p:4d}: {cols}", flush=True)


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hazards", action="store_true")
    ap.add_argument("--crystal", action="store_true")
    ap.add_argument("--convergence", action="store_true")
    ap.add_argument("--gamma", type=float, nargs="*", default=None)
    ap.add_argument("--n-l", type=int, default=None)
    ap.add_argument("--periods", type=int, default=4)
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--cases", type=int, nargs="*", default=None, help="indices of the cases")
    args = ap.parse_args()
    if args.convergence:
        convergence(gammas=args.gamma or (0.8, 1.6, 2.4, 3.4), n_l=args.n_l or 20,
                    periods=args.periods, jobs=args.jobs)  # fmt: skip
    elif args.crystal:
        crystal(gammas=args.gamma or (1.2, 2.4), n_l=args.n_l or 20, periods=args.periods,
                jobs=args.jobs, only=args.cases)  # fmt: skip
    elif args.hazards:
        hazards(gamma=(args.gamma or [1.5])[0], n_l=args.n_l or 10, only=args.cases)
    else:
        cost(gamma=(args.gamma or [2.0])[0])
