"""The protocol on a tiny drum: dims, units, provenance, batching invariance, blow-ups."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from granpipe.drum.layout import seed_physics, steps
from granpipe.drum.model import DrumModel, omega
from granpipe.drum.protocol import run_batch, run_replica, tiny_section
from granpipe.drum.stages import init_stage, runs_stage
from granpipe.errors import SimulationError
from granpipe.io import config_from_attrs, read_dataset
from granpipe.seeds import replica_seed


def _stages(sec, tmp, batch, threads):
    init = tmp / f"init_{batch}.nc"
    run = tmp / f"run_{batch}.nc"
    init_stage(sec, batch, init, threads=threads)
    runs_stage(sec, batch, init, run, threads=threads)
    return read_dataset(init), read_dataset(run)


@pytest.fixture(scope="module")
def batch2(tiny, tmp_path_factory):
    """Replicas 0 and 1 in one batch of 2, run side by side in 2 threads."""
    return _stages(tiny, tmp_path_factory.mktemp("b2"), 0, threads=2)


def test_run_file_dims_units_and_provenance(tiny, batch2):
    init, run = batch2
    st = steps(tiny)
    n_on, n_de = st.onset // st.block, st.decay // st.block
    assert run["lambda_onset"].dims == ("replica", "time_onset")
    assert run["speed_decay"].dims == ("replica", "time_decay")
    assert run.sizes == {**run.sizes, "replica": 2, "time_onset": n_on, "time_decay": n_de}
    assert list(run["replica"].values) == [0, 1]
    assert run["lambda_onset"].attrs["units"] == "1/t0"
    assert run["speed_onset"].attrs["units"] == "d_s/t0"
    assert run["time_onset"].attrs["units"] == "t0" and run["seconds_onset"].attrs["units"] == "s"
    np.testing.assert_allclose(run["seconds_onset"].values, run["time_onset"].values * 0.034975)
    # block centres of 4 ms blocks
    np.testing.assert_allclose(run["seconds_onset"].values[:2], [0.002, 0.006], rtol=1e-4)
    for name, var in {**run.data_vars, **run.coords}.items():
        assert "units" in var.attrs and "long_name" in var.attrs, name
    phys = seed_physics(tiny)
    seeds = [replica_seed("drum", phys, r) for r in (0, 1)]
    assert list(run["seed"].values) == seeds
    assert run.attrs["seeds"] == " ".join(map(str, seeds))
    assert config_from_attrs(run)["physics"]["n_wall"] == 40
    assert run.attrs["git_commit"] and run.attrs["stage"] == "runs"
    # the stop time of the decay window
    assert run.attrs["stop_time_s"] == pytest.approx(0.2, abs=1e-4)
    # λ and V are finite block means, V positive
    assert np.isfinite(run["lambda_onset"].values).all()
    assert (run["speed_onset"].values > 0).all() and (run["speed_decay"].values > 0).all()
    # snapshots of the first replica: mobile disks inside the drum, no deep overlap
    pos = run["snapshot_position"].values
    assert pos.shape == (2, 46, 2)
    geom = DrumModel.from_physics(tiny["physics"]).geom
    assert np.hypot(pos[..., 0], pos[..., 1]).max() < geom.inner_radius
    assert init["position"].dims == ("replica", "particle", "xy")


def test_drum_stops_at_the_stop_time(tiny, batch2):
    """After the stop the wall disks are still: V loses its rigid-rotation part at once."""
    _, run = batch2
    wall = run["wall_position"].values  # snapshots at t = 0 and at the decay start
    # the drum turned between the two snapshots (clockwise: polar angle decreases)
    a0 = np.arctan2(wall[0, :, 1], wall[0, :, 0])
    a1 = np.arctan2(wall[1, :, 1], wall[1, :, 0])
    turned = np.angle(np.exp(1j * (a1 - a0)))
    assert np.all(turned < 0)
    st = steps(tiny)
    expected = -omega(tiny["physics"]) * (run["decay_start"].values[0] / st.dt_s) * st.dt
    np.testing.assert_allclose(turned, expected, rtol=1e-6)


def test_replica_is_bit_identical_whatever_the_batching(tiny, batch2, tmp_path):
    """Batch of 2 in 2 threads vs two batches of 1 in 1 thread: the same numbers."""
    _, run2 = batch2
    one = {**tiny, "ensemble": {**tiny["ensemble"], "batch_size": 1}}
    runs = [_stages(one, tmp_path, b, threads=1)[1] for b in (0, 1)]
    for r in (0, 1):
        for name in ("lambda_onset", "speed_onset", "lambda_decay", "speed_decay", "seed"):
            np.testing.assert_array_equal(
                run2[name].sel(replica=r).values, runs[r][name].sel(replica=r).values
            )


def test_replica_by_hand_equals_the_workflow(tiny, batch2):
    _, run = batch2
    ds = run_replica(tiny, 1, snapshots=False)
    for name in ("lambda_onset", "speed_decay", "continuous_time", "settle_time"):
        np.testing.assert_array_equal(ds[name].values[0], run[name].sel(replica=1).values)


def test_per_disk_record_of_the_onset_window(tiny, batch2):
    """|δu_i| and |v_i| of every mobile disk at the onset window's pile samples, float32;
    the first sample is t = 0, where replica 0's snapshot holds the same disks."""
    _, run = batch2
    S = run.sizes["pile_onset"]
    for name, units in (("disk_du_onset", "1"), ("disk_speed_onset", "d_s/t0")):
        var = run[name]
        assert var.dims == ("replica", "pile_onset", "particle") and var.shape == (2, S, 46)
        assert var.dtype == np.float32 and var.attrs["units"] == units
        assert var.attrs["long_name"] and np.isfinite(var.values).all()
    du, v = run["disk_du_onset"].values, run["disk_speed_onset"].values
    np.testing.assert_allclose(du.max(axis=-1), 1.0, rtol=1e-6)  # over the largest
    assert (du >= 0).all() and (v >= 0).all()
    snap_v = np.hypot(*run["snapshot_velocity"].values[0].T)
    np.testing.assert_array_equal(v[0, 0], snap_v.astype(np.float32))
    np.testing.assert_array_equal(du[0, 0], run["snapshot_du"].values[0].astype(np.float32))


def test_without_the_per_disk_record_the_same_bits_and_no_disk_arrays(tiny, batch2):
    _, run = batch2
    off = {**tiny, "protocol": {**tiny["protocol"], "disk_record": False}}
    assert seed_physics(off) == seed_physics(tiny)
    ds = run_replica(off, 0, snapshots=False)
    assert not [k for k in ds.data_vars if k.startswith("disk_")]
    for name in ("lambda_onset", "speed_onset", "lambda_decay", "speed_decay", "tilt_onset",
                 "speed_lyapunov_correlation_onset", "continuous_time"):  # fmt: skip
        np.testing.assert_array_equal(ds[name].values[0], run[name].sel(replica=0).values)


def test_blowup_names_study_point_replica_seed_and_step(tiny):
    # a contact time of 3e-4 t0, a quarter of the step: the integration blows up
    bad = {**tiny, "physics": {**tiny["physics"], "k_n": 1.0e8}}
    with pytest.raises(SimulationError) as err:
        run_replica(bad, 3)
    msg = str(err.value)
    seed = replica_seed("drum", seed_physics(bad), 3)
    for part in ("study=drum", "replica=3", f"seed={seed}", "step=", "point=N=46"):
        assert part in msg, msg


def test_cli_replica_writes_a_run_file(tmp_path, repo):
    out = tmp_path / "run.nc"
    granpipe = str(Path(sys.executable).with_name("granpipe"))
    proc = subprocess.run(
        [granpipe, "drum", "replica", "--seed", "5", "--tiny", "--out", str(out)],
        cwd=repo,
        capture_output=True,
        text=True,
        stdin=subprocess.DEVNULL,
        timeout=600,
    )
    assert proc.returncode == 0, proc.stderr
    ds = xr.open_dataset(out)
    assert int(ds["replica"].values[0]) == 5 and ds.attrs["stage"] == "replica"
    assert "ns per mobile particle-step" in proc.stderr


def test_initial_tangent_sets_about_ten_percent_of_components():
    from granpipe.drum.protocol import initial_tangent

    dr, dv = initial_tangent(736, np.random.default_rng(0), 0.1)
    du = np.concatenate([dr, dv], axis=1)
    frac = np.mean(du != 0)
    assert abs(frac - 0.1) < 3 * np.sqrt(0.1 * 0.9 / du.size)
    assert np.abs(du).max() <= 1.0 and (du < 0).any() and (du > 0).any()
    # each of the four kinds of component is drawn, not only positions
    assert (dr[:, 0] != 0).any() and (dv[:, 1] != 0).any()


def test_the_drum_has_turned_exactly_one_degree_at_t0(tmp_path):
    """Paper start-up on the tiny drum with the paper's 1 degree: placement, fall (stage
    init), tangent alignment (stage runs), then t = 0 - the wall disks of the t = 0
    snapshot sit at 1 degree of clockwise rotation, to within half a step's turn."""
    sec = tiny_section({}, pre_rotation_deg=1.0)
    sec["ensemble"].update(batch_size=1)
    init_stage(sec, 0, tmp_path / "init.nc")
    runs_stage(sec, 0, tmp_path / "init.nc", tmp_path / "run.nc")
    run = read_dataset(tmp_path / "run.nc")
    model = DrumModel.from_physics(sec["physics"])
    st = steps(sec)
    wall0 = run["wall_position"].sel(snapshot="t=0").values
    a0 = np.arctan2(model.walls0[:, 1], model.walls0[:, 0])
    a = np.arctan2(wall0[:, 1], wall0[:, 0])
    turned = -np.angle(np.exp(1j * (a - a0)))  # clockwise > 0
    half_step = 0.5 * omega(sec["physics"]) * st.dt
    np.testing.assert_allclose(turned, np.radians(1.0), atol=half_step + 1e-12)
    assert st.pre_rotation * st.dt_s == pytest.approx(2.5, rel=1e-4)
    init = read_dataset(tmp_path / "init.nc")
    # the init file ends the fall tangent_alignment_s before t = 0
    fell = float(init["settle_time"].values[0])
    assert fell == pytest.approx(2.5 - sec["protocol"]["tangent_alignment_s"], abs=st.block_s)


@pytest.fixture(scope="module")
def static_batch(tiny, tmp_path_factory):
    """Replica 0 of the tiny drum under static friction, through the stages."""
    sec = {**tiny, "physics": {**tiny["physics"], "friction": "static"},
           "ensemble": {**tiny["ensemble"], "batch_size": 1}}  # fmt: skip
    return sec, _stages(sec, tmp_path_factory.mktemp("static"), 0, threads=1)


def test_static_friction_init_file_carries_spins_and_springs_to_the_runs(static_batch):
    """The init file holds spins and stretched springs; the runs stage continues from
    them exactly as a replica run by hand in one process (no file between)."""
    sec, (init, run) = static_batch
    assert init.attrs["friction"] == "static"
    spin = init["spin"].values[0]
    pairs = init["shear_pair"].values[0]
    xi = init["shear_history"].values[0][pairs[:, 0] >= 0]
    assert np.abs(spin).max() > 0 and len(xi) > 10 and np.all(xi != 0)
    assert np.all(pairs[pairs[:, 0] >= 0, 0] < pairs[pairs[:, 0] >= 0, 1])
    ds = run_replica(sec, 0, snapshots=False)
    for name in ("lambda_onset", "speed_onset", "lambda_decay", "speed_decay"):
        np.testing.assert_array_equal(ds[name].values[0], run[name].sel(replica=0).values)


def test_static_friction_replicas_pair_with_the_viscous_ones(tiny, batch2, static_batch):
    """Replica k of both laws has one seed (common random numbers), and a runs stage
    refuses an init file made under the other law."""
    sec, (init, _) = static_batch
    viscous_init, _ = batch2
    assert int(init["seed"].values[0]) == int(viscous_init["seed"].sel(replica=0).values)
    assert seed_physics(sec) == seed_physics(tiny)
    with pytest.raises(ValueError, match="made under viscous friction"):
        run_batch(sec, 0, viscous_init.isel(replica=[0]))
    viscous_one = {**tiny, "ensemble": {**tiny["ensemble"], "batch_size": 1}}
    with pytest.raises(ValueError, match="made under static friction"):
        run_batch(viscous_one, 0, init)
