"""Thresholds in Γ from measures on a grid (box phase diagram, Fig. 3).

The box study runs a grid of Γ for each N_l and initial state and measures, at
each point, s_b (bouncing bed when s_b > σ/30), s_c (convection when s_c > σ),
or the detachment fraction (Fortini & Huang 2015, Appendix B; docs/box.md). The
threshold is where the measure crosses its criterion, linearly interpolated
between the two bracketing grid points:

    Γ* = Γ_i + (Γ_{i+1} − Γ_i) (c − m_i) / (m_{i+1} − m_i)

(with ``scale="log"``, m and c are replaced by their logarithms: a measure
growing exponentially with Γ, as s_b does across the bouncing transition, is
then interpolated without bias). A measure on a grid brackets its threshold;
the grid points themselves are always reported.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["Threshold", "threshold_crossing", "threshold_from_flags"]


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
        return dict(
            study=study,
            quantity=quantity,
            value=self.value,
            unit=unit,
            fit_error=None,
            ci_low=lo,
            ci_high=hi,
            n=n,
            paper_value=paper_value,
        )


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
