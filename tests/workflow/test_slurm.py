"""The workflow runs through Snakemake's SLURM executor on a real single-node SLURM cluster.

tools/slurm/install.sh (Debian packages, if missing) and tools/slurm/start.sh bring up a
private cluster (own munge, slurmctld, slurmd; free ports; state under a temp dir); the
workflow then runs with ``--profile workflow/profiles/slurm`` under ``timeout``; stop.sh
tears the cluster down. Needs root (slurmd) and, when SLURM is not installed yet, apt-get:
otherwise the tests skip, saying which. CI runs as root, so there they run for real.

What runs is chosen by ``slurm_target`` below: for now a tiny scratch workflow written into
tmp_path; to run the real workflow's quick scale make it return ``quick_scale_target(...)``.
"""

from __future__ import annotations

import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from .conftest import copy_workflow

pytestmark = pytest.mark.slurm

REPO = Path(__file__).resolve().parents[2]
TOOLS = REPO / "tools" / "slurm"
PROFILE = REPO / "workflow" / "profiles" / "slurm"
# Default bound on one workflow run through SLURM [s]; `timeout` enforces it on snakemake.
RUN_TIMEOUT = 300

# snakemake's report of a submission, and slurmctld's (SlurmctldDebug=info).
SUBMITTED = re.compile(r"has been submitted with SLURM jobid (\d+)")
SUBMITTED_CTLD = re.compile(r"_slurm_rpc_submit_batch_job: JobId=(\d+) ")


@dataclass
class SlurmCluster:
    """A running test cluster: its directory and the environment that reaches it."""

    directory: Path
    env: dict[str, str]

    @property
    def ctld_log(self) -> str:
        return (self.directory / "log" / "slurmctld.log").read_text()

    def logs_tail(self, n: int = 30) -> str:
        parts = []
        for name in ("slurmctld.log", "slurmd.log"):
            path = self.directory / "log" / name
            if path.exists():
                lines = path.read_text().splitlines()[-n:]
                parts.append(f"--- {name} ---\n" + "\n".join(lines))
        return "\n".join(parts)


@dataclass
class SlurmTarget:
    """What to run: a workdir holding a Snakefile, optional configfile and targets."""

    workdir: Path
    expected_outputs: list[Path]
    configfile: Path | None = None
    targets: list[str] = field(default_factory=list)
    extra_args: list[str] = field(default_factory=list)
    # Largest acceptable number of sbatch submissions (grouping must keep it small).
    max_submissions: int | None = None
    # Bound on the whole run [s], enforced with `timeout`.
    timeout: int = RUN_TIMEOUT


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _run_script(name: str, env: dict[str, str], timeout: float) -> subprocess.CompletedProcess:
    return subprocess.run(
        ["bash", str(TOOLS / name)],
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
        stdin=subprocess.DEVNULL,
    )


@pytest.fixture(scope="module")
def slurm_cluster():
    """Install SLURM if needed, start a private cluster, yield it, stop it."""
    if os.geteuid() != 0:
        pytest.skip("real-SLURM test needs root (slurmd, munged); CI runs it as root")
    if shutil.which("slurmctld") is None and shutil.which("apt-get") is None:
        pytest.skip("SLURM is not installed and apt-get is unavailable to install it")

    env = {k: v for k, v in os.environ.items() if not k.startswith(("SLURM_", "SBATCH_"))}
    proc = _run_script("install.sh", env, timeout=900)
    assert proc.returncode == 0, f"install.sh failed:\n{proc.stdout}\n{proc.stderr}"

    # Short path (the munge socket path must stay < 108 bytes), free ports (another cluster
    # may be up on 6817/6818).
    directory = Path(tempfile.mkdtemp(prefix="granpipe-slurm-", dir="/tmp"))
    ctld_port = _free_port()
    slurmd_port = _free_port()
    while slurmd_port == ctld_port:
        slurmd_port = _free_port()
    env.update(
        GRANPIPE_SLURM_DIR=str(directory),
        GRANPIPE_SLURM_CTLD_PORT=str(ctld_port),
        GRANPIPE_SLURMD_PORT=str(slurmd_port),
    )
    try:
        proc = _run_script("start.sh", env, timeout=120)
        assert proc.returncode == 0, f"start.sh failed:\n{proc.stdout}\n{proc.stderr}"
        # Clients and jobs reach this cluster through SLURM_CONF and the wrappers in bin/;
        # jobs find `python`/`granpipe` of this interpreter's environment on PATH.
        env["SLURM_CONF"] = str(directory / "slurm.conf")
        env["PATH"] = os.pathsep.join(
            [str(directory / "bin"), str(Path(sys.executable).parent), env.get("PATH", "")]
        )
        env["MPLBACKEND"] = "Agg"
        yield SlurmCluster(directory=directory, env=env)
    finally:
        proc = _run_script("stop.sh", env, timeout=120)
        if proc.returncode != 0:  # pragma: no cover - reported, not fatal for the tests
            print(f"stop.sh failed:\n{proc.stdout}\n{proc.stderr}", file=sys.stderr)
        shutil.rmtree(directory, ignore_errors=True)


def run_through_slurm(cluster: SlurmCluster, target: SlurmTarget) -> subprocess.CompletedProcess:
    """Run ``target`` with the SLURM profile, bounded by ``target.timeout`` [s]."""
    timeout = target.timeout
    cmd = [sys.executable, "-m", "snakemake", "--profile", str(PROFILE)]
    if target.configfile is not None:
        cmd += ["--configfile", str(target.configfile)]
    cmd += [*target.extra_args, *target.targets]
    # SIGTERM first (snakemake then scancels its jobs), SIGKILL 20 s later.
    return subprocess.run(
        ["timeout", "-k", "20", str(timeout), *cmd],
        cwd=target.workdir,
        env=cluster.env,
        capture_output=True,
        text=True,
        timeout=timeout + 60,
        stdin=subprocess.DEVNULL,
    )


SCRATCH_SNAKEFILE = """\
N_RUNS = 4

rule all:
    input: "summary.txt"

# Many small independent jobs, all in one SLURM job with `--group-components runs=50`.
rule runs:
    output: "runs/{i}.txt"
    log: "logs/runs/{i}.log"
    group: "runs"
    threads: 1
    resources: runtime=2, mem_mb=200
    shell:
        "(echo slurm_job_id=$SLURM_JOB_ID; echo python=$(command -v python);"
        " echo granpipe=$(command -v granpipe)) > {output} 2> {log}"

rule ensemble:
    input: expand("runs/{i}.txt", i=range(N_RUNS))
    output: "ensemble.txt"
    log: "logs/ensemble.log"
    group: "post"
    shell: "cat {input} > {output} 2> {log}"

rule summary:
    input: "ensemble.txt"
    output: "summary.txt"
    log: "logs/summary.log"
    group: "post"
    shell: "(grep -c slurm_job_id= {input}; echo slurm_job_id=$SLURM_JOB_ID) > {output} 2> {log}"
"""


def scratch_target(tmp_path: Path) -> SlurmTarget:
    """Three rules, four grouped `runs` jobs: two sbatch submissions when grouping works."""
    (tmp_path / "Snakefile").write_text(SCRATCH_SNAKEFILE)
    outputs = [tmp_path / "runs" / f"{i}.txt" for i in range(4)]
    outputs += [tmp_path / "ensemble.txt", tmp_path / "summary.txt"]
    return SlurmTarget(
        workdir=tmp_path,
        expected_outputs=outputs,
        # As documented in the profile: several components (here: runs) per SLURM job.
        extra_args=["--group-components", "runs=50"],
        max_submissions=2,
    )


def quick_scale_target(tmp_path: Path) -> SlurmTarget:
    """The real workflow at the quick scale, on a scratch copy of the repository's workflow:
    every landed study's summary table and figures must come back through SLURM."""
    import yaml

    workdir = copy_workflow(tmp_path)
    cfg = yaml.safe_load((workdir / "config" / "quick.yaml").read_text())
    landed = [
        s for s in cfg["studies"]
        if "register_targets" in (workdir / "workflow" / "rules" / f"{s}.smk").read_text()
    ]  # fmt: skip
    root = workdir / "results" / "quick"
    outputs = [root / s / "fits" / "summary.csv" for s in landed]
    outputs += [root / s / "figures" for s in landed]
    return SlurmTarget(
        workdir=workdir,
        configfile=workdir / "config" / "quick.yaml",
        expected_outputs=outputs,
        timeout=1200,
    )


def slurm_target(tmp_path: Path) -> SlurmTarget:
    """What test_workflow_runs_through_slurm runs: the quick scale of the real workflow."""
    return quick_scale_target(tmp_path)


def test_cluster_accepts_and_runs_a_batch_job(slurm_cluster, tmp_path):
    """sbatch -> slurmd -> srun step works, and start.sh is idempotent."""
    again = _run_script("start.sh", slurm_cluster.env, timeout=60)
    assert again.returncode == 0, again.stderr
    assert "already running" in again.stdout

    out = tmp_path / "job.out"
    proc = subprocess.run(
        ["timeout", "30", "sbatch", "--parsable", "-o", str(out),
         "--wrap", "srun -n1 sh -c 'echo step=$SLURM_STEP_ID job=$SLURM_JOB_ID'"],
        env=slurm_cluster.env, capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr + slurm_cluster.logs_tail()
    job_id = proc.stdout.strip().split(";")[0]
    # `sbatch --wait` polls slowly; squeue keeps a finished job for MinJobAge (600 s).
    deadline = time.monotonic() + 60
    state = ""
    while time.monotonic() < deadline:
        state = subprocess.run(
            ["squeue", "-h", "--states=all", "-j", job_id, "-o", "%T"],
            env=slurm_cluster.env, capture_output=True, text=True, timeout=30,
        ).stdout.strip()  # fmt: skip
        if state in ("COMPLETED", "FAILED", "CANCELLED", "TIMEOUT", "NODE_FAIL", "OUT_OF_MEMORY"):
            break
        time.sleep(0.2)
    assert state == "COMPLETED", f"job {job_id}: {state!r}\n" + slurm_cluster.logs_tail()
    assert out.read_text().split() == ["step=0", f"job={job_id}"]


def test_workflow_runs_through_slurm(slurm_cluster, tmp_path):
    target = slurm_target(tmp_path)
    ctld_before = len(slurm_cluster.ctld_log)
    proc = run_through_slurm(slurm_cluster, target)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, (
        f"snakemake through SLURM failed ({proc.returncode}; 124 = timeout):\n{text[-6000:]}\n"
        + slurm_cluster.logs_tail()
    )
    missing = [p for p in target.expected_outputs if not p.exists()]
    assert not missing, f"outputs missing: {missing}"

    # Jobs went through sbatch (no sacct needed): the controller logged each submission of
    # this run and its exit status 0, and these are the job ids snakemake reported.
    ctld = slurm_cluster.ctld_log[ctld_before:]
    job_ids = SUBMITTED_CTLD.findall(ctld)
    assert job_ids, f"slurmctld saw no submission:\n{ctld[-3000:]}"
    assert set(SUBMITTED.findall(text)) <= set(job_ids), text[-3000:]
    for job_id in job_ids:
        assert f"_job_complete: JobId={job_id} WEXITSTATUS 0" in ctld, ctld[-3000:]
    if target.max_submissions is not None:
        assert len(job_ids) <= target.max_submissions, f"grouping failed: {len(job_ids)} jobs"

    # Scratch workflow: every rule ran inside one of those allocations, with the
    # submitting environment (this interpreter's python and granpipe on PATH).
    runs = sorted(target.workdir.glob("runs/*.txt"))
    for path in runs:
        fields = dict(line.split("=", 1) for line in path.read_text().splitlines())
        assert fields["slurm_job_id"] in job_ids, path
        assert Path(fields["python"]).parent == Path(sys.executable).parent, fields
        assert Path(fields["granpipe"]).parent == Path(sys.executable).parent, fields
    if runs:
        # The grouped runs share one allocation; the post group gets another.
        assert len({p.read_text().splitlines()[0] for p in runs}) == 1
        summary = (target.workdir / "summary.txt").read_text().split()
        assert summary[0] == str(len(runs))
        assert summary[1].split("=")[1] in job_ids
