"""One replica of the drum study, step by step (paper Sec. II.2-II.3; docs/drum.md).

Two start-ups (``protocol.startup``), each its own parameter point:

**paper** (default) — the paper's Sec. II.2: "The drum is ... set into rotation ... We
place the N non-wall disks randomly inside the drum and allow them to fall to the
bottom", and data are collected "after a brief equilibration period, corresponding to
one degree of rotation".

1. **Placement** (stage ``init``) — the N mobile disks at random without overlap over
   the whole free disk of the drum (:func:`granpipe.drum.preparation.random_placement`,
   clearance ``protocol.placement_gap``), at rest, in a drum that is already turning.
2. **Fall** (stage ``init``) — the disks fall and settle while the drum turns, with no
   speed cap or extra damping, until ``protocol.tangent_alignment_s`` before t = 0.
   Falling disks strike the pile at 8-9 d_s/t0 and overlap by up to ~0.6 of the smaller
   radius; the bad-state bound ``physics.max_overlap`` (default 1: a centre reaching the
   other disk's rim) is set above that (docs/drum.md, "Start-up").
3. **Tangent vector** (stage ``runs``) — about ``protocol.tangent_fraction`` (10 %) of
   the 4N components δx, δy, δv_x, δv_y, each chosen with that probability, get values
   uniform in [−1, 1] (Sec. II.3); it evolves for ``tangent_alignment_s`` before t = 0,
   which is reached exactly ``pre_rotation_deg`` (1° = 2.5 s) after the placement.

**settled** — the earlier reading, kept for comparison: the disks fall and settle to
rest in a *still* drum (disk speeds capped at ``settle.max_speed`` after every block;
settled when every block mean of V/sqrt(N) over ``settle.hold_s`` is below
``settle.speed_threshold``, at least ``settle.min_time_s`` after the placement; flagged
``settled = 0`` if not after ``settle.max_time_s``); then the drum starts turning, the
tangent vector is set, and t = 0 comes after ``pre_rotation_deg``.

Then, for both:

4. **Onset window** — ``protocol.onset_window_s`` recorded from t = 0: block means of
   λ(t) and V(t) over ``protocol.block_s`` (4 ms = 100 steps), and the pile's state
   (surface tilt, centroid angle, rigid-rotation speed;
   :func:`granpipe.drum.measures.pile_state`) at t = 0 and every
   ``protocol.pile_sample_s`` (0.1 s), between engine calls of that length (the same
   bits as longer calls); with ``protocol.disk_record`` (default) also each mobile
   disk's |δu_i| and |v_i| at these samples (:func:`disk_sample`; it only reads the
   state, so λ(t) and V(t) are the same bits with it or without).
5. **Continuous avalanche** — the avalanche *flows* at the end of a chunk if the mean of
   V over the preceding ``protocol.continuous_hold_s`` exceeds
   ``1 + protocol.continuous_excess`` times the speed of rigid rotation with the drum,
   Ω sqrt(Σ r_i²). The first such time after t = 0 is recorded (``continuous_time``).
   If it flows at the end of the onset window, the decay window starts there. Otherwise
   the drum keeps turning until it flows, at a chunk end, and the decay window starts
   there; the tangent vector goes on evolving meanwhile (``tangent_while_waiting``,
   default). With ``tangent_while_waiting: false`` it is switched off during the wait
   (forward dynamics only) and a fresh one evolves for ``decay_alignment_s`` before the
   decay window; the trajectory is the same, but docs/drum.md ("Alignment") shows that
   2.5 s are not enough for λ of the decay window to be unchanged. If it does
   not flow by ``protocol.max_rotation_s`` after t = 0, the replica is flagged
   (``continuous = 0``), its decay window is recorded anyway, and by default it is left
   out of the ensemble.
6. **Decay window** — ``protocol.decay_window_s`` recorded from a fresh t = 0: the drum
   still turns for ``protocol.decay_rotating_s`` (5 s), then stops abruptly (wall
   velocities zero from that step on); recorded as the onset window.

A replica's random stream is ``replica_rng("drum", physics, replica)`` with ``physics``
the point's seeding subset (:func:`granpipe.drum.layout.seed_physics`); its first
spawned child places the disks, the second draws the tangent vectors. Every replica
runs on its own engine state, so its output depends on nothing else: not the batch, its
size, the thread count or the order. Replicas of a batch run side by side in threads
(the engine's kernels release the GIL).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import xarray as xr

from ..analysis.lyapunov import lyapunov_vector_magnitude
from ..errors import SimulationError
from ..seeds import batch_replicas, replica_rng, replica_seed
from .layout import Steps, filled, load, point_name, seed_physics, steps
from .measures import ReplicaRecord, Snapshot, batch_dataset, pile_sample
from .model import DrumModel, tiny_physics
from .preparation import Start, prepare

__all__ = [
    "Progress",
    "initial_tangent",
    "run_protocol",
    "disk_sample",
    "init_batch",
    "run_batch",
    "run_replica",
    "replica_streams",
    "tiny_section",
    "TINY_PROTOCOL",
]

Log = Callable[[str], None]


def _quiet(msg: str) -> None:
    pass


def replica_streams(section: Mapping, replica: int, physics: Mapping | None = None):
    """(placement rng, tangent rng, seed) of a replica (children of its own stream)."""
    physics = seed_physics(section) if physics is None else physics
    rng = replica_rng("drum", physics, replica)
    place, tangent = rng.spawn(2)
    return place, tangent, replica_seed("drum", physics, replica)


def initial_tangent(n_mobile: int, rng: np.random.Generator, fraction: float):
    """(dr, dv), each (N, 2): ~``fraction`` of the 4N components uniform in [−1, 1], others 0."""
    mask = rng.random((n_mobile, 4)) < fraction
    values = rng.uniform(-1.0, 1.0, (n_mobile, 4))
    du = np.where(mask, values, 0.0)
    if not du.any():  # vanishingly unlikely for N = 736; keep the vector non-zero
        du[rng.integers(n_mobile), rng.integers(4)] = rng.uniform(-1.0, 1.0)
    return du[:, :2], du[:, 2:]


# --------------------------------------------------------------------------- progress
class Progress:
    """Progress lines for long jobs: replica k of n, simulated time, elapsed, remaining.

    ``update`` is cheap and thread-safe; it prints at most every ``interval`` s of wall
    time. ``expected_steps`` per replica sets the estimate of the time remaining.
    """

    def __init__(self, n_replicas: int, expected_steps: int, log: Log, interval: float = 30.0,
                 what: str = "replica"):  # fmt: skip
        self.n = int(n_replicas)
        self.expected = max(1, int(expected_steps))
        self.log = log
        self.interval = float(interval)
        self.what = what
        self.t_start = time.perf_counter()
        self.last = self.t_start
        self.done_steps: dict[int, int] = {}
        self.finished = 0
        self.lock = threading.Lock()

    def update(self, k: int, steps_done: int, sim_time_s: float, phase: str, force=False):
        now = time.perf_counter()
        with self.lock:
            self.done_steps[k] = steps_done
            if not force and now - self.last < self.interval:
                return
            self.last = now
            frac = sum(min(s, self.expected) for s in self.done_steps.values()) / (
                self.n * self.expected
            )
            elapsed = now - self.t_start
            remaining = elapsed * (1.0 - frac) / frac if frac > 0 else float("nan")
        self.log(
            f"{self.what} {k + 1} of {self.n}: {phase}, t = {sim_time_s:.2f} s; "
            f"elapsed {elapsed:.0f} s, about {remaining:.0f} s remaining"
        )

    def finish(self, k: int, msg: str):
        with self.lock:
            self.done_steps[k] = self.expected
            self.finished += 1
        self.log(f"{self.what} {k + 1} of {self.n} done: {msg}")


# --------------------------------------------------------------------------- start-ups


# --------------------------------------------------------------------------- protocol
def _snapshot(model, state, label, description):
    n = model.n_mobile
    du = np.full(n, np.nan)
    if state.has_tangent:
        du = lyapunov_vector_magnitude(*(x[:n] for x in state.tangent_stored), relative=True)
    return Snapshot(
        positions=state.positions[:n].copy(),
        velocities=state.velocities[:n].copy(),
        wall_positions=state.positions[n:].copy(),
        label=label,
        description=description,
        du=du,
    )


def disk_sample(model, state) -> tuple[np.ndarray, np.ndarray]:
    """(|δu_i| over its largest [1], |v_i| [d_s/t0]) of the mobile disks, each (N,)
    float32; |δu_i| NaN without a tangent vector (the same measure as the shear cell's,
    :func:`granpipe.analysis.lyapunov.lyapunov_vector_magnitude`)."""
    n = model.n_mobile
    du = np.full(n, np.nan, np.float32)
    if state.has_tangent:
        dr, dv = state.tangent_stored
        du = lyapunov_vector_magnitude(dr[:n], dv[:n], relative=True).astype(np.float32)
    return du, np.hypot(*state.velocities[:n].T).astype(np.float32)


def run_protocol(
    model: DrumModel,
    st: Steps,
    protocol: Mapping,
    start: Start,
    tangent_rng: np.random.Generator,
    *,
    replica: int = 0,
    seed: int = 0,
    snapshots: bool = False,
    on_chunk: Callable[[int, float, str], None] | None = None,
    on_frame=None,
    frame_window: str = "onset",
) -> ReplicaRecord:
    """Steps 3-6 of the module docstring from a prepared start; one onset-decay pair.

    Returns a :class:`~granpipe.drum.measures.ReplicaRecord` (λ in 1/t0, V in d_s/t0,
    times in s); ``settled``/``settle_time`` are copied from ``start``.

    ``on_frame``: None in a run; a replay's :class:`granpipe.trajectory.FrameRecorder`,
    started at t = 0 of the window ``frame_window`` (``onset`` or ``decay``) and running
    that window's steps in its place (:func:`granpipe.drum.trajectory.trajectory`).
    """
    t_wall = time.perf_counter()
    om = model.omega
    sim = model.simulation(om)
    state = model.new_state(sim, start.positions, start.velocities, t=-st.alignment * st.dt,
                            wall_angle=start.wall_angle, spins=start.spins,
                            shear=start.shear)  # fmt: skip
    n_w = model.geom.n_wall
    fraction = float(protocol["tangent_fraction"])

    def new_tangent():
        dr, dv = initial_tangent(model.n_mobile, tangent_rng, fraction)
        sim.set_tangent(state, np.concatenate([dr, np.zeros((n_w, 2))]),
                        np.concatenate([dv, np.zeros((n_w, 2))]))  # fmt: skip

    total = 0
    frames = None  # the replay's recorder, once its window has started

    def watch(window):
        nonlocal frames
        if on_frame is not None and window == frame_window:
            on_frame.start(state)
            frames = on_frame

    def advance(sim_, n_steps, stride, phase, t_origin_s, tangent=True):
        nonlocal total
        rec = sim_.run(state, n_steps, stride=stride, tangent=tangent)
        total += n_steps
        if on_chunk is not None:
            on_chunk(total, t_origin_s, phase)
        return rec

    def recorded(sim_, n_steps, phase, t_origin_s, pile, seconds, disks=None):
        """``advance`` with the tangent vector, in engine calls of at most ``st.sample``
        steps, the pile sampled after each (the same bits as one call: the engine keeps
        nothing between calls that a split changes), and the disks too into ``disks``
        (a list) unless it is None."""
        nonlocal total
        lam, v = [], []
        done_ = 0
        while done_ < n_steps:
            m = min(st.sample, n_steps - done_)
            if frames is None:
                rec = sim_.run(state, m, stride=st.block, tangent=True)
            else:
                rec = frames.run(sim_, state, m, stride=st.block, tangent=True)
            lam.append(rec.local_lyapunov)
            v.append(rec.global_speed)
            done_ += m
            pile.append(pile_sample(model, state, om))
            if disks is not None:
                disks.append(disk_sample(model, state))
            seconds.append((seconds[-1] if seconds else 0.0) + m * st.dt_s)
        total += n_steps
        if on_chunk is not None:
            on_chunk(total, t_origin_s, phase)
        return np.concatenate(lam), np.concatenate(v)

    def align(n_steps, phase, t_end_s):
        done = 0
        while done < n_steps:
            n = min(st.chunk, n_steps - done)
            advance(sim, n, 0, phase, t_end_s - (n_steps - done - n) * st.dt_s)
            done += n

    # 3. the tangent vector aligns over the last stretch before t = 0
    new_tangent()
    align(st.alignment, "rotation before t = 0", 0.0)
    snaps = [_snapshot(model, state, "t=0", "before the onset (onset window, t = 0)")] \
        if snapshots else []  # fmt: skip

    # 4-5. onset window, watching for a continuous avalanche
    lam_on, v_on = [], []
    speeds: list[np.ndarray] = []  # V of every block since t = 0
    hold = st.continuous_hold
    excess = float(protocol["continuous_excess"])
    t_cont = None  # first chunk end at which the avalanche flowed (criterion met)

    def flowing() -> bool:
        v = np.concatenate(speeds)
        if len(v) < hold:
            return False
        return bool(np.mean(v[-hold:]) > (1.0 + excess) * model.rigid_speed(state, om))

    pile_on, sec_on = [pile_sample(model, state, om)], [0.0]
    disks_on = [disk_sample(model, state)] if protocol["disk_record"] else None
    watch("onset")
    done = 0
    while done < st.onset:
        n = min(st.chunk, st.onset - done)
        lam, v = recorded(sim, n, "onset window", (done + n) * st.dt_s, pile_on, sec_on,
                          disks_on)  # fmt: skip
        lam_on.append(lam)
        v_on.append(v)
        speeds.append(v)
        done += n
        if t_cont is None and flowing():
            t_cont = done * st.dt_s
    # 5. not flowing yet: keep turning without the tangent vector (V only, to watch the
    # criterion) until it flows, then align a fresh tangent vector before the decay window
    is_flowing = flowing()
    waited = False
    keep = bool(protocol["tangent_while_waiting"])
    while not is_flowing and done < st.max_rotation:
        rec = advance(sim, st.chunk, st.block, "waiting for a continuous avalanche",
                      (done + st.chunk) * st.dt_s, tangent=keep)  # fmt: skip
        speeds.append(rec.global_speed)
        done += st.chunk
        waited = True
        is_flowing = flowing()
        if t_cont is None and is_flowing:
            t_cont = done * st.dt_s
    if waited and not keep:
        new_tangent()
        align(st.realign, "aligning the tangent vector", (done + st.realign) * st.dt_s)
        done += st.realign
    continuous = bool(is_flowing)
    continuous_time = t_cont if t_cont is not None else math.nan
    decay_start = done * st.dt_s
    if snapshots:
        snaps.append(
            _snapshot(model, state, "avalanche",
                      f"continuous avalanche (t = {decay_start:.1f} s, start of the decay window)")
        )  # fmt: skip

    # 6. decay window: still turning for decay_rotating steps, then stopped abruptly.
    # The wall angle is part of the engine state, so switching to a still drum between
    # two chunks stops it exactly at that step, without a jump.
    sim_stopped = model.simulation(0.0)
    lam_de, v_de = [], []
    pile_de, sec_de = [pile_sample(model, state, om)], [0.0]
    frames = None
    watch("decay")
    done = 0
    while done < st.decay:
        turning = done < st.decay_rotating
        end = st.decay_rotating if turning else st.decay
        n = min(st.chunk, end - done)
        lam, v = recorded(sim if turning else sim_stopped, n, "decay window",
                          (done + n) * st.dt_s, pile_de, sec_de)  # fmt: skip
        lam_de.append(lam)
        v_de.append(v)
        done += n
    return ReplicaRecord(
        replica=int(replica),
        seed=int(seed),
        lambda_onset=np.concatenate(lam_on),
        speed_onset=np.concatenate(v_on),
        lambda_decay=np.concatenate(lam_de),
        speed_decay=np.concatenate(v_de),
        settled=bool(start.settled),
        settle_time=float(start.settle_time),
        continuous=continuous,
        continuous_time=continuous_time,
        decay_start=decay_start,
        wall_time=time.perf_counter() - t_wall,
        n_steps=int(total),
        snapshots=snaps,
        pile_onset=np.asarray(pile_on),
        pile_seconds_onset=np.asarray(sec_on),
        pile_decay=np.asarray(pile_de),
        pile_seconds_decay=np.asarray(sec_de),
        disk_du_onset=None if disks_on is None else np.stack([d for d, _ in disks_on]),
        disk_speed_onset=None if disks_on is None else np.stack([v for _, v in disks_on]),
    )


# --------------------------------------------------------------------------- batches
def _map(fn, items, threads: int):
    """``[fn(x) for x in items]``, in ``threads`` threads (order kept; first error raised)."""
    items = list(items)
    if threads <= 1 or len(items) <= 1:
        return [fn(x) for x in items]
    with ThreadPoolExecutor(max_workers=min(threads, len(items))) as pool:
        return list(pool.map(fn, items))


def _with_context(exc: SimulationError, section, replica, seed, stage):
    return exc.with_context(
        study="drum", stage=stage, point=point_name(section), replica=int(replica), seed=int(seed)
    )


def _shear_variables(starts: list[Start]) -> dict:
    """Static friction: spins and shear histories of every replica, the contacts padded
    to the longest list (pair ``(-1, -1)``, history 0)."""
    k = max(len(p.shear[1]) for p in starts)
    pairs = np.full((len(starts), k, 2), -1, np.int64)
    xi = np.zeros((len(starts), k))
    for r, p in enumerate(starts):
        pairs[r, : len(p.shear[1])] = p.shear[0]
        xi[r, : len(p.shear[1])] = p.shear[1]
    return {
        "spin": (
            ("replica", "particle"),
            np.stack([p.spins for p in starts]),
            {"units": "rad/t0", "long_name": "mobile-disk spin at the end of the start-up"},
        ),
        "shear_pair": (
            ("replica", "spring", "end"),
            pairs,
            {"units": "1", "long_name": "disks (i < j; wall disks after the mobile ones) of a "
             "stretched tangential spring; -1 pads"},
        ),
        "shear_history": (
            ("replica", "spring"),
            xi,
            {"units": "d_s", "long_name": "tangential spring's shear history (of i relative to j)"},
        ),
    }  # fmt: skip


def _init_dataset(model: DrumModel, replicas, seeds, starts: list[Start]) -> xr.Dataset:
    r = ("replica",)
    shear = _shear_variables(starts) if model.static else {}
    return xr.Dataset(
        {
            "position": (
                ("replica", "particle", "xy"),
                np.stack([p.positions for p in starts]),
                {"units": "d_s", "long_name": "mobile-disk centre at the end of the start-up"},
            ),
            "velocity": (
                ("replica", "particle", "xy"),
                np.stack([p.velocities for p in starts]),
                {"units": "d_s/t0", "long_name": "mobile-disk velocity at the end of the start-up"},
            ),
            "wall_angle": (
                r,
                np.array([p.wall_angle for p in starts]),
                {"units": "rad", "long_name": "clockwise angle the drum turned since placement"},
            ),
            "seed": (
                r,
                np.asarray(seeds, np.int64),
                {"units": "1", "long_name": "seed of the replica's random stream"},
            ),
            "settled": (
                r,
                np.array([p.settled for p in starts], np.int8),
                {"units": "1", "long_name": "1 if the settling criterion was met (paper: 1)"},
            ),
            "settle_time": (
                r,
                np.array([p.settle_time for p in starts]),
                {"units": "s", "long_name": "duration of the fall (and settling)"},
            ),
            "n_steps": (
                r,
                np.array([p.n_steps for p in starts], np.int64),
                {"units": "1", "long_name": "steps of the start-up"},
            ),
            "wall_time": (
                r,
                np.array([p.wall_time for p in starts]),
                {"units": "s", "long_name": "wall-clock cost of placement and start-up"},
            ),
            "diameter": (
                "particle",
                model.diameters,
                {"units": "d_s", "long_name": "mobile-disk diameter"},
            ),
            "wall_position": (
                ("wall", "xy"),
                model.walls0,
                {"units": "d_s", "long_name": "wall-disk centre at the placement"},
            ),
            **shear,
        },  # fmt: skip
        coords={
            "replica": (
                "replica",
                np.asarray(replicas, np.int64),
                {"units": "1", "long_name": "replica index"},
            ),
        },  # fmt: skip
        attrs={
            "n_mobile": model.n_mobile,
            "n_wall": model.geom.n_wall,
            "drum_radius": model.geom.radius,
            "friction": model.physics["friction"],
        },  # fmt: skip
    )


def init_batch(section: Mapping, batch: int, *, threads: int = 1, log: Log = _quiet):
    """Placement and start-up of every replica of ``batch`` (the init file's Dataset)."""
    sec = load(section)
    st = steps(sec)
    physics = seed_physics(sec)
    model = DrumModel.from_physics(sec["physics"])
    replicas = list(batch_replicas(int(batch), int(sec["ensemble"]["batch_size"])))
    startup = sec["protocol"]["startup"]
    expected = st.settle_max if startup == "settled" else st.pre_rotation - st.alignment
    progress = Progress(len(replicas), expected, log, what="start-up of replica")
    log(
        f"init batch {batch} ({point_name(sec)}): replicas {replicas[0]}..{replicas[-1]}, "
        f"N = {model.n_mobile}, drum radius {model.geom.radius:.3f} d_s, {startup} start-up, "
        f"{threads} thread(s)"
    )

    def one(item):
        k, replica = item
        place_rng, _, seed = replica_streams(sec, replica, physics)
        try:
            start = prepare(model, sec, st, place_rng,
                            on_chunk=lambda n, t: progress.update(k, n, t, startup))  # fmt: skip
        except SimulationError as exc:
            raise _with_context(exc, sec, replica, seed, "init") from exc
        ns = start.wall_time / max(1, start.n_steps * model.n_mobile) * 1e9
        what = "fell for" if startup == "paper" else (
            "settled after" if start.settled else "NOT settled after")  # fmt: skip
        progress.finish(
            k,
            f"{what} {start.settle_time:.2f} s ({start.wall_time:.1f} s wall, "
            f"{ns:.0f} ns per particle-step)",
        )
        return seed, start

    out = _map(one, list(enumerate(replicas)), threads)
    return _init_dataset(model, replicas, [s for s, _ in out], [p for _, p in out])


def _expected_steps(st: Steps) -> int:
    return st.alignment + st.onset + st.decay


def _start_of(init: xr.Dataset, k: int) -> Start:
    spins = shear = None
    if "spin" in init:
        spins = init["spin"].values[k]
        pairs = init["shear_pair"].values[k]
        keep = pairs[:, 0] >= 0
        shear = (pairs[keep], init["shear_history"].values[k][keep])
    return Start(
        spins=spins,
        shear=shear,
        positions=init["position"].values[k],
        velocities=init["velocity"].values[k],
        wall_angle=float(init["wall_angle"].values[k]),
        settled=bool(init["settled"].values[k]),
        settle_time=float(init["settle_time"].values[k]),
        n_steps=int(init["n_steps"].values[k]),
        wall_time=float(init["wall_time"].values[k]),
    )


def _cost_line(rec, model) -> str:
    ns = rec.wall_time / max(1, rec.n_steps * model.n_mobile) * 1e9
    return f"{rec.wall_time:.1f} s wall, {ns:.0f} ns per mobile particle-step"


def run_batch(section: Mapping, batch: int, init: xr.Dataset, *, threads: int = 1,
              log: Log = _quiet) -> xr.Dataset:  # fmt: skip
    """The protocol for every replica of ``batch`` from its start (the run file)."""
    sec = load(section)
    st = steps(sec)
    physics = seed_physics(sec)
    model = DrumModel.from_physics(sec["physics"])
    replicas = list(batch_replicas(int(batch), int(sec["ensemble"]["batch_size"])))
    if list(init["replica"].values) != replicas:
        raise ValueError(
            f"init file holds replicas {list(init['replica'].values)}, batch {batch} needs "
            f"{replicas}: was it made with another batch_size?"
        )
    made = init.attrs.get("friction", "viscous")
    if made != sec["physics"]["friction"] or (model.static and "spin" not in init):
        raise ValueError(
            f"init file was made under {made} friction, this point has "
            f"{sec['physics']['friction']} friction"
        )
    progress = Progress(len(replicas), _expected_steps(st), log)
    log(
        f"runs batch {batch} ({point_name(sec)}): replicas {replicas[0]}..{replicas[-1]}, "
        f"{_expected_steps(st)} steps each at least, {threads} thread(s)"
    )

    def one(item):
        k, replica = item
        _, tangent_rng, seed = replica_streams(sec, replica, physics)
        if int(init["seed"].values[k]) != seed:
            raise ValueError(f"replica {replica}: init file seed differs (other physics?)")
        start = _start_of(init, k)
        try:
            rec = run_protocol(
                model, st, sec["protocol"], start, tangent_rng, replica=replica, seed=seed,
                snapshots=(k == 0),
                on_chunk=lambda n, t, phase: progress.update(k, n, t, phase),
            )  # fmt: skip
        except SimulationError as exc:
            raise _with_context(exc, sec, replica, seed, "runs") from exc
        progress.finish(
            k,
            f"continuous avalanche at {rec.continuous_time:.2f} s, decay from "
            f"{rec.decay_start:.2f} s; {_cost_line(rec, model)}",
        )
        # the replica's total cost includes its start-up
        rec.wall_time += start.wall_time
        rec.n_steps += start.n_steps
        return rec

    records = _map(one, list(enumerate(replicas)), threads)
    return batch_dataset(records, st, model.diameters, model.geom.d_wall)


def run_replica(section: Mapping, replica: int, *, log: Log = _quiet,
                snapshots: bool = True) -> xr.Dataset:  # fmt: skip
    """One replica by hand: placement, start-up and protocol (a one-replica run file).

    The same numbers as replica ``replica`` of the workflow with this (point's) section.
    """
    sec = load(section)
    st = steps(sec)
    model = DrumModel.from_physics(sec["physics"])
    place_rng, tangent_rng, seed = replica_streams(sec, replica)
    progress = Progress(1, st.pre_rotation + _expected_steps(st), log)
    try:
        start = prepare(model, sec, st, place_rng,
                        on_chunk=lambda n, t: progress.update(0, n, t, "start-up"))  # fmt: skip
        # the stage runs starts from what the init file holds: the same arrays here
        rec = run_protocol(
            model, st, sec["protocol"], start, tangent_rng, replica=replica, seed=seed,
            snapshots=snapshots,
            on_chunk=lambda n, t, ph: progress.update(0, start.n_steps + n, t, ph),
        )  # fmt: skip
    except SimulationError as exc:
        raise _with_context(exc, sec, replica, seed, "replica") from exc
    rec.wall_time += start.wall_time
    rec.n_steps += start.n_steps
    log(
        f"replica {replica} (seed {seed}): start-up {start.settle_time:.2f} s "
        f"(settled={start.settled}), continuous at {rec.continuous_time:.2f} s; "
        f"{rec.n_steps} steps, {_cost_line(rec, model)}"
    )
    return batch_dataset([rec], st, model.diameters, model.geom.d_wall)


# --------------------------------------------------------------- the tiny drum's protocol
TINY_PROTOCOL = {
    "pre_rotation_deg": 0.2,
    "onset_window_s": 0.6,
    "decay_window_s": 0.6,
    "decay_rotating_s": 0.2,
    "continuous_hold_s": 0.2,
    "max_rotation_s": 1.0,
    "chunk_s": 0.2,
    "pile_sample_s": 0.1,
    "tangent_alignment_s": 0.1,
    "decay_alignment_s": 0.1,
}
"""Short windows for the tiny drum (tests, ``granpipe drum replica --tiny``)."""


TINY_SETTLE = {"min_time_s": 0.4, "max_time_s": 1.0}


def tiny_section(section: Mapping | None = None, n_wall: int = 40, **protocol) -> dict:
    """A section with a tiny drum (:func:`granpipe.drum.model.tiny_physics`).

    Same disks, contact law, Δt and Ω as the paper, 40 wall disks (radius 8.8 d_s) and
    23 + 23 mobile disks (the paper's filling fraction); settling and protocol
    shortened (:data:`TINY_PROTOCOL`, :data:`TINY_SETTLE`; ``protocol`` overrides
    keys) so that one replica takes about a second.
    """

    sec = filled(section)
    sec["physics"] = tiny_physics(n_wall, sec["physics"])
    sec["protocol"].update(TINY_PROTOCOL)
    sec["protocol"].update(protocol)
    sec["settle"].update(TINY_SETTLE)
    return filled(sec)
