"""Helpers to run Snakemake on the repository or on a scratch copy of the workflow, and the
quick scale run once per session, of which every test that needs it gets its own copy."""

import copy
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
SNAKEMAKE = str(Path(sys.executable).with_name("snakemake"))


def snakemake_env() -> dict[str, str]:
    """Environment for Snakemake runs: jobs call the `granpipe` console script, so this
    interpreter's bin folder comes first on PATH."""
    bindir = str(Path(sys.executable).parent)
    return {**os.environ, "MPLBACKEND": "Agg", "PATH": bindir + os.pathsep + os.environ["PATH"]}


def run_snakemake(*args, cwd=REPO, timeout=600, check=True, env=None, umask=None):
    """Run snakemake with ``args`` in ``cwd`` (in ``env``, default :func:`snakemake_env`;
    under ``umask`` if given); return the CompletedProcess (text)."""
    proc = subprocess.run(
        [SNAKEMAKE, *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=timeout,
        env=snakemake_env() if env is None else env,
        stdin=subprocess.DEVNULL,
        preexec_fn=None if umask is None else (lambda: os.umask(umask)),
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


@pytest.fixture(scope="session")
def pristine_quick(tmp_path_factory):
    """The quick scale run to completion once per session, under umask 022, on a scratch
    copy of the workflow (``config/scratch.yaml``). Tests never change it: they take
    :func:`quick`, a copy of their own."""
    workdir = copy_workflow(tmp_path_factory.mktemp("pristine"))
    base = yaml.safe_load((workdir / "config/quick.yaml").read_text())
    (workdir / "config/scratch.yaml").write_text(yaml.safe_dump(base, sort_keys=False))
    run_snakemake(
        "--cores", "2", "--configfile", "config/scratch.yaml", cwd=workdir, timeout=1500,
        umask=0o022,
    )  # fmt: skip
    return workdir, base


@pytest.fixture
def quick(pristine_quick, tmp_path):
    """This test's own copy of the finished quick scale (results, Snakemake's metadata and
    modification times included: nothing is planned in it), and its config."""
    source, base = pristine_quick
    workdir = tmp_path / "quick"
    shutil.copytree(source, workdir, symlinks=True)
    return workdir, copy.deepcopy(base)
