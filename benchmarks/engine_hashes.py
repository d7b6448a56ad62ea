"""sha256 of the engine's outputs on a tiny drum with tangent dynamics (the paper's law and
static friction) and on a small driven box, built through the studies' entry points.

    PYTHONPATH=src .venv/bin/python benchmarks/engine_hashes.py

A change meant to keep the results bit for bit must print the same hashes before and after
(a few seconds of CPU after compilation; fixed seeds).
"""

import hashlib

import numpy as np

from granpipe.box import model as box_model
from granpipe.box import preparation as box_prep
from granpipe.drum.layout import steps
from granpipe.drum.model import DrumModel
from granpipe.drum.preparation import prepare
from granpipe.drum.protocol import initial_tangent, replica_streams, tiny_section

# the small box of the tests (tests/box/conftest.py), written out so that the hashes stay
# those of this exact box when the tests' box changes
BOX_PHYSICS = {
    "Lx": 6.0,
    "kappa_n": 1.0e6,
    "kappa_t": 1.0e4,
    "gamma_n": 100.0,
    "gamma_t": 100.0,
    "mu": 0.6,
    "mu_bottom": 0.6,
    "mu_side_walls": 0.6,
    "omega": 1.0,
    "steps_per_contact": 50.0,
}
BOX_INIT = {"crystal_rows": "spanning", "crystal_noise": 1.0e-6, "crystal_relax_time": 0.2}
BOX_PROTOCOL = {"start_phase": "sine", "ramp_periods": 0.0}


def h(x):
    a = np.ascontiguousarray(np.asarray(x))
    digest = hashlib.sha256(a.tobytes() + str(a.dtype).encode() + str(a.shape).encode())
    return digest.hexdigest()[:16]


def drum(friction: str):
    """A tiny drum replica (placement and start-up of replica 0), then 3,000 steps turning
    with a random tangent vector, lambda and V recorded in blocks of 100 steps."""
    sec = tiny_section({"physics": {"friction": friction}})
    model = DrumModel.from_physics(sec["physics"])
    st = steps(sec)
    place_rng, tangent_rng, _ = replica_streams(sec, 0)
    start = prepare(model, sec, st, place_rng)
    sim = model.simulation(model.omega)
    state = model.new_state(sim, start.positions, start.velocities, wall_angle=start.wall_angle,
                            spins=start.spins, shear=start.shear)  # fmt: skip
    dr, dv = initial_tangent(model.n_mobile, tangent_rng, 0.5)
    n_w = model.geom.n_wall
    sim.set_tangent(state, np.r_[dr, np.zeros((n_w, 2))], np.r_[dv, np.zeros((n_w, 2))])
    rec = sim.run(state, 3000, stride=100, tangent=True)
    tr, tv = state.tangent
    out = {
        "positions": state.positions,
        "velocities": state.velocities,
        "tangent_r": tr,
        "tangent_v": tv,
        "lambda": rec.local_lyapunov,
        "lambda_count": rec.lyapunov_count,
        "V": rec.global_speed,
    }
    if friction == "static":
        out["spins"] = state.spins
        out["tangent_spin"] = state.tangent_spin
    return out


def box():
    """A crystal of 30 disks (Lx = 6, prepared as the box study does) driven at Gamma = 2
    for 20,000 steps."""
    n = 30
    prep = box_prep.prepare(BOX_PHYSICS, BOX_INIT, n, "crystal", np.random.default_rng(3))
    drive = box_model.drive_for(BOX_PHYSICS, BOX_PROTOCOL, 2.0)
    _, dt = box_model.steps_per_period(BOX_PHYSICS, 16)
    sim = box_prep.box_simulation(BOX_PHYSICS, dt, box_model.flat_walls(BOX_PHYSICS, drive))
    radii, masses = box_prep.disk_arrays(n)
    state = sim.new_state(prep.positions, radii, masses, velocities=prep.velocities,
                          spins=prep.spins)  # fmt: skip
    sim.run(state, 20000)
    return {"positions": state.positions, "velocities": state.velocities, "spins": state.spins}


def main():
    for tag, out in (("drum", drum("viscous")), ("drum_static", drum("static")), ("box", box())):
        for k, v in out.items():
            print(f"{tag}.{k}: {h(v)}")


if __name__ == "__main__":
    main()
