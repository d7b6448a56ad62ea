"""``granpipe status``: per study and scale, batches present and missing, latest fits.

Expected outputs come from each study's ``granpipe.<study>.layout.run_files(section)``
(the same function the workflow's target lists use); a study without a layout module
is reported by what exists on disk.
"""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path

import pandas as pd

from .config import STUDIES, load

__all__ = ["report", "expected_run_files"]


def expected_run_files(study: str, section: dict) -> list[str] | None:
    """Run files (relative to ``results/<scale>/<study>/``) a config section asks for."""
    modname = f"granpipe.{study}.layout"
    if importlib.util.find_spec(modname) is None:
        return None
    run_files = getattr(importlib.import_module(modname), "run_files", None)
    return None if run_files is None else list(run_files(section))


def _summary_lines(csv: Path, limit: int = 12) -> list[str]:
    if not csv.exists():
        return ["    no fits yet"]
    table = pd.read_csv(csv)
    lines = []
    for row in table.head(limit).itertuples(index=False):
        ci = ""
        if pd.notna(getattr(row, "ci_low", None)) and pd.notna(getattr(row, "ci_high", None)):
            ci = f"  CI [{row.ci_low:.4g}, {row.ci_high:.4g}]"
        paper_value = getattr(row, "paper_value", None)
        paper = f"  (paper {paper_value})" if pd.notna(paper_value) else ""
        unit = row.unit if isinstance(row.unit, str) else ""
        lines.append(f"    {row.quantity} = {row.value:.6g} {unit}{ci}{paper}")
    if len(table) > limit:
        lines.append(f"    ... {len(table) - limit} more rows in {csv}")
    return lines


def report(results: str | Path = "results", configfile: str | Path | None = None) -> str:
    """Text report of what exists under ``results`` (and what is missing for ``configfile``)."""
    results = Path(results)
    cfg = load(configfile) if configfile else None
    scales = (
        [cfg["scale"]]
        if cfg
        else sorted(p.name for p in results.iterdir() if p.is_dir())
        if results.exists()
        else []
    )
    out = []
    for scale in scales:
        out.append(f"scale {scale}:")
        for study in STUDIES:
            root = results / scale / study
            if cfg is not None and study not in cfg["studies"]:
                continue
            present = sorted(str(p.relative_to(root)) for p in root.glob("runs/**/*.nc"))
            line = f"  {study}: {len(present)} run file(s)"
            if cfg is not None:
                expected = expected_run_files(study, cfg[study])
                if expected is not None:
                    missing = sorted(set(expected) - set(present))
                    line += f" of {len(expected)} expected, {len(missing)} missing"
            out.append(line)
            out.extend(_summary_lines(root / "fits" / "summary.csv"))
    return "\n".join(out) if out else f"no results under {results}"
