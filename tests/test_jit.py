"""numba's on-disk cache notices an edit to any jitted source, in a new process."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

import granpipe

LEAF = "from .._jit import njit\n\n\n@njit\ndef leaf():\n    return {value}\n"
PROBE = (
    "from .._jit import njit\nfrom ._probe_leaf import leaf\n\n\n"
    "@njit\ndef probe():\n    return leaf() + 1.0\n"
)


def _run(root: Path, locators: str | None = None) -> str:
    env = {**os.environ, "PYTHONPATH": str(root)}
    env.pop("NUMBA_CACHE_DIR", None)
    if locators:
        env["NUMBA_CACHE_LOCATOR_CLASSES"] = locators
    code = "from granpipe.engine._probe import probe; print(probe())"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True)  # fmt: skip
    return out.stdout.strip()


def _scratch(tmp_path: Path) -> Path:
    pkg = tmp_path / "granpipe"
    shutil.copytree(Path(granpipe.__file__).parent, pkg,
                    ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
    (pkg / "engine" / "_probe_leaf.py").write_text(LEAF.format(value="1.0"))
    (pkg / "engine" / "_probe.py").write_text(PROBE)
    return pkg


def _edit_leaf(pkg: Path, value: str) -> None:
    leaf = pkg / "engine" / "_probe_leaf.py"
    before = leaf.stat().st_mtime_ns
    leaf.write_text(LEAF.format(value=value))
    os.utime(leaf, ns=(before + 10**9, before + 10**9))  # a visibly newer file


def test_an_edit_to_a_called_file_reaches_its_cached_caller(tmp_path):
    pkg = _scratch(tmp_path)
    assert _run(tmp_path) == "2.0"
    assert list((pkg / "engine" / "__pycache__").glob("_probe.probe-*.nbi")), "not cached"
    assert _run(tmp_path) == "2.0"  # from the cache
    _edit_leaf(pkg, "5.0")
    assert _run(tmp_path) == "6.0"


def test_numbas_own_locator_would_keep_the_stale_code(tmp_path):
    """The control: with numba's default locator the same edit goes unnoticed."""
    pkg = _scratch(tmp_path)
    assert _run(tmp_path, "InTreeCacheLocator") == "2.0"
    _edit_leaf(pkg, "5.0")
    assert _run(tmp_path, "InTreeCacheLocator") == "2.0"
