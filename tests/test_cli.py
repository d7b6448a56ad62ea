import subprocess
import sys
from pathlib import Path

import granpipe
from granpipe.cli import StudyGroup, cli

GRANPIPE = str(Path(sys.executable).with_name("granpipe"))


def run(*args):
    return subprocess.run(
        [GRANPIPE, *args], capture_output=True, text=True, stdin=subprocess.DEVNULL
    )


def test_version_matches_package():
    proc = run("--version")
    assert proc.returncode == 0
    assert granpipe.__version__ in proc.stdout


def test_every_study_stage_has_help():
    group = cli
    assert isinstance(group, StudyGroup)
    studies = [s for s in group.list_commands(None) if s in ("drum", "column", "box")]
    for study in studies:
        sub = group.get_command(None, study)
        for stage in sub.list_commands(None):
            proc = run(study, stage, "--help")
            assert proc.returncode == 0, proc.stderr
            assert "Usage:" in proc.stdout


def test_check_config_names_the_bad_key(tmp_path, repo):
    bad = tmp_path / "bad.yaml"
    bad.write_text((repo / "config/quick.yaml").read_text() + "\nnot_a_key: 3\n")
    proc = run("check-config", str(bad))
    assert proc.returncode == 1
    assert "'not_a_key'" in proc.stderr
    good = run("check-config", str(repo / "config/quick.yaml"))
    assert good.returncode == 0 and "scale: quick" in good.stdout
