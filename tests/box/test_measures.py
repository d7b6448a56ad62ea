"""Box measures on synthetic configurations and records with known answers.

First per point, from run files: parts joined in order without repeating the shared
frame, the right axes handed to s_c, s_b and the detachment fraction, slips counted only
in the bulk, pooling over periods. Then detection and observables on given arrays.
"""

import math

import numpy as np
import pytest
import xarray as xr
from scipy.spatial import cKDTree

from granpipe.box import measures, preparation
from granpipe.box.measures import (
    BOUNCING_THRESHOLD,
    bed_gap,
    bond_order,
    bouncing_measure,
    classify_order,
    convection_measure,
    crystal_check,
    delaunay_coordination,
    detachment_fraction,
    free_surface_height,
    granular_temperature,
    local_order,
    nearest_neighbours,
    select_tracers,
    slip_flags,
    slip_probability,
)

N_K = 8
DETECTION = {
    "convection_s_c": 1.0,
    "bouncing_s_b": 1.0 / 30.0,
    "detachment_gap": 1e-3,
    "detachment_fraction": 0.02,
    "roll_significance": 3.0,
    "roll_displacement": 1.0,
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
            "point": "N_l=20,Gamma=2.0,init=crystal,mu_w=0.6,walls=shaken,torque=lever",
            "N_l": 20, "N": frames.shape[1], "Gamma": 2.0, "init": "crystal", "mu_w": 0.6,
            "side_walls": "shaken", "wall_torque": "lever", "replica": 0,
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
    f0 = preparation.crystal_positions(390, 20.0, "spanning")  # 20 rows, 20/19
    f1 = f0 + np.array([0.3, 0.1])  # period 0: the bed moves rigidly, no slip
    f2 = f1.copy()
    rows = np.round((f0[:, 1] - 0.5) / preparation.ROW_SPACING).astype(int)
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


H = np.sqrt(3.0) / 2.0


def hex_crystal(n_x=20, n_rows=30, a=1.0):
    """Orientation A of the paper's Fig. 2: close-packed rows horizontal."""
    i, r = np.meshgrid(np.arange(n_x), np.arange(n_rows))
    x = a * (i + 0.5 + 0.5 * (r % 2))
    z = a * (0.5 + H * r)
    return np.column_stack([x.ravel(), z.ravel()])


def square_lattice(n_x=20, n_rows=20):
    i, r = np.meshgrid(np.arange(n_x), np.arange(n_rows))
    return np.column_stack([i.ravel() + 0.5, r.ravel() + 0.5]).astype(float)


# ------------------------------------------------------------------ tracers
def test_free_surface_ignores_flying_grains():
    pos = hex_crystal()
    top = 0.5 + H * 29
    assert free_surface_height(pos) == pytest.approx(top)
    flying = np.vstack([pos, [[3.0, top + 8], [9.0, top + 15], [15.0, top + 4]]])
    assert free_surface_height(flying) == pytest.approx(top)


def test_select_tracers_crystal_row():
    pos = hex_crystal(n_rows=31)
    idx = select_tracers(pos)
    assert len(idx) == 20
    np.testing.assert_allclose(pos[idx, 1], 0.5 + H * 15)  # the middle row of 31
    assert np.all(np.diff(pos[idx, 0]) > 0)
    assert len(select_tracers(pos, n_tracers=12)) == 12


def test_select_tracers_jittered_bed():
    rng = np.random.default_rng(0)
    pos = hex_crystal(n_rows=40) + rng.normal(0, 0.08, size=(800, 2))
    idx = select_tracers(pos)
    mid = 0.5 * (pos[:, 1].min() + free_surface_height(pos))
    assert 15 <= len(idx) <= 25
    assert np.all(np.abs(pos[idx, 1] - np.median(pos[idx, 1])) < 0.5)
    assert abs(np.median(pos[idx, 1]) - mid) < H


# --------------------------------------------------------------- detection
def test_convection_measure_known_answer():
    # Each cycle the tracer line is a zero-mean pattern of unit variance times a_j.
    u = np.array([-1.5, -0.5, 0.5, 1.5])
    u = u / u.std()
    a = np.array([0.0, 0.5, 1.0, 2.0])
    z = 10.0 + 0.3 * np.arange(4)[:, None] + a[:, None] * u[None, :]
    s_c, s_j = convection_measure(z)
    np.testing.assert_allclose(s_j, a, atol=1e-12)
    assert s_c == pytest.approx(np.sqrt(np.mean(a**2)))
    assert s_c > 1.0  # convection by the paper's criterion
    assert convection_measure(np.full((5, 20), 7.0))[0] == 0.0  # a straight line


def test_bouncing_measure_comoving_and_bouncing():
    n_cyc, n_ph, n_t = 8, 64, 20
    phase = 2 * np.pi * np.arange(n_ph) / n_ph
    plate = 1.5 * np.sin(phase)
    rng = np.random.default_rng(1)
    offsets = 10.0 + rng.normal(0, 0.3, size=n_t)  # heights in the bed, constant
    z = plate[None, :, None] + offsets[None, None, :] + np.zeros((n_cyc, 1, 1))
    s_b, s_k = bouncing_measure(z, plate)
    assert s_b == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(s_k, offsets.mean())
    # Eq. (B4) as printed would give the rms height, ~10 sigma >> sigma/30.
    assert np.sqrt(np.mean(s_k**2)) > 100 * BOUNCING_THRESHOLD
    # A flight profile g(k) above the plate: s_b is its standard deviation over phases.
    g = np.maximum(0.0, np.sin(phase) - 0.5) * 0.4
    zb = z + g[None, :, None]
    s_b, s_k = bouncing_measure(zb, np.broadcast_to(plate, (n_cyc, n_ph)))
    assert s_b == pytest.approx(g.std())
    assert s_b > BOUNCING_THRESHOLD


def test_bed_gap_and_detachment_fraction():
    n_cyc, n_ph, N = 5, 360, 50
    phase = 2 * np.pi * (np.arange(n_ph) + 0.5) / n_ph
    plate = np.broadcast_to(np.sin(phase), (n_cyc, n_ph))
    gap_true = np.maximum(0.0, np.sin(phase) - 0.5)  # in flight for 120 of 360 degrees
    rng = np.random.default_rng(2)
    z = plate[..., None] + 0.5 + gap_true[None, :, None] + rng.uniform(0, 5, size=(n_cyc, n_ph, N))
    z[..., 7] = plate + 0.5 + gap_true - 2e-4  # lowest grain: overlap 2e-4 when in contact
    gap = bed_gap(z, plate)
    np.testing.assert_allclose(gap, np.broadcast_to(gap_true - 2e-4, gap.shape), atol=1e-12)
    frac, per = detachment_fraction(gap)
    # sin > 0.5 + 1.2e-3 on (30.08 deg, 149.92 deg): 120 of the 360 mid-degree samples.
    assert frac == pytest.approx(120 / 360) and per.shape == (n_cyc,)
    assert detachment_fraction(np.full((3, 10), -1e-4))[0] == 0.0


def test_granular_temperature_eq2():
    rng = np.random.default_rng(3)
    u = rng.normal(size=(10, 100, 2))
    u -= u.mean(axis=1, keepdims=True)  # exact zero-momentum fluctuations
    v_cm = rng.normal(size=(10, 1, 2)) * 5
    T = granular_temperature(u + v_cm)
    np.testing.assert_allclose(T, 0.5 * (u**2).sum(axis=(1, 2)) / 100, rtol=1e-12)
    # Masses: the centre of mass is mass weighted; twice the mass, twice T.
    np.testing.assert_allclose(granular_temperature(u + v_cm, 2.0), 2 * T, rtol=1e-12)
    m = np.r_[np.ones(50), 3 * np.ones(50)]
    v = np.zeros((100, 2))
    v[:50, 0] = 3.0  # cm velocity (50*3)/(200) = 0.75
    expect = (50 * 0.5 * 2.25**2 + 50 * 0.5 * 3 * 0.75**2) / 100
    assert granular_temperature(v, m) == pytest.approx(expect)


# -------------------------------------------------------------------- slips
def test_slip_shear_band_and_rigid_motions():
    pos = hex_crystal(n_x=20, n_rows=40)
    z_plane = 0.5 + H * 19.5  # between rows 19 and 20
    above = pos[:, 1] > z_plane
    surface = pos[:, 1].max()
    sheared = pos.copy()
    sheared[above, 0] += 0.5
    slipped, bulk = slip_flags(pos, sheared)
    row = np.rint((pos[:, 1] - 0.5) / H).astype(int)
    assert np.array_equal(bulk, pos[:, 1] < surface - 10.0)
    # Rows 19 and 20 each have two neighbours across the plane; the ends of
    # the rows have only one, so they do not count.
    interior = (pos[:, 0] > 1.0) & (pos[:, 0] < 19.0)
    expected = np.isin(row, [19, 20]) & bulk & interior
    assert np.array_equal(slipped & interior, expected)
    assert not np.any(slipped & ~np.isin(row, [19, 20]))
    # Below the threshold: no slip.
    small = pos.copy()
    small[above, 0] += 0.15
    assert not slip_flags(pos, small)[0].any()
    # Uniform translation and a small rigid rotation: no slip.
    assert not slip_flags(pos, pos + [3.0, -7.0])[0].any()
    th = np.radians(5.0)
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    assert not slip_flags(pos, pos @ R.T + 1.0)[0].any()
    # A 20-degree rotation changes every separation by 0.35 sigma: counted (documented).
    th = np.radians(20.0)
    R = np.array([[np.cos(th), -np.sin(th)], [np.sin(th), np.cos(th)]])
    assert slip_flags(pos, pos @ R.T)[0][bulk & interior].all()


def test_slip_probability_over_periods():
    pos = hex_crystal(n_x=20, n_rows=40)
    above = pos[:, 1] > 0.5 + H * 19.5
    frames = [pos]
    for p in range(4):
        nxt = frames[-1].copy()
        if p % 2 == 0:  # slip in periods 0 and 2 only
            nxt[above, 0] += 1.0
        frames.append(nxt)
    res = slip_probability(np.array(frames))
    slipped, bulk = slip_flags(pos, frames[1])
    frac = slipped.sum() / bulk.sum()
    np.testing.assert_allclose(res.per_period, [frac, 0, frac, 0])
    assert res.p_s == pytest.approx(frac / 2)
    assert res.n_trials == 4 * bulk.sum() and res.n_slips == 2 * slipped.sum()
    assert res.n_periods == 4 and res.sem > 0


def test_no_bulk_in_a_shallow_bed():
    pos = hex_crystal(n_x=20, n_rows=10)  # N_l = 10: ~8 sigma tall, no bulk
    res = slip_probability(np.array([pos, pos + 0.01]))
    assert np.isnan(res.p_s) and res.n_trials == 0


# -------------------------------------------------------------- local order
def psi_reference(pos, k, r_max, n_neighbours=None, boxsize=None):
    """Direct numpy ψ_k: the reference for the freud implementation."""
    tree = cKDTree(pos, boxsize=boxsize)
    kk = (n_neighbours or 64) + 1
    dist, idx = tree.query(pos, k=min(kk, len(pos)), distance_upper_bound=r_max)
    psi = np.full(len(pos), np.nan + 0j)
    n = np.zeros(len(pos), int)
    for i in range(len(pos)):
        js = idx[i][(np.isfinite(dist[i])) & (idx[i] != i)]
        if n_neighbours:
            js = js[:n_neighbours]
        d = pos[js] - pos[i]
        if boxsize is not None:
            d -= boxsize * np.round(d / boxsize)
        n[i] = len(js)
        if len(js):
            psi[i] = np.exp(1j * k * np.arctan2(d[:, 1], d[:, 0])).mean()
    return psi, n


def test_psi6_perfect_triangular_lattice():
    pos = hex_crystal()
    psi6, n = bond_order(pos, 6)
    interior = n == 6
    assert interior.sum() == 18 * 28  # all but the boundary
    np.testing.assert_allclose(np.abs(psi6[interior]), 1.0, atol=1e-5)
    psi4, _ = bond_order(pos, 4)
    np.testing.assert_allclose(np.abs(psi4[interior]), 0.0, atol=1e-5)
    # Bottom row against a wall: 4 neighbours at 0, 60, 120, 180 degrees, still hexagonal.
    bottom = (pos[:, 1] < 1.0) & (n == 4)
    np.testing.assert_allclose(np.abs(psi6[bottom]), 1.0, atol=1e-5)


def test_psi6_random_points_near_zero_mean():
    rng = np.random.default_rng(5)
    pos = rng.uniform(0, 40, size=(1600, 2))  # density 1
    psi6, n = bond_order(pos, 6, r_max=1.5)
    ok = n > 0
    mean = np.mean(psi6[ok])
    assert abs(mean) < 0.05  # phases random: the complex mean vanishes
    assert np.mean(np.abs(psi6[n >= 4])) < 0.6  # and the local order is poor


def test_freud_matches_numpy_reference_periodic_and_open():
    rng = np.random.default_rng(6)
    L = np.array([20.0, 20 * H * 2])  # 20 x 24 rows: commensurate periodic lattice
    pos = hex_crystal(20, 24) + rng.normal(0, 0.05, size=(480, 2))
    pos %= L
    for k in (6, 4):
        f, nf = bond_order(pos, k, r_max=1.2, periodic_box=tuple(L))
        r, nr = psi_reference(pos, k, 1.2, boxsize=L)
        np.testing.assert_array_equal(nf, nr)
        np.testing.assert_allclose(f, r, atol=1e-4)
    open_pos = hex_crystal(20, 30) + rng.normal(0, 0.05, size=(600, 2))
    open_pos[:, 1] -= 500.0  # far from the origin, like a box at z = -Lz/2
    for kw in ({"r_max": 1.2}, {"r_max": 1.5, "n_neighbours": 6}):
        f, nf = bond_order(open_pos, 6, **kw)
        r, nr = psi_reference(open_pos, 6, kw["r_max"], kw.get("n_neighbours"))
        np.testing.assert_array_equal(nf, nr)
        np.testing.assert_allclose(f, r, atol=1e-4, equal_nan=True)  # freud is float32
    # Non-periodic: the particles at the left and right edges must not see each other.
    _, n = bond_order(hex_crystal(), 6)
    assert n.max() == 6 and np.sum(n < 6) == 600 - 18 * 28


def test_classification_hex_square_disordered():
    hexo = local_order(hex_crystal())
    assert np.all(hexo["order"][hexo["n"] >= 4] == 1)
    sq = local_order(square_lattice())
    assert np.all(sq["order"][sq["n"] >= 3] == 2)
    np.testing.assert_allclose(np.abs(sq["psi6"][sq["n"] == 4]), 0.0, atol=1e-5)
    # Two opposite neighbours: |psi6| = |psi4| = 1, but too few to classify.
    line = np.column_stack([np.arange(10.0), np.zeros(10)])
    lo = local_order(line)
    assert np.all(lo["order"] == 0)
    assert classify_order(np.array([0.9]), np.array([0.1]), np.array([2]))[0] == 0
    rng = np.random.default_rng(7)
    rnd = local_order(rng.uniform(0, 40, size=(1600, 2)), r_max=1.5)
    assert np.mean(rnd["order"] == 0) > 0.7


def test_nearest_neighbours_padding():
    pos = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 5.0]])
    nb = nearest_neighbours(pos, 6, 1.2)
    assert nb.shape == (3, 6)
    assert nb[0, 0] == 1 and np.all(nb[0, 1:] == -1) and np.all(nb[2] == -1)


# ------------------------------------------------------------- crystal check
def edge_dislocation(pos, core, b=1.0, nu=1.0 / 3.0):
    """Displace ``pos`` by the isotropic elastic field of an edge dislocation with Burgers
    vector (b, 0) at ``core`` (Hirth & Lothe, Eq. 3-45); the cut along the negative x axis
    shifts rows by one lattice spacing, so the lattice closes up except at the core."""
    x, y = (pos - core).T
    r2 = x * x + y * y
    ux = b / (2 * np.pi) * (np.arctan2(y, x) + x * y / (2 * (1 - nu) * r2))
    uy = (
        -b
        / (2 * np.pi)
        * ((1 - 2 * nu) / (4 * (1 - nu)) * np.log(r2) + (x * x - y * y) / (4 * (1 - nu) * r2))
    )
    return pos + np.column_stack([ux, uy])


def test_crystal_check_perfect_lattice_and_one_dislocation():
    lattice = hex_crystal(n_x=30, n_rows=34)
    lx = 31.0
    perfect = crystal_check(lattice, lx)
    assert perfect.n_bulk > 600 and perfect.dislocations == 0 and perfect.intact
    assert perfect.psi6 == pytest.approx(1.0, abs=1e-12) and perfect.hexagonal == 1.0
    # a few per cent of thermal noise moves no Delaunay neighbour
    rng = np.random.default_rng(3)
    assert crystal_check(lattice + rng.normal(0, 0.02, lattice.shape), lx).intact

    core = np.array([15.25, 0.5 + 14.5 * H])  # between two rows, off every site
    bent = edge_dislocation(lattice, core)
    check = crystal_check(bent, lx)
    # the core is one five- and one seven-fold site (the dislocation's 5-7 pair) ...
    z = delaunay_coordination(bent)
    near = np.hypot(*(bent - core).T) < 1.0
    assert sorted(z[near & (z != 6)]) == [5, 7] and check.dislocations == 2
    assert not check.intact
    # ... where |ψ6| falls below the crystal threshold, while the bulk mean hardly moves
    psi6 = np.abs(local_order(bent)["psi6"])
    assert psi6[near].mean() < 0.9 and psi6[near].min() < 0.7
    assert check.psi6 > 0.99


# ------------------------------------------------- rolls against diffusion (Eq. B2)
ROLL_LX, ROLL_H = 20.0, 10.0


def _bed_grid():
    x, z = np.meshgrid(np.arange(20) + 0.5, np.arange(10) + 0.5)
    return np.column_stack([x.ravel(), z.ravel()])


def _diffusing_record(step, periods, seed, bounce=0.0):
    """Frames of a bed whose disks take independent Gaussian steps (``step`` σ per axis per
    period); with ``bounce`` the whole bed also jumps by a common Gaussian height (irregular
    bouncing seen at one phase)."""
    rng = np.random.default_rng(seed)
    steps = rng.normal(0.0, step, (periods, 200, 2))
    steps[..., 1] += rng.normal(0.0, bounce, (periods, 1))
    return np.concatenate([_bed_grid()[None], _bed_grid() + np.cumsum(steps, axis=0)])


def _roll_record(speed, periods, seed, noise=0.03):
    """Frames of a bed carried by a pair of rolls, up at the centre and down at both side
    walls at ``speed`` σ per period (stream function ψ ∝ sin(2πx/L_x) sin(πz/H), zero on
    the walls, floor and surface), plus Gaussian steps of ``noise`` σ."""
    rng = np.random.default_rng(seed)
    amp = speed * ROLL_LX / (2 * np.pi)

    def velocity(p):
        kx, kz = 2 * np.pi / ROLL_LX, np.pi / ROLL_H
        x, z = p[:, 0], p[:, 1]
        return np.column_stack([amp * kz * np.sin(kx * x) * np.cos(kz * z),
                                -amp * kx * np.cos(kx * x) * np.sin(kz * z)])  # fmt: skip

    frames = [_bed_grid()]
    for _ in range(periods):
        p = frames[-1].copy()
        for _ in range(10):  # midpoint rule, 10 substeps per period
            p = p + 0.1 * velocity(p + 0.05 * velocity(p))
        frames.append(p + rng.normal(0.0, noise, p.shape))
    return np.asarray(frames)


def _tracer_spread(frames):
    """s_c of Eq. (B2) of the row at mid-height, over records of 8, 32 and 200 periods."""
    row = np.nonzero(frames[0, :, 1] == 4.5)[0]
    return {n: convection_measure(frames[:n, row, 1])[0] for n in (8, 32, 200)}


def test_diffusion_crosses_eq_b2_later_in_a_shorter_record_and_never_rolls():
    """Diffusion makes s_c² = mean_j s_j² grow with the record (s_j² ≈ j D), so on a grid of
    step sizes Eq. (B2) reports convection at a larger step the shorter one looks, while
    the roll criterion (a standard normal score without rolls), with or without a bouncing
    bed, stays below 3 at every record."""
    grid = np.array([0.02, 0.04, 0.08, 0.16, 0.32, 0.64])
    s_c = {n: [] for n in (8, 32, 200)}
    for k, step in enumerate(grid):
        frames = _diffusing_record(step, 200, seed=k)
        for n, v in _tracer_spread(frames).items():
            s_c[n].append(v)
        for record in (_diffusing_record(step, 200, seed=k, bounce=2.0), frames):
            c = measures.roll_contrast(record, ROLL_LX)
            for n in (8, 32, 200):
                z = measures.roll_significance(c, n)
                assert z < 3.0
                assert measures.roll_level(z, measures.roll_displacement(c, n), DETECTION) < 1
    from granpipe.box.fits import threshold_crossing

    onset = {n: threshold_crossing(grid, s_c[n], 1.0, scale="log").value for n in s_c}
    assert onset[8] > onset[32] > onset[200]
    assert 0.05 < onset[200] < 0.2 and onset[8] > 0.3


def test_a_roll_gives_both_criteria_and_the_roll_score_sooner():
    """A pair of rolls deforms the tracer line (s_c > σ over 200 periods) and gives a
    persistent wall-to-centre contrast c_j ≈ the roll's mean vertical speed difference, so
    the roll score passes 3 at 8 periods already, where Eq. (B2) is not yet; the roll
    criterion once the centre has risen 1 σ above the walls (32 periods)."""
    frames = _roll_record(0.05, 200, seed=1)
    s_c = _tracer_spread(frames)
    assert s_c[200] > 1.0 > s_c[8]
    c = measures.roll_contrast(frames, ROLL_LX)
    assert measures.roll_significance(c, 8) > 3.0 and measures.roll_significance(c) > 10.0
    assert 0.02 < np.nanmean(c[:8]) < 0.08
    # the centre rises ~0.05 σ per period above the walls: the criterion, which also asks
    # for a rise of 1 σ, is met once the roll has carried the bed that far
    level = {n: measures.roll_level(measures.roll_significance(c, n),
                                    measures.roll_displacement(c, n), DETECTION)
             for n in (8, 32, 200)}  # fmt: skip
    assert level[8] < 1.0 < level[32] < level[200]
    assert measures.roll_displacement(c) == pytest.approx(np.nansum(c))
    # the opposite rolls (up at the walls) give a negative t
    reverse = _roll_record(-0.05, 32, seed=2)
    assert measures.roll_significance(measures.roll_contrast(reverse, ROLL_LX)) < -3.0


def test_a_steady_drift_scores_like_a_roll_but_has_not_carried_the_bed():
    """A packing that creeps regularly (the centre sinking or rising against the walls by
    1e-4 σ per period, scatter 1e-6 σ: a comoving bed compacting) scores far beyond 3 and
    is a roll by the score alone (``roll_displacement`` 0), not by the criterion, whose
    rise of 1 σ it does not reach in 200 periods (0.02 σ); diffusing beds fail both."""
    rng = np.random.default_rng(3)
    drift = 1e-4 + rng.normal(0.0, 1e-6, 200)
    z, rise = measures.roll_significance(drift), measures.roll_displacement(drift)
    assert z > 30.0 and rise == pytest.approx(0.02, rel=0.01)
    assert measures.roll_level(z, rise, {**DETECTION, "roll_displacement": 0.0}) > 1.0
    assert measures.roll_level(z, rise, DETECTION) == pytest.approx(0.02, rel=0.01)
    for _ in range(20):
        c = rng.normal(0.0, 0.3, 200)
        z, rise = measures.roll_significance(c), measures.roll_displacement(c)
        assert measures.roll_level(z, rise, DETECTION) < 1.0
    assert math.isnan(measures.roll_displacement(np.full(5, np.nan)))


def test_the_roll_score_of_a_bed_without_rolls_is_standard_normal_at_any_record():
    """Student's t over 8 periods has a standard deviation of sqrt(7/5) = 1.18; the score
    is mapped to the normal tail, so its spread is 1 over 8 periods as over 200."""
    rng = np.random.default_rng(5)
    for n in (8, 200):
        z = [measures.roll_significance(rng.normal(0.0, 0.1, n)) for _ in range(2000)]
        assert np.mean(z) == pytest.approx(0.0, abs=0.07)
        assert np.std(z) == pytest.approx(1.0, abs=0.05)


def test_slips_at_each_slip_phase_and_the_crystal_at_the_ramp_end(synthetic):
    """The cycle starts only shift the bed rigidly; the frames half a cycle on hold the slip
    plane of the synthetic record, and the bed is in flight there in both periods. p_s is
    then zero at the cycle start and the slip plane's count at phase 1/2, where the flight
    reading takes it; a dislocated crystal at the ramp's end fails the check there."""
    f0, _, f2 = synthetic["f"]
    rigid = np.stack([f0, f0 + 0.1, f0 + 0.2])
    half = np.stack([f0, f2])[:, None]  # (period, slip phase 1, N, 2)
    z_tr = np.repeat(synthetic["run"].z_tracers, 1, axis=0)
    gap = np.full((2, N_K), -1e-5)
    gap[:, N_K // 2] = 0.2
    zp, tg = synthetic["run"].z_plate, synthetic["run"].T_g
    parts = [_part(j, rigid[j : j + 2], z_tr[j : j + 1], zp[j : j + 1], gap[j : j + 1],
                   tg[j : j + 1]) for j in range(2)]  # fmt: skip
    for j, p in enumerate(parts):
        p["phase_positions"] = (("period", "slip_phase", "particle", "xy"),
                                half[j : j + 1].astype(np.float32))  # fmt: skip
    core = np.array([10.25, 0.5 + 9.5 * H])
    parts[0]["positions_ramp_end"] = (("particle", "xy"), edge_dislocation(f0, core))
    ds = measures.point_dataset({0: measures.concat_parts(parts)}, DETECTION, SLIPS, ORDER, 20.0)
    np.testing.assert_allclose(ds["slip_phase"].values, [0.0, 0.5])
    assert ds["p_s_phase"].values[0] == 0.0 == float(ds.p_s)
    expected = slip_probability(np.stack([f0, f2]), threshold=0.2, min_count=2,
                                r_max=1.2, bulk_depth=SLIPS["surface_depth"])  # fmt: skip
    assert expected.n_slips > 30
    assert int(ds["n_slips_phase"].values[1]) == expected.n_slips
    np.testing.assert_allclose(ds["flight_phase"].values, [0.0, 1.0])
    from granpipe.box.fits import phase_slip_columns

    cols = phase_slip_columns(ds)
    assert cols["flight_phase"] == 0.5 and cols["n_slips_flight"] == expected.n_slips
    assert cols["p_s_phase_0of2"] == 0.0 and cols["p_s_phase_1of2"] == expected.p_s
    assert int(ds.crystal_intact_ramp) == 0 and float(ds.dislocations_ramp) >= 2
    assert int(ds.crystal_intact) == 1  # the cycle starts are the perfect crystal
