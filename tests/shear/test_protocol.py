"""One replica of the shear cell: tangent dynamics against twins, reproducibility, the
batch file."""

import numpy as np
import pytest

from granpipe.shear.model import ShearCell
from granpipe.shear.preparation import grow
from granpipe.shear.protocol import run_batch, run_replica


def _twin_error(cell, sim, pos, vel, angle, du, eps, steps):
    """Relative distance between (twin − base)/ε and the tangent vector after ``steps``."""
    n = cell.n_mobile
    pad = np.zeros((len(cell.walls), 2))
    base = cell.new_state(sim, pos, vel, wall_angle=angle)
    sim.set_tangent(base, np.r_[du[:, 0], pad], np.r_[du[:, 1], pad])
    sim.run(base, steps, tangent=True)
    twin = cell.new_state(sim, pos + eps * du[:, 0], vel + eps * du[:, 1], wall_angle=angle)
    sim.run(twin, steps)
    tr, tv = (x[:n] for x in base.tangent)
    gr = (twin.positions[:n] - base.positions[:n]) / eps
    gv = (twin.velocities[:n] - base.velocities[:n]) / eps
    err = np.sqrt(((gr - tr) ** 2).sum() + ((gv - tv) ** 2).sum())
    return err / np.sqrt((tr**2).sum() + (tv**2).sum())


def test_twin_trajectories_agree_with_the_tangent_vector_in_the_sheared_annulus(tiny):
    """In the sheared cell (inner ring turning, outer still, no gravity), (state(ε δu) −
    state)/ε matches the tangent vector: the tangent map is the derivative of the discrete
    map with wall disks of rate 1 and 0.

    Eq. (1)'s normal damping jumps by γ_n v_n when two disks first touch, and in a sheared
    packing contacts form at almost every step with closing speeds v_n ~ 1e-2, i.e.
    v_n Δt ~ 1e-5 per step: a twin displaced by ε ≳ 1e-6 starts some contact one step
    earlier or later than the base, and from then on differs by O(γ_n v_n Δt), not O(ε)
    (measured: relative error 4e-3 after 10 steps at ε = 1e-6, 1e-7 after 100 steps at
    ε = 1e-7). So: the O(ε) scaling over a few steps, and agreement to round-off over
    1,000 steps with ε = 1e-8: the error there is the twin difference's round-off, which
    grows as 1/ε (tenfold at ε = 1e-9), not a term of the tangent map."""
    cell = ShearCell.from_physics(tiny["physics"])
    sim, state = grow(cell, tiny["preparation"], np.random.default_rng(2))
    n = cell.n_mobile
    pos, vel = state.positions[:n].copy(), state.velocities[:n].copy()
    du = np.random.default_rng(5).uniform(-1, 1, (n, 2, 2))
    args = (cell, sim, pos, vel, state.wall_angle, du)
    e = [_twin_error(*args, eps, 3) for eps in (1e-5, 1e-6, 1e-7)]
    assert 8 < e[0] / e[1] < 12 and 8 < e[1] / e[2] < 12
    long = [_twin_error(*args, eps, 1000) for eps in (1e-8, 1e-9)]
    assert long[0] < 1e-4
    assert 5 < long[1] / long[0] < 20


def test_a_replica_depends_on_its_seed_only(tiny):
    """Replica 1 alone equals replica 1 of the batch [0, 1]; replicas 0 and 1 differ."""
    alone = run_replica(tiny, 1)
    ds, seeds = run_batch(tiny, [0, 1])
    np.testing.assert_array_equal(ds["local_lyapunov"].values[1], alone["lam"])
    np.testing.assert_array_equal(ds["network_changes"].values[1], alone["changes"])
    assert not np.array_equal(ds["local_lyapunov"].values[0], alone["lam"])
    assert len(set(seeds)) == 2


def test_the_batch_file_records_what_the_protocol_says(tiny):
    ds, _ = run_batch(tiny, [0])
    block, sample, record = (tiny["protocol"][k] for k in ("block_s", "sample_s", "record_s"))
    assert ds.sizes["time"] == round(record / block)
    assert ds.sizes["sample"] == round(record / sample)
    assert float(ds.attrs["sample_s"]) == pytest.approx(sample, rel=1e-4)  # whole steps
    assert np.all(np.isfinite(ds["local_lyapunov"].values))
    c = ds["speed_lyapunov_correlation"].values
    assert np.all(np.abs(c[np.isfinite(c)]) <= 1.0)
    du = ds["snapshot_du"].values[0]
    assert du.max() == pytest.approx(1.0) and du.min() >= 0


def test_the_whole_tangent_vectors_growth_rate_is_the_log_ratio_of_its_norms(tiny):
    """``lyapunov_all`` of each sample is ``(ln|δu(t_k)| − ln|δu(t_k−1)|)/Δt`` of the whole
    tangent vector over the mobile disks (rattlers included), at its true size: replayed
    step for step from the replica's seed with the engine's rescaled vector, and, summed
    over the samples, the growth of the vector over the whole record (it telescopes; the
    drum paper's λ over disks with two contacts does not)."""
    from granpipe.seeds import replica_rng
    from granpipe.shear.protocol import Steps

    rec = run_replica(tiny, 0)
    cell = ShearCell.from_physics(tiny["physics"])
    st = Steps(tiny)
    place, tangent = replica_rng("shear", tiny["physics"], 0).spawn(2)
    sim, state = grow(cell, tiny["preparation"], place)
    n = cell.n_mobile
    sim.random_tangent(state, tangent, float(tiny["protocol"]["tangent_fraction"]))
    sim.run(state, st.align, tangent=True)

    def log_norm():
        tr, tv = state.tangent
        return 0.5 * np.log((tr[:n] ** 2).sum() + (tv[:n] ** 2).sum())

    dt = float(tiny["physics"]["dt"])
    first = prev = log_norm()
    for k in range(st.n_samples):
        sim.run(state, st.sample, stride=st.block, tangent=True)
        now = log_norm()
        assert rec["lam_all"][k] == pytest.approx((now - prev) / (st.sample * dt), rel=1e-9)
        prev = now
    total = rec["lam_all"].sum() * st.sample * dt
    assert total == pytest.approx(prev - first, rel=1e-9)
    assert np.ptp(rec["lam_all"]) > 0
