"""Product behaviour of the workflow on a scratch copy at the quick scale.

The quick scale runs once per session (``pristine_quick``); every test works on its own
copy of it (``quick``), so they pass in any order: partial reruns plan exactly the
stages a config edit touches, figures regenerate from cached data alone, growing an
ensemble reuses every batch, a SIGKILLed job leaves nothing under its final name and its
rerun is byte-identical, a blow-up names study, point, replica, seed and step while
``--keep-going`` finishes the rest, a second workflow on the same directory is refused by
Snakemake's lock, and ``--report`` gathers every figure.
"""

from __future__ import annotations

import copy
import os
import re
import signal
import subprocess
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import pytest
import xarray as xr
import yaml

from granpipe.status import expected_run_files

from .conftest import SNAKEMAKE, run_snakemake, snakemake_env

pytestmark = pytest.mark.workflow


@dataclass(frozen=True)
class Knobs:
    """Where each study keeps the keys the product tests edit."""

    fit_key: tuple  # an analysis setting: only fits and figures may rerun
    fit_value: object
    timestep_key: tuple  # a physics setting: simulations and everything downstream
    replicas_key: tuple | None  # growing the ensemble appends batches (None: not tested)
    batch_size_key: tuple | None
    grow_rules: frozenset  # the simulation rules a grown ensemble runs, one job each
    sim_rules: frozenset
    fit_rules: frozenset  # rules that may rerun after a fit edit
    figure_rule: str
    batch_glob: str  # run files, relative to results/quick/<study>/


KNOBS = {
    "drum": Knobs(
        fit_key=("fits", "moving_average_s"),
        fit_value=0.2,
        timestep_key=("physics", "dt"),
        replicas_key=("ensemble", "n_replicas"),
        batch_size_key=("ensemble", "batch_size"),
        grow_rules=frozenset({"drum_init", "drum_runs"}),
        sim_rules=frozenset({"drum_init", "drum_runs"}),
        # the shear cell's contrast figure shows the drum's aligned λ̄: a drum fit edit
        # redraws it too; the movies find the pile's events with the fits' detector
        fit_rules=frozenset(
            {"drum_fits", "drum_summary", "drum_figures", "shear_figures", "drum_movie"}
        ),  # fmt: skip
        figure_rule="drum_figures",
        batch_glob="runs/*/batch_*.nc",
    ),
    "box": Knobs(
        fit_key=("fits", "confidence"),
        fit_value=0.9,
        timestep_key=("physics", "steps_per_contact"),
        replicas_key=None,
        batch_size_key=None,
        grow_rules=frozenset(),
        sim_rules=frozenset({"box_init", "box_runs"}),
        fit_rules=frozenset({"box_fits", "box_figures"}),
        figure_rule="box_figures",
        batch_glob="runs/*/replica_*.part_*.nc",
    ),
    "column": Knobs(
        fit_key=("relaxation", "n_boot"),
        fit_value=77,
        timestep_key=("integrator", "step_factor"),
        replicas_key=("relaxation", "n_replicas"),
        batch_size_key=("relaxation", "batch_size"),
        grow_rules=frozenset({"column_relaxation"}),
        sim_rules=frozenset({"column_trajectories", "column_relaxation", "column_chaos"}),
        fit_rules=frozenset({"column_fits", "column_figures"}),
        figure_rule="column_figures",
        batch_glob="runs/relaxation/batch_*.nc",
    ),
    "shear": Knobs(
        fit_key=("fits", "moving_average_s"),
        fit_value=0.2,
        timestep_key=("physics", "dt"),
        replicas_key=("ensemble", "n_replicas"),
        batch_size_key=("ensemble", "batch_size"),
        grow_rules=frozenset({"shear_runs"}),
        sim_rules=frozenset({"shear_runs"}),
        fit_rules=frozenset({"shear_fits", "shear_summary", "shear_figures"}),
        figure_rule="shear_figures",
        batch_glob="runs/*/batch_*.nc",
    ),
}


def _get(cfg, key):
    for k in key:
        cfg = cfg[k]
    return cfg


def _set(cfg, key, value):
    for k in key[:-1]:
        cfg = cfg[k]
    cfg[key[-1]] = value


def planned_jobs(workdir: Path, configfile: str, *extra) -> dict[str, int]:
    """Rule -> job count of what ``snakemake -n`` would run."""
    proc = run_snakemake("-n", "--cores", "2", "--configfile", configfile, *extra, cwd=workdir)
    text = proc.stdout
    if "Nothing to be done" in text:
        return {}
    table = text.split("Job stats:", 1)[1]
    jobs = {}
    for line in table.splitlines()[3:]:
        parts = line.split()
        if len(parts) != 2 or not parts[1].isdigit():
            break
        if parts[0] != "total":
            jobs[parts[0]] = int(parts[1])
    return jobs


def write_config(workdir: Path, cfg: dict, name: str) -> str:
    path = workdir / "config" / name
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return f"config/{name}"


# Wall-clock cost of a replica: recorded for benchmarks, the one variable that may differ.
COST_VARIABLES = {"wall_time", "wall_seconds"}


def data_bytes(path: Path) -> dict[str, bytes]:
    """The raw bytes of every data variable but the wall-clock costs (attributes such as
    the creation time are excluded too)."""
    with xr.open_dataset(path) as ds:
        names = [n for n in ds.data_vars if n not in COST_VARIABLES]
        assert names, f"{path} has no data variables"
        return {name: ds[name].values.tobytes() for name in names}


def studies(base):
    return [s for s in base["studies"] if s in KNOBS]


# the movies each study's quick scale writes: (how many, frames in each), from
# config/quick.yaml's movie sections
MOVIES = {"drum": (2, 11), "shear": (1, 11), "box": (2, 9)}


def movie_files(workdir, study):
    return sorted((workdir / "results" / "quick" / study / "movie").glob("*.mp4"))


def test_quick_scale_produced_every_target(quick):
    import imageio.v2 as imageio

    workdir, base = quick
    assert planned_jobs(workdir, "config/scratch.yaml") == {}
    for study in studies(base):
        root = workdir / "results" / "quick" / study
        assert (root / "fits" / "summary.csv").exists()
        assert list((root / "figures").glob("fig*.png"))
        assert list((root / "figures").glob("fig*.pdf"))
        if study in MOVIES:
            n, frames = MOVIES[study]
            movies = movie_files(workdir, study)
            assert len(movies) == n, movies
            for movie in movies:
                assert imageio.get_reader(movie).count_frames() == frames, movie


def test_status_counts_present_and_missing_batches(quick):
    workdir, base = quick
    granpipe = str(Path(SNAKEMAKE).with_name("granpipe"))

    def status():
        proc = subprocess.run(
            [granpipe, "status", "--results", "results", "--configfile", "config/scratch.yaml"],
            cwd=workdir, capture_output=True, text=True, check=True,
        )  # fmt: skip
        return proc.stdout

    text = status()
    for study in studies(base):
        n = len(list((workdir / "results" / "quick" / study).glob(KNOBS[study].batch_glob)))
        found = re.search(rf"{study}: (\d+) run file\(s\) of (\d+) expected, 0 missing", text)
        assert found and found[1] == found[2] and int(found[1]) >= n, text
        assert "quantity" not in text and " = " in text  # fitted numbers are listed
    study = studies(base)[0]
    victim = sorted((workdir / "results" / "quick" / study).glob(KNOBS[study].batch_glob))[0]
    aside = victim.with_name("aside.tmp")
    victim.rename(aside)  # a rename keeps the mtime, so later plans are unchanged
    try:
        assert "1 missing" in status()
    finally:
        aside.rename(victim)


def test_fit_edit_plans_only_fits_and_figures(quick):
    workdir, base = quick
    for study in studies(base):
        knobs = KNOBS[study]
        cfg = copy.deepcopy(base)
        _set(cfg[study], knobs.fit_key, knobs.fit_value)
        assert _get(cfg[study], knobs.fit_key) != _get(base[study], knobs.fit_key)
        jobs = planned_jobs(workdir, write_config(workdir, cfg, "fit_edit.yaml"))
        planned = set(jobs) - {"all"}
        assert planned, f"{study}: editing {knobs.fit_key} planned nothing"
        assert planned <= knobs.fit_rules, f"{study}: fit edit planned {sorted(planned)}"


def test_box_detection_edit_plans_every_ensemble_and_no_simulation(quick):
    """The ensemble stage's config subset (detection, slips, order) reaches Snakemake's
    params trigger: an edit of a detection threshold reruns every point's ensemble and the
    fits and figures after it, and no prepared state or run."""
    workdir, base = quick
    if "box" not in studies(base):
        pytest.skip("the quick scale runs no box")
    cfg = copy.deepcopy(base)
    cfg["box"]["detection"]["roll_significance"] = 2.5
    jobs = planned_jobs(workdir, write_config(workdir, cfg, "detection_edit.yaml"))
    n_points = len(list((workdir / "results" / "quick" / "box" / "ensemble").glob("*.nc")))
    assert n_points and jobs.get("box_ensemble") == n_points, jobs
    assert {"box_fits", "box_figures"} <= set(jobs)
    assert not {"box_init", "box_runs"} & set(jobs), jobs


def test_timestep_edit_plans_simulations_and_downstream(quick):
    workdir, base = quick
    for study in studies(base):
        knobs = KNOBS[study]
        cfg = copy.deepcopy(base)
        _set(cfg[study], knobs.timestep_key, 0.9 * _get(base[study], knobs.timestep_key))
        jobs = planned_jobs(workdir, write_config(workdir, cfg, "dt_edit.yaml"))
        assert knobs.sim_rules <= set(jobs), f"{study}: dt edit planned {sorted(jobs)}"
        assert knobs.fit_rules <= set(jobs)


def test_forcerun_figures_regenerates_from_cached_data_alone(quick):
    workdir, base = quick
    for study in studies(base):
        knobs = KNOBS[study]
        root = workdir / "results" / "quick" / study
        data = {p: p.stat().st_mtime_ns for p in root.rglob("*.nc")}
        figs = {p: p.stat().st_mtime_ns for p in (root / "figures").glob("fig*.png")}
        jobs = planned_jobs(workdir, "config/scratch.yaml", "--forcerun", knobs.figure_rule)
        assert set(jobs) - {"all"} == {knobs.figure_rule}
        run_snakemake(
            "--cores", "2", "--configfile", "config/scratch.yaml",
            "--forcerun", knobs.figure_rule, cwd=workdir,
        )  # fmt: skip
        assert {p: p.stat().st_mtime_ns for p in data} == data, "data files were rewritten"
        assert all(p.stat().st_mtime_ns > t for p, t in figs.items())


def test_growing_the_ensemble_reuses_every_batch(quick):
    workdir, base = quick
    growable = [s for s in studies(base) if KNOBS[s].replicas_key]
    assert growable, "no landed study with a replica count"
    for study in growable:
        knobs = KNOBS[study]
        root = workdir / "results" / "quick" / study
        before = sorted(root.glob(knobs.batch_glob))
        snap = {p: (p.read_bytes(), p.stat().st_mtime_ns) for p in before}
        cfg = copy.deepcopy(base)
        cfg["studies"] = [study]
        n0 = _get(base[study], knobs.replicas_key)
        batch = _get(base[study], knobs.batch_size_key)
        _set(cfg[study], knobs.replicas_key, n0 + batch)
        configfile = write_config(workdir, cfg, "grown.yaml")
        jobs = planned_jobs(workdir, configfile)
        planned_sims = {r: n for r, n in jobs.items() if r in knobs.sim_rules}
        assert planned_sims == dict.fromkeys(knobs.grow_rules, 1), f"{study}: planned {jobs}"
        run_snakemake("--cores", "2", "--configfile", configfile, cwd=workdir, timeout=900)
        after = sorted(root.glob(knobs.batch_glob))
        assert len(after) == len(before) + 1
        for p, (content, mtime) in snap.items():
            assert p.read_bytes() == content and p.stat().st_mtime_ns == mtime


def test_adding_a_drum_period_plans_only_its_point(quick):
    """A second drum period is its own point: only its batches, its ensemble and fits, and
    the summary and figures that gather every point are planned."""
    workdir, base = quick
    if "drum" not in studies(base):
        pytest.skip("the drum study is not part of this scale")
    cfg = copy.deepcopy(base)
    cfg["studies"] = ["drum"]
    period = cfg["drum"]["physics"]["period_s"]
    period = period[0] if isinstance(period, list) else period
    cfg["drum"]["physics"]["period_s"] = [period, period / 2]
    one = copy.deepcopy(base)
    one["studies"] = ["drum"]
    # what the second period adds is the difference of the two plans
    before = planned_jobs(workdir, write_config(workdir, one, "one_period.yaml"))
    jobs = planned_jobs(workdir, write_config(workdir, cfg, "two_periods.yaml"))
    ens = base["drum"]["ensemble"]
    n = -(-ens["n_replicas"] // ens["batch_size"])
    added = {k: jobs.get(k, 0) - before.get(k, 0) for k in set(jobs) | set(before)}
    added = {k: v for k, v in added.items() if v}
    for gathering in ("drum_summary", "drum_figures", "all"):  # they gather every point
        assert jobs.get(gathering) == 1
        added.pop(gathering, None)
    assert added == {"drum_init": n, "drum_runs": n, "drum_ensemble": 1, "drum_fits": 1}, (
        before, jobs,
    )  # fmt: skip


def _shear_jobs_added(quick, edit) -> tuple[dict, dict]:
    """Jobs a shear-only config plans beyond the quick scale's once ``edit`` has changed its
    shear section (the gathering rules planned once each and left out), and the quick
    scale's shear section."""
    workdir, base = quick
    if "shear" not in studies(base):
        pytest.skip("the shear study is not part of this scale")
    one = copy.deepcopy(base)
    one["studies"] = ["shear"]
    two = copy.deepcopy(one)
    edit(two["shear"])
    before = planned_jobs(workdir, write_config(workdir, one, "base.yaml"))
    jobs = planned_jobs(workdir, write_config(workdir, two, "edited.yaml"))
    added = {k: jobs.get(k, 0) - before.get(k, 0) for k in set(jobs) | set(before)}
    added = {k: v for k, v in added.items() if v}
    for gathering in ("shear_summary", "shear_figures", "all"):
        assert jobs.get(gathering) == 1, (before, jobs)
        added.pop(gathering, None)
    return added, base["shear"]


def test_adding_a_packing_fraction_plans_only_its_point(quick):
    """A second φ of the shear cell is its own point: only its batches and fits, and the
    summary and figures that gather every point, are planned."""

    def edit(shear):
        phi = shear["physics"]["phi"]
        shear["physics"]["phi"] = [*(phi if isinstance(phi, list) else [phi]), 0.7]

    added, shear = _shear_jobs_added(quick, edit)
    ens = shear["ensemble"]
    n = -(-ens["n_replicas"] // ens["batch_size"])
    assert added == {"shear_runs": n, "shear_fits": 1}


def test_adding_a_variant_plans_only_its_points_with_its_own_replicas(quick):
    """A variant of the shear cell (its own φ grid and replica count) adds only its
    batches and fits beside the base section's, which stay done."""

    def edit(shear):
        shear["variants"] = {"ratio_1_4": {"physics": {"d_large": 1.4, "phi": [0.7, 0.75]},
                                           "ensemble": {"n_replicas": 3}}}  # fmt: skip

    added, shear = _shear_jobs_added(quick, edit)
    n = -(-3 // shear["ensemble"]["batch_size"])
    assert added == {"shear_runs": 2 * n, "shear_fits": 2}


def test_adding_a_wall_friction_plans_only_its_points(quick):
    """A second side-wall friction is its own set of initial states and points: only their
    jobs, and the fits and figures that gather every point, are planned."""
    workdir, base = quick
    if "box" not in studies(base):
        pytest.skip("the box study is not part of this scale")
    one = copy.deepcopy(base)
    one["studies"] = ["box"]
    two = copy.deepcopy(one)
    grid = two["box"]["grid"]
    grid["mu_side_walls"] = [*grid["mu_side_walls"], 0.25]
    before = planned_jobs(workdir, write_config(workdir, one, "one_wall.yaml"))
    jobs = planned_jobs(workdir, write_config(workdir, two, "two_walls.yaml"))
    states = len(grid["N_l"]) * len(grid["inits"]) * grid["replicas"]
    points = len(grid["N_l"]) * len(grid["inits"]) * len(grid["Gamma"])
    parts = -(-base["box"]["protocol"]["measured_periods"] // base["box"]["protocol"][
        "periods_per_part"])  # fmt: skip
    added = {k: jobs.get(k, 0) - before.get(k, 0) for k in set(jobs) | set(before)}
    added = {k: v for k, v in added.items() if v}
    for gathering in ("box_fits", "box_figures", "all"):
        assert jobs.get(gathering) == 1
        added.pop(gathering, None)
    assert added == {
        "box_init": states, "box_runs": points * grid["replicas"] * parts,
        "box_ensemble": points,
    }, (before, jobs)  # fmt: skip


def test_sigkill_mid_write_leaves_nothing_and_rerun_is_identical(quick):
    workdir, base = quick
    study = studies(base)[0]
    knobs = KNOBS[study]
    root = workdir / "results" / "quick" / study
    target = sorted(root.glob(knobs.batch_glob))[0]
    reference = data_bytes(target)
    target.unlink()
    rel = str(target.relative_to(workdir))
    proc = subprocess.Popen(
        [SNAKEMAKE, "--cores", "1", "--configfile", "config/scratch.yaml", "--", rel],
        cwd=workdir,
        # The job pauses between writing its temporary file and renaming it.
        env={**snakemake_env(), "GRANPIPE_FAULT_DELAY_RENAME": "30"},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    # Wait for the job's temporary file: the write has begun. Then kill everything.
    deadline = time.monotonic() + 600
    tmp_seen = False
    while time.monotonic() < deadline and proc.poll() is None:
        if list(target.parent.glob(f".{target.name}.*.tmp")):
            tmp_seen = True
            break
        time.sleep(0.005)
    assert tmp_seen, "the job ended before its temporary file appeared"
    time.sleep(1.0)  # let the write get under way (the hook holds it before the rename)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    assert not target.exists(), "a killed job left a file under its final name"
    # The rerun (after Snakemake's lock of the killed run is cleared) recomputes it.
    run_snakemake("--unlock", "--configfile", "config/scratch.yaml", cwd=workdir)
    run_snakemake(
        "--cores", "2", "--configfile", "config/scratch.yaml", "--rerun-incomplete", rel,
        cwd=workdir, timeout=900,
    )  # fmt: skip
    assert data_bytes(target) == reference


def test_killed_forcerun_resumes_with_a_plain_rerun(quick):
    """A --forcerun of the drum runs removes their files; SIGKILL it while the first job
    writes, and after --unlock (Snakemake's own lock survives a SIGKILL) a plain rerun
    recomputes every missing run file, byte-identical, and leaves no temporary file."""
    workdir, base = quick
    if "drum" not in studies(base):
        pytest.skip("the drum study is not part of this scale")
    root = workdir / "results" / "quick" / "drum"
    runs = [root / f for f in expected_run_files("drum", base["drum"])]
    reference = {p: data_bytes(p) for p in runs}
    # the run files as targets: the DAG holds only their jobs (every write here waits 30 s
    # before its rename)
    proc = subprocess.Popen(
        [SNAKEMAKE, "--cores", "1", "--configfile", "config/scratch.yaml",
         "--forcerun", "drum_runs", "--", *(str(p.relative_to(workdir)) for p in runs)],
        cwd=workdir, env={**snakemake_env(), "GRANPIPE_FAULT_DELAY_RENAME": "30"},
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )  # fmt: skip
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and proc.poll() is None:
        if any(root.rglob("runs/*/.batch_*.tmp")):
            break
        time.sleep(0.01)
    assert any(root.rglob("runs/*/.batch_*.tmp")), "no run file was being written"
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    missing = [p for p in runs if not p.exists()]
    assert missing, "the forced run removed no file before it was killed"
    run_snakemake("--unlock", "--configfile", "config/scratch.yaml", cwd=workdir)
    run_snakemake("--cores", "2", "--configfile", "config/scratch.yaml", cwd=workdir,
                  timeout=900)  # fmt: skip
    for p, data in reference.items():
        assert data_bytes(p) == data, p
    assert not list(root.rglob(".*.tmp")), "a stale temporary file was left behind"
    assert planned_jobs(workdir, "config/scratch.yaml") == {}


def test_second_workflow_on_same_directory_is_refused(quick):
    """While one run recomputes a batch, a second run on the same directory is refused
    by Snakemake's lock; the forced recomputation reproduces the batch's data bytes."""
    workdir, base = quick
    study = studies(base)[0]
    knobs = KNOBS[study]
    target = sorted((workdir / "results" / "quick" / study).glob(knobs.batch_glob))[-1]
    reference = data_bytes(target)
    rel = str(target.relative_to(workdir))
    sim_rule = sorted(knobs.sim_rules)[-1]
    first = subprocess.Popen(
        [SNAKEMAKE, "--cores", "1", "--configfile", "config/scratch.yaml",
         "--forcerun", sim_rule, "--allowed-rules", sim_rule, "--", rel],
        cwd=workdir, env=snakemake_env(), stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True,
    )  # fmt: skip
    locks = workdir / ".snakemake" / "locks"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not list(locks.glob("*.lock")):
        time.sleep(0.05)
    assert list(locks.glob("*.lock")), "the first run never took its lock"
    # A second run that would write the same batch: its output is locked by the first.
    second = run_snakemake(
        "--cores", "1", "--configfile", "config/scratch.yaml", "--forcerun", sim_rule,
        "--allowed-rules", sim_rule, "--", rel, cwd=workdir, check=False,
    )  # fmt: skip
    out, _ = first.communicate(timeout=900)
    assert second.returncode != 0
    assert "LockException" in second.stdout + second.stderr or "cannot be locked" in (
        second.stdout + second.stderr
    )
    assert first.returncode == 0, out
    assert data_bytes(target) == reference


def test_report_gathers_every_figure_and_summary(quick):
    workdir, base = quick
    run_snakemake(
        "--configfile", "config/scratch.yaml", "--report", "report.zip", cwd=workdir, timeout=600
    )
    names = zipfile.ZipFile(workdir / "report.zip").namelist()
    for study in studies(base):
        figures = (workdir / "results" / "quick" / study / "figures").glob("fig*.png")
        for fig in [*figures, *movie_files(workdir, study)]:
            assert any(n.endswith(fig.name) for n in names), f"{fig.name} missing from report"
        assert any(n.endswith("summary.csv") for n in names)


def test_blow_up_names_replica_and_keep_going_finishes_the_rest(quick):
    """A timestep far past stability blows up every replica of one study: its jobs fail
    naming study, point, replica, seed and step; --keep-going still runs the other
    studies' pending jobs (their figures, forced)."""
    workdir, base = quick
    names = studies(base)
    if len(names) < 2:
        pytest.fail("needs two landed studies to show the rest of the workflow continuing")
    broken, other = names[0], names[1]
    cfg = copy.deepcopy(base)
    key = KNOBS[broken].timestep_key
    _set(cfg[broken], key, 40.0 * _get(base[broken], key))
    figs = workdir / "results" / "quick" / other / "figures"
    before = {p: p.stat().st_mtime_ns for p in figs.glob("fig*.png")}
    proc = run_snakemake(
        "--cores", "2", "--configfile", write_config(workdir, cfg, "blowup.yaml"),
        "--keep-going", "--forcerun", KNOBS[other].figure_rule,
        cwd=workdir, check=False, timeout=900,
    )  # fmt: skip
    assert proc.returncode != 0
    logs = "\n".join(
        p.read_text() for p in (workdir / "results" / "quick" / "logs" / broken).rglob("*.log")
    )
    for word in (f"study={broken}", "point=", "replica=", "seed=", "step="):
        assert word in logs, f"blow-up message lacks {word!r}:\n{logs[-2000:]}"
    assert all(p.stat().st_mtime_ns > t for p, t in before.items()), "the rest did not run"
