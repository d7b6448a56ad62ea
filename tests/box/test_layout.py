"""Point names, file lists and per-stage config subsets of the box study."""

import copy

import pytest

from granpipe.box import layout
from granpipe.config import load

from .conftest import SECTION


@pytest.mark.parametrize("gamma", [0.8, 1.0, 2.2, 3.25, 0.1 + 0.2])
def test_point_name_round_trips_exactly(gamma):
    name = layout.point_name(20, gamma, "crystal")
    assert layout.parse_point(name) == (20, gamma, "crystal")


def test_bad_point_names_are_refused():
    with pytest.raises(ValueError):
        layout.parse_point("N_l=20,Gamma=2.2,init=glass")
    with pytest.raises(ValueError):
        layout.point_name(20, 2.2, "glass")


def test_run_files_cover_points_replicas_and_parts():
    sec = copy.deepcopy(SECTION)
    sec["grid"]["replicas"] = 2
    sec["protocol"]["measured_periods"] = 5
    sec["protocol"]["periods_per_part"] = 2
    files = layout.run_files(sec)
    # 1 N_l x 2 inits x 2 Γ points, 2 replicas, ceil(5/2) = 3 parts
    assert len(files) == 4 * 2 * 3 == len(set(files))
    assert "runs/N_l=5,Gamma=2.0,init=random/replica_0001.part_002.nc" in files
    assert [list(layout.part_periods(sec, p)) for p in range(3)] == [[0, 1], [2, 3], [4]]


def test_growing_measured_periods_by_whole_parts_keeps_earlier_part_params():
    sec = copy.deepcopy(SECTION)
    sec["protocol"]["measured_periods"] = 4
    sec["protocol"]["periods_per_part"] = 2
    before = [layout.runs_params(sec, p) for p in range(2)]
    sec["protocol"]["measured_periods"] = 6
    after = [layout.runs_params(sec, p) for p in range(3)]
    assert after[:2] == before
    assert after[2]["part_periods"] == [4, 6]
    # a physics edit changes every part
    sec["physics"]["mu"] = 0.5
    assert layout.runs_params(sec, 0) != after[0]


def test_stage_subsets_hold_only_what_the_stage_reads():
    assert set(layout.init_params(SECTION)) == {"physics", "init"}
    assert set(layout.ensemble_params(SECTION)) == {"Lx", "detection", "slips", "order"}
    assert set(layout.fits_params(SECTION)) == {"detection", "fits"}
    assert "resources" not in str(layout.runs_params(SECTION, 0))


@pytest.mark.parametrize("scale", ["config/config.yaml", "config/quick.yaml", "config/paper.yaml"])
def test_scale_configs_expand(repo, scale):
    cfg = load(repo / scale)
    box = cfg["box"]
    files = layout.run_files(box)
    assert len(files) == len(layout.points(box)) * layout.n_parts(box) * box["grid"]["replicas"]
    assert layout.sim_minutes(box, max(box["grid"]["N_l"]), 0) >= box["resources"]["min_runtime"]
