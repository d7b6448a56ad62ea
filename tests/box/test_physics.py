"""Physics of the box study on small systems with Table I's contact law and Δt = t_c/50.

Each check could fail: a crystal that is not hexagonal, a random packing that is, a bed
that leaves a plate accelerating below g, a bed that stays on one accelerating at 2g,
parts that do not continue exactly, a blow-up without its context.
"""

import numpy as np
import pytest

from granpipe.box import measures, preparation, protocol, stages
from granpipe.errors import SimulationError

from .conftest import INIT, PHYSICS, PROTOCOL

WIDE = {**PHYSICS, "Lx": 20.0}


@pytest.fixture(scope="module")
def crystal_small():
    """A relaxed spanning crystal of 33 disks in Lx = 6 (rows 6/5, six rows)."""
    return preparation.prepare(PHYSICS, INIT, 33, "crystal", np.random.default_rng(0))


def test_settled_crystal_is_hexagonal_and_random_packing_is_not():
    rng = np.random.default_rng(11)
    crystal = preparation.prepare(WIDE, INIT, 200, "crystal", rng)
    random = preparation.prepare(WIDE, INIT, 200, "random", np.random.default_rng(11))
    assert random.settled and random.kinetic_energy < INIT["settle_kinetic_energy"]
    psi_c = preparation.bulk_psi6(crystal.positions, 20.0)
    psi_r = preparation.bulk_psi6(random.positions, 20.0)
    hex_c = np.mean(measures.local_order(crystal.positions)["order"] == 1)
    hex_r = np.mean(measures.local_order(random.positions)["order"] == 1)
    assert psi_c > 0.999
    assert hex_c > 0.98  # all but the two bottom corners
    assert psi_r < 0.97
    assert hex_r < 0.9


def _run(physics, gamma, start, periods=range(2), proto=PROTOCOL):
    return protocol.run_part(
        physics, proto, gamma, 0, periods, start_positions=start.positions,
        start_velocities=start.velocities, start_spins=start.spins,
    )  # fmt: skip


def test_frictionless_walls_below_g_bed_moves_rigidly_with_the_plate(crystal_small):
    res = _run({**PHYSICS, "mu_side_walls": 0.0}, 0.7, crystal_small)
    s_b, s_k = measures.bouncing_measure(res.z_tracers, res.z_plate)
    detach, _ = measures.detachment_fraction(res.bed_gap)
    assert s_b < 1e-3  # the tracers keep their height above the plate to 1e-3 σ
    assert detach == 0.0 and res.bed_gap.max() < 1e-4
    assert res.granular_temperature.mean() < 1e-6
    assert np.all(res.plate_contacts > 0)


def test_frictionless_walls_at_two_g_bed_leaves_the_plate_every_cycle(crystal_small):
    res = _run({**PHYSICS, "mu_side_walls": 0.0}, 2.0, crystal_small)
    s_b, _ = measures.bouncing_measure(res.z_tracers, res.z_plate)
    detach, per_cycle = measures.detachment_fraction(res.bed_gap)
    assert s_b > 1.0 / 30.0
    assert np.all(per_cycle > 0.2)  # in flight for a good part of every cycle
    assert res.bed_gap.max() > 0.5


def test_parts_continue_exactly(crystal_small):
    proto = {**PROTOCOL, "transient_periods": 1}
    whole = _run(PHYSICS, 1.5, crystal_small, range(2), proto)
    first = _run(PHYSICS, 1.5, crystal_small, range(1), proto)
    second = protocol.run_part(
        PHYSICS, proto, 1.5, 1, range(1, 2), previous_state=first.final_state,
        tracers=first.tracers,
    )  # fmt: skip
    np.testing.assert_array_equal(whole.cycle_positions[1], first.cycle_positions[1])
    np.testing.assert_array_equal(whole.cycle_positions[2], second.cycle_positions[1])
    np.testing.assert_array_equal(whole.z_tracers[1], second.z_tracers[0])
    np.testing.assert_array_equal(whole.granular_temperature[1], second.granular_temperature[0])


def test_init_depends_only_on_seed_and_physics(tmp_path):
    params = {
        "physics": PHYSICS,
        "init": {**INIT, "crystal_noise": 1e-4, "crystal_relax_time": 0.0},
    }
    a = stages.init_stage(params, 5, "crystal", 0, tmp_path / "a.nc", log=None)
    b = stages.init_stage(params, 5, "crystal", 0, tmp_path / "b.nc", log=None)
    c = stages.init_stage(params, 5, "crystal", 1, tmp_path / "c.nc", log=None)
    from granpipe.io import read_dataset

    pa, pb, pc = (read_dataset(p)["positions"].values for p in (a, b, c))
    np.testing.assert_array_equal(pa, pb)
    assert np.abs(pa - pc).max() > 1e-6


def test_blow_up_names_study_point_replica_and_seed(tmp_path):
    # Δt = 5 t_c: the integration is unstable and the engine must stop it
    params = {"physics": {**PHYSICS, "steps_per_contact": 0.2}, "init": INIT}
    with pytest.raises(SimulationError) as err:
        stages.init_stage(params, 5, "random", 3, tmp_path / "x.nc", log=None)
    text = str(err.value)
    for word in ("study=box", "point=N_l=5,init=random", "replica=3", "seed=", "particle="):
        assert word in text
    assert not (tmp_path / "x.nc").exists()


def test_slip_frames_at_other_phases_leave_the_run_unchanged(crystal_small):
    """With four slip phases the cycle starts, tracers and samples are the same bits as with
    one; the frame of phase k = N_k/4 of period j is the sample of that phase (the plate
    where the drive puts it a quarter period on); the ramp's end is kept once."""
    proto = {**PROTOCOL, "transient_periods": 1, "ramp_periods": 0.5}
    one = _run(PHYSICS, 2.0, crystal_small, range(2), proto)
    four = _run(PHYSICS, 2.0, crystal_small, range(2), {**proto, "slip_phases": 4})
    np.testing.assert_array_equal(one.cycle_positions, four.cycle_positions)
    np.testing.assert_array_equal(one.z_tracers, four.z_tracers)
    assert one.phase_positions.shape == (2, 0, 33, 2)
    assert four.phase_positions.shape == (2, 3, 33, 2)
    n_k = PROTOCOL["phases_per_period"]
    quarter = four.phase_positions[:, 0, four.tracers, 1]
    np.testing.assert_array_equal(quarter, four.z_tracers[:, n_k // 4].astype(np.float32))
    # the ramp ends half a period in: the first transient sample at or after it
    assert four.drive.ramp_time <= four.ramp_time < four.drive.ramp_time + four.drive.period / n_k
    np.testing.assert_array_equal(one.ramp_positions, four.ramp_positions)
    with pytest.raises(ValueError, match="slip_phases = 3"):
        _run(PHYSICS, 2.0, crystal_small, range(1), {**proto, "slip_phases": 3})
