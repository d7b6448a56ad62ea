# Config access, path and batch helpers, and target lists shared by the study rules.
# No science here: rules call the granpipe CLI with the config subset as --params.

import json
import os
import sys
from pathlib import Path

from granpipe.seeds import batch_replicas

# Jobs run the `granpipe` of the interpreter that runs Snakemake (its console script sits
# beside it), whatever PATH the user's shell has: the folder comes first on the PATH the
# jobs inherit, locally and through SLURM's --export=ALL.


envvars:
    "PATH",


_BIN = str(Path(sys.executable).parent)
if os.environ.get("PATH", "").split(os.pathsep)[0] != _BIN:
    os.environ["PATH"] = os.pathsep.join([_BIN, os.environ.get("PATH", "")])

STUDY_TARGETS = {}


def enabled(study):
    """Whether this scale runs ``study``."""
    return study in config["studies"]


def study_cfg(study):
    """The validated config section of ``study``."""
    return config[study]


def out(study, *parts):
    """Path under results/<scale>/<study>/."""
    return str(Path(config["results"], config["scale"], study, *parts))


def log_path(study, *parts):
    """Path of a rule's log: results/<scale>/logs/<study>/..."""
    return str(Path(config["results"], config["scale"], "logs", study, *parts))


def as_json(obj):
    """Canonical JSON text of a config subset (what rules pass as --params)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"))


def pick(mapping, *keys):
    """Sub-mapping of ``mapping`` with the given top-level keys (all must exist)."""
    return {k: mapping[k] for k in keys}


def n_batches(n_replicas, batch_size):
    """Number of batches covering ``n_replicas`` replicas in fixed batches of ``batch_size``.

    Replica ranges per batch never depend on the total, so growing an ensemble only
    appends batches (granpipe.seeds.batch_replicas).
    """
    return -(-int(n_replicas) // int(batch_size))


def batch_ids(n_replicas, batch_size):
    return [f"{b:04d}" for b in range(n_batches(n_replicas, batch_size))]


def register_targets(study, fn):
    """Record the function that lists the final outputs of ``study``."""
    STUDY_TARGETS[study] = fn


def all_targets():
    """Final outputs of every study this scale runs."""
    targets = []
    for study in config["studies"]:
        if study in STUDY_TARGETS:
            targets.extend(STUDY_TARGETS[study]())
    return targets
