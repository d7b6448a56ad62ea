"""Fits of the box study: phase-diagram thresholds, T_g* regions, Arrhenius barriers.

Glue between the per-point ensemble files and :mod:`granpipe.analysis.regression` and
:mod:`granpipe.analysis.summary`:

* :func:`points_table` — one row per point (N_l, Γ, init, μ_w) with its measures; a
  crystal point whose bulk is no longer a defect-free crystal when measurement begins
  (``crystal_intact`` = 0) is kept in the table for the figures but left out of every
  crystal fit (column ``used``).
* :func:`thresholds` — per (N_l, init, μ_w): Γ of bouncing (s_b > σ/30, Appendix B with
  our correction, docs/box.md), of detachment (the bed off the plate for more than the set
  fraction of the cycle; docs/box.md, hazard (iii)) and of convection (s_c > σ);
  linear interpolation
  of log s between the bracketing grid points, which are reported.
* :func:`temperature_fits` — per (N_l, init, μ_w): continuous segmented regression of
  ln T_g* on ln K_m with ``breakpoints_random`` (A | B) or ``breakpoints_crystal``
  (A1 | A2 | B) breakpoints (Fig. 4), breakpoints as K_m with profile-likelihood CIs.
* :func:`slip_fits` — per (N_l, init, μ_w): Arrhenius fits ``p_s ∝ exp(−E_b/K_m)`` over the
  whole range and in each T_g* region (Fig. 5); regions without slips give NaN with
  zero-count upper bounds.
* :func:`summary_rows` — rows of ``summary.csv`` beside the paper's numbers (given on the
  rows of the paper's side-wall friction, Table I's 0.6).

Thresholds in Γ from measures on a grid (:func:`threshold_crossing`,
:func:`threshold_from_flags`). At each point of a grid of Γ for each N_l and initial
state the study measures s_b (bouncing bed when s_b > σ/30), s_c (convection when
s_c > σ), or the detachment fraction (Fortini & Huang 2015, Appendix B; docs/box.md). The
threshold is where the measure crosses its criterion, linearly interpolated between the
two bracketing grid points:

    Γ* = Γ_i + (Γ_{i+1} − Γ_i) (c − m_i) / (m_{i+1} − m_i)

(with ``scale="log"``, m and c are replaced by their logarithms: a measure
growing exponentially with Γ, as s_b does across the bouncing transition, is
then interpolated without bias). A measure on a grid brackets its threshold;
the grid points themselves are always reported.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from ..analysis import regression
from ..analysis.summary import summary_row
from ..io import read_dataset
from .layout import Walls
from .measures import combined_score, roll_displacement, roll_level, roll_significance

__all__ = [
    "points_table",
    "cost_rows",
    "thresholds_table",
    "temperature_fits",
    "slip_fits",
    "slip_bends",
    "summary_rows",
    "used_mask",
    "convection_after",
    "slips_between",
    "bouncing_mask",
    "CRYSTAL_POINTS",
    "TEMPERATURE_POINTS",
    "SLIP_WEIGHTS",
    "REGION_NAMES",
    "PAPER",
    "Threshold",
    "threshold_crossing",
    "threshold_from_flags",
]


# ------------------------------------------------------------ thresholds in Γ
@dataclass(frozen=True)
class Threshold:
    """A threshold in Γ and what brackets it.

    Attributes
    ----------
    value : float
        Interpolated crossing (``NaN`` if the grid does not bracket one).
    low, high : float
        Grid points bracketing the crossing: the last below the criterion and
        the first at or above it. ``status="below_grid"``: criterion met at the
        first grid point (low is NaN, high = first point); ``"above_grid"``:
        never met (low = last point, high is NaN).
    ci_low, ci_high : float
        Crossings of the upper and lower bands of the measure, when given (for
        flags: the bracket itself).
    status : str, "crossed", "below_grid" or "above_grid"
    n_crossings : int
        Upward crossings along the grid; more than one means the measure is not
        monotonic in Γ (e.g. s_b near Γ = 1, docs/box.md hazard iii): check it.
    """

    value: float
    low: float
    high: float
    ci_low: float = math.nan
    ci_high: float = math.nan
    status: str = "crossed"
    n_crossings: int = 1

    def summary_row(
        self,
        study: str,
        quantity: str,
        paper_value: float | None = None,
        unit: str = "1",
        n: int | None = None,
    ) -> dict:
        """A ``summary.csv`` row; without a band, the CI columns hold the bracket.

        For a threshold outside the grid, value is empty and the bracket names
        the grid end (e.g. ci_low = last Γ for ``above_grid``).
        """
        lo, hi = self.ci_low, self.ci_high
        if math.isnan(lo) and math.isnan(hi):
            lo, hi = self.low, self.high
        return summary_row(
            study, quantity, self.value, unit, ci_low=lo, ci_high=hi, n=n,
            paper_value=paper_value,
        )  # fmt: skip


def _crossings(g, f):
    """Indices i with f_i < 0 <= f_{i+1} (upward crossings of zero)."""
    ok = np.isfinite(f[:-1]) & np.isfinite(f[1:])
    return np.nonzero(ok & (f[:-1] < 0) & (f[1:] >= 0))[0]


def _interp(g, f, i):
    return float(g[i] + (g[i + 1] - g[i]) * (-f[i]) / (f[i + 1] - f[i]))


def _transform(m, c, scale):
    m = np.asarray(m, dtype=np.float64)
    if scale == "linear":
        return m - c
    if scale == "log":
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.log(m) - math.log(c)
    raise ValueError("scale must be 'linear' or 'log'")


def _locate(g, f, which):
    idx = _crossings(g, f)
    finite = np.isfinite(f)
    if finite.any() and f[np.argmax(finite)] >= 0:
        # Met at the first finite grid point: the threshold is below the grid.
        first = int(np.argmax(finite))
        return math.nan, math.nan, float(g[first]), "below_grid", len(idx)
    if len(idx) == 0:
        last = len(f) - 1 - int(np.argmax(finite[::-1])) if finite.any() else len(f) - 1
        return math.nan, float(g[last]), math.nan, "above_grid", 0
    i = idx[0] if which == "first" else idx[-1]
    return _interp(g, f, i), float(g[i]), float(g[i + 1]), "crossed", len(idx)


def threshold_crossing(
    gamma: np.ndarray,
    measure: np.ndarray,
    criterion: float,
    *,
    measure_low: np.ndarray | None = None,
    measure_high: np.ndarray | None = None,
    scale: str = "linear",
    which: str = "first",
) -> Threshold:
    """Γ at which ``measure`` first rises through ``criterion``, interpolated.

    Parameters
    ----------
    gamma : (n,) float, the grid of Γ (any order; sorted here)
    measure : (n,) float, e.g. s_b [σ] or s_c [σ] or a detachment fraction
    criterion : float, e.g. ``BOUNCING_THRESHOLD`` (σ/30) or ``CONVECTION_THRESHOLD`` (σ)
    measure_low, measure_high : (n,) float, optional
        A confidence band of the measure; the threshold's interval runs from
        the crossing of ``measure_high`` (earliest) to that of ``measure_low``
        (latest). An end that does not cross inside the grid is the grid end
        (lower) or NaN (upper).
    scale : {"linear", "log"}
        Interpolate the measure linearly or its logarithm.
    which : {"first", "last"}
        Which upward crossing to report if the measure crosses several times.

    For a measure that falls through the criterion, pass its negative and the
    negated criterion (``scale="linear"``).
    """
    g = np.asarray(gamma, dtype=np.float64)
    order = np.argsort(g, kind="stable")
    g = g[order]
    f = _transform(np.asarray(measure)[order], criterion, scale)
    value, lo, hi, status, n = _locate(g, f, which)
    ci = [math.nan, math.nan]
    for k, band in enumerate((measure_high, measure_low)):
        if band is None:
            continue
        fb = _transform(np.asarray(band)[order], criterion, scale)
        v, _, h, st, _ = _locate(g, fb, which)
        if st == "crossed":
            ci[k] = v
        elif st == "below_grid":
            ci[k] = float(g[0]) if k == 0 else h
    return Threshold(value, lo, hi, ci[0], ci[1], status, n)


def threshold_from_flags(gamma: np.ndarray, flags: np.ndarray) -> Threshold:
    """Threshold from yes/no flags on a grid: the midpoint of the bracket.

    The flag switches from False to True between ``low`` and ``high``; without
    a continuous measure nothing places it better inside that interval, so the
    value is the midpoint and (ci_low, ci_high) = (low, high).
    """
    g = np.asarray(gamma, dtype=np.float64)
    order = np.argsort(g, kind="stable")
    g = g[order]
    f = np.where(np.asarray(flags, dtype=bool)[order], 1.0, -1.0)
    _, lo, hi, status, n = _locate(g, f, "first")
    if status != "crossed":
        return Threshold(math.nan, lo, hi, math.nan, math.nan, status, n)
    return Threshold(0.5 * (lo + hi), lo, hi, lo, hi, status, n)


# ------------------------------------------------------------ the study's fits
REGION_NAMES = {0: ["all"], 1: ["A", "B"], 2: ["A1", "A2", "B"]}

#: The paper's numbers (Sec. IV-V): T_g slope change for random starts at K_m ≈ 3.3
#: (the convection onset), E_b = 7 ± 1 (random, whole range), 130 ± 20 (crystal A2),
#: 7 ± 1 (crystal B); comoving → bouncing "slightly above" Γ = 1.
PAPER = {
    "K_m_break_random": 3.3,
    "E_b_random_all": 7.0,
    "E_b_crystal_A2": 130.0,
    "E_b_crystal_B": 7.0,
    "Gamma_bouncing": 1.0,
}
PAPER_MU_W = 0.6
"""Table I's wall-particle Coulomb coefficient: the rows compared with the paper."""

_COLUMNS = (
    "s_c", "s_b", "s_b_printed", "detachment_fraction", "max_gap", "T_g", "T_g_sem", "p_s",
    "p_s_sem", "n_slips", "n_trials", "psi6_start", "psi6_end", "hexagonal_start",
    "hexagonal_end", "dislocations_start", "dislocations_end", "launch_ratio",
    "convection", "bouncing", "detached", "crystal_intact", "roll_velocity",
    "roll_significance", "roll_displacement", "rolls", "psi6_ramp", "dislocations_ramp",
    "crystal_intact_ramp",
)  # fmt: skip

#: Per-point rows of the crystal check: summary name -> table column.
ORDER_ROWS = {
    "psi6_at_measurement_start": "psi6_start",
    "psi6_at_measurement_end": "psi6_end",
    "hexagonal_at_measurement_start": "hexagonal_start",
    "hexagonal_at_measurement_end": "hexagonal_end",
    "dislocations_at_measurement_start": "dislocations_start",
    "dislocations_at_measurement_end": "dislocations_end",
    "psi6_at_ramp_end": "psi6_ramp",
    "dislocations_at_ramp_end": "dislocations_ramp",
}

_FLIGHT = ("p_s", "p_s_sem", "n_slips", "n_trials")
"""Slip columns that the ``_flight`` reading takes from the slip phase of longest flight."""


def phase_slip_columns(ds: xr.Dataset) -> dict:
    """Columns of a point's slips at each phase of the cycle (``protocol.slip_phases`` = n
    > 1): ``p_s_phase_<m>of<n>`` (m = 0 the cycle start) and, for the reading "slips
    sampled in flight", ``<column>_flight`` of :data:`_FLIGHT` at the slip phase whose
    bed is most often off the plate (``flight_phase``), that phase as ``flight_phase``.
    Empty with the cycle start alone."""
    n = int(ds.sizes.get("slip_phase", 1))
    if n < 2:
        return {}
    out = {f"p_s_phase_{m}of{n}": float(ds["p_s_phase"].values[m]) for m in range(n)}
    m = int(np.argmax(ds["flight_phase"].values))
    for c in _FLIGHT:
        out[f"{c}_flight"] = float(ds[f"{c}_phase"].values[m])
        out[f"{c}_replica_flight"] = _replica_values(ds, f"{c}_phase_replica", c, m)
    out["flight_phase"] = float(ds["slip_phase"].values[m])
    return out


_REPLICA_SUFFIXES = ("_replica", "_replica_flight")
"""Suffixes of the points table's per-replica columns (a tuple per point)."""


def _replica_values(ds: xr.Dataset, name: str, pooled: str, phase: int | None = None) -> tuple:
    """A point's per-replica values of ``name`` (at slip phase ``phase``), or with one
    replica and no such variable (files written before it) the pooled ``pooled``."""
    if name in ds:
        v = ds[name].values
        return tuple(float(x) for x in (v if phase is None else v[:, phase]))
    if int(ds.attrs["replicas"]) == 1:
        src = ds[pooled] if phase is None else ds[f"{pooled}_phase"][phase]
        return (float(src.values),)
    raise KeyError(f"{ds.attrs.get('point', '?')}: no {name} for its replicas")


def convection_after(s_j: np.ndarray, n_periods: int) -> float:
    """s_c of Eq. (B2) over the first ``n_periods`` cycles of each replica, averaged over
    the replicas as the point's s_c is [σ]; NaN when the record is shorter.

    Parameters
    ----------
    s_j : (replicas, periods) float [σ], Eq. (B1) per cycle
    """
    s_j = np.atleast_2d(np.asarray(s_j, dtype=np.float64))
    if n_periods > s_j.shape[1]:
        return math.nan
    return float(np.mean(np.sqrt(np.nanmean(s_j[:, :n_periods] ** 2, axis=1))))


def rolls_after(contrast: np.ndarray, n_periods: int) -> float:
    """The roll score (:func:`~granpipe.box.measures.roll_significance`) over the
    first ``n_periods`` periods of each replica, the replicas' scores combined as the
    point's are (:func:`~granpipe.box.measures.combined_score`); NaN when the record is
    shorter.

    Parameters
    ----------
    contrast : (replicas, periods) float [σ], c_j of each replica
        (:func:`~granpipe.box.measures.roll_contrast`)
    """
    c = np.atleast_2d(np.asarray(contrast, dtype=np.float64))
    if n_periods > c.shape[1]:
        return math.nan
    return combined_score([roll_significance(row, n_periods) for row in c])


def roll_displacement_after(contrast: np.ndarray, n_periods: int) -> float:
    """The centre's rise above the walls (:func:`~granpipe.box.measures.roll_displacement`)
    over the first ``n_periods`` periods, averaged over the replicas as the point's is
    [σ]; NaN when the record is shorter.

    Parameters
    ----------
    contrast : (replicas, periods) float [σ], c_j of each replica
    """
    c = np.atleast_2d(np.asarray(contrast, dtype=np.float64))
    if n_periods > c.shape[1]:
        return math.nan
    return float(np.nanmean([roll_displacement(row, n_periods) for row in c]))


def slips_between(p_s_period: np.ndarray, first: int, last: int) -> float:
    """p_s over the measured periods ``first`` … ``last`` − 1 (0 the first measured), all
    replicas pooled as the point's p_s is; NaN when the record is shorter than ``last``.

    Parameters
    ----------
    p_s_period : (replicas, periods) float, the fraction of bulk disks slipping per period
    """
    p = np.atleast_2d(np.asarray(p_s_period, dtype=np.float64))
    if last > p.shape[1] or not np.isfinite(p[:, first:last]).any():
        return math.nan
    return float(np.nanmean(p[:, first:last]))


def points_table(
    files: Sequence[str | Path],
    detection: Mapping,
    crystal_points: str = "initialisation",
    records: Sequence[int] = (),
    slip_windows: Sequence[Sequence[int]] = (),
) -> pd.DataFrame:
    """One row per ensemble file: N_l, N, Gamma, K_m, init, the walls (mu_w, side_walls,
    wall_torque), the measures, the cost and ``used`` (:func:`used_mask` under
    ``crystal_points``); ``s_c_<n>``, ``roll_<n>`` and ``roll_displacement_<n>`` for each
    record length n of ``records`` (:func:`convection_after`, :func:`rolls_after`,
    :func:`roll_displacement_after`), ``p_s_<a>_<b>`` for each window [a, b) of measured
    periods of ``slip_windows`` (:func:`slips_between`), and the roll criterion under
    ``detection`` over the whole record and each record length (:func:`roll_levels`);
    ``<column>_replica`` per replica (a tuple) of the slip columns and s_c, and
    ``convecting_replica``: each replica's own s_c at least ``detection.convection_s_c``."""
    rows = []
    for f in files:
        ds = read_dataset(f)
        row = {
            "point": ds.attrs["point"],
            "N_l": int(ds.attrs["N_l"]),
            "N": int(ds.attrs["N"]),
            "Gamma": float(ds.attrs["Gamma"]),
            "K_m": float(ds.attrs["K_m"]),
            "init": str(ds.attrs["init"]),
            "mu_w": float(ds.attrs["mu_w"]),
            "side_walls": str(ds.attrs["side_walls"]),
            "wall_torque": str(ds.attrs["wall_torque"]),
            "replicas": int(ds.attrs["replicas"]),
            "measured_periods": int(ds.attrs["measured_periods"]),
            "wall_seconds": float(ds.attrs["wall_seconds"]),
            "steps": int(ds.attrs["steps"]),
            "ns_per_particle_step": float(ds.attrs["ns_per_particle_step"]),
        }
        for c in _COLUMNS:
            row[c] = float(ds[c].values)
        for c in (*_FLIGHT, "s_c"):
            row[f"{c}_replica"] = _replica_values(ds, f"{c}_replica", c)
        for n in records:
            row[f"s_c_{int(n)}"] = convection_after(ds["s_j"].values, int(n))
            row[f"roll_{int(n)}"] = rolls_after(ds["roll_contrast"].values, int(n))
            row[f"roll_displacement_{int(n)}"] = roll_displacement_after(
                ds["roll_contrast"].values, int(n)
            )
        for a, b in slip_windows:
            row[f"p_s_{int(a)}_{int(b)}"] = slips_between(ds["p_s_period"].values, int(a), int(b))
        row.update(phase_slip_columns(ds))
        rows.append(row)
    table = roll_levels(pd.DataFrame(rows), detection)
    level = float(detection["convection_s_c"])
    table["convecting_replica"] = [tuple(bool(v >= level) for v in s) for s in table["s_c_replica"]]
    table["used"] = used_mask(table, crystal_points)
    order = ["init", *WALL_COLUMNS, "N_l", "Gamma"]
    return table.sort_values(order, kind="stable").reset_index(drop=True)


CRYSTAL_POINTS = ("initialisation", "intact")
"""Readings of "a crystal point" (``fits.crystal_points``): every point started from the
crystal, as the paper labels its points (its region A2 *is* defect nucleation in the
crystal), or only those whose crystal was intact when measurement began."""


def used_mask(table: pd.DataFrame, crystal_points: str = "initialisation") -> pd.Series:
    """True for the points the fits use: every point (``initialisation``: labelled by
    their start, the paper's reading), or every random point and the crystal points whose
    crystal was intact when measurement began (``intact``: ``crystal_intact`` = 1)."""
    if crystal_points not in CRYSTAL_POINTS:
        raise ValueError(f"crystal_points must be one of {CRYSTAL_POINTS}, not {crystal_points!r}")
    if crystal_points == "initialisation":
        return pd.Series(True, index=table.index)
    return (table["init"] != "crystal") | (table["crystal_intact"] == 1)


WALL_COLUMNS = ("mu_w", "side_walls", "wall_torque")
"""Columns of the points table that make a point's :class:`~granpipe.box.layout.Walls`."""


def _groups(table: pd.DataFrame, used_only: bool = True):
    """(init, N_l, walls, points sorted by Γ) per group; without the points left out of the
    fits unless ``used_only`` is False."""
    for (init, mu_w, side, torque, n_l), g in table.groupby(
        ["init", *WALL_COLUMNS, "N_l"], sort=True
    ):
        if used_only:  # a table without the column (built by hand) uses every point
            g = g[g["used"].astype(bool)] if "used" in g else g
        if len(g):
            yield init, int(n_l), Walls(float(mu_w), side, torque), g.sort_values("Gamma")


CRITERIA = {
    # name: (column, config key, interpolation scale)
    "bouncing": ("s_b", "bouncing_s_b", "log"),
    "detachment": ("detachment_fraction", "detachment_fraction", "linear"),
    "convection": ("s_c", "convection_s_c", "log"),
    "rolls": ("roll_level", None, "linear"),
}
"""Onset criteria: (table column, detection key of its level, interpolation scale); the
rolls' column is :func:`roll_levels`, rolls where it reaches 1 (no key)."""


THRESHOLD_COLUMNS = (
    "init", "N_l", "mu_w", "side_walls", "wall_torque", "criterion", "measure", "level",
    "Gamma", "K_m", "Gamma_low", "Gamma_high", "status", "n_crossings", "n_points",
)  # fmt: skip
"""Columns of :func:`thresholds_table` (also when no group has a point the fits use, e.g.
a grid of crystal starts none of which stayed intact)."""


def _criteria(table: pd.DataFrame) -> dict:
    """:data:`CRITERIA` and, for each record length n the table holds (``s_c_<n>``,
    ``roll_level_<n>``, not longer than every point's record), ``convection_<n>periods`` and
    ``rolls_<n>periods``: Eq. (B2) and the roll criterion over the first n cycles (the
    onset as a function of how long one looks)."""
    out = dict(CRITERIA)
    for col in table.columns:
        for prefix, name, key, scale in (
            ("s_c_", "convection", "convection_s_c", "log"),
            ("roll_level_", "rolls", None, "linear"),
        ):
            n = col[len(prefix) :]
            if col.startswith(prefix) and n.isdigit() and table[col].notna().all():
                out[f"{name}_{n}periods"] = (col, key, scale)
    return out


def roll_levels(table: pd.DataFrame, detection: Mapping) -> pd.DataFrame:
    """``table`` with ``roll_level`` (over the whole record) and ``roll_level_<n>`` (over
    the first n periods, for each ``roll_<n>``): the roll criterion
    (:func:`~granpipe.box.measures.roll_level`) of the score and the centre's rise."""
    out = table.copy()
    pairs = [("roll_significance", "roll_displacement", "roll_level")]
    for col in table.columns:
        n = col.removeprefix("roll_")
        if n.isdigit() and f"roll_displacement_{n}" in table:
            pairs.append((col, f"roll_displacement_{n}", f"roll_level_{n}"))
    for score, rise, level in pairs:
        out[level] = [
            roll_level(z, d, detection)
            for z, d in zip(table[score].to_numpy(float), table[rise].to_numpy(float), strict=True)
        ]
    return out


def thresholds_table(table: pd.DataFrame, detection: Mapping) -> pd.DataFrame:
    """Thresholds in Γ per (init, N_l, criterion), with the bracketing grid points; the
    criteria of :func:`_criteria`."""
    rows = []
    criteria = _criteria(table)
    for init, n_l, walls, g in _groups(table):
        for name, (col, key, scale) in criteria.items():
            crit = 1.0 if key is None else float(detection[key])
            values = g[col].to_numpy()
            if scale == "log":
                # a measure at exactly zero (a rigid bed) sits below any positive criterion
                values = np.where(values > 0, values, crit * 1e-12)
            th = threshold_crossing(g["Gamma"].to_numpy(), values, crit, scale=scale)
            rows.append(
                {
                    "init": init,
                    "N_l": n_l,
                    **walls._asdict(),
                    "criterion": name,
                    "measure": col,
                    "level": crit,
                    "Gamma": th.value,
                    "K_m": th.value**2 if math.isfinite(th.value) else math.nan,
                    "Gamma_low": th.low,
                    "Gamma_high": th.high,
                    "status": th.status,
                    "n_crossings": th.n_crossings,
                    "n_points": len(g),
                }
            )
    return pd.DataFrame(rows, columns=list(THRESHOLD_COLUMNS))


TEMPERATURE_POINTS = ("bouncing", "all")
"""Points of the T_g* fits (``fits.temperature_points``): those whose bed leaves the plate
(the paper's regions A and B both lie inside the bouncing bed: "the transition occurs at
K_m ≃ 3.3 … the energy value at the onset of convection"), or every point (the comoving
bed's T_g* of 1e-11 … 1e-8 included, whose step to the bouncing bed's ~1e-3 then takes a
breakpoint)."""


def bouncing_mask(table: pd.DataFrame, detection: Mapping) -> np.ndarray:
    """(n,) bool: the bed leaves the plate — its detachment fraction (the share of the
    cycle with a gap under the lowest disk) exceeds ``detection.detachment_fraction``."""
    return table["detachment_fraction"].to_numpy() > float(detection["detachment_fraction"])


def temperature_fits(table: pd.DataFrame, fits_cfg: Mapping, detection: Mapping) -> dict:
    """Segmented fits of ln T_g* vs ln K_m per group over the points of
    ``fits.temperature_points`` (:data:`TEMPERATURE_POINTS`; ``detection`` flags the
    bouncing bed, :func:`bouncing_mask`): {(init, N_l, walls): dict}."""
    out = {}
    level = float(fits_cfg["confidence"])
    which = str(fits_cfg.get("temperature_points", "bouncing"))
    if which not in TEMPERATURE_POINTS:
        raise ValueError(f"temperature_points must be one of {TEMPERATURE_POINTS}, not {which!r}")
    for init, n_l, walls, g in _groups(table):
        k = int(fits_cfg[f"breakpoints_{init}"])
        ok = np.isfinite(g["T_g"]) & (g["T_g"] > 0)
        if which == "bouncing":
            ok &= bouncing_mask(g, detection)
        g = g[ok]
        sem = g["T_g_sem"].to_numpy()
        sem = sem if np.all(np.isfinite(sem) & (sem > 0)) else None
        try:
            fit, bic = regression.loglog_segmented(
                g["K_m"].to_numpy(),
                g["T_g"].to_numpy(),
                k,
                T_g_sem=sem,
                level=level,
            )
        except (ValueError, np.linalg.LinAlgError) as exc:
            note = f"T_g* fit refused on {len(g)} points: {exc}"
            out[(init, n_l, walls)] = _refused_temperature_fit(k, len(g), note)
            continue
        bp, bp_ci = fit.exp_breakpoints()
        out[(init, n_l, walls)] = {
            "fit": fit,
            "n_breakpoints": k,
            "breakpoints_K_m": np.atleast_1d(bp),
            "breakpoints_K_m_ci": np.atleast_2d(bp_ci) if k else np.zeros((0, 2)),
            "breakpoints_K_m_se": np.atleast_1d(np.exp(fit.breakpoints) * fit.breakpoint_se),
            "slopes": fit.slopes,
            "slope_se": fit.slope_se,
            "slope_ci": fit.slope_ci,
            "bic": bic,
            "n_points": int(fit.n),
            "regions": REGION_NAMES[k],
        }
    return out


def _refused_temperature_fit(k: int, n_points: int, note: str) -> dict:
    """A group's entry of :func:`temperature_fits` without a fit (no ``"fit"`` key): its
    breakpoints and slopes NaN, ``error`` saying why."""
    nan = math.nan
    return {
        "error": note,
        "n_breakpoints": k,
        "breakpoints_K_m": np.full(k, nan),
        "breakpoints_K_m_ci": np.full((k, 2), nan),
        "breakpoints_K_m_se": np.full(k, nan),
        "slopes": np.full(k + 1, nan),
        "slope_se": np.full(k + 1, nan),
        "slope_ci": np.full((k + 1, 2), nan),
        "n_points": int(n_points),
        "regions": REGION_NAMES[k],
    }


SLIP_WEIGHTS = ("unweighted", "weighted")
"""Readings of the Arrhenius fit of ln p_s on 1/K_m (``fits.slip_weights``): unweighted
least squares, its error from the residuals (the paper's "exponential fit functions"
state no weights), or weighted by each point's error (the scatter over periods, or the
counts). The other reading's rows carry the suffix ``_weighted`` / ``_unweighted``."""


SLIP_REPLICAS = ("pooled", "each")
"""What one point of the Arrhenius fit is (``fits.slip_replicas``): a parameter point, its
p_s pooled over its replicas (the residual scatter about the line holds the replicas'
spread through the scatter of the point means), or each replica of each point (the spread
enters the residuals directly; a replica without a slip is left out of the line, as a
point without one is, so where slips are rare this reading leans high)."""


def _slip_data(g: pd.DataFrame, each: bool) -> tuple[np.ndarray, dict]:
    """K_m and the slip columns of :data:`_FLIGHT` of a group's points: (n,) per point,
    or per replica of each point (``each``, from the ``<column>_replica`` columns)."""
    if not each:
        return g["K_m"].to_numpy(), {c: g[c].to_numpy(dtype=float) for c in _FLIGHT}
    n = g["p_s_replica"].map(len).to_numpy()
    cols = {c: np.concatenate([np.asarray(v, dtype=float) for v in g[f"{c}_replica"]])
            for c in _FLIGHT}  # fmt: skip
    return np.repeat(g["K_m"].to_numpy(), n), cols


CRYSTAL_REGIONS = ("temperature", "convection", "replica", "slips")
"""Where the crystal's region A2 ends and B begins in the barrier fits
(``fits.crystal_regions``): at the second T_g* break (Fig. 5's dashed lines are "the
regions defined in Fig. 4"), at the crystal's convection onset by Eq. (B2) (the paper
has B begin "upon the onset of convection"; the two coincide in the paper, not
necessarily here), per replica (``replica``): above the first break each replica of a
crystal point is its own point of the fit, in B if its own s_c reaches the convection
level (``detection.convection_s_c``), else in A2 (where crystals nucleate defects, one
replica may convect while another stays intact at the same Γ), or where the slip curve
itself bends (``slips``): the break of a continuous two-segment fit of ln p_s against
1/K_m over the slipping points above the first T_g* break (A2's "steep increase of slip
events, which slows down considerably" in B, the paper's Sec. IV; :func:`slip_bends`).
A1 ends at the first T_g* break in every reading."""

SLIP_BEND_MIN_POINTS = 3
"""Fewest slipping points on either side of the crystal's slip bend (``slips`` reading):
each segment must show its own slope."""


def slip_bends(table: pd.DataFrame, tfits: Mapping, fits_cfg: Mapping) -> dict:
    """(init, N_l, walls) -> the crystal's slip bend under ``fits.crystal_regions: slips``
    ({} under the other readings): {"K_m", "K_m_ci" (2,), "n_points"} from
    :func:`granpipe.analysis.regression.segmented_fit` with one break of y = ln p_s
    against x = 1/K_m (its profile-likelihood interval at ``fits.confidence``), over the
    points of ``fits.slip_replicas`` with p_s > 0 above the first T_g* break; {"error"}
    where it cannot be fitted, saying why."""
    if str(fits_cfg.get("crystal_regions", "temperature")) != "slips":
        return {}
    each = str(fits_cfg.get("slip_replicas", "pooled")) == "each"
    level = float(fits_cfg["confidence"])
    out = {}
    for init, n_l, walls, g in _groups(table):
        tf = tfits.get((init, n_l, walls)) or {}
        if init != "crystal" or tf.get("n_breakpoints", 0) != 2:
            continue
        if "fit" not in tf:
            out[(init, n_l, walls)] = {"error": f"no temperature fit: {tf.get('error')}"}
            continue
        K, kw = _slip_data(g, each)
        p = kw["p_s"]
        use = np.isfinite(p) & (p > 0) & (K > tf["breakpoints_K_m"][0])
        if use.sum() < 2 * SLIP_BEND_MIN_POINTS:
            out[(init, n_l, walls)] = {
                "error": f"{int(use.sum())} slipping points above the first T_g* break are too "
                f"few for the slip bend ({2 * SLIP_BEND_MIN_POINTS} needed; "
                "fits.crystal_regions: slips)"
            }
            continue
        seg = regression.segmented_fit(
            1.0 / K[use], np.log(p[use]), 1, min_points=SLIP_BEND_MIN_POINTS, level=level
        )
        psi, (lo, hi) = float(seg.breakpoints[0]), seg.breakpoint_ci[0]
        out[(init, n_l, walls)] = {
            "K_m": 1.0 / psi,
            "K_m_ci": np.array([1.0 / hi, 1.0 / lo]),
            "n_points": int(use.sum()),
        }
    return out


def _replica_regions(g: pd.DataFrame, keep: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """(kept replicas,) int: the region of each replica of the group's points under the
    ``replica`` reading of :data:`CRYSTAL_REGIONS` (the regions below the last break by
    K_m; above it, the last region if the replica convects), in :func:`_slip_data`'s
    order with ``keep`` applied."""
    if "convecting_replica" not in g:
        raise ValueError("the points carry no per-replica s_c: A2 and B cannot be split by "
                         "replica (fits.crystal_regions: replica)")  # fmt: skip
    K, _ = _slip_data(g, True)
    convecting = np.concatenate([np.asarray(v, dtype=bool) for v in g["convecting_replica"]])
    if len(convecting) != len(K):
        raise ValueError("convecting_replica and p_s_replica differ in length")
    below = np.searchsorted(np.sort(bounds)[:-1], K, side="left")
    last = len(bounds) - 1
    return np.where(below == last, below + convecting, below)[keep]


def _bend_bounds(bounds: np.ndarray, bend: Mapping | None) -> np.ndarray:
    """The crystal's region bounds in K_m with A2/B moved to its slip bend."""
    if not bend:
        raise ValueError("no slip bend was fitted (fits.crystal_regions: slips)")
    if "error" in bend:
        raise ValueError(bend["error"])
    return np.array([bounds[0], bend["K_m"]])


def _onset_bounds(bounds: np.ndarray, k_onset: float | None) -> np.ndarray:
    """The crystal's region bounds in K_m with A2/B moved to the convection onset."""
    if k_onset is None or not math.isfinite(k_onset):
        raise ValueError("the crystal's convection onset is not on the grid: A2 and B "
                         "cannot be split there (fits.crystal_regions: convection)")  # fmt: skip
    if k_onset <= bounds[0]:
        raise ValueError(f"the crystal's convection onset K_m = {k_onset:.3g} lies below its "
                         f"first T_g* break {bounds[0]:.3g}")  # fmt: skip
    return np.array([bounds[0], k_onset])


def convection_onsets(ths: pd.DataFrame) -> dict:
    """(init, N_l, walls) -> K_m of the convection onset by Eq. (B2) over the whole
    record (NaN where the grid does not bracket it), from :func:`thresholds_table`."""
    rows = ths[ths["criterion"] == "convection"]
    return {(r.init, int(r.N_l), _walls_of(r)): float(r.K_m) for r in rows.itertuples()}


def slip_fits(
    table: pd.DataFrame,
    tfits: Mapping,
    fits_cfg: Mapping,
    onsets: Mapping | None = None,
    bends: Mapping | None = None,
) -> dict:
    """Arrhenius fits per group: {(init, N_l, walls): {region: ArrheniusFit}} incl. "all",
    in the reading of ``fits.slip_weights`` (:data:`SLIP_WEIGHTS`) and, under
    ``<region>_<other reading>``, the other; the fitted points are those of
    ``fits.slip_replicas`` (:data:`SLIP_REPLICAS`), the crystal's regions those of
    ``fits.crystal_regions`` (:data:`CRYSTAL_REGIONS`; ``onsets`` from
    :func:`convection_onsets` for the reading ``convection``, ``bends`` from
    :func:`slip_bends` for the reading ``slips``; under ``replica`` the
    crystal's points are its replicas whatever ``fits.slip_replicas`` says)."""
    level = float(fits_cfg["confidence"])
    main = str(fits_cfg.get("slip_weights", "unweighted"))
    if main not in SLIP_WEIGHTS:
        raise ValueError(f"slip_weights must be one of {SLIP_WEIGHTS}, not {main!r}")
    other = SLIP_WEIGHTS[1 - SLIP_WEIGHTS.index(main)]
    each = str(fits_cfg.get("slip_replicas", "pooled"))
    if each not in SLIP_REPLICAS:
        raise ValueError(f"slip_replicas must be one of {SLIP_REPLICAS}, not {each!r}")
    regions = str(fits_cfg.get("crystal_regions", "temperature"))
    if regions not in CRYSTAL_REGIONS:
        raise ValueError(f"crystal_regions must be one of {CRYSTAL_REGIONS}, not {regions!r}")
    by_onset = regions == "convection"
    out = {}
    for init, n_l, walls, g in _groups(table):
        by_replica = init == "crystal" and regions == "replica"
        K, kw = _slip_data(g, each == "each" or by_replica)
        keep = np.isfinite(kw["p_s"]) & (kw["n_trials"] > 0)
        K = K[keep]
        kw = {k: v[keep] for k, v in kw.items()}
        sem = kw.pop("p_s_sem")
        # the scatter over periods is the honest error where slips happened; counts otherwise
        kw["p_s_sem"] = np.where(np.isfinite(sem) & (sem > 0), sem, np.nan)
        if np.isnan(kw["p_s_sem"]).any():
            kw.pop("p_s_sem")
        # unweighted: p_s alone (n_trials kept for the zero-count bounds)
        plain = {"p_s": kw["p_s"], "n_trials": kw["n_trials"]}
        fits = {}
        tf = tfits.get((init, n_l, walls)) or {}
        for reading, args in ((main, plain if main == "unweighted" else kw),
                              (other, plain if other == "unweighted" else kw)):  # fmt: skip
            suffix = "" if reading == main else f"_{reading}"
            try:
                fits[f"all{suffix}"] = regression.arrhenius_fit(K, level=level, **args)
            except ValueError as exc:
                fits[f"all{suffix}"] = regression.ArrheniusFit.refused(level, str(exc))
            if tf.get("n_breakpoints", 0) == 0:
                continue
            try:
                if "fit" not in tf:
                    raise ValueError(f"no temperature fit to split the regions: {tf['error']}")
                bounds = tf["breakpoints_K_m"]
                if init == "crystal" and by_onset and len(bounds) == 2:
                    bounds = _onset_bounds(bounds, (onsets or {}).get((init, n_l, walls)))
                if init == "crystal" and regions == "slips" and len(bounds) == 2:
                    bounds = _bend_bounds(bounds, (bends or {}).get((init, n_l, walls)))
                if by_replica:
                    labels = _replica_regions(g, keep, bounds)
                    by = regression.arrhenius_by_label(
                        K, labels, tf["regions"], level=level, **args
                    )
                else:
                    by = regression.arrhenius_by_region(
                        K, bounds, tf["regions"], level=level, **args
                    )
            except ValueError as exc:
                by = {r: regression.ArrheniusFit.refused(level, str(exc)) for r in tf["regions"]}
            fits.update({f"{r}{suffix}": f for r, f in by.items()})
        out[(init, n_l, walls)] = fits
    if "p_s_flight" in table.columns:  # the same fits with slips sampled in flight
        names = [f"{c}{r}" for c in _FLIGHT for r in ("", "_replica")
                 if f"{c}{r}_flight" in table.columns]  # fmt: skip
        flight = table.assign(**{c: table[f"{c}_flight"] for c in names})
        flight = flight.drop(columns=[f"{c}_flight" for c in names])
        for key, fl in slip_fits(flight, tfits, fits_cfg, onsets, bends).items():
            out.setdefault(key, {}).update({f"{r}_flight": f for r, f in fl.items()})
    return out


def _fmt_q(name: str, init: str, n_l: int, walls: Walls) -> str:
    return f"{name}[N_l={n_l},init={init},{walls.text}]"


def _paper(value, walls: Walls):
    """The paper's value on rows of its own walls (Table I's side-wall friction, the whole
    box shaken), None on the others."""
    return value if is_paper_walls(walls) else None


def is_paper_walls(walls: Walls) -> bool:
    """Table I's side-wall friction with the whole box driven (Sec. II), either torque."""
    return math.isclose(walls.mu_w, PAPER_MU_W) and walls.side_walls == "shaken"


def _walls_of(row) -> Walls:
    return Walls(float(row.mu_w), str(row.side_walls), str(row.wall_torque))


def summary_rows(
    table: pd.DataFrame,
    ths: pd.DataFrame,
    tfits: Mapping,
    sfits: Mapping,
    bends: Mapping | None = None,
) -> list[dict]:
    """Rows of ``summary.csv`` (docs/results.md); quantities name N_l and init; the
    crystal's slip bend (``K_m_slip_bend``) where ``bends`` (:func:`slip_bends`) has it."""
    rows = []
    windows = [c for c in table.columns if re.fullmatch(r"p_s_\d+_\d+", c)]
    phases = [c for c in table.columns if re.fullmatch(r"p_s_phase_\d+of\d+", c)]
    for r in table.to_dict("records"):
        for name, col in ORDER_ROWS.items():
            rows.append(summary_row("box", f"{name}[{r['point']}]", r[col], "1", n=r["replicas"]))
        for col in windows:  # p_s over a window of measured periods ("p_s_0_50": 1-50)
            if math.isfinite(r[col]):
                name = f"{col.replace('p_s', 'p_s_periods')}[{r['point']}]"
                rows.append(summary_row("box", name, r[col], "1", n=r["replicas"]))
        for col in phases:  # p_s between the same phase of consecutive cycles
            rows.append(summary_row("box", f"{col}[{r['point']}]", r[col], "1", n=r["replicas"]))
    for init, n_l, walls, g in _groups(table, used_only=False):
        if init == "crystal":
            for name, col in (
                ("crystal_intact_points", "crystal_intact"),
                ("crystal_intact_points_ramp_end", "crystal_intact_ramp"),
            ):
                rows.append(
                    summary_row("box", _fmt_q(name, init, n_l, walls),
                                int((g[col] == 1).sum()), "1", n=len(g))
                )  # fmt: skip
    for r in ths.itertuples(index=False):
        th = Threshold(
            r.Gamma, r.Gamma_low, r.Gamma_high, status=r.status, n_crossings=r.n_crossings
        )
        paper = PAPER["Gamma_bouncing"] if r.criterion in ("bouncing", "detachment") else None
        if r.criterion == "convection" and r.init == "random":
            paper = math.sqrt(PAPER["K_m_break_random"])
        q = _fmt_q(f"Gamma_{r.criterion}", r.init, r.N_l, _walls_of(r))
        rows.append(th.summary_row("box", q, _paper(paper, _walls_of(r)), "1", r.n_points))
    for (init, n_l, walls), tf in tfits.items():
        for i, name in enumerate(["K_m_break_1", "K_m_break_2"][: tf["n_breakpoints"]]):
            paper = PAPER["K_m_break_random"] if (init == "random" and i == 0) else None
            lo, hi = tf["breakpoints_K_m_ci"][i]
            rows.append(
                summary_row(
                    "box",
                    _fmt_q(name, init, n_l, walls),
                    tf["breakpoints_K_m"][i],
                    "1",
                    fit_error=tf["breakpoints_K_m_se"][i],
                    ci_low=lo,
                    ci_high=hi,
                    n=tf["n_points"],
                    paper_value=_paper(paper, walls),
                )  # fmt: skip
            )
        for i, region in enumerate(tf["regions"]):
            lo, hi = tf["slope_ci"][i]
            rows.append(
                summary_row(
                    "box",
                    _fmt_q(f"T_g_slope_{region}", init, n_l, walls),
                    tf["slopes"][i],
                    "1",
                    fit_error=tf["slope_se"][i],
                    ci_low=lo,
                    ci_high=hi,
                    n=tf["n_points"],
                )  # fmt: skip
            )
    for (init, n_l, walls), fits in sfits.items():
        for region, af in fits.items():
            paper = _paper(PAPER.get(f"E_b_{init}_{region}"), walls)
            rows.append(af.summary_row("box", _fmt_q(f"E_b_{region}", init, n_l, walls), paper))
    for (init, n_l, walls), bend in (bends or {}).items():
        lo, hi = bend.get("K_m_ci", (None, None))
        rows.append(
            summary_row("box", _fmt_q("K_m_slip_bend", init, n_l, walls), bend.get("K_m"), "1",
                        ci_low=lo, ci_high=hi, n=bend.get("n_points"))
        )  # fmt: skip
    return rows


def cost_rows(table: pd.DataFrame) -> list[dict]:
    """Rows of ``fits/costs.csv`` (the columns of ``summary.csv``): the wall-clock cost per
    particle-step of each (N_l, init, walls). Wall-clock time differs between two runs of
    the same config, so it stays out of ``summary.csv``, which two such runs give byte for
    byte."""
    rows = []
    for init, n_l, walls, g in _groups(table, used_only=False):
        cost = float(1e9 * g["wall_seconds"].sum() / max((g["steps"] * g["N"]).sum(), 1))
        rows.append(
            summary_row("box", _fmt_q("cost_ns_per_particle_step", init, n_l, walls), cost, "ns",
                        n=len(g))
        )  # fmt: skip
    return rows


_TEXT_COLUMNS = {
    "init": "initial state",
    "side_walls": "drive of the side walls",
    "wall_torque": "torque of the walls' friction",
}


def fits_datasets(
    table: pd.DataFrame,
    ths: pd.DataFrame,
    tfits: Mapping,
    sfits: Mapping,
    bends: Mapping | None = None,
) -> dict[str, xr.Dataset]:
    """Labelled datasets for ``fits/phase_diagram.nc``, ``temperature.nc``, ``slips.nc``."""

    def lab(units, long_name):
        return {"units": units, "long_name": long_name}

    pts = xr.Dataset(
        {
            c: ("point", table[c].to_numpy(dtype=float), lab("1", c))
            for c in table.columns
            # the per-replica slip columns stay in the ensemble files
            if c not in ("point", *_TEXT_COLUMNS) and not c.endswith(_REPLICA_SUFFIXES)
        },
        coords={
            "point": ("point", table["point"].to_numpy(dtype=str), lab("1", "parameter point")),
            **{
                c: ("point", table[c].to_numpy(dtype=str), lab("1", long))
                for c, long in _TEXT_COLUMNS.items()
            },
        },
    )
    for c, u in (("s_c", "sigma"), ("s_b", "sigma"), ("T_g", "m*g*sigma")):
        pts[c].attrs["units"] = u
    th = xr.Dataset(
        {
            f"threshold_{c}": (
                "threshold",
                ths[c].to_numpy(dtype=float),
                lab("1", f"threshold {c}"),
            )
            for c in (
                "N_l",
                "mu_w",
                "level",
                "Gamma",
                "K_m",
                "Gamma_low",
                "Gamma_high",
                "n_crossings",
            )  # fmt: skip
        },
        coords={
            "threshold": ("threshold", np.arange(len(ths)), lab("1", "threshold index")),
            **{
                f"threshold_{c}": ("threshold", ths[c].to_numpy(dtype=str), lab("1", c))
                for c in ("init", "criterion", "status", "side_walls", "wall_torque")
            },
        },
    )
    th["threshold_N_l"].attrs["units"] = "1/sigma"
    phase = xr.merge([pts, th])
    trows = []
    for (init, n_l, walls), tf in tfits.items():
        note = tf.get("error", "")
        for i in range(tf["n_breakpoints"]):
            trows.append(
                (init, n_l, *walls, "breakpoint", i, tf["breakpoints_K_m"][i],
                 tf["breakpoints_K_m_se"][i], *tf["breakpoints_K_m_ci"][i], note)
            )  # fmt: skip
        for i in range(len(tf["slopes"])):
            trows.append(
                (init, n_l, *walls, f"slope_{tf['regions'][i]}", i, tf["slopes"][i],
                 tf["slope_se"][i], *tf["slope_ci"][i], note)
            )  # fmt: skip
        intercept = tf["fit"].intercept if "fit" in tf else math.nan
        trows.append((init, n_l, *walls, "intercept", 0, intercept, *[math.nan] * 3, note))
    temp = _rows_dataset(trows, "temperature fit of ln T_g* on ln K_m")
    srows = []
    for (init, n_l, walls), fits in sfits.items():
        for region, af in fits.items():
            srows.append(
                (init, n_l, *walls, f"E_b_{region}", 0, af.E_b, af.E_b_se, *af.E_b_ci, af.note)
            )
            srows.append(
                (init, n_l, *walls, f"log_A_{region}", 0, af.log_A, af.log_A_se, np.nan, np.nan,
                 af.note)
            )  # fmt: skip
    for (init, n_l, walls), bend in (bends or {}).items():  # the crystal's A2/B bound
        lo, hi = bend.get("K_m_ci", (np.nan, np.nan))
        srows.append((init, n_l, *walls, "K_m_bend", 0, bend.get("K_m", np.nan), np.nan, lo, hi,
                      bend.get("error", "")))  # fmt: skip
    slips = _rows_dataset(srows, "Arrhenius fit p_s = A exp(-E_b/K_m)")
    return {"phase_diagram": phase, "temperature": temp, "slips": slips}


def _rows_dataset(rows, what: str) -> xr.Dataset:
    cols = [
        "init", "N_l", *WALL_COLUMNS, "name", "index", "value", "se", "ci_low", "ci_high", "note"
    ]  # fmt: skip
    df = pd.DataFrame(rows, columns=cols)

    def lab(units, long_name):
        return {"units": units, "long_name": long_name}

    return xr.Dataset(
        {
            "value": ("row", df["value"].to_numpy(float), lab("1", what)),
            "se": ("row", df["se"].to_numpy(float), lab("1", "standard error")),
            "ci_low": ("row", df["ci_low"].to_numpy(float), lab("1", "CI lower bound")),
            "ci_high": ("row", df["ci_high"].to_numpy(float), lab("1", "CI upper bound")),
            "N_l": ("row", df["N_l"].to_numpy(float), lab("1/sigma", "linear density")),
            "mu_w": ("row", df["mu_w"].to_numpy(float), lab("1", "side-wall friction")),
        },
        coords={
            "row": ("row", np.arange(len(df)), lab("1", "row")),
            **{c: ("row", df[c].to_numpy(str), lab("1", _TEXT_COLUMNS[c])) for c in _TEXT_COLUMNS},
            "name": ("row", df["name"].to_numpy(str), lab("1", "fitted quantity")),
            "index": ("row", df["index"].to_numpy(int), lab("1", "index within the quantity")),
            "note": ("row", df["note"].to_numpy(str), lab("1", "why the value is empty")),
        },
    )
