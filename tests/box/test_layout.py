"""Point names, file lists and per-stage config subsets of the box study."""

import copy

import pytest

from granpipe.box import layout
from granpipe.config import load
from granpipe.io import config_hash

from .conftest import SECTION

W6 = layout.Walls(0.6, "shaken", "lever")


@pytest.mark.parametrize("gamma", [0.8, 1.0, 2.2, 3.25, 0.1 + 0.2])
def test_point_name_round_trips_exactly(gamma):
    walls = layout.Walls(0.1 + gamma, "still", "none")
    name = layout.point_name(20, gamma, "crystal", walls)
    assert layout.parse_point(name) == (20, gamma, "crystal", walls)


def test_bad_point_names_are_refused():
    with pytest.raises(ValueError):
        layout.parse_point("N_l=20,Gamma=2.2,init=glass,mu_w=0.6,walls=shaken,torque=lever")
    with pytest.raises(ValueError):
        layout.parse_point("N_l=20,Gamma=2.2,init=crystal,mu_w=0.6")
    with pytest.raises(ValueError):
        layout.parse_point("N_l=20,Gamma=2.2,init=crystal,mu_w=0.6,walls=loose,torque=lever")
    with pytest.raises(ValueError):
        layout.point_name(20, 2.2, "glass", W6)
    with pytest.raises(ValueError):
        layout.point_name(20, 2.2, "crystal", layout.Walls(0.6, "shaken", "half"))


def test_run_files_cover_points_replicas_and_parts():
    sec = copy.deepcopy(SECTION)
    sec["grid"]["replicas"] = 2
    sec["protocol"]["measured_periods"] = 5
    sec["protocol"]["periods_per_part"] = 2
    files = layout.run_files(sec)
    # 1 N_l x 2 inits x 2 Γ points, 2 replicas, ceil(5/2) = 3 parts
    assert len(files) == 4 * 2 * 3 == len(set(files))
    assert (
        "runs/N_l=5,Gamma=2.0,init=random,mu_w=0.6,walls=shaken,torque=lever/"
        "replica_0001.part_002.nc" in files
    )
    assert [list(layout.part_periods(sec, p)) for p in range(3)] == [[0, 1], [2, 3], [4]]


def test_grid_blocks_add_points_and_replicas_and_leave_the_grids_files_alone():
    sec = copy.deepcopy(SECTION)
    before = layout.run_files(sec)
    hashes = {pt: layout.ensemble_params(sec, layout.point_name(*pt)) for pt in layout.points(sec)}
    g0 = float(sec["grid"]["Gamma"][0])
    # one grid point again with 3 replicas, a new Γ of one start, a new N_l
    sec["grid"]["blocks"] = [
        {"N_l": [5], "Gamma": [g0, 2.55], "inits": ["crystal"], "replicas": 3},
        {"N_l": [7], "Gamma": [g0]},
    ]
    pts = layout.points(sec)
    assert len(pts) == len(set(pts)) == len(hashes) + 1 + 2
    assert (5, 2.55, "crystal", W6) in pts and (5, 2.55, "random", W6) not in pts
    files = layout.run_files(sec)
    assert set(before) <= set(files)
    assert len(files) == len(before) + (2 + 3 + 2) * layout.n_parts(sec)
    assert list(layout.replicas(sec, 5, g0, "crystal")) == [0, 1, 2]
    assert list(layout.replicas(sec, 5, g0, "random")) == [0]
    assert list(layout.replicas(sec, 7, g0, "random")) == [0]
    # the prepared states: three crystal replicas for N_l 5, one of each start for N_l 7
    states = layout.init_files(sec)
    assert len(states) == 3 + 1 + 2 == len(set(states))
    # an untouched point keeps its ensemble subset; a point with more replicas reduces them
    for pt, params in hashes.items():
        now = layout.ensemble_params(sec, layout.point_name(*pt))
        if pt[1:3] == (g0, "crystal"):
            assert now["replicas"] == 3 != params["replicas"]
        else:
            assert now == params


def test_growing_measured_periods_by_whole_parts_keeps_earlier_part_params():
    sec = copy.deepcopy(SECTION)
    sec["protocol"]["measured_periods"] = 4
    sec["protocol"]["periods_per_part"] = 2
    before = [layout.runs_params(sec, p, W6) for p in range(2)]
    sec["protocol"]["measured_periods"] = 6
    after = [layout.runs_params(sec, p, W6) for p in range(3)]
    assert after[:2] == before
    assert after[2]["part_periods"] == [4, 6]
    # a physics edit changes every part
    sec["physics"]["mu"] = 0.5
    assert layout.runs_params(sec, 0, W6) != after[0]


def test_added_wall_friction_adds_points_and_leaves_the_others_untouched():
    sec = copy.deepcopy(SECTION)
    before = {f: layout.runs_params(sec, 0, W6) for f in layout.run_files(sec)}
    sec["grid"]["mu_side_walls"] = [0.6, 0.0]
    after = layout.run_files(sec)
    assert len(after) == 2 * len(before) and set(before) <= set(after)
    # the old points keep their parameters (and so their files); the new ones have theirs
    assert all(layout.runs_params(sec, 0, W6) == p for p in before.values())
    new = layout.runs_params(sec, 0, layout.Walls(0.0))
    assert new["physics"]["mu_side_walls"] == 0.0
    assert {k: v for k, v in new["physics"].items() if k != "mu_side_walls"} == {
        k: v for k, v in before[next(iter(before))]["physics"].items() if k != "mu_side_walls"
    }
    assert (
        layout.init_files(sec)[-1] == "init/N_l=5,init=random,mu_w=0.0,torque=lever/replica_0000.nc"
    )


def test_stage_subsets_hold_only_what_the_stage_reads():
    assert set(layout.init_params(SECTION, W6)) == {"physics", "init"}
    assert layout.init_params(SECTION, layout.Walls(0.2))["physics"]["mu_side_walls"] == 0.2
    # the plate rests while a state is prepared: the side walls' drive is not part of it
    assert "side_walls" not in layout.init_params(SECTION, W6)["physics"]
    assert set(layout.ensemble_params(SECTION)) == {"Lx", "detection", "slips", "order"}
    # a point's ensemble also names the files it reduces: the point, its replicas and
    # the config hash of each part's run files
    point = layout.point_name(*layout.points(SECTION)[0])
    one = layout.ensemble_params(SECTION, point)
    assert set(one) - {"Lx", "detection", "slips", "order"} == {
        "point", "replicas", "runs_config_hashes"
    }  # fmt: skip
    walls = layout.parse_point(point)[3]
    assert one["runs_config_hashes"] == [
        config_hash(layout.runs_params(SECTION, p, walls)) for p in range(layout.n_parts(SECTION))
    ]
    fits = layout.fits_params(SECTION)
    assert set(fits) == {"detection", "fits", "points"}
    assert fits["points"][point] == config_hash(one)
    assert set(fits["points"]) == {layout.point_name(*pt) for pt in layout.points(SECTION)}
    assert "resources" not in str(layout.runs_params(SECTION, 0, W6))


def test_wall_drives_and_torques_are_points_that_share_prepared_states():
    sec = copy.deepcopy(SECTION)
    before = {f: layout.runs_params(sec, 0, W6) for f in layout.run_files(sec)}
    inits = layout.init_files(sec)
    sec["physics"]["side_walls"] = ["shaken", "still"]
    assert set(before) < set(layout.run_files(sec)) and len(layout.run_files(sec)) == 2 * len(
        before
    )
    # a still side wall adds runs but no prepared state: both drives start from the same one
    assert layout.init_files(sec) == inits
    still = layout.Walls(0.6, "still", "lever")
    assert layout.runs_params(sec, 0, still)["physics"]["side_walls"] == "still"
    assert all(layout.runs_params(sec, 0, W6) == p for p in before.values())
    sec["physics"]["wall_torque"] = ["lever", "none"]
    assert len(layout.run_files(sec)) == 4 * len(before)
    assert len(layout.init_files(sec)) == 2 * len(inits)


@pytest.mark.parametrize("scale", ["config/config.yaml", "config/quick.yaml", "config/paper.yaml"])
def test_scale_configs_expand(repo, scale):
    cfg = load(repo / scale)
    box = cfg["box"]
    files = layout.run_files(box)
    runs = sum(len(layout.replicas(box, n, g, i)) for n, g, i, _ in layout.points(box))
    assert runs >= len(layout.points(box)) * box["grid"]["replicas"]
    assert len(files) == runs * layout.n_parts(box)
    assert layout.sim_minutes(box, max(box["grid"]["N_l"]), 0) >= box["resources"]["min_runtime"]
