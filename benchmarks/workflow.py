"""Whole-workflow benchmark: wall time of a scale per study, paper scale projected.

Usage::

    python benchmarks/workflow.py                     # read the last run's job times
    python benchmarks/workflow.py --run               # run the default scale first, timed
    python benchmarks/workflow.py --scale config/quick.yaml --run

With ``--run`` each study of the scale runs on its own (``--config studies=[s]``), so its
wall time on ``--cores`` cores is measured alone. Job times come from Snakemake's own
records (``.snakemake/metadata``: start and end of every job), so the figures also work
for a run made earlier. The paper scale is projected in core-hours from the measured
simulation cost per unit of work (drum: a replica; box: a particle-period; column: a
simulation job), times the paper config's amount of that work.

The last line is one JSON object with the figures, for logs.
"""

from __future__ import annotations

import argparse
import base64
import json
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "src"))

from granpipe.config import load  # noqa: E402

SIM_RULES = {
    "drum": {"drum_init", "drum_runs"},
    "box": {"box_init", "box_runs"},
    "column": None,  # every column rule whose name does not end in _fits/_figures/_ensemble
}


def job_records(workdir: Path, results_prefix: str) -> list[dict]:
    """One record per job output under ``results_prefix`` (rule, start, end, threads)."""
    records = []
    meta = workdir / ".snakemake" / "metadata"
    for f in meta.glob("*"):
        try:
            path = base64.urlsafe_b64decode(f.name.encode()).decode()
        except (ValueError, UnicodeDecodeError):
            continue
        if not path.startswith(results_prefix):
            continue
        rec = json.loads(f.read_text())
        if rec.get("starttime") and rec.get("endtime"):
            records.append({"path": path, **rec})
    return records


def is_sim(study: str, rule: str) -> bool:
    rules = SIM_RULES.get(study)
    if rules is not None:
        return rule in rules
    return not rule.endswith(("_fits", "_figures", "_ensemble"))


def work(study: str, section: dict) -> float:
    """Amount of simulation work a config section asks for, in the study's unit."""
    if study == "drum":
        return float(section["ensemble"]["n_replicas"])
    if study == "box":
        grid, proto = section["grid"], section["protocol"]
        periods = proto["transient_periods"] + proto["measured_periods"]
        n_points = len(grid["Gamma"]) * len(grid["inits"]) * grid["replicas"]
        lx = section["physics"]["Lx"]
        return sum(n_l * lx * periods * n_points for n_l in grid["N_l"])
    return float("nan")


UNITS = {"drum": "replica", "box": "particle-period", "column": "job"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scale", default="config/config.yaml", help="config file of the scale")
    ap.add_argument("--paper", default="config/paper.yaml", help="config to project to")
    ap.add_argument("--run", action="store_true", help="run each study first, timed")
    ap.add_argument("--cores", type=int, default=2)
    args = ap.parse_args(argv)

    cfg = load(REPO / args.scale)
    paper = load(REPO / args.paper)
    prefix = f"{cfg['results']}/{cfg['scale']}/"
    wall = {}
    if args.run:
        snakemake = str(Path(sys.executable).with_name("snakemake"))
        for study in cfg["studies"]:
            t0 = time.perf_counter()
            subprocess.run(
                [snakemake, "--cores", str(args.cores), "--configfile", args.scale,
                 "--config", f"studies=[{study}]"],
                cwd=REPO, check=True,
            )  # fmt: skip
            wall[study] = time.perf_counter() - t0

    by_study = defaultdict(list)
    for rec in job_records(REPO, prefix):
        study = rec["path"][len(prefix) :].split("/", 1)[0]
        by_study[study].append(rec)

    figures = {}
    print(f"scale {cfg['scale']} ({args.scale}), {args.cores} cores")
    for study in cfg["studies"]:
        recs = by_study.get(study, [])
        if not recs:
            print(f"  {study}: no job records under {prefix}{study}/ (run it, or pass --run)")
            continue
        # A job may have several outputs: count each job once (rule + start time).
        jobs = {(r["rule"], r["starttime"]): r for r in recs}.values()
        span = max(r["endtime"] for r in jobs) - min(r["starttime"] for r in jobs)
        sim = [r for r in jobs if is_sim(study, r["rule"])]
        sim_core_s = sum(r["endtime"] - r["starttime"] for r in sim)
        total_core_s = sum(r["endtime"] - r["starttime"] for r in jobs)
        w_scale = work(study, cfg[study]) if study != "column" else len(sim)
        per_unit = sim_core_s / w_scale if w_scale else float("nan")
        line = (
            f"  {study}: wall {wall.get(study, span) / 60:.1f} min"
            f"{' (measured)' if study in wall else ' (first job start to last job end)'}, "
            f"{len(jobs)} jobs, {total_core_s / 60:.1f} job-minutes "
            f"({sim_core_s / 60:.1f} in simulation), "
            f"{per_unit:.3g} core-s per {UNITS.get(study, 'unit')}"
        )
        fig = {"wall_s": round(wall.get(study, span), 1), "core_s_per_unit": per_unit}
        if study in paper.get("studies", []) and study != "column":
            w_paper = work(study, paper[study])
            core_h = per_unit * w_paper / 3600.0
            line += f"; paper scale: {w_paper:.4g} {UNITS[study]}s, ~{core_h:.3g} core-hours"
            fig["paper_core_hours"] = round(core_h, 1)
        print(line)
        figures[study] = fig
    print(json.dumps(figures))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
