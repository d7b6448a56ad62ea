"""Parameters of the tapped column (docs/column.md; paper Eqs. 2–3, 16–19, 27–30).

A :class:`ColumnParams` holds one monodisperse column: ``N`` particles of mass ``m`` and
radius ``r`` on a vertical line, gravity ``g``, Walton–Braun–Mindlin stiffness ``K`` with
unloading parameter ``e`` (K̂ = eK, Eq. 16), and the tap drive of Eq. (2):
``y0(t) = a sin ωt`` for ``0 < t mod T ≤ π/ω``, ``0`` for the rest of each period ``T``.

Units are whatever the caller's numbers are in (the figure-1 set is cgs: cm, g, s; the
generic set is read in SI: m, kg, s — see :data:`PARAMETER_SETS`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping

import numpy as np

from ..errors import ConfigError

__all__ = [
    "ColumnParams",
    "PARAMETER_SETS",
    "parameter_set",
    "equilibrium_positions",
    "restitution_from_e",
    "e_from_restitution",
    "physics",
]


@dataclasses.dataclass(frozen=True)
class ColumnParams:
    """One monodisperse tapped column.

    Attributes
    ----------
    N : int
        Number of particles (Eq. 1).
    m : float [mass]
        Particle mass.
    r : float [length]
        Particle radius; h = 2r is the spacing of touching particles.
    g : float [length/time²]
        Gravitational acceleration.
    K : float [mass/time²]
        WBM stiffness; loading spring K(1+e), unloading K(1−e) (Eqs. 17–19).
    e : float [1]
        K̂/K, ``0 <= e < 1``; restitution ϱ² = (1 − e)/(1 + e) (Eq. 16).
    a : float [length]
        Tap amplitude (Eq. 2).
    omega : float [1/time]
        Tap angular frequency; a tap lasts π/ω (Eq. 2).
    T : float [time]
        Tap period, ``T > π/ω``.
    smooth : bool
        Use the smooth σ_α, χ_α of Eq. (30) instead of the exact sign and step (Eq. 9).
    alpha_sigma : float [time/length]
        α of σ_α(s) = tanh(α s) (argument: a relative velocity).
    alpha_chi : float [1/length]
        α of χ_α(s) = (1 + tanh(α s))/2 (argument: a compression).
    """

    N: int
    m: float
    r: float
    g: float
    K: float
    e: float
    a: float
    omega: float
    T: float
    smooth: bool = False
    alpha_sigma: float = 0.0
    alpha_chi: float = 0.0

    def __post_init__(self):
        if int(self.N) < 1:
            raise ConfigError(f"column: N must be >= 1, got {self.N}")
        for name in ("m", "r", "K"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"column: {name} must be > 0, got {getattr(self, name)}")
        if not 0.0 <= self.e < 1.0:
            raise ConfigError(f"column: e must satisfy 0 <= e < 1, got {self.e}")
        if self.a < 0 or self.g < 0:
            raise ConfigError("column: a and g must be >= 0")
        if self.a > 0:
            if not self.omega > 0:
                raise ConfigError(f"column: omega must be > 0, got {self.omega}")
            if not self.T > self.tap_duration:
                raise ConfigError(
                    f"column: the period T = {self.T} must exceed the tap duration "
                    f"pi/omega = {self.tap_duration:.6g} (Eq. 2)"
                )
        if self.smooth and not (self.alpha_sigma > 0 and self.alpha_chi > 0):
            raise ConfigError("column: the smooth model (Eq. 30) needs alpha_sigma, alpha_chi > 0")

    # ------------------------------------------------------------ derived scales
    @property
    def mass_ratio(self) -> float:
        """𝔐 = mg/K [length]: the compression one particle's weight causes (Eq. 26)."""
        return self.m * self.g / self.K

    @property
    def h(self) -> float:
        """h = 2r, the spacing of touching particles (Section 4)."""
        return 2.0 * self.r

    @property
    def tap_duration(self) -> float:
        """π/ω [time], the time the floor moves in each period (Eq. 2)."""
        return math.pi / self.omega if self.omega > 0 else 0.0

    @property
    def contact_frequency(self) -> float:
        """ω_c = sqrt(K/m) [1/time]."""
        return math.sqrt(self.K / self.m)

    @property
    def max_frequency(self) -> float:
        """Upper bound of the chain's normal-mode frequencies, 2 sqrt(K(1+e)/m) [1/time]."""
        return 2.0 * math.sqrt(self.K * (1.0 + self.e) / self.m)

    @property
    def restitution(self) -> float:
        """ϱ = sqrt((1 − e)/(1 + e)) (Eq. 16)."""
        return restitution_from_e(self.e)

    @property
    def velocity_scale(self) -> float:
        """A velocity for tolerances and norms: max(aω, sqrt(g r), ω_c r·1e-3)."""
        return max(
            self.a * self.omega, math.sqrt(self.g * self.r), 1e-3 * self.contact_frequency * self.r
        )

    def with_(self, **changes) -> ColumnParams:
        """A copy with some fields changed (re-validated)."""
        return dataclasses.replace(self, **changes)

    def as_array(self) -> np.ndarray:
        """Packed float64 parameters for the kernels (see ``discrete.P_*``)."""
        return np.array(
            [
                self.m,
                self.r,
                self.g,
                self.K,
                self.e,
                self.a,
                self.omega,
                self.T,
                self.alpha_sigma,
                self.alpha_chi,
                self.tap_duration,
            ],
            dtype=np.float64,
        )

    def to_dict(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_mapping(cls, cfg: Mapping) -> ColumnParams:
        """Build from a config mapping (keys of the ``column.physics`` config sections).

        Accepted keys: ``N, m, r, g, e, a`` and either ``K`` or ``stiffness_factor`` κ
        (K = κ N m g / r; the paper's figure-1 choice is κ = 2, K = 2Ng/r with m = 1),
        either ``omega`` or ``Gamma`` (ω = 2πΓ) or ``tap_duration`` (ω = π/duration),
        ``T``, and optionally ``smooth, alpha_sigma, alpha_chi``.
        """
        c = dict(cfg)
        N = int(c["N"])
        m, r, g = float(c["m"]), float(c["r"]), float(c["g"])
        if "K" in c:
            K = float(c["K"])
        else:
            K = float(c.get("stiffness_factor", 2.0)) * N * m * g / r
        if "omega" in c:
            omega = float(c["omega"])
        elif "Gamma" in c:
            omega = 2.0 * math.pi * float(c["Gamma"])
        elif "tap_duration" in c:
            omega = math.pi / float(c["tap_duration"])
        else:
            raise ConfigError("column: give one of omega, Gamma, tap_duration")
        return cls(
            N=N,
            m=m,
            r=r,
            g=g,
            K=K,
            e=float(c["e"]),
            a=float(c["a"]),
            omega=omega,
            T=float(c["T"]),
            smooth=bool(c.get("smooth", False)),
            alpha_sigma=float(c.get("alpha_sigma", 0.0)),
            alpha_chi=float(c.get("alpha_chi", 0.0)),
        )


def restitution_from_e(e: float) -> float:
    """ϱ = sqrt((1 − e)/(1 + e)), Eq. (16)."""
    return math.sqrt((1.0 - e) / (1.0 + e))


def e_from_restitution(rho: float) -> float:
    """e = (1 − ϱ²)/(1 + ϱ²), Eq. (16)."""
    return (1.0 - rho * rho) / (1.0 + rho * rho)


# The paper's two parameter sets (docs/column.md). Figure 1 in cgs units (cm, g, s): r = 1 cm,
# g = 980.67 cm/s², m = 1, K = 2Ng/r, e = 0.09, a/2r = 0.53, ω = 2πΓ.
# The paper's "T = 50" has no unit. Read as seconds, four taps of 0.13–0.21 s would span
# 200 s of rest; read as 50 of the paper's time steps of 0.01 s (Section 7), T = 0.5 s,
# the ten-particle column is still moving at the next tap. We take T = 1 s: the shortest
# round period after which both columns are exactly at rest (every contact stuck, in the
# Filippov sense of the sign function at zero relative velocity) before the next tap —
# measured full rest 0.84 s (N = 5) and 0.70 s (N = 10) after the tap starts.
# The generic set in SI units (m, kg, s): N ≥ 20, T = 1, π/ω < 1/10, a ≤ 1/50, r < 1/100,
# m < 1/20; read in cgs instead, a = 0.01 cm with ω ≈ 63/s would give a peak floor
# acceleration of 0.04 g and taps that never lift the column. The paper gives no K for it:
# K = κNmg/r with κ = 50, because with the figure-1 choice κ = 2 the floor's kick aω
# (0.63 m/s) exceeds what the contact can stop, ω_c r ≈ 0.44 m/s, and the floor passes
# through the bottom particle; κ = 50 gives aω/(ω_c r) = 0.09 (figure 1: 0.18).
PARAMETER_SETS: dict[str, dict] = {
    "figure1_N5": dict(
        N=5, m=1.0, r=1.0, g=980.67, stiffness_factor=2.0, e=0.09, a=1.06, Gamma=2.4019, T=1.0
    ),
    "figure1_N10": dict(
        N=10, m=1.0, r=1.0, g=980.67, stiffness_factor=2.0, e=0.09, a=1.06, Gamma=3.8476, T=1.0
    ),
    "generic": dict(
        N=20,
        m=1e-3,
        r=5e-3,
        g=9.81,
        stiffness_factor=50.0,
        e=0.09,
        a=0.01,
        tap_duration=0.05,
        T=1.0,
    ),
}


def parameter_set(name: str, **overrides) -> ColumnParams:
    """One of :data:`PARAMETER_SETS` with optional overrides, as :class:`ColumnParams`."""
    if name not in PARAMETER_SETS:
        raise ConfigError(
            f"column: unknown parameter set {name!r}; known: {sorted(PARAMETER_SETS)}"
        )
    return ColumnParams.from_mapping({**PARAMETER_SETS[name], **overrides})


def equilibrium_positions(p: ColumnParams) -> np.ndarray:
    """Rest positions y_k(0) of the column in equilibrium on the floor at y0 = 0.

    y_k(0) = (2k − 1) r − (k/2)(2N − k + 1) 𝔐 for every k = 1..N (docs/column.md: the paper's
    separate formula for y_N in Eq. (27) is wrong; this is the k = N case of the general
    one). The compressions are c_k = (N − k)𝔐 between particles k and k+1 and N𝔐 at the
    floor, so that K c balances the weight above each contact (σ(0) = 0, Eq. 9).

    Returns
    -------
    y : (N,) float64 [length]

    Raises
    ------
    ConfigError
        If 𝔐 >= r/N (Eq. 28): the bottom particle's centre would sit at or below the
        floor, i.e. the column is not a physical stack.
    """
    M = p.mass_ratio
    if not M * p.N < p.r:
        raise ConfigError(
            f"column: unphysical equilibrium, mg/K = {M:.6g} >= r/N = {p.r / p.N:.6g} (Eq. 28); "
            "raise K (stiffness_factor > 1) or lower N"
        )
    k = np.arange(1, p.N + 1, dtype=np.float64)
    return (2.0 * k - 1.0) * p.r - 0.5 * k * (2.0 * p.N - k + 1.0) * M


# ----------------------------------------------------------- from the config
def physics(mapping: Mapping) -> ColumnParams:
    """ColumnParams from a config ``physics`` mapping (keys of ColumnParams.from_mapping)."""
    return ColumnParams.from_mapping(mapping)
