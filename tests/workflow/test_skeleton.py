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


def test_no_wildcard_value_holds_a_comma():
    """A cluster job names its jobs to Snakemake as ``rule:key=value,key=value`` (the
    --target-jobs option), which is split at commas: a wildcard whose value may hold one
    breaks every job of its rule on SLURM. Each wildcard of the workflow's rules is
    constrained, and no constraint admits a comma (the drum's γ_t points excepted: they are
    documented to run locally)."""
    import re
    from pathlib import Path

    from snakemake.api import SnakemakeApi
    from snakemake.settings.types import ConfigSettings, ResourceSettings

    repo = Path(__file__).resolve().parents[2]
    with SnakemakeApi() as api:
        workflow = api.workflow(
            resource_settings=ResourceSettings(),
            config_settings=ConfigSettings(configfiles=[repo / "config/quick.yaml"]),
            snakefile=repo / "Snakefile",
            workdir=repo,
        )._workflow
        rules = [r for r in workflow.rules if r.wildcard_names]
    assert any(r.name == "box_runs" for r in rules)
    for rule in rules:
        for name in rule.wildcard_names:
            pattern = rule.wildcard_constraints.get(name) or workflow.wildcard_constraints.get(name)
            assert pattern is not None, f"rule {rule.name}: wildcard {name} is not constrained"
            if name == "drum_friction":
                pattern = pattern.replace(",gamma_t=", "")
            assert not re.fullmatch(f"(?:{pattern})", "a,b") and "," not in pattern, (
                f"rule {rule.name}: wildcard {name} admits a comma ({pattern})"
            )
