"""Public API: :class:`Simulation` (law, walls, step), :class:`State`, :class:`Ensemble`.

The caller owns the loop (STYLE.md, jax-md): build a :class:`Simulation`, create a
state with :meth:`Simulation.new_state`, then call :meth:`Simulation.run` for
chunks of steps; the state (positions, velocities, spins, forces, neighbour list,
shear histories, tangent vector, time, wall angle) carries over exactly between
chunks, so a run split into chunks is bit-identical to one long run.
"""

from __future__ import annotations

import dataclasses
import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np

from granpipe.engine import layout as K
from granpipe.engine import passes as P
from granpipe.engine.contract import ContactLaw
from granpipe.engine.layout import STORAGE
from granpipe.engine.neighbours import cell_capacity, pair_capacity
from granpipe.engine.profile import profile_passes
from granpipe.engine.walls import NO_FLAT_WALLS, NO_WALL_DISKS, FlatWalls, WallDisks
from granpipe.errors import ConfigError, SimulationError

__all__ = ["Simulation", "State", "Ensemble", "Record"]

_STATUS_TEXT = {
    K.NONFINITE: "non-finite position or velocity",
    K.DEEP_OVERLAP: "overlap deeper than the bound (max_overlap times the smaller radius)",
    K.LIST_OVERFLOW: "neighbour list overflow (disks packed beyond the overlap bound)",
    K.TANGENT_NONFINITE: "non-finite tangent vector",
}
_WALL_NAMES = {K.LEFT_WALL: "left wall", K.RIGHT_WALL: "right wall", K.BOTTOM_WALL: "bottom wall"}


def _storage(s: dict) -> tuple:
    """The arrays of a state's storage dict as the tuple every stepping kernel takes
    (:data:`granpipe.engine.layout.STORAGE` order; ``passes.replica_of`` picks one
    replica)."""
    return tuple(s[k] for k in STORAGE)


class Ensemble:
    """R replicas of a system with the same number of disks, stacked on a leading axis.

    All array properties are views (writable) with shape ``(R, N, ...)``; after editing
    positions or velocities in place, call :meth:`Simulation.refresh`. Use
    :meth:`stack` to build one from :class:`State` objects and ``ens[r]`` to get
    replica ``r`` as a :class:`State` that shares memory with the ensemble.
    """

    _single = False

    def __init__(self, storage: dict):
        self._s = storage

    # -- construction -------------------------------------------------------------------
    @classmethod
    def stack(cls, states) -> Ensemble:
        """Stack states (or ensembles) with equal N and law into one ensemble (copies)."""
        states = list(states)
        if not states:
            raise ConfigError("Ensemble.stack needs at least one state")
        first = states[0]._s
        for s in states:
            if s._s["vec"].shape[1:] != first["vec"].shape[1:]:
                raise ConfigError("Ensemble.stack: states differ in number of disks")
        storage = {}
        for key, val in first.items():
            if isinstance(val, np.ndarray) and val.ndim >= 1 and key not in _SHARED_KEYS:
                parts = [s._s[key] for s in states]
                width = max(p.shape[-1] for p in parts)
                parts = [_pad(p, width) for p in parts]
                shape = (sum(p.shape[0] for p in parts),) + parts[0].shape[1:]
                storage[key] = np.concatenate(parts, axis=0, out=_aligned_empty(shape, val.dtype))
            else:
                storage[key] = val
        return Ensemble(_aligned(storage))

    def __len__(self):
        return self._s["vec"].shape[0]

    def __getitem__(self, r) -> State:
        if not isinstance(r, int | np.integer):
            raise TypeError("Ensemble index must be an integer")
        r = int(r)
        if not -len(self) <= r < len(self):
            raise IndexError(r)
        r %= len(self)
        storage = {}
        for key, val in self._s.items():
            if isinstance(val, np.ndarray) and val.ndim >= 1 and key not in _SHARED_KEYS:
                storage[key] = val[r : r + 1]
            else:
                storage[key] = val
        return State(storage)

    def copy(self):
        """Deep copy (independent arrays)."""
        return type(self)(
            {k: (_aligned_copy(v) if isinstance(v, np.ndarray) else v) for k, v in self._s.items()}
        )

    def to_arrays(self) -> dict:
        """Everything a run needs to continue exactly, as ``{name: numpy array}`` (copies).

        Scalars come as 0-d arrays, so the dict can go straight into netCDF variables or
        ``np.savez``; :meth:`from_arrays` rebuilds the state (or ensemble). The layout is
        the engine's own (``engine_format``); treat the arrays as opaque.
        """
        out = {"engine_format": np.asarray(_FORMAT)}
        for key, val in self._s.items():
            if key in _SCRATCH_KEYS:
                continue
            if isinstance(val, np.ndarray):
                out[key] = val.copy()
            else:
                out[key] = np.asarray(val)
        out["single"] = np.asarray(self._single)
        return out

    @staticmethod
    def from_arrays(arrays):
        """Rebuild a :class:`State` or :class:`Ensemble` saved by :meth:`to_arrays`."""
        fmt = int(np.asarray(arrays.get("engine_format", -1)))
        if fmt not in _LOADS:
            raise ConfigError(f"engine state format {fmt} is not {_FORMAT}; rerun to regenerate")
        storage = {}
        for key, val in arrays.items():
            if key in ("engine_format", "single"):
                continue
            a = np.asarray(val)
            if key in ("dt", "skin"):
                storage[key] = float(a)
            elif key == "law_id":
                storage[key] = int(a)
            elif key in ("has_spin", "has_tangent"):
                storage[key] = bool(a)
            elif key == "centre":
                storage[key] = tuple(float(c) for c in a)
            else:
                storage[key] = _aligned_copy(a)
        if fmt < 8:
            # files of format 7 and older carry three more ivec rows and 1 + a piece index
            # in the touch flags: cut the rows, keep the flags, recount the stale pairs
            storage["ivec"] = np.ascontiguousarray(storage["ivec"][:, : K.NI])
            storage["touch"] = np.minimum(storage["touch"], 1)
            storage["counters"][..., K.COUNT_STALE] = 1
        if fmt < 9:  # no wall rates before 9 (every wall disk turned at rate 1)
            storage["sca"] = _pad(storage["sca"].swapaxes(1, 2), K.NS).swapaxes(1, 2).copy()
            storage["sca"][:, K.WALL_RATE] = storage["ivec"][:, K.IS_WALL] != 0
        # scratch is rewritten before it is read
        vec = storage["vec"]
        storage.update(_scratch(vec.shape[:1], vec.shape[2], storage["pair_ij"].shape[-1]))
        cls = State if bool(np.asarray(arrays["single"])) else Ensemble
        return cls(_aligned(storage))

    # -- views --------------------------------------------------------------------------
    def _v(self, arr):
        return arr[0] if self._single else arr

    @property
    def replicas(self) -> int:
        """Number of replicas R."""
        return self._s["vec"].shape[0]

    @property
    def n(self) -> int:
        """Number of disks N (mobile and wall)."""
        return self._s["vec"].shape[2]

    @property
    def positions(self):
        """(N, 2) or (R, N, 2) float64 [length]: disk centres."""
        return self._v(self._s["vec"][:, K.POS])

    @property
    def velocities(self):
        """(N, 2) or (R, N, 2) float64 [length/time]. Wall disks: their prescribed velocity."""
        return self._v(self._s["vec"][:, K.VEL])

    @property
    def forces(self):
        """(N, 2) or (R, N, 2) float64 [force]: total force (contacts and gravity) at the
        last evaluation (zero on wall disks)."""
        return self._v(self._s["vec"][:, K.FRC])

    @property
    def spins(self):
        """(N,) or (R, N) float64 [rad/time]: angular velocities (counter-clockwise > 0)."""
        return self._v(self._s["sca"][:, K.SPIN])

    @property
    def torques(self):
        """(N,) or (R, N) float64 [force*length] at the last evaluation."""
        return self._v(self._s["sca"][:, K.TORQUE])

    @property
    def radii(self):
        """(N,) or (R, N) float64 [length]."""
        return self._v(self._s["sca"][:, K.RADIUS])

    @property
    def masses(self):
        """(N,) or (R, N) float64 [mass] (a copy; ``inf`` for wall disks)."""
        with np.errstate(divide="ignore"):
            return self._v(1.0 / self._s["sca"][:, K.INV_MASS])

    @property
    def is_wall(self):
        """(N,) or (R, N) bool (a copy): disks with prescribed motion."""
        return self._v(self._s["ivec"][:, K.IS_WALL] != 0)

    @property
    def mobile(self):
        """(N,) or (R, N) bool (a copy): disks that move under forces."""
        return ~self.is_wall

    @property
    def contacts(self):
        """(N,) or (R, N) int64 (a copy): contacts of each disk at the last force evaluation,
        walls included; disks with fewer than 2 are rattlers."""
        return self._v(self._s["ivec"][:, K.CONTACTS].copy())

    @property
    def time(self):
        """Current time [time] (float, or (R,) float64)."""
        t = self._s["clock"][:, K.T_ORIGIN] + self._s["counters"][:, K.STEP] * self._s["dt"]
        return float(t[0]) if self._single else t

    @property
    def wall_angle(self):
        """Rotation angle of the wall disks since the state was created [rad]."""
        th = self._s["clock"][:, K.THETA].copy()
        return float(th[0]) if self._single else th

    @property
    def skin(self) -> float:
        """Verlet skin of the state's neighbour list [length]."""
        return float(self._s["skin"])

    @property
    def has_tangent(self) -> bool:
        """Whether a tangent vector has been set (:meth:`Simulation.set_tangent`)."""
        return bool(self._s["has_tangent"])

    @property
    def tangent(self):
        """``(dr, dv)``: the tangent vector, each (N, 2) or (R, N, 2) float64 (copies),
        rescaled to its true size ``2**log2_scale * stored`` (wall rows are zero).

        Its scale is arbitrary (it is renormalised by powers of two, which is exact); use
        :attr:`tangent_log2_scale` with the stored vectors to avoid overflow.
        """
        scale = np.ldexp(1.0, self._s["counters"][:, K.LOG2_SCALE])[:, None, None]
        dr = self._s["vec"][:, K.T_POS] * scale
        dv = self._s["vec"][:, K.T_VEL] * scale
        return self._v(dr), self._v(dv)

    @property
    def tangent_spin(self):
        """``dspin``: the spin part of the tangent vector, (N,) or (R, N) float64 (a copy, at
        true scale; zero for laws without spin)."""
        scale = np.ldexp(1.0, self._s["counters"][:, K.LOG2_SCALE])[:, None]
        return self._v(self._s["sca"][:, K.T_SPIN] * scale)

    @property
    def tangent_stored(self):
        """``(dr, dv)`` as stored (views), of norm of order 1 after renormalisation."""
        return self._v(self._s["vec"][:, K.T_POS]), self._v(self._s["vec"][:, K.T_VEL])

    @property
    def tangent_log2_scale(self):
        """Power of two by which the stored tangent vector has been divided in total."""
        s = self._s["counters"][:, K.LOG2_SCALE].copy()
        return int(s[0]) if self._single else s

    def shear_history(self):
        """``(pairs, xi)``: the tangential springs of a state's disk pairs (laws with
        history), to carry them to a new state (:meth:`Simulation.set_shear_history`).

        Returns
        -------
        pairs : (K, 2) int64
            Disk indices ``(i, j)``, ``i < j``, of the pairs whose spring is stretched
            (wall disks included; histories against flat walls are not part of it).
        xi : (K,) float64 [length]
            Their tangential displacement, in the engine's sign convention (that of ``i``
            relative to ``j``).
        """
        if not self._single:
            raise ConfigError("shear_history is per replica: use ensemble[r].shear_history()")
        s = self._s
        npairs = int(s["counters"][0, K.N_PAIRS])
        start = s["pair_start"][0]
        xi = s["pair_xi"][0, :npairs]
        k = np.flatnonzero(xi != 0.0)
        i = np.searchsorted(start, k, side="right") - 1
        j = s["pair_ij"][0, K.PJ, k].astype(np.int64)
        return np.column_stack([i, j]).astype(np.int64), xi[k].copy()

    # -- observables --------------------------------------------------------------------
    def kinetic_energy(self):
        """Translational plus rotational kinetic energy of the mobile disks [energy]."""
        sca = self._s["sca"]
        vel = self._s["vec"][:, K.VEL]
        mob = self._s["ivec"][:, K.IS_WALL] == 0
        with np.errstate(divide="ignore"):
            m = np.where(mob, 1.0 / np.where(mob, sca[:, K.INV_MASS], 1.0), 0.0)
            inv_i = sca[:, K.INV_INERTIA]
            inertia = np.where(mob & (inv_i > 0), 1.0 / np.where(inv_i > 0, inv_i, 1.0), 0.0)
        ke = 0.5 * (m * (vel**2).sum(-1)).sum(-1)
        if self._s["has_spin"]:
            ke = ke + 0.5 * (inertia * sca[:, K.SPIN] ** 2).sum(-1)
        return float(ke[0]) if self._single else ke

    def speeds(self):
        """|v_i| of every disk, (N,) or (R, N) [length/time] (wall disks: their speed)."""
        return np.linalg.norm(self.velocities, axis=-1)

    def max_speed(self):
        """Largest speed among the mobile disks [length/time]."""
        vel = self._s["vec"][:, K.VEL]
        mob = self._s["ivec"][:, K.IS_WALL] == 0
        sp = np.where(mob, np.sqrt((vel**2).sum(-1)), 0.0).max(-1)
        return float(sp[0]) if self._single else sp

    def global_speed(self):
        """``V = sqrt(sum_i |v_i|²)`` over the mobile disks (drum paper) [length/time]."""
        vel = self._s["vec"][:, K.VEL]
        mob = self._s["ivec"][:, K.IS_WALL] == 0
        v = np.sqrt(np.where(mob, (vel**2).sum(-1), 0.0).sum(-1))
        return float(v[0]) if self._single else v

    def neighbour_stats(self) -> dict:
        """Counters: steps run, list rebuilds, pairs in the list, mean contacts per step."""
        c = self._s["counters"]
        steps = c[:, K.STEPS_RUN].astype(float)
        out = {
            "steps_run": c[:, K.STEPS_RUN].copy(),
            "rebuilds": c[:, K.N_REBUILDS].copy(),
            "pairs": c[:, K.N_PAIRS].copy(),
            "pair_capacity": self._s["pair_xi"].shape[1],
            "mean_contacts": np.where(steps > 0, c[:, K.CONTACT_SUM] / np.maximum(steps, 1), 0.0),
        }
        if self._single:
            out = {k: (v[0] if isinstance(v, np.ndarray) else v) for k, v in out.items()}
        return out

    def reset_counters(self):
        """Zero the statistics counters (steps run, rebuilds, contact sum)."""
        c = self._s["counters"]
        c[:, K.STEPS_RUN] = 0
        c[:, K.N_REBUILDS] = 0
        c[:, K.CONTACT_SUM] = 0


class State(Ensemble):
    """One system: arrays have shape ``(N, ...)``. See :class:`Ensemble` for attributes."""

    _single = True


# storage entries shared by all replicas (not stacked)
_SHARED_KEYS = {"dt", "law_id", "has_spin", "has_tangent", "centre", "skin"}
# storage entries whose last axis is the pair capacity
_PAIR_KEYS = (
    "pair_ij",
    "pair_c",
    "pair_xi",
    "pair_dxi",
    "old_j",
    "old_xi",
    "old_dxi",
    "buf",
    "touch",
    "flip",
)


_ALIGN = 64


def _aligned_empty(shape, dtype):
    """An uninitialised C-contiguous array whose data start on a 64-byte cache line."""
    dtype = np.dtype(dtype)
    nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    raw = np.empty(nbytes + _ALIGN, dtype=np.uint8)
    start = -raw.ctypes.data % _ALIGN
    return raw[start : start + nbytes].view(dtype).reshape(shape)


def _aligned_copy(a):
    """A C-contiguous copy of ``a`` whose data start on a 64-byte cache line."""
    out = _aligned_empty(a.shape, a.dtype)
    out[...] = a
    return out


def _aligned(storage: dict) -> dict:
    """``storage`` with every array on a 64-byte cache line (copied where it is not).

    numpy promises 16 bytes only, so without the copy a run's speed would depend on where
    ``malloc`` put its arrays. The vector loads and stores of the pair rows (four doubles
    from an index that is a multiple of 4) never split a line when the rows start on one
    (measured: docs/engine_performance.md, "Round 5").
    """
    return {
        k: _aligned_copy(v) if isinstance(v, np.ndarray) and v.ctypes.data % _ALIGN else v
        for k, v in storage.items()
    }


def _pad(arr, width):
    """Zero-pad the last axis (pair capacity, wall count) to ``width``."""
    if arr.shape[-1] == width:
        return arr
    out = np.zeros(arr.shape[:-1] + (width,), dtype=arr.dtype)
    out[..., : arr.shape[-1]] = arr
    return out


_FORMAT = 9
# the rows of sca holding the flat walls' shear histories and their perturbations
_HISTORY_ROWS = [K.XI_LEFT, K.XI_RIGHT, K.XI_BOTTOM, K.T_XI_LEFT, K.T_XI_RIGHT, K.T_XI_BOTTOM]
_LOADS = (6, 7, 8, _FORMAT)  # formats a state saved by an earlier engine may have
# storage that only carries values within one step or list build (pair buffers, the old
# list while histories are carried over): not saved by ``to_arrays``
_SCRATCH_KEYS = ("old_start", "old_j", "old_xi", "old_dxi", "buf", "flip")


def _scratch(lead, n, cap):
    """Zeroed scratch storage for ``lead`` replicas of ``n`` disks, pair capacity ``cap``."""
    return {
        "old_start": np.zeros(lead + (n + 1,), dtype=np.int64),
        "old_j": np.zeros(lead + (cap,), dtype=np.uint32),
        "old_xi": np.zeros(lead + (cap,)),
        "old_dxi": np.zeros(lead + (cap,)),
        "buf": np.zeros(lead + (K.NB, cap)),
        "flip": np.zeros(lead + (cap,), dtype=np.int8),
    }


@dataclass(frozen=True)
class Record:
    """Block means recorded by :meth:`Simulation.run` (exact means of per-step values).

    Attributes
    ----------
    time : (B,) float64 [time]
        Centre of each block: mean of its steps' times.
    global_speed : (B,) or (R, B) float64 [length/time]
        Block mean of ``V(t) = sqrt(sum_i |v_i(t)|²)`` over mobile disks (drum paper).
    local_lyapunov : (B,) or (R, B) float64 [1/time]
        Block mean of ``lambda(t) = (1/dt) ln(|du(t)|_S / |du(t - dt)|_S)`` over the
        steps where it is defined (both norms > 0); NaN where none is. Only with tangent.
    lyapunov_count : (B,) or (R, B) int64
        Number of steps averaged in each block of ``local_lyapunov``.
    stride : int
        Steps per block.
    """

    time: np.ndarray
    global_speed: np.ndarray
    local_lyapunov: np.ndarray | None = None
    lyapunov_count: np.ndarray | None = None
    stride: int = 0


@dataclass(frozen=True)
class Simulation:
    """A 2D DEM system: contact law, walls, gravity and time step.

    Parameters
    ----------
    law : ContactLaw
        Contact law for disk pairs and disk-wall contacts (``DrumLaw``, ``BoxLaw``,
        ``StaticFrictionLaw`` or any law of the contract, :mod:`granpipe.engine.contract`).
    dt : float [time]
        Time step of velocity Verlet.
    gravity : (2,) float [length/time²]
        Acceleration of gravity (default ``(0, -1)``: g = 1 downward, reduced units).
    wall_disks : WallDisks or None
        Motion of the disks flagged as walls (default: they stay still).
    flat_walls : FlatWalls or None
        Flat line walls (default: none).
    skin : float or None [length]
        Verlet skin; the list is rebuilt once a disk has moved ``skin/2``
        (default: 0.1 times the smallest radius at state creation).
    max_overlap : float
        Bad-state bound: a run stops (``SimulationError``) when two disks overlap by more
        than ``max_overlap`` times the smaller radius, or a disk and a flat wall by more
        than that times its radius (default 0.5; must lie in (0, 2): at 2 two equal
        centres may coincide and the contact normal is lost).
    parallel : bool
        Run the replicas of an ensemble side by side, in up to
        ``numba.get_num_threads()`` threads (the kernels release the GIL; results are
        identical either way).
    """

    law: ContactLaw
    dt: float
    gravity: tuple[float, float] = (0.0, -1.0)
    wall_disks: WallDisks | None = None
    flat_walls: FlatWalls | None = None
    skin: float | None = None
    parallel: bool = True
    max_overlap: float = 0.5

    def __post_init__(self):
        if not isinstance(self.law, ContactLaw):
            raise ConfigError("law must be a contact law (granpipe.engine.contract.ContactLaw)")
        if not (math.isfinite(self.dt) and self.dt > 0):
            raise ConfigError(f"dt must be > 0, got {self.dt!r}")
        if len(self.gravity) != 2:
            raise ConfigError("gravity must have 2 components")
        if self.skin is not None and not self.skin > 0:
            raise ConfigError(f"skin must be > 0, got {self.skin!r}")
        if not 0.0 < self.max_overlap < 2.0:
            raise ConfigError(f"max_overlap must lie in (0, 2), got {self.max_overlap!r}")

    def replace(self, **changes) -> Simulation:
        """A copy with some fields changed (e.g. ``sim.replace(wall_disks=WallDisks(...))``)."""
        return dataclasses.replace(self, **changes)

    # -- kernel parameters --------------------------------------------------------------
    def _params(self):
        """``(g, laws, wd, fw)``: gravity, the law's leaf parameters at pairs and at the
        three flat walls, and the walls' motion, as the passes take them."""
        g = np.asarray(self.gravity, dtype=np.float64)
        wd = NO_WALL_DISKS if self.wall_disks is None else self.wall_disks.params()
        fw = NO_FLAT_WALLS if self.flat_walls is None else self.flat_walls.params()
        return g, (self.law.params(), self.law.wall_params()), wd, fw

    # -- states -------------------------------------------------------------------------
    def new_state(
        self,
        positions,
        radii,
        masses,
        *,
        velocities=None,
        spins=None,
        is_wall=None,
        wall_rate=None,
        inertia=None,
        time=0.0,
    ) -> State | Ensemble:
        """Create a state and evaluate its forces.

        Parameters
        ----------
        positions : (N, 2) or (R, N, 2) float64 [length]
            Disk centres, wall disks included. A leading replica axis gives an
            :class:`Ensemble`.
        radii : (N,) or (R, N) float64 [length]
            Radii (half the diameters).
        masses : (N,) or (R, N) float64 [mass]
            Masses (ignored for wall disks, which have infinite mass).
        velocities : (N, 2) or (R, N, 2) float64 [length/time], optional
            Initial velocities of the mobile disks (default 0; wall disks get their
            prescribed velocity).
        spins : (N,) or (R, N) float64 [rad/time], optional
            Initial angular velocities (box law only; default 0).
        is_wall : (N,) or (R, N) bool, optional
            Disks whose motion is prescribed by ``wall_disks`` (default: none).
        wall_rate : (N,) or (R, N) float64, optional
            Each wall disk's angular velocity over ``wall_disks.omega`` (default 1; 0:
            still).
        inertia : (N,) or (R, N) float64 [mass*length²], optional
            Moments of inertia (box law; default ``m sigma²/8 = m a²/2``; ``inf`` keeps
            a disk from turning).
        time : float [time]
            Time of the state (default 0).

        Returns
        -------
        State (or Ensemble with a replica axis)
        """
        pos = np.asarray(positions, dtype=np.float64)
        single = pos.ndim == 2
        pos = pos[None] if single else pos
        if pos.ndim != 3 or pos.shape[2] != 2:
            raise ConfigError(f"positions must be (N, 2) or (R, N, 2), got {np.shape(positions)}")
        r_count, n = pos.shape[:2]

        def per_disk(x, name, default=None, dtype=np.float64):
            if x is None:
                x = default
            a = np.asarray(x, dtype=dtype)
            a = np.broadcast_to(a, (r_count, n)) if a.ndim <= 1 else a
            if a.shape != (r_count, n):
                raise ConfigError(f"{name} must have shape (N,) or (R, N); got {a.shape}")
            return a

        rad = per_disk(radii, "radii")
        mass = per_disk(masses, "masses")
        wall = per_disk(is_wall, "is_wall", default=False, dtype=bool)
        rate = np.where(wall, per_disk(wall_rate, "wall_rate", default=1.0), 0.0)
        if not np.all(np.isfinite(rad) & (rad > 0) & np.isfinite(rate)):
            raise ConfigError("radii must be finite and > 0, wall rates finite")
        if not np.all(wall | (np.isfinite(mass) & (mass > 0))):
            raise ConfigError("masses of mobile disks must be finite and > 0")
        if not np.all(np.isfinite(pos)):
            raise ConfigError("positions must be finite")
        vel = np.zeros_like(pos) if velocities is None else np.asarray(velocities, np.float64)
        vel = vel[None] if vel.ndim == 2 else vel
        if vel.shape != pos.shape:
            raise ConfigError(f"velocities must have the shape of positions, got {vel.shape}")
        spin = per_disk(spins, "spins", default=0.0)
        if spins is not None and not self.law.has_spin:
            raise ConfigError(f"spins need a law with rotation; the {self.law.name} law has none")
        with np.errstate(divide="ignore"):
            inv_mass = np.where(wall, 0.0, 1.0 / np.where(wall, 1.0, mass))
            if inertia is None:
                inv_inertia = np.where(wall, 0.0, 2.0 / (np.where(wall, 1.0, mass) * rad**2))
            else:
                inert = per_disk(inertia, "inertia")
                inv_inertia = np.where(wall, 0.0, 1.0 / inert)
        if not self.law.has_spin:
            inv_inertia = np.zeros_like(inv_inertia)

        skin = self.skin if self.skin is not None else 0.1 * float(rad.min())
        cap = max(pair_capacity(rad[r], skin, self.max_overlap) for r in range(r_count))
        ccap = cell_capacity(n)
        nw = wall.sum(axis=1)
        n_wmax = max(int(nw.max()), 1)
        walls = np.zeros((r_count, n_wmax), dtype=np.int64)
        for r in range(r_count):
            idx = np.flatnonzero(wall[r])
            walls[r, : idx.size] = idx

        vec = np.zeros((r_count, K.NV, n, 2))
        sca = np.zeros((r_count, K.NS, n))
        ivec = np.zeros((r_count, K.NI, n), dtype=np.int64)
        vec[:, K.POS] = pos
        vec[:, K.VEL] = np.where(wall[..., None], 0.0, vel)
        centre = (
            np.zeros(2) if self.wall_disks is None else np.asarray(self.wall_disks.centre, float)
        )
        ref = np.where(wall[..., None], pos - centre, 0.0)
        vec[:, K.WALL_REF] = ref
        vec[:, K.IM2] = inv_mass[..., None]
        vec[:, K.MOB2] = np.where(wall, 0.0, 1.0)[..., None]
        sca[:, K.RADIUS] = rad
        sca[:, K.INV_MASS] = inv_mass
        sca[:, K.INV_INERTIA] = inv_inertia
        sca[:, K.SPIN] = np.where(wall, 0.0, spin)
        sca[:, K.WALL_RATE] = rate
        ivec[:, K.IS_WALL] = wall
        clock = np.zeros((r_count, K.NCLOCK))
        clock[:, K.T_ORIGIN] = float(time)
        clock[:, K.OVERLAP_FRAC] = self.max_overlap
        clock[:, K.WALL_RMAX] = (np.abs(rate) * np.sqrt((ref**2).sum(-1))).max(-1)
        counters = np.zeros((r_count, K.NCOUNT), dtype=np.int64)
        counters[:, K.N_WALLS] = nw
        counters[:, K.NEAR_WALLS] = -1
        storage = {
            "vec": vec,
            "sca": sca,
            "ivec": ivec,
            "walls": walls,
            "pair_start": np.zeros((r_count, n + 1), dtype=np.int64),
            "pair_ij": np.zeros((r_count, 3, cap), dtype=np.uint32),
            "pair_c": np.zeros((r_count, K.NPC, cap)),
            "pair_xi": np.zeros((r_count, cap)),
            "pair_dxi": np.zeros((r_count, cap)),
            **_scratch((r_count,), n, cap),
            "touch": np.zeros((r_count, cap), dtype=np.int64),
            "cell_count": np.zeros((r_count, ccap + 1), dtype=np.int64),
            "cell_start": np.zeros((r_count, ccap + 1), dtype=np.int64),
            "clock": clock,
            "counters": counters,
            "info": np.zeros((r_count, 4), dtype=np.int64),
            "dt": float(self.dt),
            "law_id": self.law.law_id,
            "has_spin": self.law.has_spin,
            "has_tangent": False,
            "centre": tuple(float(c) for c in centre),
            "skin": skin,
        }
        storage = _aligned(storage)
        state = State(storage) if single else Ensemble(storage)
        self.refresh(state)
        return state

    def _check(self, state):
        s = state._s
        if s["law_id"] != self.law.law_id:
            raise ConfigError("state was created under a different contact law")
        centre = (
            (0.0, 0.0) if self.wall_disks is None else tuple(map(float, self.wall_disks.centre))
        )
        if s["counters"][:, K.N_WALLS].any() and centre != s["centre"]:
            raise ConfigError("wall_disks.centre differs from the one the state was created with")
        if s["dt"] != self.dt:
            # keep the time continuous under a change of step: new origin here
            t = s["clock"][:, K.T_ORIGIN] + s["counters"][:, K.STEP] * s["dt"]
            s["clock"][:, K.T_ORIGIN] = t
            s["counters"][:, K.STEP] = 0
            s["dt"] = float(self.dt)
        skin = self.skin if self.skin is not None else s["skin"]
        frac = s["clock"][:, K.OVERLAP_FRAC]
        if skin != s["skin"] or np.any(frac != self.max_overlap):
            rad = s["sca"][:, K.RADIUS]
            cap = max(pair_capacity(rad[r], skin, self.max_overlap) for r in range(rad.shape[0]))
            if cap > s["pair_xi"].shape[1]:
                for key in _PAIR_KEYS:
                    old = s[key]
                    grown = _aligned_empty(old.shape[:-1] + (cap,), old.dtype)
                    grown[...] = 0
                    grown[..., : old.shape[-1]] = old
                    s[key] = grown
            s["skin"] = skin
            frac[:] = self.max_overlap
            s["counters"][:, K.FORCE_REBUILD] = 1
        return skin

    def _raise(self, state):
        info = state._s["info"]
        bad = np.flatnonzero(info[:, 0])
        if bad.size == 0:
            return
        r = int(bad[0])
        status, particle, other, step = (int(x) for x in info[r])
        info[:, :] = 0
        t = state._s["clock"][r, K.T_ORIGIN] + step * state._s["dt"]
        ctx = {}
        if other >= 0:
            ctx["other"] = other
        elif other in _WALL_NAMES:
            ctx["other"] = _WALL_NAMES[other]
        if not state._single:
            ctx["replica"] = r
        raise SimulationError(
            _STATUS_TEXT.get(status, f"status {status}"),
            particle=particle if particle >= 0 else None,
            step=step,
            time=float(t),
            **ctx,
        )

    def _refresh_kernel(self, state, tangent, rebuild, skin):
        """A refresh: walls placed and list rebuilt (with ``rebuild``), then the forces
        evaluated with the histories left as they were (the evaluation's truncations are
        undone: a refresh looks at a state, the next step advances it)."""
        g, laws, wd, fw = self._params()
        s = state._s
        st = _storage(s)
        mode = P.TANGENT if tangent else P.FORWARD
        P.place_serial(laws, mode, rebuild, g, wd, fw, skin, st, self.dt, s["info"])
        if s["info"][:, 0].any():
            return
        kept = [s["pair_xi"].copy(), s["pair_dxi"].copy(), s["sca"][:, _HISTORY_ROWS].copy()]
        P.refresh_serial(laws, mode, fw, skin, st, self.dt, s["info"])
        s["pair_xi"][...], s["pair_dxi"][...], s["sca"][:, _HISTORY_ROWS] = kept

    def refresh(self, state) -> None:
        """Re-place the walls, rebuild the neighbour list and re-evaluate the forces.

        Call after editing positions or velocities of a state in place. Forces use the
        current (full-step) velocities; shear histories are kept as they are (the next
        step advances them). With a tangent vector set, its force perturbation is
        re-evaluated too.
        """
        skin = self._check(state)
        self._refresh_kernel(state, bool(state._s["has_tangent"]), True, skin)
        self._raise(state)

    def set_shear_history(self, state, pairs, xi) -> None:
        """Give the pairs ``pairs`` of a :class:`State` the shear histories ``xi`` (what
        :meth:`State.shear_history` returned for the same disks) and re-evaluate the
        forces, so that a state rebuilt from positions, velocities, spins and histories
        continues as the saved one would. Every other pair's history is set to zero.

        Raises
        ------
        ConfigError
            if the law has no history, or a pair is not within contact range (its
            disks are farther apart than the sum of their radii plus the skin).
        """
        if not self.law.has_history:
            raise ConfigError(f"the {self.law.name} law has no shear history")
        if not state._single:
            raise ConfigError("set_shear_history takes one State (ensemble[r])")
        pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
        xi = np.asarray(xi, np.float64).reshape(-1)
        if len(pairs) != len(xi):
            raise ConfigError(f"{len(pairs)} pairs but {len(xi)} histories")
        skin = self._check(state)
        self._refresh_kernel(state, bool(state._s["has_tangent"]), True, skin)
        self._raise(state)
        s = state._s
        start = s["pair_start"][0]
        pj = s["pair_ij"][0, K.PJ]
        n = state.n
        s["pair_xi"][0, :] = 0.0
        for (i, j), x in zip(pairs, xi, strict=True):
            if not (0 <= i < j < n):
                raise ConfigError(f"pair ({i}, {j}) is not (i, j) with 0 <= i < j < {n}")
            row = pj[start[i] : start[i + 1]]
            k = int(np.searchsorted(row, j))
            if k == len(row) or row[k] != j:
                raise ConfigError(f"pair ({i}, {j}) is not within contact range")
            s["pair_xi"][0, start[i] + k] = x
        self._refresh_kernel(state, bool(state._s["has_tangent"]), False, skin)
        self._raise(state)

    def set_tangent(self, state, dr, dv, dspin=None) -> None:
        """Set the tangent vector ``du = (dr, dv[, dspin])`` (wall rows are ignored).

        Parameters
        ----------
        dr, dv : (N, 2) or (R, N, 2) float64
            Perturbations of positions and velocities.
        dspin : (N,) or (R, N) float64, optional
            Perturbation of the spins (laws with spin; default 0). The perturbations of
            the shear histories start at zero.

        The matching force perturbation (``dF = J_r dr + J_v dv``, and torques) is
        evaluated at the current state; the forces themselves are left untouched, so
        setting a tangent vector never changes the trajectory.
        """
        if dspin is not None and not self.law.has_spin:
            raise ConfigError(f"the {self.law.name} law has no spin to perturb")
        skin = self._check(state)
        s = state._s
        shape = s["vec"][:, K.POS].shape
        dr = np.asarray(dr, np.float64).reshape(shape)
        dv = np.asarray(dv, np.float64).reshape(shape)
        ds = np.zeros(shape[:2]) if dspin is None else np.asarray(dspin, np.float64)
        ds = ds.reshape(shape[:2])
        wall = s["ivec"][:, K.IS_WALL] != 0
        s["vec"][:, K.T_POS] = np.where(wall[..., None], 0.0, dr)
        s["vec"][:, K.T_VEL] = np.where(wall[..., None], 0.0, dv)
        s["sca"][:, K.T_SPIN] = np.where(wall, 0.0, ds)
        s["sca"][:, K.T_XI_LEFT : K.T_XI_BOTTOM + 1] = 0.0
        s["pair_dxi"][:] = 0.0
        s["counters"][:, K.LOG2_SCALE] = 0
        s["has_tangent"] = True
        # the perturbations at the state as it stands (the refresh's evaluation: histories
        # kept); the forces and torques from the last step are kept, so that setting a
        # tangent vector never changes the trajectory
        saved = s["vec"][:, K.FRC].copy(), s["sca"][:, K.TORQUE].copy()
        self._refresh_kernel(state, True, False, skin)
        s["vec"][:, K.FRC], s["sca"][:, K.TORQUE] = saved
        self._raise(state)

    def random_tangent(self, state, rng, fraction=0.1) -> None:
        """Set a random tangent vector as the drum paper does (Sec. III).

        About ``fraction`` of the 4 N_mobile components, chosen uniformly at random,
        get values uniform in [-1, 1]; the others are zero.

        Parameters
        ----------
        rng : numpy.random.Generator
        fraction : float
        """
        s = state._s
        r_count, n = s["vec"].shape[0], s["vec"].shape[2]
        mob = s["ivec"][:, K.IS_WALL] == 0
        du = np.zeros((r_count, n, 4))
        for r in range(r_count):
            idx = np.flatnonzero(mob[r])
            comps = rng.random((idx.size, 4)) < fraction
            du[r, idx] = np.where(comps, rng.uniform(-1.0, 1.0, (idx.size, 4)), 0.0)
        self.set_tangent(state, du[..., :2], du[..., 2:])

    def profile_passes(self, state, *, repeats: int = 5, nrep: int = 2000) -> dict:
        """Seconds per call of each pass of this simulation's step loop, timed on its own
        on a copy of ``state`` (best of ``repeats`` jitted loops of ``nrep`` calls;
        :mod:`granpipe.engine.profile`), with ``n_pairs`` and ``n_particles``; ``state``
        itself is left as it was.
        """
        if not state._single:
            raise ConfigError("profile_passes takes one State (ensemble[r])")
        skin = self._check(state)
        _g, laws, _wd, fw = self._params()
        copy = state.copy()
        return profile_passes(laws, fw, skin, _storage(copy._s), repeats, nrep)

    # -- running ------------------------------------------------------------------------
    def run(self, state, n_steps, *, stride=0, tangent=False) -> Record:
        """Advance ``state`` in place by ``n_steps`` steps.

        Parameters
        ----------
        state : State or Ensemble
        n_steps : int
            Number of velocity-Verlet steps.
        stride : int
            If > 0, record block means over ``stride`` steps (``n_steps`` must be a
            multiple); see :class:`Record`.
        tangent : bool
            Evolve the tangent vector too (every law has tangent dynamics; set it first
            with :meth:`set_tangent` or :meth:`random_tangent`) and record
            ``local_lyapunov``.

        Returns
        -------
        Record
            Block means (empty arrays when ``stride == 0``).

        Raises
        ------
        SimulationError
            On a non-finite state or an overlap deeper than ``max_overlap``; names the
            particle, step and time (and replica for an ensemble). The state is left as
            it was at the failing step.
        """
        n_steps = int(n_steps)
        stride = int(stride)
        if n_steps < 0:
            raise ConfigError("n_steps must be >= 0")
        if stride < 0 or (stride > 0 and n_steps % stride):
            raise ConfigError(f"n_steps ({n_steps}) must be a multiple of stride ({stride})")
        if tangent and not state.has_tangent:
            raise ConfigError("set a tangent vector first (Simulation.set_tangent)")
        skin = self._check(state)
        s = state._s
        r_count = s["vec"].shape[0]
        blocks = n_steps // stride if stride else 0
        t_start = s["clock"][:, K.T_ORIGIN] + s["counters"][:, K.STEP] * self.dt
        speed = np.zeros((r_count, blocks))
        lam = np.zeros((r_count, blocks))
        nlam = np.zeros((r_count, blocks), dtype=np.int64)
        g, laws, wd, fw = self._params()
        mode = P.TANGENT if tangent else P.FORWARD
        storage = _storage(s)

        def replicas(r0, r1):
            P.run_serial(
                laws, mode, n_steps, stride, self.dt, g, wd, fw, skin,
                tuple(a[r0:r1] for a in storage), lam[r0:r1], nlam[r0:r1], speed[r0:r1],
                s["info"][r0:r1],
            )  # fmt: skip

        threads = min(numba.get_num_threads(), r_count) if self.parallel else 1
        if threads > 1:
            with ThreadPoolExecutor(threads) as pool:
                list(pool.map(lambda r: replicas(r, r + 1), range(r_count)))
        else:
            replicas(0, r_count)
        self._raise(state)
        # block b holds steps b*stride+1 .. (b+1)*stride after the start
        centre = (np.arange(blocks) * stride + 0.5 * (stride + 1)) * self.dt
        time = t_start[0] + centre
        one = state._single
        return Record(
            time=time,
            global_speed=speed[0] if one else speed,
            local_lyapunov=None if not tangent else (lam[0] if one else lam),
            lyapunov_count=None if not tangent else (nlam[0] if one else nlam),
            stride=stride,
        )
