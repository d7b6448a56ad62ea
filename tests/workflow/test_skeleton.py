"""The workflow plans at every scale, passes --lint, and refuses a bad config up front."""

import pytest
import yaml

from .conftest import run_snakemake

SCALES = ["config/config.yaml", "config/quick.yaml", "config/paper.yaml"]


@pytest.mark.parametrize("configfile", SCALES)
def test_dry_run_plans_at_every_scale(configfile, scratch_workflow):
    # A scratch copy has no results yet: every study's stages are planned.
    proc = run_snakemake("-n", "--cores", "2", "--configfile", configfile, cwd=scratch_workflow)
    text = proc.stdout + proc.stderr
    assert "dry-run" in text
    cfg = yaml.safe_load((scratch_workflow / configfile).read_text())
    for study in cfg["studies"]:
        assert f"{study}_figures" in text, f"{configfile}: no {study}_figures job planned"


@pytest.mark.parametrize("configfile", SCALES)
def test_lint_is_clean_at_every_scale(configfile):
    proc = run_snakemake("--lint", "--configfile", configfile, check=False)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    assert "Congratulations, your workflow is in a good condition!" in text


def test_bad_config_stops_before_any_job_with_key_named(scratch_workflow):
    cfg = yaml.safe_load((scratch_workflow / "config/quick.yaml").read_text())
    study = cfg["studies"][0]
    cfg[study]["not_a_key"] = 1
    cfg["scale"] = "broken"
    (scratch_workflow / "config/broken.yaml").write_text(yaml.safe_dump(cfg))
    proc = run_snakemake(
        "--cores", "1", "--configfile", "config/broken.yaml", cwd=scratch_workflow, check=False
    )
    assert proc.returncode != 0
    text = proc.stdout + proc.stderr
    assert f"'{study}.not_a_key'" in text
    # Nothing ran: no results folder, no job output.
    assert not (scratch_workflow / "results").exists()
