import json
import subprocess
import sys
from pathlib import Path

import pytest

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
    """Every study of the registry (``granpipe.config.STUDIES``) and each of its stages."""
    from granpipe.config import STUDIES

    group = cli
    assert isinstance(group, StudyGroup)
    studies = [s for s in group.list_commands(None) if s in STUDIES]
    assert studies and set(studies) == set(STUDIES), studies
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


def _misuses(tmp_path, repo):
    """(argv, the argument the error must name): the misuses of the issue's list."""
    from granpipe.box import layout
    from tests.box.conftest import SECTION

    junk = tmp_path / "junk.nc"
    junk.write_text("not netCDF")
    out = str(tmp_path / "out.nc")
    box_runs = json.dumps(layout.runs_params(SECTION, 1, layout.Walls(0.6)))
    relax = {"physics": {"N": 20, "m": 0.001, "r": 0.005, "g": 9.81, "stiffness_factor": 50.0,
                         "e": 0.09, "a": 0.01, "tap_duration": 0.05, "T": 1.0},
             "n_taps": -1, "batch_size": 2, "perturbation": 1.0, "step_factor": 0.1}  # fmt: skip
    drum = ["drum", "init", "--params", "{}", "--out", out]
    box = ["box", "runs", "--params", box_runs, "--N-l", "5", "--init", "crystal",
           "--init-file", str(junk), "--out", out]  # fmt: skip
    return [
        (["check-config", "/bin/ls"], "/bin/ls is not a text"),
        (["check-config", str(tmp_path)], "is a directory"),
        (["status", "--results", str(repo / "README.md")], "'--results'"),
        (["drum", "runs", "--params", "{}", "--batch", "0", "--init", str(junk), "--out", out],
         "cannot read " + str(junk)),
        ([*drum, "--batch", "-1"], "'--batch'"),
        (["drum", "replica", "--seed", str(10**23), "--out", out, "--tiny"], "'--seed'"),
        ([*box, "--Gamma", "1.6", "--part", "1"], "--previous"),
        (["column", "relaxation", "--params", json.dumps(relax), "--batch", "0", "--out", out],
         "'n_taps' = -1"),
        ([*drum, "--batch", "0", "--threads", "0"], "'--threads'"),
        ([*drum, "--batch", "0", "--threads", "-3"], "'--threads'"),
        (["column", "relaxation", "--params", json.dumps({**relax, "n_taps": 10**12}),
          "--batch", "0", "--out", out], "out of memory"),
        ([*box, "--Gamma", "-1.6"], "'--Gamma'"),
        ([*box, "--Gamma", "nan"], "'--Gamma'"),
        ([*box, "--Gamma", "inf"], "'--Gamma'"),
        (["drum", "ensemble", "--params", "{}", "--out", out, str(junk)],
         "--params lacks the key"),
        (["box", "init", "--params", "{}", "--N-l", "5", "--init", "crystal", "--out", out],
         "--params lacks the key"),
        ([*drum[:3], '{"physics": {"dt": NaN}}', *drum[4:], "--batch", "0"], "--params"),
        ([*drum[:3], "[1, 2]", *drum[4:], "--batch", "0"], "--params"),
    ]  # fmt: skip


def test_misuse_is_one_line_naming_the_argument(tmp_path, repo, capsys):
    """Every misuse ends in one line on stderr naming the argument: no traceback, no file."""
    from granpipe.cli import main

    for argv, named in _misuses(tmp_path, repo):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        err = capsys.readouterr().err
        assert exit_.value.code != 0, argv
        # the error is one line; only a stage's own progress lines ("[study hh:mm:ss] ...")
        # may come before it (the out-of-memory case fails after the stage has started)
        lines = [x for x in err.splitlines() if not x.startswith("[")]
        assert len(lines) == 1 and lines[0].startswith("granpipe: error: "), (argv, err)
        assert named in err, (argv, err)
        assert not (tmp_path / "out.nc").exists(), argv
