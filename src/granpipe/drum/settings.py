"""The ``drum:`` config section: defaults, the seeding subset, and times in steps.

Config keys and units: ``config/README.md`` (drum section) and
``workflow/schemas/drum.schema.yaml``. Physics is in reduced units (d_s, m_s,
t0 = sqrt(d_s/g)); protocol and analysis times are in seconds, as the paper
quotes them, and are converted here to whole numbers of steps of Δt.
"""

from __future__ import annotations

import copy
import functools
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import yaml

from ..config import schema_dir
from ..errors import ConfigError

__all__ = [
    "check",
    "MAX_SIMULATION_JOBS",
    "PHYSICS_KEYS",
    "POINT_KEYS",
    "filled",
    "omega",
    "points",
    "reference_point",
    "point_label",
    "seed_physics",
    "Steps",
    "steps",
    "tiny_section",
    "TINY_PROTOCOL",
]

PHYSICS_KEYS = ("physics", "settle", "protocol")
"""Sub-sections that change a replica's trajectory (the settle section only for the
``settled`` start-up): with n_replicas and batch_size excluded, so that a larger ensemble
reuses every batch."""

POINT_KEYS = (("physics", "period_s"), ("protocol", "startup"))
"""Keys that may hold a list: each entry makes its own parameter point (``drum.design``)."""

_NOT_SEEDED = (("physics", "max_overlap"),)
"""Keys that never change a trajectory (a bad-state bound), left out of the seed."""


def _fill_defaults(instance, schema, root):
    """Recursively set schema defaults (objects and their properties) in place."""
    if "$ref" in schema:
        ref = schema["$ref"]
        if not ref.startswith("#/"):
            raise ValueError(f"unsupported $ref {ref}")
        target = root
        for part in ref[2:].split("/"):
            target = target[part]
        schema = {**target, **{k: v for k, v in schema.items() if k != "$ref"}}
    if isinstance(instance, dict) and "properties" in schema:
        for key, sub in schema["properties"].items():
            if key not in instance and "default" in sub:
                instance[key] = copy.deepcopy(sub["default"])
            if key in instance:
                _fill_defaults(instance[key], sub, root)
    return instance


@functools.lru_cache(maxsize=4)
def _schema(path: str, mtime: int):
    """The drum schema and its validator, read once per file version."""
    import jsonschema

    schema = yaml.safe_load(Path(path).read_text())
    return schema, jsonschema.Draft202012Validator(schema)


def filled(section: Mapping | None) -> dict:
    """A deep copy of a ``drum`` section with every schema default filled in, checked.

    The workflow's top-level validation does not fill defaults through the
    ``$ref`` to ``drum.schema.yaml``, so library code always goes through this (the
    schema is read once per process and file version).

    Raises
    ------
    ConfigError
        naming the key, if the section violates the schema or a fit window is not
        ordered.
    """
    path = schema_dir() / "drum.schema.yaml"
    schema, validator = _schema(str(path), path.stat().st_mtime_ns)
    sec = _fill_defaults(copy.deepcopy(dict(section or {})), schema, schema)
    errors = sorted(validator.iter_errors(sec), key=lambda e: list(map(str, e.absolute_path)))
    if errors:
        msgs = ["drum." + ".".join(map(str, e.absolute_path)) + f": {e.message}" for e in errors]
        raise ConfigError("invalid drum configuration:\n  - " + "\n  - ".join(msgs))
    for key in ("onset_vertex_window_s", "onset_zero_window_s", "decay_zero_window_s"):
        lo, hi = sec["fits"][key]
        if not lo < hi:
            raise ConfigError(f"config key 'drum.fits.{key}' = {[lo, hi]} must be increasing")
    if sec["protocol"]["decay_rotating_s"] >= sec["protocol"]["decay_window_s"]:
        raise ConfigError(
            "config key 'drum.protocol.decay_rotating_s' must be shorter than decay_window_s"
        )
    return sec


MAX_SIMULATION_JOBS = 10_000
"""The most init + runs jobs a drum config may ask for. Snakemake's planning time grows
with the number of jobs: the paper scale (2,939 jobs over the three studies, 1,560 of
them the drum's) plans in 17 s, ~6 ms per job, so 10,000 jobs take about a minute before
anything runs; a larger ``batch_size`` is the remedy."""


def check(section: Mapping) -> dict:
    """Every check of a ``drum`` section, before any job runs; returns it filled.

    Beyond the schema (:func:`filled`): fit windows inside the recorded windows, settling
    times min ≤ max, the snapshot batch among the batches, and a plan Snakemake can
    build (:data:`MAX_SIMULATION_JOBS`). Raises ConfigError naming the key.
    """
    sec = filled(section)
    pr, fi = sec["protocol"], sec["fits"]
    for key, window in (
        ("onset_vertex_window_s", "onset_window_s"), ("onset_zero_window_s", "onset_window_s"),
        ("vertex_search_s", "onset_window_s"), ("startup_window_s", "onset_window_s"),
        ("decay_zero_window_s", "decay_window_s"),
    ):  # fmt: skip
        lo, hi = fi[key]
        if not lo < hi:
            raise ConfigError(f"config key 'drum.fits.{key}' = {[lo, hi]} must be increasing")
        if hi > pr[window]:
            raise ConfigError(
                f"config key 'drum.fits.{key}' = {[lo, hi]} reaches beyond the recorded "
                f"window 'drum.protocol.{window}' = {pr[window]} s"
            )
    st = sec["settle"]
    if st["min_time_s"] > st["max_time_s"]:
        raise ConfigError(
            f"config keys 'drum.settle.min_time_s' = {st['min_time_s']} and "
            f"'drum.settle.max_time_s' = {st['max_time_s']}: min must not exceed max"
        )
    pts = points(sec)
    batches = [
        -(-int(p["ensemble"]["n_replicas"]) // int(p["ensemble"]["batch_size"])) for p in pts
    ]
    snap = int(sec["figures"]["snapshot_batch"])
    if snap >= batches[0]:
        raise ConfigError(
            f"config key 'drum.figures.snapshot_batch' = {snap}: the reference point has "
            f"only {batches[0]} batch(es) (0..{batches[0] - 1})"
        )
    jobs = 2 * sum(batches)
    if jobs > MAX_SIMULATION_JOBS:
        raise ConfigError(
            f"config keys 'drum.ensemble.n_replicas' / 'batch_size': {jobs} simulation jobs "
            f"over {len(pts)} point(s), more than {MAX_SIMULATION_JOBS} (Snakemake would "
            "take over a minute to plan them): raise 'drum.ensemble.batch_size'"
        )
    for p in pts:
        steps(p)  # times shorter than a step, a pre-rotation of no step
    return sec


def omega(physics: Mapping) -> float:
    """Angular speed of the drum's clockwise rotation [rad/t0], 2π t0 / period.

    ``physics.period_s`` must be one number here (a point's section, :func:`points`).
    """
    period = physics["period_s"]
    if isinstance(period, list | tuple):
        raise ConfigError("drum.physics.period_s is a list: take one point (settings.points)")
    return 2.0 * math.pi * float(physics["t0_s"]) / float(period)


def _values(sec: Mapping, key: tuple) -> list:
    v = sec[key[0]][key[1]]
    return list(v) if isinstance(v, list | tuple) else [v]


def points(section: Mapping) -> list[dict]:
    """The parameter points of a section: one filled section per point, each with one
    ``physics.period_s`` and one ``protocol.startup``.

    With ``design: star`` (default) the first entry of every list gives the *reference
    point* (listed first), and every further entry varies that one key from it (so four
    periods and two start-ups give five points); ``product`` takes every combination.
    A point's section does not depend on the other entries of the lists, so adding an
    entry adds its point and changes no other. Points other than the reference have
    ``ensemble.variant_replicas`` replicas when that is set.
    """
    sec = filled(section)
    values = [_values(sec, key) for key in POINT_KEYS]
    if sec["design"] == "product":
        combos = [list(c) for c in itertools.product(*values)]
    else:
        ref = [v[0] for v in values]
        combos = [ref]
        for i, vals in enumerate(values):
            combos += [ref[:i] + [v] + ref[i + 1 :] for v in vals[1:]]
    out = []
    variant = sec["ensemble"]["variant_replicas"]
    for i, combo in enumerate(combos):
        p = copy.deepcopy(dict(sec))
        for (a, b), v in zip(POINT_KEYS, combo, strict=True):
            p[a][b] = v
        if i > 0 and variant is not None:
            p["ensemble"]["n_replicas"] = int(variant)
        out.append(p)
    return out


def reference_point(section: Mapping) -> dict:
    """The first point of :func:`points`: the entries the paper's numbers refer to."""
    return points(section)[0]


def point_label(point: Mapping, section: Mapping) -> str:
    """Suffix of a point's summary rows: ``""`` for the reference point, else the keys
    where it differs from it, e.g. ``"[period=450s]"`` or ``"[startup=settled]"``."""
    ref = reference_point(section)
    diff = []
    for a, b in POINT_KEYS:
        if point[a][b] != ref[a][b]:
            diff.append(_point_part(b, point[a][b]))
    return f"[{','.join(diff)}]" if diff else ""


def _point_part(key: str, value) -> str:
    if key == "period_s":
        return f"period={float(value):.4g}s"
    return f"{key}={value}"


def seed_physics(section: Mapping) -> dict:
    """The subset of a point's section that defines a replica: physics, protocol, and
    settle for the ``settled`` start-up (the bad-state bound left out).

    :func:`granpipe.seeds.replica_rng` hashes it; sample sizes, fits and figures are
    not part of it.
    """
    sec = filled(section)
    omega(sec["physics"])  # one point only
    keys = [k for k in PHYSICS_KEYS if k != "settle" or sec["protocol"]["startup"] == "settled"]
    out = {k: copy.deepcopy(sec[k]) for k in keys}
    for a, b in _NOT_SEEDED:
        out[a].pop(b, None)
    return out


def _n_steps(seconds: float, dt_s: float, what: str) -> int:
    n = seconds / dt_s
    k = round(n)
    if seconds > 0 and k == 0:
        raise ConfigError(f"{what} = {seconds} s is shorter than one time step ({dt_s} s)")
    return int(k)


@dataclass(frozen=True)
class Steps:
    """Protocol durations of a section, in whole steps of Δt.

    Attributes
    ----------
    dt : float [t0]
    dt_s : float [s]
    block : int
        Steps per stored block mean (block_s rounded to a whole number of steps).
    pre_rotation : int
        Steps of rotation before t = 0: ``pre_rotation_deg`` (1° = 62,500 steps at the
        paper's Ω and Δt), or ``pre_rotation_s`` when set; for the ``paper`` start-up
        they start at the placement and include the fall.
    alignment : int
        Steps over which the tangent vector evolves before t = 0 (the paper start-up:
        ``tangent_alignment_s`` in whole blocks, at most ``pre_rotation``; the settled
        start-up: ``pre_rotation``, the tangent being set when the rotation starts).
    realign : int
        With ``tangent_while_waiting: false``: steps from the moment the avalanche became
        continuous, when that was after the onset window, to the decay window, over which
        a fresh tangent vector aligns (``decay_alignment_s`` in whole blocks).
    onset : int
        Steps of the onset window (a whole number of blocks).
    decay_rotating : int
        Steps of the decay window with the drum still turning (a whole number of blocks).
    decay : int
        Steps of the decay window (a whole number of blocks).
    chunk : int
        Steps per engine call (a whole number of blocks).
    continuous_hold : int
        Blocks the continuous-avalanche criterion looks back over.
    max_rotation : int
        Steps after t = 0 by which the avalanche must be continuous.
    settle_min, settle_max : int
        Steps of settling at least / at most (whole numbers of blocks).
    settle_hold : int
        Blocks the settling criterion looks back over.
    """

    dt: float
    dt_s: float
    block: int
    pre_rotation: int
    alignment: int
    realign: int
    onset: int
    decay_rotating: int
    decay: int
    chunk: int
    continuous_hold: int
    max_rotation: int
    settle_min: int
    settle_max: int
    settle_hold: int

    @property
    def block_s(self) -> float:
        """Duration of one stored block [s]."""
        return self.block * self.dt_s

    @property
    def block_t0(self) -> float:
        """Duration of one stored block [t0]."""
        return self.block * self.dt


def steps(section: Mapping) -> Steps:
    """Convert the protocol times of a section (seconds, degrees) into steps."""
    sec = filled(section)
    ph, pr, st = sec["physics"], sec["protocol"], sec["settle"]
    dt = float(ph["dt"])
    dt_s = dt * float(ph["t0_s"])
    block = _n_steps(pr["block_s"], dt_s, "drum.protocol.block_s")

    def blocks(seconds, what):  # whole number of blocks, at least one
        return max(1, math.ceil(_n_steps(seconds, dt_s, what) / block - 1e-9))

    if pr["pre_rotation_s"] is None:
        pre = int(round(math.radians(pr["pre_rotation_deg"]) / (omega(ph) * dt)))
    else:
        pre = _n_steps(pr["pre_rotation_s"], dt_s, "drum.protocol.pre_rotation_s")
    realign = block * round(_n_steps(pr["decay_alignment_s"], dt_s, "") / block)
    align = block * round(_n_steps(pr["tangent_alignment_s"], dt_s, "") / block)
    align = pre if pr["startup"] == "settled" else min(pre, align)
    return Steps(
        dt=dt,
        dt_s=dt_s,
        block=block,
        pre_rotation=pre,
        alignment=align,
        realign=realign,
        onset=block * blocks(pr["onset_window_s"], "drum.protocol.onset_window_s"),
        decay_rotating=block * round(_n_steps(pr["decay_rotating_s"], dt_s, "") / block),
        decay=block * blocks(pr["decay_window_s"], "drum.protocol.decay_window_s"),
        chunk=block * blocks(pr["chunk_s"], "drum.protocol.chunk_s"),
        continuous_hold=blocks(pr["continuous_hold_s"], "drum.protocol.continuous_hold_s"),
        max_rotation=_n_steps(pr["max_rotation_s"], dt_s, "drum.protocol.max_rotation_s"),
        settle_min=block * round(_n_steps(st["min_time_s"], dt_s, "") / block),
        settle_max=block * blocks(st["max_time_s"], "drum.settle.max_time_s"),
        settle_hold=blocks(st["hold_s"], "drum.settle.hold_s"),
    )


TINY_PROTOCOL = {
    "pre_rotation_deg": 0.2,
    "onset_window_s": 0.6,
    "decay_window_s": 0.6,
    "decay_rotating_s": 0.2,
    "continuous_hold_s": 0.2,
    "max_rotation_s": 1.0,
    "chunk_s": 0.2,
    "tangent_alignment_s": 0.1,
    "decay_alignment_s": 0.1,
}
"""Short windows for the tiny drum (tests, ``granpipe drum replica --tiny``)."""

TINY_SETTLE = {"min_time_s": 0.4, "max_time_s": 1.0}


def tiny_section(section: Mapping | None = None, n_wall: int = 40, **protocol) -> dict:
    """A section with a tiny drum (:func:`granpipe.drum.geometry.tiny_physics`).

    Same disks, contact law, Δt and Ω as the paper, 40 wall disks (radius 8.8 d_s) and
    23 + 23 mobile disks (the paper's filling fraction); settling and protocol
    shortened (:data:`TINY_PROTOCOL`, :data:`TINY_SETTLE`; ``protocol`` overrides
    keys) so that one replica takes about a second.
    """
    from .geometry import tiny_physics

    sec = filled(section)
    sec["physics"] = tiny_physics(n_wall, sec["physics"])
    sec["protocol"].update(TINY_PROTOCOL)
    sec["protocol"].update(protocol)
    sec["settle"].update(TINY_SETTLE)
    return filled(sec)
