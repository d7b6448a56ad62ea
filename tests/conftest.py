"""Shared pytest fixtures: repository paths and a non-interactive matplotlib backend."""

import os
from pathlib import Path

import pytest

os.environ.setdefault("MPLBACKEND", "Agg")

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def repo() -> Path:
    """The repository root (holds Snakefile, config/, workflow/)."""
    return REPO


def pytest_collection_modifyitems(items):
    """Under ``pytest -n`` (``make test`` runs two workers, ``--dist loadgroup``): a test
    file's tests share one worker, so its module fixtures are built once, and every
    workflow test shares one, so the quick scale runs once and one SLURM cluster starts."""
    for item in items:
        path = Path(str(item.fspath)).relative_to(REPO)
        group = "workflow" if path.parts[:2] == ("tests", "workflow") else str(path)
        item.add_marker(pytest.mark.xdist_group(group))
