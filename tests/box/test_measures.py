"""Per-point measures from run files, on synthetic records with known answers.

The analysis helpers test the generic functions; these tests check the box glue: parts
joined in order without repeating the shared frame, the right axes handed to s_c, s_b and
the detachment fraction, slips counted only in the bulk, pooling over periods.
"""

import math

import numpy as np
import pytest
import xarray as xr

from granpipe.box import lattice, measures

N_K = 8
DETECTION = {
    "convection_s_c": 1.0,
    "bouncing_s_b": 1.0 / 30.0,
    "detachment_gap": 1e-3,
    "detachment_fraction": 0.02,
}
SLIPS = {"displacement": 0.2, "min_neighbours": 2, "neighbour_cutoff": 1.2, "surface_depth": 4.0}
ORDER = {"neighbour_cutoff": 1.2, "threshold": 0.7, "crystal_min_psi6": 0.9}


def _part(part, frames, z_tr, z_plate, gap, tg):
    n_p = z_tr.shape[0]

    def v(dims, data):
        return (dims, data, {"units": "1", "long_name": "x"})

    ds = xr.Dataset(
        {
            "z_tracers": v(("period", "phase", "tracer"), z_tr),
            "z_plate": v(("period", "phase"), z_plate),
            "bed_gap": v(("period", "phase"), gap),
            "T_g": v(("period", "phase"), tg),
            "z_cm": v(("period", "phase"), np.zeros((n_p, N_K))),
            "vz_cm": v(("period", "phase"), np.zeros((n_p, N_K))),
            "plate_contacts": v(("period", "phase"), np.ones((n_p, N_K), int)),
            "positions": v(("frame", "particle", "xy"), frames.astype(np.float32)),
        },
        attrs={
            "point": "N_l=20,Gamma=2.0,init=crystal,mu_w=0.6", "N_l": 20,
            "N": frames.shape[1], "Gamma": 2.0, "init": "crystal", "mu_w": 0.6, "replica": 0,
            "part": part, "seed": "1",
            "amplitude": 2.0, "omega": 1.0, "wall_seconds": 1.0, "steps": 1000,
        },
    )  # fmt: skip
    if part == 0:
        ds["transient_vz_cm"] = v(("transient_sample",), np.array([0.0, 3.0, 1.0]))
        ds["transient_max_vz"] = v(("transient_sample",), np.array([0.0, 5.0, 1.0]))
    return ds


@pytest.fixture(scope="module")
def synthetic():
    """Three cycle starts of a 20-row crystal: a rigid shift, then a slip plane."""
    f0 = lattice.crystal_positions(390, 20.0, "spanning")  # 20 rows, 20/19
    f1 = f0 + np.array([0.3, 0.1])  # period 0: the bed moves rigidly, no slip
    f2 = f1.copy()
    rows = np.round((f0[:, 1] - 0.5) / lattice.ROW_SPACING).astype(int)
    f2[rows >= 8, 0] += 0.5  # period 1: rows 8 and up slide by σ/2 over row 7
    rng = np.random.default_rng(0)
    n_t = 19
    # tracer heights at cycle starts: ±a about the row height -> s_j = a
    a = np.array([0.5, 1.5])
    z_tr = np.empty((2, N_K, n_t))
    signs = np.where(np.arange(n_t) % 2 == 0, 1.0, -1.0)
    signs[-1] = 0.0
    signs *= math.sqrt(n_t / (n_t - 1))  # variance exactly a² with one zero entry
    # s(k) = 5 + c sin(2πk/N_k) above a plate moving as sin: s_b = c/√2
    k = np.arange(N_K)
    c = 0.2
    z_plate = np.tile(np.sin(2 * np.pi * k / N_K), (2, 1))
    for j in range(2):
        z_tr[j] = (z_plate[j] + 5.0 + c * np.sin(2 * np.pi * k / N_K))[:, None] + 0.0
        z_tr[j, 0] += a[j] * signs
        z_tr[j, 1:] += 1e-3 * rng.standard_normal((N_K - 1, n_t))  # noise averaging out
    gap = np.full((2, N_K), -1e-5)
    gap[0, 2:5] = 0.3  # 3 of 8 phases in flight in cycle 0, 1 in cycle 1
    gap[1, 3] = 0.01
    tg = np.array([[1.0] * N_K, [3.0] * N_K])
    part0 = _part(0, np.stack([f0, f1]), z_tr[:1], z_plate[:1], gap[:1], tg[:1])
    part1 = _part(1, np.stack([f1, f2]), z_tr[1:], z_plate[1:], gap[1:], tg[1:])
    run = measures.concat_parts([part0, part1])
    ds = measures.point_dataset({0: run}, DETECTION, SLIPS, ORDER, 20.0)
    return {"run": run, "ds": ds, "f": (f0, f1, f2), "rows": rows, "a": a, "c": c}


def test_parts_join_without_repeating_the_shared_frame(synthetic):
    run = synthetic["run"]
    f0, f1, f2 = synthetic["f"]
    assert run.frames.shape == (3, 390, 2)
    np.testing.assert_allclose(run.frames[1], f1, atol=1e-5)
    np.testing.assert_allclose(run.frames[2], f2, atol=1e-5)
    assert run.z_tracers.shape == (2, N_K, 19) and run.steps == 2000


def test_detection_measures_read_the_right_axes(synthetic):
    ds = synthetic["ds"]
    a, c = synthetic["a"], synthetic["c"]
    assert float(ds.s_c) == pytest.approx(math.sqrt(np.mean(a**2)), rel=1e-6)  # Eq. (B2)
    assert float(ds.s_b) == pytest.approx(c / math.sqrt(2), rel=0.02)
    assert float(ds.detachment_fraction) == pytest.approx((3 / 8 + 1 / 8) / 2)
    assert float(ds.T_g) == pytest.approx(2.0) and float(ds.T_g_sem) == pytest.approx(1.0)
    assert int(ds.convection) == 1 and int(ds.bouncing) == 1 and int(ds.detached) == 1
    assert float(ds.launch_ratio) == pytest.approx(1.5)  # 3.0 / (A ω = 2)


def test_slips_counted_at_the_slip_plane_in_the_bulk_only(synthetic):
    ds, rows = synthetic["ds"], synthetic["rows"]
    f0 = synthetic["f"][0]
    top = f0[:, 1].max()
    bulk = int(np.sum(f0[:, 1] < top - SLIPS["surface_depth"]))
    # row 7 (19 disks) sees two neighbours of row 8 shift; row 8 (20 disks) sees two
    # neighbours of row 7 except its end disks, which touch one
    expected = 19 + 18
    assert set(rows[rows <= 8]) <= set(range(9)) and 8 * 0.866 + 0.5 < top - 4.0
    assert int(ds.n_slips) == expected
    assert int(ds.n_trials) == 2 * bulk
    assert float(ds.p_s) == pytest.approx(0.5 * expected / bulk)
    np.testing.assert_allclose(ds.p_s_period.values[0], [0.0, expected / bulk])


def test_crystal_order_at_measurement_start(synthetic):
    ds = synthetic["ds"]
    assert float(ds.psi6_start) == pytest.approx(1.0, abs=1e-5)
    assert int(ds.crystal_intact) == 1 and int(ds.dislocations_start) == 0
    assert float(ds.hexagonal_start) == 1.0
    # the slip of period 1 leaves rows 7 and 8 on top of each other: square contacts
    # along the slip plane, no longer the defect-free crystal
    assert int(ds.intact_end_replica[0]) == 0 and int(ds.dislocations_end) > 0


def test_convergence_of_the_full_record_is_the_point_value(synthetic):
    run, ds = synthetic["run"], synthetic["ds"]
    record = (run.z_tracers, run.z_plate, run.T_g, run.frames)
    conv = measures.convergence(*record, SLIPS, [1, 2])
    # all periods: the point's own estimates; one period: that period's
    assert conv["s_c"][1] == pytest.approx(float(ds.s_c), rel=1e-12)
    assert conv["s_b"][1] == pytest.approx(float(ds.s_b), rel=1e-12)
    assert conv["T_g"][1] == pytest.approx(float(ds.T_g), rel=1e-12)
    assert conv["p_s"][1] == pytest.approx(float(ds.p_s), rel=1e-12)
    assert conv["s_c"][0] == pytest.approx(synthetic["a"][0], rel=1e-6)  # s_0 = a_0
    assert conv["T_g"][0] == pytest.approx(1.0) and conv["p_s"][0] == 0.0
    with pytest.raises(ValueError, match="periods"):
        measures.convergence(*record, SLIPS, [3])
