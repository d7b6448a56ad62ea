"""Where the box study's files live, and which parameter points a config section asks for.

One source of truth for ``workflow/rules/box.smk`` (its target lists and wildcards) and
``granpipe status`` (:func:`run_files`). Paths are relative to ``results/<scale>/box/``.

A *parameter point* is ``(N_l, Gamma, init, walls)``, named
``N_l=20,Gamma=2.2,init=crystal,mu_w=0.6,walls=shaken,torque=lever`` (:func:`point_name`).
``walls`` (:class:`Walls`) is the side walls' Coulomb coefficient (``grid.mu_side_walls``),
their drive (``physics.side_walls``: shaken with the plate or still) and whether wall
friction exerts a torque (``physics.wall_torque``); each combination is its own set of
points. An *initial state* is ``(N_l, init, walls)`` without the drive of the side walls
(the plate rests during the preparation, so a shaken and a still side wall are the same
wall there), named ``N_l=20,init=crystal,mu_w=0.6,torque=lever``; every Γ and both wall
drives of one ``(N_l, init, mu_w, torque, replica)`` start from the same prepared state,
so that thresholds compare like with like. A run of ``measured_periods`` periods is split
in consecutive *parts* of ``periods_per_part`` periods (part 0 also carries the ramp and
the transient); part ``p`` continues from the final state stored in part ``p - 1``.

    >>> w = Walls(0.6, "shaken", "lever")
    >>> point_name(20, 2.2, "crystal", w)
    'N_l=20,Gamma=2.2,init=crystal,mu_w=0.6,walls=shaken,torque=lever'
    >>> parse_point(point_name(20, 2.2, "crystal", w)) == (20, 2.2, "crystal", w)
    True
    >>> state_name(20, "crystal", w)
    'N_l=20,init=crystal,mu_w=0.6,torque=lever'
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from typing import NamedTuple

__all__ = [
    "check",
    "movie_points",
    "movie_params",
    "movie_file",
    "INITS",
    "SIDE_WALLS",
    "WALL_TORQUES",
    "Walls",
    "wall_settings",
    "gamma_text",
    "point_name",
    "physics_for",
    "state_name",
    "parse_point",
    "init_states",
    "wall_frictions",
    "grid_blocks",
    "points",
    "n_parts",
    "part_periods",
    "init_file",
    "replicas",
    "point_run_files",
    "run_file",
    "run_files",
    "init_files",
    "ensemble_file",
    "ensemble_files",
    "FIGURES",
    "figure_files",
    "FITS",
    "fit_files",
    "POINT_RE",
    "init_params",
    "runs_params",
    "trajectory_params",
    "previous_part_params",
    "ensemble_params",
    "fits_params",
    "figures_params",
    "run_steps",
    "n_disks",
    "sim_minutes",
    "run_inputs",
]

INITS = ("crystal", "random")
SIDE_WALLS = ("shaken", "still")
"""``physics.side_walls``: the side walls move with the plate (the whole box is driven,
the paper's Sec. II), or stand still while the plate moves (docs/box.md, "Which walls
move")."""
WALL_TORQUES = ("lever", "none")
"""``physics.wall_torque``: a wall's tangential force exerts the torque of its lever on the
disk, or none (the ``σ_j = 0`` reading of Eq. A4 for a flat wall)."""

_NUM = r"[0-9.eE+-]+"
_WALLS_RE = re.compile(
    rf"mu_w=({_NUM}),walls=({'|'.join(SIDE_WALLS)}),torque=({'|'.join(WALL_TORQUES)})"
)

BYTES_PER_DISK = 4096
"""A generous bound on a run's memory per disk (engine state and lists,
``granpipe.engine.layout``), besides the 16 bytes per disk and recorded period."""


def check(section: Mapping) -> None:
    """Cross-key checks of a ``box`` section before any job runs (ConfigError names the
    key): ``fits.N_l`` one of ``grid.N_l``, a transient at least as long as the ramp, a
    plan Snakemake can build (parts numbered in three digits), a box wide enough for a
    crystal row, slip phases among the sampling phases, and runs that fit in this
    machine's memory."""
    from ..errors import ConfigError

    grid = section.get("grid", {})
    n_ls = [int(n) for n in grid.get("N_l", [])]
    n_ls += [int(n) for b in grid.get("blocks", ()) for n in b.get("N_l", ()) if n not in n_ls]
    want = section.get("fits", {}).get("N_l")
    if want is not None and int(want) not in n_ls:
        raise ConfigError(f"config key 'box.fits.N_l' = {want} is not in 'box.grid.N_l' "
                          f"or its blocks' = {n_ls}")  # fmt: skip
    pr = section.get("protocol", {})
    ramp, transient = pr.get("ramp_periods", 0.0), pr.get("transient_periods", 0)
    if ramp > transient:
        raise ConfigError(
            f"config keys 'box.protocol.ramp_periods' = {ramp} and 'transient_periods' = "
            f"{transient}: the ramp must end before the measurement starts"
        )
    from ..config import check_memory, check_plan
    from .preparation import crystal_row_lengths

    # the point-replicas counted per block, not listed (as :func:`points` would): a grid
    # too large to plan is never built
    runs = sum(
        len(b["N_l"]) * len(b["inits"]) * len(b["Gamma"]) * int(b["replicas"])
        for b in grid_blocks(section)
    )
    jobs = len(wall_settings(section)) * runs * (n_parts(section) + 1)
    check_plan("box.grid", jobs, "raise 'box.protocol.periods_per_part' or shrink the grid")
    if n_parts(section) > 1000:  # the rules' three-digit part pattern
        raise ConfigError(
            f"config keys 'box.protocol.measured_periods' and 'periods_per_part': "
            f"{n_parts(section)} parts per run, more than 1000"
        )
    lx = float(section["physics"]["Lx"])
    rows = section.get("init", {}).get("crystal_rows", "spanning")
    if "crystal" in section["grid"].get("inits", INITS) and min(crystal_row_lengths(lx, rows)) < 1:
        raise ConfigError(
            f"config key 'box.physics.Lx' = {lx} holds no crystal row ('box.init.crystal_rows'"
            f" = {rows}: rows of floor(Lx) and floor(Lx) - 1 disks): at least 2 for a crystal"
        )
    from .model import contact_time, min_steps_per_contact

    physics = section["physics"]
    try:
        contact_time(physics)
    except ValueError:
        msg = (f"config key 'box.physics.gamma_n' = {physics['gamma_n']}: the contact is "
               "overdamped (Eq. A5 has no contact time)")  # fmt: skip
        raise ConfigError(msg) from None
    spc, bound = float(physics["steps_per_contact"]), min_steps_per_contact(physics)
    if spc <= bound:
        raise ConfigError(f"config key 'box.physics.steps_per_contact' = {spc:g}: the explicit "
                          f"step is unstable below {bound:.3g} steps per contact time "
                          "(ω0 Δt < 2)")  # fmt: skip
    mv = section.get("movie", {})
    if mv.get("enabled", True):
        _check_movie(section, mv)
    n_k, n_s = int(pr.get("phases_per_period", 64)), int(pr.get("slip_phases", 1))
    if n_k % n_s:
        raise ConfigError(
            f"config key 'box.protocol.slip_phases' = {n_s} does not divide "
            f"'box.protocol.phases_per_period' = {n_k}: the slip frames are sampling phases"
        )
    frames = (int(pr.get("periods_per_part", 200)) + 1) * n_s
    check_memory(
        "box.grid.N_l", max(n_ls), n_disks(section, max(n_ls)) * (BYTES_PER_DISK + 16 * frames)
    )


def _check_movie(section: Mapping, mv: Mapping) -> None:
    """``movie``'s point among the grid's, its replica among the point's, its periods
    within the record."""
    from ..errors import ConfigError

    grid, pr = section["grid"], section.get("protocol", {})
    for key, have in (("N_l", [int(n) for n in grid["N_l"]]),
                      ("Gamma", [float(g) for g in grid["Gamma"]])):  # fmt: skip
        if mv.get(key) is not None and mv[key] not in have:
            raise ConfigError(f"config key 'box.movie.{key}' = {mv[key]} is not in "
                              f"'box.grid.{key}' = {have}")  # fmt: skip
    inits = list(grid.get("inits", INITS))
    for init in mv.get("inits") or inits:
        if init not in inits:
            raise ConfigError(f"config key 'box.movie.inits' holds {init!r}, not in "
                              f"'box.grid.inits' = {inits}")  # fmt: skip
    n = int(grid.get("replicas", 1))
    if int(mv.get("replica", 0)) >= n:
        raise ConfigError(f"config key 'box.movie.replica' = {mv['replica']} is outside "
                          f"the ensemble (replicas 0 .. {n - 1}, 'box.grid.replicas')")  # fmt: skip
    total = int(pr.get("transient_periods", 0)) + int(pr.get("measured_periods", 0))
    if int(mv.get("periods", 2)) > total:
        raise ConfigError(f"config key 'box.movie.periods' = {mv['periods']} exceeds the "
                          f"record's {total} periods (transient and measured)")  # fmt: skip


def movie_points(section: Mapping) -> list[str]:
    """The names of the movie's points: ``movie.N_l`` (default the grid's first) at
    ``movie.Gamma`` (default the grid's largest), one per start of ``movie.inits``
    (default every start of the grid), under the first wall setting."""
    mv, grid = section["movie"], section["grid"]
    n_l = int(grid["N_l"][0] if mv["N_l"] is None else mv["N_l"])
    gamma = float(max(grid["Gamma"]) if mv["Gamma"] is None else mv["Gamma"])
    walls = wall_settings(section)[0]
    starts = mv["inits"] or grid.get("inits", INITS)
    return [point_name(n_l, gamma, init, walls) for init in starts]


def movie_params(section: Mapping, point: str) -> dict:
    """``granpipe box movie``'s subset: the replay's (:func:`trajectory_params`) and the
    ``movie`` section."""
    return {**trajectory_params(section, point), "movie": dict(section["movie"])}


def movie_file(section: Mapping, point: str) -> str:
    return f"movie/{point}.{section['movie']['format']}"


def gamma_text(gamma: float) -> str:
    """Shortest text that reads back as the same float (``repr``): 2.2 -> '2.2', 1 -> '1.0'."""
    return repr(float(gamma))


class Walls(NamedTuple):
    """The walls of a set of points: side-wall friction ``mu_w``, the side walls' drive
    (:data:`SIDE_WALLS`) and the wall torque (:data:`WALL_TORQUES`)."""

    mu_w: float
    side_walls: str = "shaken"
    wall_torque: str = "lever"

    @property
    def text(self) -> str:
        """``mu_w=0.6,walls=shaken,torque=lever`` (a point name's wall part)."""
        return f"mu_w={gamma_text(self.mu_w)},walls={self.side_walls},torque={self.wall_torque}"

    @property
    def state_text(self) -> str:
        """``mu_w=0.6,torque=lever``: what of the walls a prepared state depends on."""
        return f"mu_w={gamma_text(self.mu_w)},torque={self.wall_torque}"

    @classmethod
    def parse(cls, text: str) -> Walls:
        """Inverse of :attr:`text`."""
        m = _WALLS_RE.fullmatch(text)
        if not m:
            raise ValueError(
                f"not a box wall setting: {text!r} (expected mu_w=..,walls=..,torque=..)"
            )
        return cls(float(m.group(1)), m.group(2), m.group(3))

    @classmethod
    def of_point(cls, wildcards) -> Walls:
        """The walls of a point's rule wildcards (``box_mu_w``, ``box_side``, ``box_torque``)."""
        walls = cls(float(wildcards.box_mu_w), wildcards.box_side, wildcards.box_torque)
        walls.check()
        return walls

    @classmethod
    def of_state(cls, wildcards) -> Walls:
        """The walls of a prepared state's rule wildcards (``box_mu_w``, ``box_torque``; the
        side walls' drive, which a prepared state does not depend on, set to the default)."""
        walls = cls(float(wildcards.box_mu_w), "shaken", wildcards.box_torque)
        walls.check()
        return walls

    def check(self) -> None:
        if self.side_walls not in SIDE_WALLS:
            raise ValueError(f"side_walls must be one of {SIDE_WALLS}, got {self.side_walls!r}")
        if self.wall_torque not in WALL_TORQUES:
            raise ValueError(f"wall_torque must be one of {WALL_TORQUES}, got {self.wall_torque!r}")


POINT_RE = re.compile(rf"^N_l=(\d+),Gamma=({_NUM}),init=(crystal|random),({_WALLS_RE.pattern})$")


def point_name(n_l: int, gamma: float, init: str, walls: Walls) -> str:
    """Name of a parameter point, e.g. ``N_l=20,Gamma=2.2,init=crystal,mu_w=0.6,walls=shaken,
    torque=lever``."""
    if init not in INITS:
        raise ValueError(f"init must be one of {INITS}, got {init!r}")
    walls.check()
    return f"N_l={int(n_l)},Gamma={gamma_text(gamma)},init={init},{walls.text}"


def state_name(n_l: int, init: str, walls: Walls) -> str:
    """Name of a prepared initial state, e.g. ``N_l=20,init=random,mu_w=0.6,torque=lever``."""
    if init not in INITS:
        raise ValueError(f"init must be one of {INITS}, got {init!r}")
    walls.check()
    return f"N_l={int(n_l)},init={init},{walls.state_text}"


def parse_point(name: str) -> tuple[int, float, str, Walls]:
    """Inverse of :func:`point_name`: ``(N_l, Gamma, init, walls)``."""
    m = POINT_RE.match(name)
    if not m:
        raise ValueError(
            f"not a box point name: {name!r} "
            "(expected N_l=..,Gamma=..,init=..,mu_w=..,walls=..,torque=..)"
        )
    return int(m.group(1)), float(m.group(2)), m.group(3), Walls.parse(m.group(4))


def _as_list(value) -> list:
    return list(value) if isinstance(value, list | tuple) else [value]


def wall_frictions(section: Mapping) -> list[float]:
    """The side walls' Coulomb coefficients of the grid (``grid.mu_side_walls``)."""
    return [float(m) for m in section["grid"]["mu_side_walls"]]


def wall_settings(section: Mapping) -> list[Walls]:
    """Every wall setting of the grid: ``grid.mu_side_walls`` × ``physics.side_walls`` ×
    ``physics.wall_torque`` (each a value or a list), in config order."""
    physics = section["physics"]
    return [
        Walls(mu_w, side, torque)
        for mu_w in wall_frictions(section)
        for side in _as_list(physics.get("side_walls", "shaken"))
        for torque in _as_list(physics.get("wall_torque", "lever"))
    ]


def physics_for(section: Mapping, walls: Walls) -> dict:
    """``box.physics`` of the points with wall setting ``walls``: ``mu_side_walls``,
    ``side_walls`` and ``wall_torque`` single values (what :func:`granpipe.box.model.box_law`
    and :func:`granpipe.box.model.flat_walls` read)."""
    return {
        **dict(section["physics"]),
        "mu_side_walls": float(walls.mu_w),
        "side_walls": walls.side_walls,
        "wall_torque": walls.wall_torque,
    }


def preparation_physics(physics: Mapping) -> dict:
    """The physics a prepared state depends on: all but the side walls' drive (the plate
    rests during the preparation)."""
    return {k: v for k, v in physics.items() if k != "side_walls"}


def grid_blocks(section: Mapping) -> list[dict]:
    """The grid's products of ``N_l`` × ``inits`` × ``Gamma``, each with its replica count:
    ``grid`` itself first, then each of ``grid.blocks`` with the grid's ``inits`` and
    ``replicas`` where it leaves them out (e.g. more replicas of one start where a barrier
    is decided)."""
    grid = section["grid"]
    base = {k: grid[k] for k in ("N_l", "Gamma", "inits", "replicas")}
    return [base] + [{**base, **dict(b)} for b in grid.get("blocks", ())]


def _block_points(section: Mapping) -> dict[tuple[int, float, str], int]:
    """``(N_l, Gamma, init)`` -> its replicas (the largest of the blocks holding it), in
    config order."""
    out: dict[tuple[int, float, str], int] = {}
    for b in grid_blocks(section):
        for n_l in b["N_l"]:
            for init in b["inits"]:
                for g in b["Gamma"]:
                    key = (int(n_l), float(g), init)
                    out[key] = max(out.get(key, 0), int(b["replicas"]))
    return out


def init_states(section: Mapping) -> list[tuple[int, str, Walls]]:
    """``(N_l, init, walls)`` of the grid's prepared states (one per shared state: the
    first wall setting of each ``(mu_w, wall_torque)``), in config order."""
    seen, out = set(), []
    for walls in wall_settings(section):
        for n_l, _, init in _block_points(section):
            key = state_name(n_l, init, walls)
            if key not in seen:
                seen.add(key)
                out.append((int(n_l), init, walls))
    return out


def points(section: Mapping) -> list[tuple[int, float, str, Walls]]:
    """``(N_l, Gamma, init, walls)`` of every parameter point the grid and its blocks ask
    for, in config order (a point in several blocks once)."""
    return [
        (n_l, g, init, walls)
        for walls in wall_settings(section)
        for n_l, g, init in _block_points(section)
    ]


def n_parts(section: Mapping) -> int:
    """Number of consecutive run files per point and replica."""
    proto = section["protocol"]
    return max(1, math.ceil(int(proto["measured_periods"]) / int(proto["periods_per_part"])))


def part_periods(section: Mapping, part: int) -> range:
    """Measured-period indices (0-based, after the transient) covered by ``part``."""
    proto = section["protocol"]
    m, p = int(proto["measured_periods"]), int(proto["periods_per_part"])
    if not 0 <= part < n_parts(section):
        raise ValueError(f"part {part} out of range 0..{n_parts(section) - 1}")
    return range(part * p, min(m, (part + 1) * p))


def replicas(
    section: Mapping, n_l: int | None = None, gamma: float | None = None, init: str | None = None
) -> range:
    """Replicas of the point ``(n_l, gamma, init)`` (the largest count of the blocks
    holding it); of the prepared state ``(n_l, init)`` when ``gamma`` is None (the most
    any of its points needs); of the whole grid when all are None."""
    counts = [
        r for (n, g, i), r in _block_points(section).items()
        if (n_l is None or n == int(n_l)) and (init is None or i == init)
        and (gamma is None or g == float(gamma))
    ]  # fmt: skip
    return range(max(counts, default=0))


def init_file(n_l: int, init: str, walls: Walls, replica: int) -> str:
    return f"init/{state_name(n_l, init, walls)}/replica_{int(replica):04d}.nc"


def run_file(n_l: int, gamma: float, init: str, walls: Walls, replica: int, part: int) -> str:
    point = point_name(n_l, gamma, init, walls)
    return f"runs/{point}/replica_{int(replica):04d}.part_{int(part):03d}.nc"


def ensemble_file(n_l: int, gamma: float, init: str, walls: Walls) -> str:
    return f"ensemble/{point_name(n_l, gamma, init, walls)}.nc"


def init_files(section: Mapping) -> list[str]:
    """Prepared initial states (relative to ``results/<scale>/box/``)."""
    return [
        init_file(*s, r) for s in init_states(section) for r in replicas(section, s[0], init=s[1])
    ]


def run_files(section: Mapping) -> list[str]:
    """Every run file a config section asks for (relative to ``results/<scale>/box/``)."""
    return [f for pt in points(section) for f in point_run_files(section, *pt)]


def point_run_files(section: Mapping, n_l: int, gamma: float, init: str, walls: Walls) -> list[str]:
    """The run files of one point (all replicas, all parts)."""
    return [
        run_file(n_l, gamma, init, walls, r, p)
        for r in replicas(section, n_l, gamma, init)
        for p in range(n_parts(section))
    ]


def ensemble_files(section: Mapping) -> list[str]:
    return [ensemble_file(*pt) for pt in points(section)]


FITS = (
    "fits/phase_diagram.nc", "fits/temperature.nc", "fits/slips.nc", "fits/summary.csv",
    "fits/costs.csv",
)  # fmt: skip
"""Outputs of the fits stage (``costs.csv``: the wall-clock costs, apart from the fitted
numbers of ``summary.csv``)."""

FIGURES = {
    1: "fig1_snapshots",
    3: "fig3_phase_diagram",
    4: "fig4_granular_temperature",
    5: "fig5_slip_probability",
    6: "fig6_walls",
    7: "fig7_onset_record",
}
"""Figure number -> file stem (PNG and PDF of each); 6 (thresholds against the side walls'
friction) and 7 (the convection onset against the record it looked at) are ours."""


def fit_files() -> list[str]:
    return list(FITS)


def figure_files(kind: str = "png") -> list[str]:
    return [f"figures/{stem}.{kind}" for stem in FIGURES.values()]


# ---------------------------------------------------- config subsets of each stage
def init_params(section: Mapping, walls: Walls) -> dict:
    """Config subset of the init stage: the physics a prepared state depends on
    (:func:`preparation_physics` of the points' physics) and the preparation."""
    return {
        "physics": preparation_physics(physics_for(section, walls)),
        "init": dict(section["init"]),
    }


def runs_params(section: Mapping, part: int, walls: Walls) -> dict:
    """The exact config subset a run part depends on (what the rule passes as --params).

    ``measured_periods`` is replaced by the measured periods of this part, so that raising
    ``measured_periods`` by whole parts leaves the existing parts untouched.
    """
    proto = {k: v for k, v in section["protocol"].items() if k != "measured_periods"}
    periods = part_periods(section, part)
    return {
        "physics": physics_for(section, walls),
        "init": dict(section["init"]),
        "protocol": proto,
        "part_periods": [periods.start, periods.stop],
    }


def trajectory_params(section: Mapping, point: str) -> dict:
    """``granpipe box trajectory``'s subset for ``point`` (its name): the physics of its
    walls, the preparation, the whole protocol (a replay runs every part in one), the
    point's ``N_l``, ``Gamma`` and start, and the replica count."""
    n_l, gamma, kind, walls = parse_point(point)
    return {"physics": physics_for(section, walls), "init": dict(section["init"]),
            "protocol": dict(section["protocol"]), "N_l": n_l, "Gamma": gamma,
            "init_kind": kind, "replicas": int(section["grid"]["replicas"])}  # fmt: skip


def previous_part_params(params: Mapping) -> dict:
    """The config subset of the part before the one whose subset is ``params``
    (:func:`runs_params`): every part but the last is ``periods_per_part`` long."""
    p0 = int(params["part_periods"][0])
    return {**params, "part_periods": [p0 - int(params["protocol"]["periods_per_part"]), p0]}


def ensemble_params(section: Mapping, point: str | None = None) -> dict:
    """Config subset of the ensemble stage: detection, slips, order and the box width; for
    one ``point`` (its name) also which files it reduces: the point, its replica count and
    the config hash of each part's run files."""
    from ..io import config_hash

    out = {
        "Lx": float(section["physics"]["Lx"]),
        "detection": dict(section["detection"]),
        "slips": dict(section["slips"]),
        "order": dict(section["order"]),
    }
    if point is not None:
        n_l, gamma, init, walls = parse_point(point)
        out.update(
            point=point,
            replicas=len(replicas(section, n_l, gamma, init)),
            runs_config_hashes=[
                config_hash(runs_params(section, part, walls)) for part in range(n_parts(section))
            ],
        )
    return out


def _inputs(section: Mapping) -> dict:
    """The config hashes of the files the fits and figures read: ``points`` (point name ->
    its ensemble file's) and ``states`` (initial state name -> its init files')."""
    from ..io import config_hash

    return {
        "points": {
            point_name(*pt): config_hash(ensemble_params(section, point_name(*pt)))
            for pt in points(section)
        },
        "states": {
            state_name(*st): config_hash(init_params(section, st[2])) for st in init_states(section)
        },
    }


def fits_params(section: Mapping) -> dict:
    """Config subset of the fits stage (criteria and fit settings) and the config hash
    of each point's ensemble file."""
    return {
        "detection": dict(section["detection"]),
        "fits": dict(section["fits"]),
        "points": _inputs(section)["points"],
    }


def figures_params(section: Mapping) -> dict:
    """Config subset of the figures stage, with the config hashes of the ensemble and
    init files it reads."""
    return {
        "Lx": float(section["physics"]["Lx"]),
        "order": dict(section["order"]),
        "fits": dict(section["fits"]),
        **_inputs(section),
    }


def run_steps(section: Mapping, part: int) -> int:
    """Time steps of one run part (transient included in part 0), for runtime requests."""
    import math as _m

    physics, proto = section["physics"], section["protocol"]
    m_eff = 0.5
    w2 = float(physics["kappa_n"]) / m_eff - float(physics["gamma_n"]) ** 2 / 4.0
    dt = _m.pi / _m.sqrt(w2) / float(physics["steps_per_contact"])
    per_period = 2.0 * _m.pi / float(physics["omega"]) / dt
    periods = len(part_periods(section, part))
    if part == 0:
        periods += int(proto["transient_periods"]) + 0.25
    return int(per_period * periods)


def n_disks(section: Mapping, n_l: int) -> int:
    """N = N_l Lx."""
    return int(round(int(n_l) * float(section["physics"]["Lx"])))


def sim_minutes(section: Mapping, n_l: int, part: int) -> int:
    """Runtime request of one simulation job: twice the cost model, at least ``min_runtime``.

    Cost model: N × steps × ``resources.ns_per_particle_step``.
    """
    res = section["resources"]
    seconds = n_disks(section, n_l) * run_steps(section, part) * res["ns_per_particle_step"] * 1e-9
    return max(int(res["min_runtime"]), int(2 * seconds / 60) + 1)


def run_inputs(section: Mapping, wildcards) -> dict[str, str]:
    """Inputs of a run part (relative paths): the initial state, and the previous part."""
    n_l, init, walls, rep, part = (
        int(wildcards.box_nl),
        wildcards.box_init,
        Walls.of_point(wildcards),
        int(wildcards.box_rep),
        int(wildcards.box_part),
    )
    files = {"init": init_file(n_l, init, walls, rep)}
    if part > 0:
        gamma = float(wildcards.box_gamma)
        files["previous"] = run_file(n_l, gamma, init, walls, rep, part - 1)
    return files
