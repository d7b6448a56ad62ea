"""The config subset of each column rule (granpipe.column.layout.rule_params)."""

import copy
import json

import pytest

from granpipe.column import layout
from granpipe.config import load


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
    assert p["ensemble_relaxation"] == {"kind": "relaxation"}
    assert p["ensemble_chaos"] == {"confidence": section["chaos"].get("confidence", 0.95)}
    assert p["fits"]["units"] == p["figures"]["units"] == layout.units(section)
    json.dumps(p, sort_keys=True)  # what the rules pass as --params


def test_an_edit_changes_only_the_rules_that_read_it(section):
    before = layout.rule_params(section)
    edited = copy.deepcopy(section)
    edited["relaxation"]["n_boot"] = int(edited["relaxation"].get("n_boot", 1000)) + 1
    after = layout.rule_params(edited)
    changed = {k for k in before if before[k] != after[k]}
    assert changed == {"fits"}
    edited["chaos"]["confidence"] = 0.9
    assert layout.rule_params(edited)["ensemble_chaos"] == {"confidence": 0.9}
    with pytest.raises(ValueError):
        layout.ensemble_params(section, "trajectories")
