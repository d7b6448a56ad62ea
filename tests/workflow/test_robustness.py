"""No silent wrong numbers, documented commands that work, and faults that recover, on the
workflow itself: each test takes its own copy of the finished quick scale (``quick``) and
runs only the jobs that prove its point.
"""

from __future__ import annotations

import copy
import os
import shutil
import stat

import pytest
import yaml

from .conftest import run_snakemake
from .test_product import data_bytes, planned_jobs, write_config

pytestmark = pytest.mark.workflow


def test_outputs_are_readable_by_the_group(quick):
    """Under umask 022 every file the quick scale wrote is group- and world-readable (not
    the 0600 of a temporary file)."""
    workdir, _ = quick
    files = [p for p in (workdir / "results").rglob("*") if p.is_file()]
    assert any(p.suffix == ".nc" for p in files) and any(p.suffix == ".csv" for p in files)
    modes = {p: stat.S_IMODE(p.stat().st_mode) for p in files}
    assert {m for p, m in modes.items() if p.suffix in (".nc", ".csv", ".png")} == {0o644}
    assert all(m & stat.S_IRGRP for m in modes.values()), modes


def test_quick_scale_runs_with_path_stripped_of_the_environment(quick):
    """`.venv/bin/snakemake ...` without the environment on PATH: one job of each study,
    a simulation among them, runs the granpipe beside Snakemake's interpreter."""
    workdir, _ = quick
    bare = "/usr/bin:/bin"
    if shutil.which("granpipe", path=bare):
        pytest.skip("a granpipe is installed system-wide")
    env = {"HOME": os.environ.get("HOME", "/tmp"), "PATH": bare, "MPLBACKEND": "Agg"}
    targets = [
        "results/quick/drum/fits/summary.csv",
        "results/quick/column/runs/relaxation/batch_0000.nc",
        "results/quick/box/fits/summary.csv",
    ]
    before = {t: (workdir / t).stat().st_mtime_ns for t in targets}
    proc = run_snakemake(
        "--cores", "2", "--configfile", "config/scratch.yaml", "--forcerun", "drum_summary",
        "column_relaxation", "box_fits", "--", *targets, cwd=workdir, env=env,
    )  # fmt: skip
    assert "3 of 3 steps (100%) done" in proc.stdout + proc.stderr
    assert all((workdir / t).stat().st_mtime_ns > m for t, m in before.items())


def test_a_results_path_with_a_space_and_a_quote_runs(quick):
    """`results: "res ult's"`: the rules that pass lists of files (the drum and column
    figures, the box figures' initial states, a box part's --previous) and every other path
    reach the shell through Snakemake's quoting. The drum and column data are copied
    there, their figures forced; the box runs afresh with two parts per run."""
    workdir, base = quick
    cfg = copy.deepcopy(base)
    cfg["results"] = "res ult's"
    cfg["box"]["grid"]["inits"] = ["crystal"]
    cfg["box"]["protocol"]["periods_per_part"] = 1  # two parts: part 1 takes --previous
    root = workdir / "res ult's" / "quick"
    for study in ("drum", "column"):
        shutil.copytree(workdir / "results" / "quick" / study, root / study)
    configfile = write_config(workdir, cfg, "quoted.yaml")
    run_snakemake(
        "--cores", "2", "--configfile", configfile, "--forcerun", "drum_figures",
        "column_figures", cwd=workdir, timeout=900,
    )  # fmt: skip
    assert planned_jobs(workdir, configfile) == {}
    for study in ("drum", "column", "box"):
        assert list((root / study / "figures").glob("fig*.png")), study
    assert list((root / "box" / "runs").glob("*/replica_0000.part_001.nc"))


def test_a_truncated_run_file_is_named_once_with_the_fix_and_then_recomputed(quick):
    """A drum run file cut to half its size after it was written: the plain rerun stops at
    the stage that reads it, whose log names it once with the fix; done as told (remove it,
    rerun), the file comes back bit-identical."""
    workdir, _ = quick
    runs = sorted((workdir / "results/quick/drum/runs").glob("*/batch_0000.nc"))
    target = runs[0]
    reference = data_bytes(target)
    with open(target, "r+b") as fh:
        fh.truncate(target.stat().st_size // 2)
    proc = run_snakemake(
        "--cores", "2", "--configfile", "config/scratch.yaml", cwd=workdir, check=False
    )
    assert proc.returncode != 0
    logs = workdir / "results/quick/logs/drum"
    text = "".join(p.read_text() for p in logs.rglob("*.log"))
    rel = str(target.relative_to(workdir))
    errors = [line for line in text.splitlines() if "cannot read" in line]
    assert len(errors) == 1 and rel in errors[0] and "remove it and rerun" in errors[0], text
    assert "Traceback" not in text
    target.unlink()
    run_snakemake("--cores", "2", "--configfile", "config/scratch.yaml", cwd=workdir,
                  timeout=900)  # fmt: skip
    assert data_bytes(target) == reference
    assert planned_jobs(workdir, "config/scratch.yaml") == {}


def test_a_rerun_gives_byte_identical_summaries(quick):
    """The box's simulations run again (their wall-clock times differ) and every study's
    fits again: each summary.csv is the same, byte for byte; the costs have their file."""
    workdir, base = quick
    summaries = {s: workdir / "results/quick" / s / "fits/summary.csv" for s in base["studies"]}
    before = {s: p.read_bytes() for s, p in summaries.items()}
    costs = workdir / "results/quick/box/fits/costs.csv"
    cost_time = costs.stat().st_mtime_ns
    run_snakemake(
        "--cores", "2", "--configfile", "config/scratch.yaml", "--forcerun", "box_runs",
        "drum_fits", "column_fits", "--", *(str(p.relative_to(workdir)) for p in
                                            summaries.values()),
        cwd=workdir, timeout=900,
    )  # fmt: skip
    assert costs.stat().st_mtime_ns > cost_time  # the box's fits did run again
    for study, path in summaries.items():
        assert path.read_bytes() == before[study], study
    assert b"cost" not in before["box"] and b"cost_ns_per_particle_step" in costs.read_bytes()


def test_scale_leaving_the_results_tree_is_refused_before_any_job(scratch_workflow):
    cfg = yaml.safe_load((scratch_workflow / "config/quick.yaml").read_text())
    cfg["scale"] = ".."
    configfile = write_config(scratch_workflow, cfg, "escape.yaml")
    proc = run_snakemake("--cores", "1", "--configfile", configfile, cwd=scratch_workflow,
                         check=False)  # fmt: skip
    assert proc.returncode != 0
    assert "config key 'scale' = '..' is not a folder name" in proc.stdout + proc.stderr
    assert not (scratch_workflow / "results").exists() and not (scratch_workflow / "logs").exists()
