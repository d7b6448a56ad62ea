"""The drum's config section and where the study's files live (``results/<scale>/drum/``).

The ``drum:`` section: schema defaults and checks (:func:`filled`, :func:`check`),
parameter points (:func:`points`) and the seeding subset (:func:`seed_physics`). A stage
fills its ``--params`` once (:func:`load`) and hands the result down read-only
(:class:`FrozenSection`), never filled again. Config keys and units: ``config/README.md``
(drum section) and ``workflow/schemas/drum.schema.yaml``. Physics is in reduced units
(d_s, m_s, t0 = sqrt(d_s/g)); protocol and analysis times are in seconds, as the paper
quotes them (:func:`steps` converts them to whole steps of Δt).

One folder per parameter point (:func:`points`), named after its size, drum period,
start-up and friction law, e.g. ``N=736,period=900s,startup=paper,friction=viscous``. Replicas
come in fixed batches of ``ensemble.batch_size`` (:func:`granpipe.seeds.batch_replicas`),
so a larger ``n_replicas`` only appends batches, and a new period, start-up or friction
law only adds its own point. The workflow (``workflow/rules/drum.smk``) and ``granpipe status`` list
files through these functions, and the config subsets each rule depends on are built
here too (:func:`rule_params`).
"""

from __future__ import annotations

import copy
import functools
import itertools
import math
from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType

from ..config import (
    MAX_SIMULATION_JOBS,
    check_memory,
    check_plan,
    fill_defaults,
    read_schema,
    schema_dir,
)
from ..errors import ConfigError
from ..io import config_hash
from .model import PAPER_PHYSICS, geometry, omega

__all__ = [
    "Steps",
    "steps",
    "POINT_PATTERN",
    "FRICTION_WILDCARD",
    "PAPER_GAMMA_T",
    "STARTUPS",
    "FRICTIONS",
    "point_of",
    "point_name",
    "point_names",
    "movie_sim_params",
    "movie_params",
    "movie_input",
    "movie_file",
    "point_sections",
    "rule_params",
    "trajectory_params",
    "ENSEMBLE_KEYS",
    "batch_ids",
    "n_batches",
    "init_file",
    "run_file",
    "run_files",
    "init_files",
    "ensemble_file",
    "fits_file",
    "summary_file",
    "FIGURES",
    "COMPARISON_FIGURES",
    "figure_files",
    "check",
    "MAX_SIMULATION_JOBS",
    "PHYSICS_KEYS",
    "POINT_KEYS",
    "filled",
    "load",
    "FrozenSection",
    "thaw",
    "points",
    "reference_point",
    "point_label",
    "seed_physics",
    "trajectory_keys",
]

FIGURES = {
    2: "snapshot",
    3: "onset",
    4: "decay",
    5: "lambda_vs_speed",
    9: "aligned",
}
"""Figure number -> name for the reference point: ``figures/fig<k>_<name>.{png,pdf}``."""

COMPARISON_FIGURES = {
    6: "startup",
    7: "lag_vs_rotation",
    8: "friction",
}
"""Figures across points: V and λ̄ of each start-up; the lags against the drum's Ω; V and
λ̄ of each friction law."""


POINT_PATTERN = "N={drum_n},period={drum_period}s,startup={drum_startup},friction={drum_friction}"
"""A point's folder name as Snakemake wildcards (:func:`point_name` fills them). A point
whose γ_t is not the paper's carries it after the friction law (``friction=viscous,
gamma_t=3.44635``), inside the ``drum_friction`` wildcard (:data:`FRICTION_WILDCARD`)."""

PAPER_GAMMA_T = PAPER_PHYSICS["gamma_t"]
"""The paper's γ_t (Table 1): points with another value name it in their folder."""

FRICTION_WILDCARD = r"(viscous|static)(,gamma_t=[0-9.e+-]+)?"
"""What the ``drum_friction`` wildcard matches: the law, and γ_t when it is not the
paper's. Such a value holds "," and "=", which grouped cluster jobs cannot carry: the γ_t
points (``config/drum_sensitivity.yaml``) run locally."""

STARTUPS = ("paper", "settled")
FRICTIONS = ("viscous", "static")


def point_of(wildcards) -> str:
    """The point name of a job's wildcards ``drum_n``, ``drum_period``, ``drum_startup``,
    ``drum_friction``."""
    return POINT_PATTERN.format(
        drum_n=wildcards.drum_n, drum_period=wildcards.drum_period,
        drum_startup=wildcards.drum_startup, drum_friction=wildcards.drum_friction,
    )  # fmt: skip


def point_name(point: Mapping) -> str:
    """Folder name of a parameter point, e.g.
    ``N=736,period=900s,startup=paper,friction=viscous``."""
    sec = load(point)
    ph = sec["physics"]
    n = int(ph["n_small"]) + int(ph["n_large"])
    period = ph["period_s"]
    if isinstance(period, list | tuple):
        raise ValueError("point_name needs one point's section (points)")
    gamma_t = (
        "" if float(ph["gamma_t"]) == PAPER_GAMMA_T else f",{_point_part('gamma_t', ph['gamma_t'])}"
    )
    return (
        f"N={n},period={float(period):.4g}s,startup={sec['protocol']['startup']},"
        f"friction={ph['friction']}{gamma_t}"
    )


def point_sections(section: Mapping) -> dict[str, dict]:
    """``{point name: point section}`` in the order of :func:`points`."""
    return {point_name(p): p for p in points(section)}


def point_names(section: Mapping) -> list[str]:
    return list(point_sections(section))


ENSEMBLE_KEYS = ("ensemble", "point", "runs_config_hash")
"""The keys of an ensemble rule's config subset (:func:`rule_params`); a fits rule's subset
holds them too, so that the fits stage knows the config hash of the ensemble file it
reads."""


def rule_params(section: Mapping) -> dict[str, dict]:
    """The config subset each drum rule depends on (its ``params:``), per point.

    Returns ``{"sim": {point: ...}, "ensemble": {point: ...}, "fits": {point: ...},
    "figures": ...}``: a simulation depends on its point's physics (``k_t`` only under
    static friction), settle (settled start-up only), protocol and batch size
    (:func:`trajectory_keys`); the ensemble on ``exclude_flagged`` and on which files it
    reduces: its point's name and the config hash of that point's run files
    (``runs_config_hash``, the hash of the point's simulation subset, :data:`ENSEMBLE_KEYS`);
    the fits on those and ``fits`` (and its point's label, for the row names); the
    figures on ``figures`` and the list of points (name, period, start-up, friction,
    label, runs config hash; the reference first: a list, because the JSON of the params
    has sorted keys). Editing the physics of one point, or adding a point, changes no
    other point's subsets. A stage checks every file it reads against the point and
    hash its subset names (:func:`granpipe.io.expect_input`).
    """
    sec = filled(section)
    sim, ensemble, fits, table = {}, {}, {}, []
    flagged = {"exclude_flagged": sec["ensemble"]["exclude_flagged"]}
    for name, p in point_sections(sec).items():
        sim[name] = {
            **trajectory_keys(p),
            "ensemble": {"batch_size": p["ensemble"]["batch_size"]},
        }
        runs_hash = config_hash(sim[name])
        ensemble[name] = {"ensemble": flagged, "point": name, "runs_config_hash": runs_hash}
        fits[name] = {**ensemble[name], "fits": sec["fits"], "label": point_label(p, sec)}
        table.append({
            "name": name,
            "period_s": p["physics"]["period_s"],
            "startup": p["protocol"]["startup"],
            "friction": p["physics"]["friction"],
            "gamma_t": p["physics"]["gamma_t"],
            "label": fits[name]["label"],
            "runs_config_hash": runs_hash,
        })  # fmt: skip
    return {
        "sim": sim,
        "ensemble": ensemble,
        "fits": fits,
        "figures": {"figures": sec["figures"], "points": table},
    }


def trajectory_params(section: Mapping, point: str) -> dict:
    """``granpipe drum trajectory``'s subset for ``point``: its simulation subset (a replay
    is the run) and its replica count (the replicas it may replay)."""
    sec = filled(section)
    sim = rule_params(sec)["sim"][point]
    n = point_sections(sec)[point]["ensemble"]["n_replicas"]
    return {**sim, "ensemble": {**sim["ensemble"], "n_replicas": n}}


def movie_sim_params(point: Mapping) -> dict:
    """A point's simulation subset (its runs' config hash is this subset's) from its
    section: :func:`trajectory_keys` and the batch size."""
    sec = load(point)
    return {**trajectory_keys(sec), "ensemble": {"batch_size": sec["ensemble"]["batch_size"]}}


def movie_params(section: Mapping) -> dict:
    """``granpipe drum movie``'s subset: the reference point's replay
    (:func:`trajectory_params`), the fits (the detector that finds the events) and the
    ``movie`` section."""
    sec = filled(section)
    ref = point_names(sec)[0]
    return {**trajectory_params(sec, ref), "fits": sec["fits"], "movie": sec["movie"]}


def movie_input(section: Mapping) -> str:
    """The run file the movies read: the reference point's batch holding
    ``movie.replica`` (batch 0 when null)."""
    sec = filled(section)
    replica = sec["movie"]["replica"] or 0
    return run_file(points(sec)[0], replica // int(sec["ensemble"]["batch_size"]))


def movie_file(section: Mapping, part: str) -> str:
    sec = filled(section)
    return f"movie/{point_names(sec)[0]}_{part}.{sec['movie']['format']}"


def n_batches(section: Mapping) -> int:
    ens = load(section)["ensemble"]
    return -(-int(ens["n_replicas"]) // int(ens["batch_size"]))


def batch_ids(section: Mapping) -> list[str]:
    """Batch labels ``0000``, ``0001``, ... covering ``ensemble.n_replicas``."""
    return [f"{b:04d}" for b in range(n_batches(section))]


def init_file(point: Mapping, batch: str | int) -> str:
    return f"init/{point_name(point)}/batch_{int(batch):04d}.nc"


def run_file(point: Mapping, batch: str | int) -> str:
    return f"runs/{point_name(point)}/batch_{int(batch):04d}.nc"


def _files(section: Mapping, kind: str, point: str | None) -> list[str]:
    sections = point_sections(section)
    names = list(sections) if point is None else [point]
    return [f"{kind}/{p}/batch_{b}.nc" for p in names for b in batch_ids(sections[p])]


def init_files(section: Mapping, point: str | None = None) -> list[str]:
    """Init files relative to ``results/<scale>/drum/`` (of one point, or of all)."""
    return _files(section, "init", point)


def run_files(section: Mapping, point: str | None = None) -> list[str]:
    """Run files relative to ``results/<scale>/drum/`` (of one point, or of all; used by
    ``granpipe status``)."""
    return _files(section, "runs", point)


def ensemble_file(point: Mapping | str) -> str:
    name = point if isinstance(point, str) else point_name(point)
    return f"ensemble/{name}.nc"


def fits_file(point: Mapping | str) -> str:
    name = point if isinstance(point, str) else point_name(point)
    return f"fits/{name}.nc"


def summary_file() -> str:
    return "fits/summary.csv"


def figure_files(exts=("png", "pdf")) -> list[str]:
    figs = {**FIGURES, **COMPARISON_FIGURES}
    return [f"figures/fig{k}_{name}.{ext}" for k, name in figs.items() for ext in exts]


# ----- the drum config section: defaults, checks, points, the seeding subset
PHYSICS_KEYS = ("physics", "settle", "protocol")
"""Sub-sections that change a replica's trajectory (the settle section only for the
``settled`` start-up): with n_replicas and batch_size excluded, so that a larger ensemble
reuses every batch."""


POINT_KEYS = (
    ("physics", "period_s"),
    ("protocol", "startup"),
    ("physics", "friction"),
    ("physics", "gamma_t"),
)
"""Keys that may hold a list: each entry makes its own parameter point (``drum.design``)."""


_NOT_SEEDED = (
    ("physics", "max_overlap"),
    ("physics", "friction"),
    ("physics", "k_t"),
    ("protocol", "pile_sample_s"),
    ("protocol", "disk_record"),
)
"""Keys left out of the seed: the bad-state bound, the pile's sampling and its per-disk
record (they never change a trajectory), and the friction law, so that replica k of a
static-friction point starts from the same placement and tangent vector as replica k of
its viscous twin (paired replicas: the difference between the laws is measured on common
random numbers)."""


@functools.lru_cache(maxsize=4)
def _schema(path: str, mtime: int):
    """The drum schema and its validator, read once per file version."""
    import jsonschema

    schema = read_schema(path)
    return schema, jsonschema.Draft202012Validator(schema)


def _freeze(obj):
    """Read-only copy: mappings as ``types.MappingProxyType``, lists as tuples."""
    if isinstance(obj, Mapping):
        return MappingProxyType({k: _freeze(v) for k, v in obj.items()})
    if isinstance(obj, list | tuple):
        return tuple(_freeze(v) for v in obj)
    return obj


def thaw(obj):
    """A plain, mutable deep copy (dicts and lists) of a (frozen) section or sub-section,
    e.g. to hash or serialise it."""
    if isinstance(obj, Mapping):
        return {k: thaw(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [thaw(v) for v in obj]
    return obj


class FrozenSection(Mapping):
    """A filled and checked ``drum`` section, read-only all the way down (:func:`load`).

    Sub-sections are ``types.MappingProxyType`` and lists are tuples, so assignment at
    any level raises ``TypeError``. :func:`load` and :func:`filled` take it as already
    filled: handed down from the stage that loaded it, it is never filled again.
    """

    __slots__ = ("_data",)

    def __init__(self, section: Mapping):
        object.__setattr__(self, "_data", _freeze(section))

    def __getitem__(self, key):
        return self._data[key]

    def __iter__(self):
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def __repr__(self) -> str:
        return f"FrozenSection({thaw(self)!r})"

    def __setattr__(self, name, value):
        raise AttributeError("a FrozenSection is read-only")

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):
        return self

    def __reduce__(self):
        return (FrozenSection, (thaw(self),))


def load(section: Mapping | None) -> FrozenSection:
    """The ``drum`` section filled once and frozen: what a stage makes of its ``--params``
    and hands down (:func:`filled`, then :class:`FrozenSection`). A section already
    loaded is returned as it is, without reading the schema again."""
    if isinstance(section, FrozenSection):
        return section
    return FrozenSection(filled(section))


def filled(section: Mapping | None) -> dict:
    """A deep copy of a ``drum`` section with every schema default filled in, checked.

    The workflow's top-level validation does not fill defaults through the
    ``$ref`` to ``drum.schema.yaml``, so library code always goes through this or
    :func:`load` (the schema is read once per process and file version). A
    :class:`FrozenSection` is already filled: it comes back as a mutable copy.

    Raises
    ------
    ConfigError
        naming the key, if the section violates the schema or a fit window is not
        ordered.
    """
    if isinstance(section, FrozenSection):
        return thaw(section)
    path = schema_dir() / "drum.schema.yaml"
    schema, validator = _schema(str(path), path.stat().st_mtime_ns)
    sec = fill_defaults(copy.deepcopy(dict(section or {})), schema, schema)
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


PLACEMENT_LIMIT = 0.45
"""The largest area fraction of the mobile disks, each grown by the placement gap, in the
disk their centres may reach: random sequential addition stalls towards its jamming
limit (0.547 in the plane; the paper's drum fills 0.23)."""

BYTES_PER_BLOCK = 256
"""A generous bound on one replica's recorded bytes per block (block means of λ, V, the
pile's tilt and centroid, counts), for the memory check of :func:`check`."""

BYTES_PER_DISK_SAMPLE = 16
"""One replica's recorded bytes per mobile disk and pile sample of the onset window with
``protocol.disk_record`` (|δu_i| and |v_i| as float32, held twice while a batch's arrays
are stacked), for the memory check of :func:`check`."""

BYTES_PER_DISK = 4096
"""A generous bound on one replica's memory per disk (state rows, neighbour and pair
lists, pair buffers: ``granpipe.engine.layout``), for the memory check of :func:`check`."""


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
    ph = sec["physics"]
    if ph["k_t"] is not None and "static" not in _values(sec, ("physics", "friction")):
        raise ConfigError(
            f"config key 'drum.physics.k_t' = {ph['k_t']} is set, but no point has "
            "'drum.physics.friction' static: it would change nothing"
        )
    st = sec["settle"]
    if st["min_time_s"] > st["max_time_s"]:
        raise ConfigError(
            f"config keys 'drum.settle.min_time_s' = {st['min_time_s']} and "
            f"'drum.settle.max_time_s' = {st['max_time_s']}: min must not exceed max"
        )
    # every point has at least one batch (two jobs): refuse a list of points too long to
    # plan before building them (points() copies the section once per point)
    n_points = len(_combinations(sec))
    check_plan(
        "drum.physics.period_s", 2 * n_points,
        f"{n_points} point(s); list fewer values in the point keys",
    )  # fmt: skip
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
    check_plan(
        "drum.ensemble.n_replicas", 2 * sum(batches),
        f"{len(pts)} point(s); raise 'drum.ensemble.batch_size'",
    )  # fmt: skip
    mv = sec["movie"]
    n_ref = int(pts[0]["ensemble"]["n_replicas"])
    if mv["enabled"] and mv["replica"] is not None and int(mv["replica"]) >= n_ref:
        raise ConfigError(f"config key 'drum.movie.replica' = {mv['replica']} is outside the "
                          f"reference point's ensemble (replicas 0 .. {n_ref - 1})")  # fmt: skip
    for p in pts:
        st = steps(p)  # times shorter than a step, a pre-rotation of no step
        # a batch's block records (λ, V and the pile's state per block, a few rows each)
        blocks = (st.onset + st.decay + st.max_rotation) // st.block
        check_memory(
            "drum.protocol.onset_window_s", p["protocol"]["onset_window_s"],
            BYTES_PER_BLOCK * blocks * int(p["ensemble"]["batch_size"]),
        )  # fmt: skip
    _check_drum(sec)
    for p in pts:  # the per-disk record of the onset window's pile samples (after the disks)
        if p["protocol"]["disk_record"]:
            st = steps(p)
            n_mobile = int(p["physics"]["n_small"]) + int(p["physics"]["n_large"])
            check_memory(
                "drum.protocol.disk_record", True,
                BYTES_PER_DISK_SAMPLE * (st.onset // st.sample + 1) * n_mobile
                * int(p["ensemble"]["batch_size"]),
            )  # fmt: skip
    return sec


def _check_drum(sec: Mapping) -> None:
    """The drum holds its disks: the largest fits inside the wall ring with the placement
    gap, and all of them can be placed at random (:data:`PLACEMENT_LIMIT`); one job's
    replicas fit in this machine's memory."""

    ph, gap = sec["physics"], float(sec["protocol"]["placement_gap"])
    # counted, not built: an array of n_small disks is what the memory check guards against
    sizes = [(float(ph[f"d_{k}"]), int(ph[f"n_{k}"])) for k in ("small", "large")]
    n = sum(count for _, count in sizes) + int(ph["n_wall"])
    check_memory(
        "drum.physics.n_small", ph["n_small"],
        n * BYTES_PER_DISK * int(sec["ensemble"]["threads"]),
    )  # fmt: skip
    inner = geometry(ph).inner_radius
    d_max = max(d for d, count in sizes if count > 0)
    reach = inner - gap
    if reach - d_max / 2 <= 0:
        raise ConfigError(
            f"config keys 'drum.physics.n_wall' = {ph['n_wall']} and 'd_wall' = {ph['d_wall']}: "
            f"the wall ring's free radius {inner:.4g} d_s holds no disk of diameter "
            f"{d_max:g} with the placement gap {gap:g}"
        )
    fraction = sum(count * (d + gap) ** 2 for d, count in sizes) / (4.0 * reach**2)
    if fraction > PLACEMENT_LIMIT:
        raise ConfigError(
            f"config keys 'drum.physics.n_small' = {ph['n_small']} and 'n_large' = "
            f"{ph['n_large']}: the disks (with the placement gap) would cover {fraction:.3g} "
            f"of the drum's free disk (radius {inner:.4g} d_s from 'n_wall' = "
            f"{ph['n_wall']} and 'd_wall' = {ph['d_wall']}), more than the "
            f"{PLACEMENT_LIMIT} random placement reaches: fewer disks or a larger drum"
        )


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
    combos = _combinations(sec)
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


def _combinations(sec: Mapping) -> list[list]:
    """The values of :data:`POINT_KEYS` of every point of a filled section, in the order
    of :func:`points` (a few values per point: cheap where the points are not)."""
    values = [_values(sec, key) for key in POINT_KEYS]
    if sec["design"] == "product":
        return [list(c) for c in itertools.product(*values)]
    ref = [v[0] for v in values]
    combos = [ref]
    for i, vals in enumerate(values):
        combos += [ref[:i] + [v] + ref[i + 1 :] for v in vals[1:]]
    return combos


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
    if key == "gamma_t":
        return f"gamma_t={float(value):.6g}"
    return f"{key}={value}"


def trajectory_keys(point: Mapping) -> dict:
    """The sub-sections of one point that shape its trajectories (a plain copy): physics
    (without ``k_t`` under viscous friction, where it plays no part), protocol, and
    settle for the ``settled`` start-up only."""
    sec = load(point)
    keys = [k for k in PHYSICS_KEYS if k != "settle" or sec["protocol"]["startup"] == "settled"]
    out = {k: thaw(sec[k]) for k in keys}
    if out["physics"]["friction"] != "static":
        out["physics"].pop("k_t", None)
    return out


def seed_physics(section: Mapping) -> dict:
    """The subset of a point's section that defines a replica: physics, protocol, and
    settle for the ``settled`` start-up (the bad-state bound left out).

    :func:`granpipe.seeds.replica_rng` hashes it; sample sizes, fits and figures are
    not part of it.
    """
    sec = load(section)
    omega(sec["physics"])  # one point only
    if any(isinstance(sec["physics"][k], list | tuple) for k in ("friction", "gamma_t")):
        raise ValueError("seed_physics needs one point's section (points)")
    out = trajectory_keys(sec)
    for a, b in _NOT_SEEDED:
        out[a].pop(b, None)
    return out


# --------------------------------------------------------------------------- steps
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
    sample : int
        Steps between two samples of the pile's state in the recorded windows
        (``pile_sample_s`` in whole blocks; ``chunk`` is a whole number of them).
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
    sample: int
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
    sec = load(section)
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
    # chunk and pile sample count blocks of the configured block_s, so that whether one
    # divides the other does not depend on the time step
    _n_steps(pr["chunk_s"], dt_s, "drum.protocol.chunk_s")
    _n_steps(pr["pile_sample_s"], dt_s, "drum.protocol.pile_sample_s")
    chunk = block * max(1, round(pr["chunk_s"] / pr["block_s"]))
    sample = block * max(1, round(pr["pile_sample_s"] / pr["block_s"]))
    if chunk % sample:
        raise ConfigError(
            f"config key 'drum.protocol.pile_sample_s' = {pr['pile_sample_s']} s must divide "
            f"'drum.protocol.chunk_s' = {pr['chunk_s']} s into whole blocks of "
            f"{pr['block_s']} s"
        )
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
        chunk=chunk,
        sample=sample,
        continuous_hold=blocks(pr["continuous_hold_s"], "drum.protocol.continuous_hold_s"),
        max_rotation=_n_steps(pr["max_rotation_s"], dt_s, "drum.protocol.max_rotation_s"),
        settle_min=block * round(_n_steps(st["min_time_s"], dt_s, "") / block),
        settle_max=block * blocks(st["max_time_s"], "drum.settle.max_time_s"),
        settle_hold=blocks(st["hold_s"], "drum.settle.hold_s"),
    )
