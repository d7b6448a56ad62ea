"""The config subset of each column rule (granpipe.column.layout.rule_params)."""

import copy
import json

import pytest

from granpipe.column import layout
from granpipe.config import load
from granpipe.io import config_hash


@pytest.fixture(scope="module")
def section():
    return load("config/config.yaml")["column"]


def test_rule_params_are_the_per_rule_subsets(section):
    p = layout.rule_params(section)
    assert set(p["trajectories"]) == set(layout.figure_sets(section))
    for name, sub in p["trajectories"].items():
        assert sub == layout.trajectory_params(section, name)
        assert list(sub["sets"]) == [name]
    assert p["relaxation"] == layout.relaxation_params(section)
    assert p["chaos"] == layout.chaos_params(section)
    assert p["continuum"] == layout.continuum_params(section)
    assert p["convergence"] == layout.continuum_params(section, True)
    # each reduction names the config hash of every file it may read
    assert p["ensemble_relaxation"] == {
        "kind": "relaxation", "runs_config_hash": config_hash(p["relaxation"])
    }  # fmt: skip
    chaos = p["ensemble_chaos"]
    assert chaos["confidence"] == section["chaos"].get("confidence", 0.95)
    assert list(chaos["points"]) == layout.chaos_points(section)
    first = layout.chaos_points(section)[0]
    a, t = (float(v.split("=")[1]) for v in first.split(","))
    assert chaos["points"][first] == config_hash(
        {**p["chaos"], "physics": {**p["chaos"]["physics"], "a": a, "T": t}}
    )
    assert p["fits"]["units"] == p["figures"]["units"] == layout.units(section)
    assert p["fits"]["inputs"] == {
        "relaxation": config_hash(p["ensemble_relaxation"]),
        "chaos": config_hash(chaos),
        "continuum": config_hash(p["continuum"]),
        "convergence": config_hash(p["convergence"]),
    }
    assert p["figures"]["inputs"]["trajectories"] == {
        name: config_hash(sub) for name, sub in p["trajectories"].items()
    }
    json.dumps(p, sort_keys=True)  # what the rules pass as --params


def test_an_edit_changes_only_the_rules_that_read_it(section):
    before = layout.rule_params(section)
    edited = copy.deepcopy(section)
    edited["relaxation"]["n_boot"] = int(edited["relaxation"].get("n_boot", 1000)) + 1
    after = layout.rule_params(edited)
    changed = {k for k in before if before[k] != after[k]}
    assert changed == {"fits"}
    edited["chaos"]["confidence"] = 0.9
    assert layout.rule_params(edited)["ensemble_chaos"]["confidence"] == 0.9
    with pytest.raises(ValueError):
        layout.ensemble_params(section, "trajectories")
