import copy
import re

import pytest
import yaml

from granpipe import config
from granpipe.errors import ConfigError

SCALES = [
    "config/config.yaml",
    "config/quick.yaml",
    "config/validation.yaml",
    "config/paper.yaml",
    "config/box_walls.yaml",
    "config/friction.yaml",
    "config/friction_long.yaml",
]


@pytest.fixture(params=SCALES)
def scale_cfg(request, repo):
    return yaml.safe_load((repo / request.param).read_text())


def _schema_for(path, schema, base):
    """Resolve the sub-schema that governs key ``path``: follows ``$ref`` to sibling files
    and to ``#/...`` pointers inside the current file, and ``additionalProperties``."""
    root = schema

    def resolve(node):
        nonlocal root
        while isinstance(node, dict) and "$ref" in node:
            ref = node["$ref"]
            if ref.startswith("#/"):
                target = root
                for part in ref[2:].split("/"):
                    target = target[part]
                node = target
            else:
                root = node = yaml.safe_load((base / ref).read_text())
        return node

    schema = resolve(schema)
    for key in path:
        props = schema.get("properties", {})
        extra = schema.get("additionalProperties")
        sub = props.get(key, extra if isinstance(extra, dict) else {})
        schema = resolve(sub)
    return schema


def _leaves(obj, path=()):
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _leaves(v, (*path, k))
    else:
        yield path, obj


def _set(cfg, path, value):
    node = cfg
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value


def test_every_scale_validates(scale_cfg):
    filled = config.validate(copy.deepcopy(scale_cfg))
    assert filled["scale"] == scale_cfg["scale"]
    assert set(filled["studies"]) <= set(filled)


def test_load_fills_defaults_and_matches_validate(repo):
    a = config.load(repo / "config/quick.yaml")
    b = config.validate(yaml.safe_load((repo / "config/quick.yaml").read_text()))
    assert a == b


@pytest.mark.parametrize(
    "mutate, key",
    [
        (lambda c: c.update(bogus=1), "'bogus'"),
        (lambda c: c.update(scale=3), "'scale'"),
        (lambda c: c.update(studies=[]), "'studies'"),
        (lambda c: c.update(studies=["drum", "moon"]), "'studies[1]'"),
        (lambda c: c.update(results=""), "'results'"),
    ],
)
def test_top_level_errors_name_the_key(scale_cfg, mutate, key):
    cfg = copy.deepcopy(scale_cfg)
    mutate(cfg)
    with pytest.raises(ConfigError, match=key.replace("[", r"\[").replace("]", r"\]")):
        config.validate(cfg)


def test_study_listed_without_section_is_rejected(scale_cfg):
    cfg = copy.deepcopy(scale_cfg)
    study = cfg["studies"][0]
    del cfg[study]
    with pytest.raises(ConfigError, match=f"missing config key '{study}'"):
        config.validate(cfg)


def test_unknown_key_inside_a_study_is_rejected(scale_cfg):
    cfg = copy.deepcopy(scale_cfg)
    study = cfg["studies"][0]
    cfg[study]["no_such_key"] = 1
    with pytest.raises(ConfigError, match=f"'{study}.no_such_key'"):
        config.validate(cfg)


def test_non_positive_and_mistyped_numbers_are_rejected(repo):
    """Every key the schemas require to be > 0 (timesteps, counts) rejects 0 and -1,
    and every numeric key rejects a string, each time naming the dotted key (on the quick
    scale, which sets every study's keys; the other scales share the schemas)."""
    scale_cfg = yaml.safe_load((repo / "config/quick.yaml").read_text())
    base = repo / "workflow/schemas"
    top = yaml.safe_load((base / "config.schema.yaml").read_text())
    positive = 0
    for path, value in _leaves(scale_cfg):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            continue
        schema = _schema_for(path, top, base)
        dotted = ".".join(path)
        bad_values = ["ten"]
        if schema.get("exclusiveMinimum") == 0:
            bad_values += [0, -1]
            positive += 1
        for bad in bad_values:
            cfg = copy.deepcopy(scale_cfg)
            _set(cfg, path, bad)
            with pytest.raises(ConfigError, match=f"'{dotted}'"):
                config.validate(cfg)
    studies_with_schema = [
        s
        for s in scale_cfg["studies"]
        if yaml.safe_load((base / f"{s}.schema.yaml").read_text()).get("properties")
    ]
    if studies_with_schema:
        assert positive > 0, "no strictly positive key (timestep/count) found in the schemas"


def test_missing_and_invalid_files(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        config.load(tmp_path / "nope.yaml")
    (tmp_path / "bad.yaml").write_text("scale: [unclosed\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        config.load(tmp_path / "bad.yaml")


def _quick(repo):
    return yaml.safe_load((repo / "config/quick.yaml").read_text())


@pytest.mark.parametrize(
    "path, value, match",
    [
        (("drum", "fits", "lowpass_fraction"), float("nan"), "drum.fits.lowpass_fraction"),
        (("box", "physics", "mu"), float("inf"), "box.physics.mu"),
        (("drum", "fits", "onset_zero_window_s"), [0.5, 99.0], "beyond the recorded window"),
        (("drum", "fits", "decay_zero_window_s"), [1.2, 0.6], "must be increasing"),
        (("drum", "settle", "min_time_s"), 9.0, "min must not exceed max"),
        (("drum", "figures", "snapshot_batch"), 7, "drum.figures.snapshot_batch"),
        (("drum", "ensemble", "n_replicas"), 10**6, "simulation jobs"),
        (("box", "fits", "N_l"), 33, "box.fits.N_l"),
        (("box", "physics", "steps_per_contact"), 1e-6, "'box.physics.steps_per_contact' = 1e-06"),
        (("box", "physics", "steps_per_contact"), 1.5, "unstable below 1.57 steps"),
        (("box", "physics", "gamma_n"), 3000.0, "'box.physics.gamma_n' = 3000.0: the contact"),
        (("box", "protocol", "slip_phases"), 3, "'box.protocol.slip_phases' = 3 does not divide"),
        (("box", "detection", "roll_significance"), 0.0, "box.detection.roll_significance"),
        (("results",), "README.md", "'results' = 'README.md' is an existing file"),
        # the report's movies: a point and a replica the scale runs
        (("drum", "movie", "replica"), 2, "'drum.movie.replica' = 2 is outside"),
        (("shear", "movie", "phi"), 0.9, "'shear.movie.phi' = 0.9 is not one of"),
        (("shear", "movie", "replica"), 5, "'shear.movie.replica' = 5 is outside"),
        (("box", "movie", "N_l"), 40, "'box.movie.N_l' = 40 is not in"),
        (("box", "movie", "Gamma"), 2.5, "'box.movie.Gamma' = 2.5 is not in"),
        (("box", "movie", "replica"), 1, "'box.movie.replica' = 1 is outside"),
        (("box", "movie", "periods"), 9, "'box.movie.periods' = 9 exceeds"),
        (("drum", "movie", "format"), "avi", "drum.movie.format"),
        (("column", "continuum", "sigma_width"), 0.0, "column.continuum.sigma_width"),
        (("column", "continuum", "convergence", "lw_refinements"), [2, 3, 8], "lw_refinements"),
        (("column", "chaos", "return_taps"), 4, "column.chaos.return_taps"),
        (("column", "chaos", "return_taps"), 1, "column.chaos.return_taps"),
        (("column", "chaos", "return_max_period"), 2, "column.chaos.return_max_period"),
        (("column", "chaos", "return_max_period"), 0, "column.chaos.return_max_period"),
        (("column", "chaos", "return_tolerance"), 0.0, "column.chaos.return_tolerance"),
        (("column", "chaos", "return_tolerance"), "tight", "column.chaos.return_tolerance"),
        # outputs outside <results>/<scale>/
        (("scale",), "..", "'scale' = '..' is not a folder name"),
        (("scale",), ".", "'scale' = '.' is not a folder name"),
        (("scale",), "s" * 65, "'scale' is 65 characters long"),
        (("results",), "/tmp/elsewhere", "'results' = '/tmp/elsewhere' must be relative"),
        (("results",), "results/../..", "climbs out of the working directory"),
        (("results",), ".", "is the working directory itself"),
        (("results",), "r" * 300, "'results' is too long"),
        # the physics: what a job would otherwise trip on after other jobs ran
        (("column", "relaxation", "physics", "N"), 1, "'column.relaxation.physics.N' = 1"),
        (("column", "relaxation", "physics", "stiffness_factor"), 1.0, "Eq. 28"),
        (("column", "figure1", "sets", "N5", "stiffness_factor"), 0.5, "figure1.sets.N5': c"),
        (("column", "relaxation", "physics", "T"), 0.01, "tap duration"),
        (("column", "chaos", "periods"), [0.01, 1.2], "'column.chaos.periods': column: the pe"),
        (("column", "relaxation", "n_replicas"), 10**6, "simulation jobs"),
        (("column", "relaxation", "physics", "N"), 10**12, "GB of memory"),
        (("drum", "physics", "n_small"), 3000, "more than the 0.45 random placement reaches"),
        (("drum", "physics", "n_wall"), 8, "'n_wall' = 8"),
        (("drum", "physics", "dt"), 10**400, "'drum.physics.dt' = 1000"),
        (("drum", "fits", "seed"), 2**64, "'drum.fits.seed'"),
        (("box", "physics", "Lx"), 1.5, "'box.physics.Lx' = 1.5 holds no crystal row"),
        (("box", "grid", "N_l"), [10**9], "'box.grid.N_l' = 1000000000: one job would need"),
        (("box", "protocol", "periods_per_part"), 1, None),
        # counted before anything of that size is built (no array of 10**12 disks, no list
        # of 10**18 batch names, no section copied per point of a long list)
        (("drum", "physics", "n_small"), 10**12, "'drum.physics.n_small' = 1000000000000: one"),
        (
            ("drum", "protocol", "onset_window_s"),
            1e12,
            "'drum.protocol.onset_window_s' = 1000000000000.0: one job",
        ),
        (("column", "relaxation", "n_replicas"), 10**18, "'column.relaxation.n_replicas': 5"),
        (("column", "relaxation", "n_taps"), 10**12, "'column.relaxation.n_taps' = 1000000000000"),
        (
            ("column", "chaos", "periods"),
            [1.0 + i / 1e4 for i in range(6000)],
            "'column.chaos.amplitudes': 12005 simulation jobs",
        ),
        (
            ("drum", "physics", "period_s"),
            [100.0 + i for i in range(6000)],
            "'drum.physics.period_s': 12000 simulation jobs",
        ),
    ],
)
def test_refusals_before_any_job_name_the_key(repo, path, value, match, monkeypatch):
    """NaN and inf anywhere, fit windows outside the record or reversed, min > max, the
    snapshot batch beyond the batches, a plan too large to build, a grid selection not in
    the grid, a smooth sign of zero width, refinements that are not nested, a return-map
    window longer than the measured taps or shorter than two longest periods, a period
    below 1, a tolerance that is not a positive number."""
    monkeypatch.chdir(repo)  # paths in the config are relative to the working directory
    cfg = _quick(repo)
    _set(cfg, path, value)
    if match is None:  # parts numbered past the rules' three digits
        cfg["box"]["protocol"]["measured_periods"] = 1001
        cfg["box"]["grid"].update(Gamma=[1.0], inits=["crystal"])
        match = "1001 parts per run, more than 1000"
    with pytest.raises(ConfigError, match=re.escape(match)):
        config.validate(cfg)


def test_drum_memory_is_checked_against_the_machine(repo):
    cfg = _quick(repo)
    cfg["drum"]["physics"].update(n_small=10**6, n_large=10**6, n_wall=10**9)
    with pytest.raises(ConfigError, match=r"'drum\.physics\.n_small' = 1000000: one job"):
        config.validate(cfg)


def test_reasons_say_what_is_wrong_not_which_schema_branch(repo):
    cfg = _quick(repo)
    cfg["drum"]["physics"]["period_s"] = 0
    with pytest.raises(ConfigError) as err:
        config.validate(cfg)
    assert "'drum.physics.period_s' = 0" in str(err.value) and "array" not in str(err.value)
    assert "less than or equal to the minimum of 0" in str(err.value)
    cfg["drum"]["physics"]["period_s"] = [900.0, -450.0]
    with pytest.raises(ConfigError, match=r"'drum\.physics\.period_s\[1\]' = -450\.0"):
        config.validate(cfg)


def _bomb(tmp_path, repo, levels):
    """A config whose scale is ``levels`` levels of aliases of ten items each."""
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, levels)]
    text = (
        (repo / "config/quick.yaml").read_text().replace("scale: quick", f"scale: *a{levels - 1}")
    )
    path = tmp_path / f"bomb{levels}.yaml"
    path.write_text("\n".join(lines) + "\n" + text)
    return path


def test_a_value_that_aliases_expand_is_shown_cut(tmp_path, repo):
    """Aliases that expand to 10**5 items: the error names the key, its value cut short."""
    with pytest.raises(ConfigError) as err:
        config.load(_bomb(tmp_path, repo, 5))
    assert "'scale' = [[[[" in str(err.value) and "characters)" in str(err.value)
    assert len(str(err.value)) < 2000
    # ten levels, 10**10 items: refused as it is read, before anything walks it
    with pytest.raises(ConfigError, match=r"bomb10\.yaml expands .* more than 1000000 values"):
        config.load(_bomb(tmp_path, repo, 10))


def test_defaults_of_the_study_schemas_are_filled(repo):
    """A box or column key left out takes its schema default (no KeyError in a check)."""
    cfg = _quick(repo)
    del cfg["box"]["grid"]["inits"], cfg["box"]["physics"]["Lx"]
    del cfg["column"]["integrator"]
    filled = config.validate(cfg)
    assert filled["box"]["grid"]["inits"] == ["crystal", "random"]
    assert filled["box"]["physics"]["Lx"] == 20.0
    assert filled["column"]["integrator"]["step_factor"] == 0.1


def test_yaml_errors_and_duplicate_keys_name_file_and_line(tmp_path, repo):
    (tmp_path / "dup.yaml").write_text("scale: quick\nresults: results\nscale: other\n")
    with pytest.raises(ConfigError, match=r"dup\.yaml, line 3.*duplicate key 'scale'.*line 1"):
        config.load(tmp_path / "dup.yaml")
    (tmp_path / "broken.yaml").write_text("scale: quick\nstudies: [drum\n")
    with pytest.raises(ConfigError, match=r"broken\.yaml, line \d+, column \d+"):
        config.load(tmp_path / "broken.yaml")
    # the scale files themselves have no duplicate key
    for name in ("config.yaml", "quick.yaml", "validation.yaml", "paper.yaml"):
        config.read_yaml(repo / "config" / name)


def test_check_config_cli_reports_one_line_not_a_traceback(tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    (tmp_path / "dup.yaml").write_text("scale: a\nscale: b\n")
    granpipe = str(Path(sys.executable).with_name("granpipe"))
    proc = subprocess.run([granpipe, "check-config", str(tmp_path / "dup.yaml")],
                          capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert "line 2" in proc.stderr and "duplicate key" in proc.stderr
