"""The drum config section (seeding subset, checks naming the key, parameter points) and
the file layout."""

import re

import pytest

from granpipe.drum import layout
from granpipe.drum.layout import filled, point_label, points, seed_physics, steps
from granpipe.errors import ConfigError


def test_seed_subset_excludes_sample_sizes_and_analysis():
    a = seed_physics({"ensemble": {"n_replicas": 10}, "fits": {"seed": 3}})
    b = seed_physics({"ensemble": {"n_replicas": 99}})
    # the paper start-up does not depend on the settling keys, nor on the overlap bound
    assert a == b and set(a) == {"physics", "protocol"} and "max_overlap" not in a["physics"]
    assert seed_physics({"settle": {"max_speed": 3.0}, "physics": {"max_overlap": 0.9}}) == a
    c = seed_physics({"protocol": {"block_s": 0.008}})
    assert c != a
    # the friction law is not seeded: replica k of both laws starts alike (paired)
    assert seed_physics({"physics": {"friction": "static", "k_t": 100.0}}) == a
    settled = seed_physics({"protocol": {"startup": "settled"}})
    assert set(settled) == {"physics", "settle", "protocol"}
    assert seed_physics({"protocol": {"startup": "settled"}, "settle": {"max_speed": 3}}) != settled


def test_bad_windows_and_keys_name_the_key():
    with pytest.raises(ConfigError, match="onset_zero_window_s"):
        filled({"fits": {"onset_zero_window_s": [20.0, 10.0]}})
    with pytest.raises(ConfigError, match="not_a_key"):
        filled({"physics": {"not_a_key": 1}})
    with pytest.raises(ConfigError, match="dt"):
        filled({"physics": {"dt": 0.0}})


def test_layout_batches_and_files():
    sec = {"ensemble": {"n_replicas": 5, "batch_size": 2}}
    assert layout.point_name(sec) == "N=736,period=900s,startup=paper,friction=viscous"
    assert layout.batch_ids(sec) == ["0000", "0001", "0002"]  # whole batches: 6 replicas
    files = layout.run_files(sec)
    name = "N=736,period=900s,startup=paper,friction=viscous"
    assert files[0] == f"runs/{name}/batch_0000.nc" and len(files) == 3
    assert layout.init_files(sec)[2].startswith("init/")
    grown = layout.run_files({"ensemble": {"n_replicas": 9, "batch_size": 2}})
    assert grown[:3] == files  # a larger ensemble only appends batches
    assert len(layout.figure_files()) == 16  # Figs. 2-9, PNG and PDF


def test_points_vary_one_key_at_a_time_from_the_reference():
    sec = {"physics": {"period_s": [900.0, 450.0, 225.0], "friction": ["viscous", "static"]},
           "protocol": {"startup": ["paper", "settled"]}}  # fmt: skip
    pts = points(sec)
    got = [(p["physics"]["period_s"], p["protocol"]["startup"], p["physics"]["friction"])
           for p in pts]  # fmt: skip
    assert got == [
        (900.0, "paper", "viscous"), (450.0, "paper", "viscous"), (225.0, "paper", "viscous"),
        (900.0, "settled", "viscous"), (900.0, "paper", "static"),
    ]  # fmt: skip
    assert [point_label(p, sec) for p in pts] == [
        "", "[period=450s]", "[period=225s]", "[startup=settled]", "[friction=static]"
    ]  # fmt: skip
    prod = points({**sec, "design": "product"})
    assert len(prod) == 12 and len({layout.point_name(p) for p in prod}) == 12
    # a point's simulation subset does not depend on the other entries of the lists
    alone = layout.rule_params({"physics": {"period_s": 450.0}})["sim"]
    listed = layout.rule_params(sec)["sim"]
    name = "N=736,period=450s,startup=paper,friction=viscous"
    assert alone[name] == listed[name]
    # k_t shapes the static point only, and is refused where no point uses it
    stiff = layout.rule_params({**sec, "physics": {**sec["physics"], "k_t": 100.0}})["sim"]
    static = "N=736,period=900s,startup=paper,friction=static"
    assert stiff[name] == listed[name] and stiff[static] != listed[static]
    with pytest.raises(ConfigError, match="k_t"):
        layout.check({"physics": {"k_t": 100.0}})
    with pytest.raises(ConfigError, match="period_s"):
        filled({"physics": {"period_s": [900.0, -1.0]}})


def _count_schema_reads(monkeypatch):
    """Count the fills of a drum section (each fill asks for the schema once)."""
    calls = []
    read = layout._schema

    def counting(*args):
        calls.append(args)
        return read(*args)

    monkeypatch.setattr(layout, "_schema", counting)
    return calls


def test_load_fills_once_and_hands_down_a_read_only_section(monkeypatch):
    calls = _count_schema_reads(monkeypatch)
    sec = layout.load({"physics": {"period_s": 450.0}})
    assert len(calls) == 1
    assert sec["physics"]["period_s"] == 450.0 and sec["physics"]["dt"] > 0
    # loading, filling, naming, seeding a loaded section never fills it again
    assert layout.load(sec) is sec
    assert layout.point_name(sec) == layout.point_name({"physics": {"period_s": 450.0}})
    calls.clear()
    seeded = layout.seed_physics(sec)
    plain = layout.filled(sec)
    assert calls == []
    assert seeded == layout.seed_physics(plain)
    assert plain == layout.filled({"physics": {"period_s": 450.0}})
    plain["physics"]["dt"] = 1.0  # a mutable copy
    assert sec["physics"]["dt"] != 1.0
    with pytest.raises(TypeError):
        sec["physics"] = {}
    with pytest.raises(TypeError):
        sec["physics"]["dt"] = 1.0
    with pytest.raises(TypeError):
        sec["fits"]["onset_vertex_window_s"][0] = 0.0
    with pytest.raises(AttributeError):
        sec.extra = 1


def test_gamma_t_points_name_their_value_and_keep_the_papers_names():
    from granpipe.drum import layout

    sec = {"physics": {"gamma_t": [6.8927, 3.44635, 13.7854]}}
    pts = points(sec)
    names = [layout.point_name(p) for p in pts]
    base = "N=736,period=900s,startup=paper,friction=viscous"
    assert names == [base, base + ",gamma_t=3.44635", base + ",gamma_t=13.7854"]
    assert [point_label(p, sec) for p in pts] == ["", "[gamma_t=3.44635]", "[gamma_t=13.7854]"]
    # each point's folder matches the workflow's pattern, its friction wildcard included

    pattern = layout.POINT_PATTERN.replace("{drum_friction}", layout.FRICTION_WILDCARD)
    pattern = re.sub(r"\{drum_\w+\}", "[^,=]+", pattern)
    assert all(re.fullmatch(pattern, n) for n in names)
    # the paper's gamma_t keeps today's seeds; another one seeds its own replicas
    assert seed_physics(pts[0]) == seed_physics({})
    assert seed_physics(pts[1])["physics"]["gamma_t"] == 3.44635
    with pytest.raises(ValueError, match="one point"):
        seed_physics(filled(sec))
    with pytest.raises(ConfigError, match="gamma_t"):
        filled({"physics": {"gamma_t": [1.0, 1.0]}})


def test_pile_sample_must_divide_the_chunk_and_is_not_seeded():
    with pytest.raises(ConfigError, match="pile_sample_s"):
        steps(filled({"protocol": {"pile_sample_s": 0.3}}))
    assert seed_physics({"protocol": {"pile_sample_s": 0.25}}) == seed_physics({})
    st = steps(filled({}))
    assert st.sample == 25 * st.block and st.chunk == 5 * st.sample  # 0.1 s, 0.5 s
