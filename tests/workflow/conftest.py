"""Helpers to run Snakemake on the repository or on a scratch copy of the workflow."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))


def snakemake_env() -> dict[str, str]:
    """Environment for Snakemake runs: jobs call the `granpipe` console script, so this
    interpreter's bin folder comes first on PATH."""
    bindir = str(Path(sys.executable).parent)
    return {**os.environ, "MPLBACKEND": "Agg", "PATH": bindir + os.pathsep + os.environ["PATH"]}


def run_snakemake(*args, cwd=REPO, timeout=600, check=True):
    """Run snakemake with ``args`` in ``cwd``; return the CompletedProcess (text)."""
    env = snakemake_env()
    proc = subprocess.run(
        [SNAKEMAKE, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=env,
        stdin=subprocess.DEVNULL,
    )
    if check and proc.returncode != 0:
        raise AssertionError(
            f"snakemake {' '.join(args)} failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}"
        )
    return proc


def copy_workflow(dest: Path) -> Path:
    """A scratch copy of the workflow (Snakefile, workflow/, config/) in ``dest``."""
    shutil.copy2(REPO / "Snakefile", dest / "Snakefile")
    shutil.copytree(REPO / "workflow", dest / "workflow")
    shutil.copytree(REPO / "config", dest / "config")
    return dest


@pytest.fixture
def scratch_workflow(tmp_path):
    return copy_workflow(tmp_path)
