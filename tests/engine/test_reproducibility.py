"""Bit-identical results: repeated runs, chunking, replicas side by side; bad states raise."""

import numpy as np
import pytest

from granpipe.engine import BoxLaw, Ensemble, FlatWalls, Simulation, State, WallDisks
from granpipe.engine import layout as K
from granpipe.engine import layout as L
from granpipe.errors import ConfigError, SimulationError
from tests.engine.conftest import DRUM_LAW, DT_DRUM, small_drum
from tests.engine.geometry import random_disks_in_box

BOX_LAW = BoxLaw(kappa_n=1e6, kappa_t=1e4, gamma_n=100.0, gamma_t=100.0, mu=0.6)
DT_BOX = BOX_LAW.contact_time(0.5) / 50


def drum_state(seed):
    pos, radii, masses, is_wall, _ = small_drum(seed=seed)
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=-0.05))
    rng = np.random.default_rng(seed)
    vel = np.where(is_wall[:, None], 0.0, rng.normal(0, 0.5, pos.shape))
    state = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall)
    sim.random_tangent(state, rng, fraction=0.3)
    return sim, state


def box_state(seed):
    rng = np.random.default_rng(seed)
    n = 40
    flat = FlatWalls(x_left=0.0, x_right=8.0, bottom=True, z0=0.0, amplitude=0.3, omega=3.0)
    pos = random_disks_in_box(rng, np.full(n, 0.5), (0, 0.35), (8, 12))
    sim = Simulation(BOX_LAW, dt=DT_BOX, flat_walls=flat)
    state = sim.new_state(pos, np.full(n, 0.5), np.ones(n), velocities=rng.normal(0, 1, (n, 2)))
    return sim, state


def arrays(state):
    s = state._s
    return [s["vec"], s["sca"], s["ivec"], s["clock"], s["counters"], s["pair_xi"]]


def assert_identical(a, b):
    for x, y in zip(arrays(a), arrays(b), strict=True):
        np.testing.assert_array_equal(x, y)


def run(sim, state, chunks, tangent):
    recs = [sim.run(state, c, stride=50, tangent=tangent) for c in chunks]
    speed = np.concatenate([r.global_speed for r in recs], axis=-1)
    lam = np.concatenate([r.local_lyapunov for r in recs], axis=-1) if tangent else None
    return speed, lam


@pytest.mark.parametrize("kind", ["drum", "box"])
def test_repeated_and_chunked_runs_are_bit_identical(kind):
    make, tangent, n = (drum_state, True, 2000) if kind == "drum" else (box_state, False, 6000)
    sim, a = make(0)
    _, b = make(0)
    _, c = make(0)
    sa, la = run(sim, a, [n], tangent)
    sb, lb = run(sim, b, [n], tangent)
    sc, lc = run(sim, c, [n // 4, n // 2, n // 4], tangent)
    assert_identical(a, b)
    assert_identical(a, c)
    np.testing.assert_array_equal(sa, sb)
    np.testing.assert_array_equal(sa, sc)
    if tangent:
        np.testing.assert_array_equal(la, lc)
        assert np.isfinite(la).sum() > len(la) // 2


@pytest.mark.parametrize("kind", ["drum", "box"])
@pytest.mark.parametrize("parallel", [True, False])
def test_replicas_side_by_side_equal_replicas_alone(kind, parallel):
    make, tangent, n = (drum_state, True, 1000) if kind == "drum" else (box_state, False, 3000)
    singles = [make(seed) for seed in (1, 2, 3)]
    sim = singles[0][0].replace(parallel=parallel)
    ens = Ensemble.stack([s for _, s in singles])
    rec = sim.run(ens, n, stride=50, tangent=tangent)
    assert rec.global_speed.shape == (3, n // 50)
    for r, (_, alone) in enumerate(singles):
        rec1 = sim.run(alone, n, stride=50, tangent=tangent)
        np.testing.assert_array_equal(ens[r].positions, alone.positions)
        np.testing.assert_array_equal(ens[r].velocities, alone.velocities)
        np.testing.assert_array_equal(rec.global_speed[r], rec1.global_speed)
        if tangent:
            np.testing.assert_array_equal(rec.local_lyapunov[r], rec1.local_lyapunov)
            np.testing.assert_array_equal(ens[r].tangent[0], alone.tangent[0])


def test_non_finite_state_raises_with_particle_step_and_time():
    sim, state = drum_state(0)
    sim.run(state, 10)
    state.velocities[7, 0] = np.nan
    with pytest.raises(SimulationError) as err:
        sim.run(state, 10)
    assert err.value.particle == 7
    assert err.value.step == 11
    assert err.value.time == pytest.approx(11 * DT_DRUM)
    assert "non-finite" in str(err.value)


@pytest.mark.parametrize("n_steps", [1, 10])
def test_non_finite_tangent_vector_raises_at_its_step(n_steps):
    """A NaN in the tangent vector is caught when the step that carried it ends: inside a
    run (the norms of a step are taken in the next step's pass) and at a run's end."""
    sim, state = drum_state(0)
    sim.run(state, 10, tangent=True)
    state.tangent_stored[1][7, 0] = np.nan
    with pytest.raises(SimulationError) as err:
        sim.run(state, n_steps, tangent=True)
    assert err.value.step == 11
    assert err.value.time == pytest.approx(11 * DT_DRUM)
    assert "non-finite tangent vector" in str(err.value)


def test_deep_overlap_raises_naming_both_disks():
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, gravity=(0.0, 0.0))
    state = sim.new_state([[0, 0], [1.2, 0]], [0.5, 0.5], [1, 1], velocities=[[40, 0], [0, 0]])
    with pytest.raises(SimulationError) as err:
        sim.run(state, 100)
    e = err.value
    assert e.particle == 0 and e.context["other"] == 1
    assert 0 < e.step < 100 and e.time == pytest.approx(e.step * DT_DRUM)


def test_deep_overlap_with_flat_wall_and_in_ensemble_names_wall_and_replica():
    flat = FlatWalls(bottom=True, z0=0.0)
    sim = Simulation(BOX_LAW, dt=DT_BOX, flat_walls=flat)
    ok = sim.new_state([[0.0, 2.0]], [0.5], [1.0])
    bad = sim.new_state([[0.0, 2.0]], [0.5], [1.0], velocities=[[0.0, -2000.0]])
    ens = Ensemble.stack([ok, bad])
    with pytest.raises(SimulationError) as err:
        sim.run(ens, 100)
    assert err.value.context == {"other": "bottom wall", "replica": 1}
    assert err.value.particle == 0


def test_initial_deep_overlap_is_reported_at_creation():
    sim = Simulation(DRUM_LAW, dt=DT_DRUM)
    with pytest.raises(SimulationError) as err:
        sim.new_state([[0, 0], [0.6, 0]], [0.5, 0.5], [1, 1])
    assert err.value.step == 0


@pytest.mark.parametrize("kind", ["drum", "box"])
def test_saved_and_restored_state_continues_bit_identically(kind, tmp_path):
    """State.to_arrays -> np.savez -> State.from_arrays continues exactly (histories, list,
    tangent vector, time and wall angle included)."""
    make, tangent, n = (drum_state, True, 600) if kind == "drum" else (box_state, False, 2000)
    sim, a = make(4)
    sim.run(a, n, tangent=tangent)
    saved = a.to_arrays()
    # scratch (pair buffers, the old list) is not saved
    assert not {"buf", "old_j", "old_xi", "old_start"} & set(saved)
    assert saved["vec"].shape[1] == K.NV
    np.savez(tmp_path / "state.npz", **saved)
    with np.load(tmp_path / "state.npz") as saved:
        b = State.from_arrays(dict(saved))
    assert isinstance(b, State) and b.time == a.time
    sim.run(a, n, tangent=tangent)
    sim.run(b, n, tangent=tangent)
    assert_identical(a, b)


@pytest.mark.parametrize("kind", ["drum", "box"])
def test_state_saved_in_format_6_continues_bit_identically(kind):
    """Format 6 had no rows for the flat walls' history perturbations, and kept each
    contact's smooth piece in its touch flags: such a state loads with them zero and
    continues exactly; an older one is refused."""
    make, tangent = (drum_state, True) if kind == "drum" else (box_state, False)
    sim, a = make(5)
    sim.run(a, 300, tangent=tangent)
    old = a.to_arrays()
    old["engine_format"] = np.asarray(6)
    old["sca"] = old["sca"][:, : L.T_XI_LEFT]
    b = State.from_arrays(old)
    assert b._s["sca"].shape == a._s["sca"].shape
    sim.run(a, 300, tangent=tangent)
    sim.run(b, 300, tangent=tangent)
    assert_identical(a, b)
    old["engine_format"] = np.asarray(5)
    with pytest.raises(ConfigError, match="format 5"):
        State.from_arrays(old)


@pytest.mark.parametrize("kind", ["drum", "box"])
def test_state_saved_in_format_7_continues_bit_identically(kind):
    """Format 7 kept each contact's smooth piece (three more rows of ``ivec``, and
    ``1 + piece`` in the touch flags): such a state loads with them dropped, recounts its
    contacts and continues exactly."""
    make, tangent = (drum_state, True) if kind == "drum" else (box_state, False)
    sim, a = make(5)
    sim.run(a, 300, tangent=tangent)
    old = a.to_arrays()
    old["engine_format"] = np.asarray(7)
    old["ivec"] = np.concatenate([old["ivec"], np.full(old["ivec"].shape[:1] + (3,) +
                                  old["ivec"].shape[2:], 2)], axis=1)  # fmt: skip
    old["touch"] = old["touch"] * 3  # 1 + piece 2 where touching
    old["sca"] = old["sca"][:, : L.WALL_RATE]  # no wall rates before format 9
    b = State.from_arrays(old)
    assert b._s["ivec"].shape == a._s["ivec"].shape
    sim.run(a, 300, tangent=tangent)
    sim.run(b, 300, tangent=tangent)
    assert_identical(a, b)


def test_state_saved_in_format_8_turns_its_wall_disks_at_rate_one():
    """Format 8 had no wall rates (every wall disk turned with the wall disks' omega):
    such a state loads with rate 1 on its wall disks and continues exactly."""
    sim, a = drum_state(5)
    sim.run(a, 300, tangent=True)
    old = a.to_arrays()
    old["engine_format"] = np.asarray(8)
    old["sca"] = old["sca"][:, : L.WALL_RATE]
    b = State.from_arrays(old)
    np.testing.assert_array_equal(b._s["sca"][:, L.WALL_RATE], a._s["ivec"][:, L.IS_WALL])
    sim.run(a, 300, tangent=True)
    sim.run(b, 300, tangent=True)
    assert_identical(a, b)


def _stored_arrays(state):
    return {k: v for k, v in state._s.items() if isinstance(v, np.ndarray) and v.ndim >= 1}


def _misaligned(state):
    """A copy of ``state`` whose arrays all start 16 bytes past a cache line."""
    out = state.copy()
    for key, a in _stored_arrays(out).items():
        raw = np.empty(a.nbytes + 128, dtype=np.uint8)
        start = (-raw.ctypes.data % 64) + 16
        b = raw[start : start + a.nbytes].view(a.dtype).reshape(a.shape)
        b[...] = a
        out._s[key] = b
    return out


@pytest.mark.parametrize("kind", ["drum", "box"])
def test_storage_starts_on_cache_lines_and_alignment_does_not_change_bits(kind):
    """Every way of making a state (new_state, copy, stack, from_arrays, a larger skin)
    puts its arrays on 64-byte cache lines (four-wide loads of the pair rows then never
    split one); a copy with every array 16 bytes off runs to the same bits."""
    make, tangent, n = (drum_state, True, 700) if kind == "drum" else (box_state, False, 2000)
    sim, state = make(3)
    ens = Ensemble.stack([state, state])
    restored = State.from_arrays(state.to_arrays())
    grown = state.copy()
    sim.replace(skin=4 * float(grown._s["skin"])).run(grown, 1)
    assert grown._s["pair_xi"].shape[1] > state._s["pair_xi"].shape[1]  # arrays regrown
    for made in (state, state.copy(), ens, restored, grown):
        for key, a in _stored_arrays(made).items():
            assert a.ctypes.data % 64 == 0, key
            assert a.flags.c_contiguous and a.flags.writeable, key
    off = _misaligned(state)
    assert all(a.ctypes.data % 64 == 16 for a in _stored_arrays(off).values())
    sa, la = run(sim, state, [n], tangent)
    sb, lb = run(sim, off, [n], tangent)
    assert all(a.ctypes.data % 64 == 16 for a in _stored_arrays(off).values())  # not moved
    np.testing.assert_array_equal(sa, sb)
    if tangent:
        np.testing.assert_array_equal(la, lb)
    assert_identical(state, off)
