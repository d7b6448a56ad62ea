"""Engine A/B: a git revision against the working tree, interleaved in one process.

    .venv/bin/python benchmarks/engine_ab.py REV [--systems df,dt,bc,bd] [--rounds 24]

On a shared VM the speed of a process can flip between levels ~1.4x apart for tens of
seconds (docs/engine_performance.md, round 5), so medians of separate processes do not
compare versions. This script imports ``src/granpipe`` of revision ``REV`` as a renamed
package (``granpipe_ab_<sha>``, exported with ``git archive`` into the system temp folder
and compiled there once) beside the working tree's ``granpipe``, builds the benchmark
systems of ``benchmarks/engine.py`` from the same settled states with both, and times
short chunks alternately (A B, then B A, ...). Both states are put on 64-byte cache lines
(with the working tree's ``simulation._aligned``), so that the ratio measures code, not
where ``malloc`` put the arrays.

Systems: ``df`` drum forward, ``dt`` drum with tangent dynamics, ``st`` the drum pile
under the static-friction law with tangent dynamics, ``bc`` box crystal, ``bd`` driven box
(a drive period split into ``rounds`` chunks). Printed per system: the fastest chunk and
the median chunk of each version (ns per particle-step; drum per mobile disk) and the
median of the per-round ratios new/old. The last line is one JSON object
``{system: ratio}``. Compare a revision with itself first (``REV`` = ``HEAD`` on a
clean tree): the ratios then show the harness's own bias.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# One BLAS thread before numpy loads (see benchmarks/engine.py).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")
# The two packages' kernels compiled into a cache of this script's own, before numba
# loads: written beside the working tree's sources, the machine code of kernels that
# met the other package's types made later processes fail to load their cache.
os.environ.setdefault("NUMBA_CACHE_DIR", os.path.join(tempfile.gettempdir(), "granpipe_ab_cache"))
# Every exported revision importable before any kernel loads: the pickled index of a
# cached kernel can name a type of the package it was compiled beside, and unpickling
# it needs that package.
ROOT = Path(tempfile.gettempdir()) / "granpipe_ab"
sys.path.insert(0, str(ROOT))

import engine as bench
import numba
import numpy as np

from granpipe.engine.simulation import _aligned

REPO = Path(__file__).resolve().parents[1]
SYSTEMS = ("df", "dt", "st", "bc", "bd")


def export(rev: str) -> str:
    """Export ``src/granpipe`` at ``rev`` as package ``granpipe_ab_<sha>``; return its name."""
    sha = subprocess.run(
        ["git", "-C", str(REPO), "rev-parse", "--short=10", rev],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    name = f"granpipe_ab_{sha}"
    pkg = ROOT / name
    if not pkg.exists():
        tmp = ROOT / f".{name}.tmp"
        tmp.mkdir(parents=True, exist_ok=True)
        archive = subprocess.run(
            ["git", "-C", str(REPO), "archive", sha, "src/granpipe"],
            check=True,
            capture_output=True,
        ).stdout
        subprocess.run(["tar", "-x", "-C", str(tmp)], input=archive, check=True)
        for path in (tmp / "src" / "granpipe").rglob("*.py"):
            text = path.read_text()
            text = re.sub(r"\bgranpipe\.", f"{name}.", text)
            text = re.sub(r"\bfrom granpipe import\b", f"from {name} import", text)
            path.write_text(text)
        (tmp / "src" / "granpipe").rename(pkg)
    return name


def systems(pkg: str, which, rounds: int) -> dict:
    """``{system: (run one chunk, particle-steps per chunk)}`` built with package ``pkg``
    from the settled states of ``benchmarks/engine.py``, on 64-byte cache lines."""
    out = {}

    def aligned(state):
        state._s = _aligned(state._s)
        return state

    for key in ("df", "dt", "st"):
        if key in which:
            sim, st = bench.drum_system(pkg=pkg)
            if key == "st":
                sim, st = bench.static_friction(sim, st, pkg=pkg)
            st = aligned(st)
            kw = {}
            if key != "df":
                sim.random_tangent(st, np.random.default_rng(1))
                kw = {"stride": 35, "tangent": True}
            sim.run(st, 35, **kw)
            out[key] = (lambda s=sim, x=st, k=kw: s.run(x, 350, **k), 350 * 736)
    if "bc" in which:
        sim, st = bench.box_crystal(pkg=pkg)
        st = aligned(st)
        sim.run(st, 10)
        out["bc"] = (lambda s=sim, x=st: s.run(x, 500), 500 * st.n)
    if "bd" in which:
        sim, st, period = bench.box_driven(pkg=pkg)
        st = aligned(st)
        sim.run(st, 10)
        chunk = period // rounds
        out["bd"] = (lambda s=sim, x=st, k=chunk: s.run(x, k), chunk * st.n)
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rev", help="git revision to compare the working tree against")
    ap.add_argument("--systems", default=",".join(SYSTEMS))
    ap.add_argument("--rounds", type=int, default=24)
    args = ap.parse_args(argv)
    which = args.systems.split(",")
    if bad := set(which) - set(SYSTEMS):
        ap.error(f"unknown systems {sorted(bad)}; choose from {','.join(SYSTEMS)}")
    numba.set_num_threads(1)
    # the settled states of benchmarks/engine.py (built and cached there if missing)
    bench.drum_system()
    bench.box_driven()
    old = systems(export(args.rev), which, args.rounds)
    new = systems("granpipe", which, args.rounds)
    ratios = {}
    for key in which:
        times = {"old": [], "new": []}
        for r in range(args.rounds):
            for label in ("old", "new") if r % 2 == 0 else ("new", "old"):
                run, work = (old if label == "old" else new)[key]
                t = time.thread_time()
                run()
                times[label].append((time.thread_time() - t) / work * 1e9)
        a, b = np.array(times["old"]), np.array(times["new"])
        ratios[key] = round(float(np.median(b / a)), 3)
        print(
            f"{key}: {args.rev} fastest {a.min():6.2f} median {np.median(a):6.2f} | working tree "
            f"fastest {b.min():6.2f} median {np.median(b):6.2f} ns/particle-step | "
            f"new/old {ratios[key]:.3f}",
            flush=True,
        )
    print(json.dumps(ratios))


if __name__ == "__main__":
    main()
