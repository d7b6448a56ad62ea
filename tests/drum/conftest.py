"""Shared fixtures of the drum tests: a tiny drum, synthetic run files."""

import numpy as np
import pytest

from granpipe.drum.layout import filled, steps
from granpipe.drum.measures import ReplicaRecord, batch_dataset
from granpipe.drum.protocol import tiny_section
from granpipe.io import write_dataset


def _write_batch(recs, st, d, folder, b):
    """A synthetic run file of batch ``b`` from replica records."""
    path = folder / f"batch_{b:04d}.nc"
    write_dataset(batch_dataset(recs, st, d, 1.3846), path, config_subset={"synthetic": True},
                  study="drum", stage="runs", batch=b)  # fmt: skip
    return path


@pytest.fixture(scope="session")
def tiny():
    """A tiny drum (40 wall disks, 23 + 23 mobile disks) with short windows, batches of 2."""
    sec = tiny_section({})
    sec["ensemble"].update(batch_size=2, n_replicas=2)
    return filled(sec)


def synthetic_runs(tmp_path, *, n_batches=3, batch_size=4, vertex=3.0, zero_on=12.0,
                   zero_de=8.0, noise=0.3, seed=1):  # fmt: skip
    """Run files with V(t) = 0.2 + 0.01 (t - vertex)² and linear λ with known zeros.

    Onset window 25 s, decay window 12 s at the default 4 ms blocks.
    """
    sec = filled({"protocol": {"onset_window_s": 25.0, "decay_window_s": 12.0}})
    st = steps(sec)
    rng = np.random.default_rng(seed)
    n_on, n_de = st.onset // st.block, st.decay // st.block
    t_on = (np.arange(n_on) + 0.5) * st.block_s
    t_de = (np.arange(n_de) + 0.5) * st.block_s
    d = np.ones(3)
    paths = []
    for b in range(n_batches):
        recs = []
        for k in range(batch_size):
            r = b * batch_size + k
            recs.append(
                ReplicaRecord(
                    replica=r,
                    seed=r,
                    lambda_onset=0.02 * (t_on - zero_on) + noise * rng.standard_normal(n_on),
                    speed_onset=0.2
                    + 0.01 * (t_on - vertex) ** 2
                    + 0.02 * rng.standard_normal(n_on),
                    lambda_decay=-0.1 * (t_de - zero_de) + noise * rng.standard_normal(n_de),
                    speed_decay=np.where(t_de < 5, 0.4, 0.1) + 0.01 * rng.standard_normal(n_de),
                    settle_time=3.0,
                    continuous_time=26.0,
                    decay_start=26.0,
                    wall_time=1.0,
                    n_steps=10,
                )
            )
        paths.append(_write_batch(recs, st, d, tmp_path, b))
    return paths


RIGID = 0.17  # d_s/t0, V of rigid rotation (constant here)


def _disk_fields(disks, r, p_on, flow):
    if disks is None:
        return {}
    du, v = disks(r, p_on, flow)
    return {"disk_du_onset": np.asarray(du, np.float32),
            "disk_speed_onset": np.asarray(v, np.float32)}  # fmt: skip


def synthetic_pile_runs(tmp_path, flows, *, stops=None, lag_on=3.0, lag_de=1.5, noise=0.3,
                        batch_size=4, onset_s=40.0, seed=2, disks=None):  # fmt: skip
    """Run files with the pile's samples, each replica flowing from its own ``flows[r]``
    [s] (NaN: never in the window) and, in the decay window, stopping its flow
    ``stops[r]`` s after the drum's stop (default 1.0 s).

    Onset: V = rigid speed × (0.9 + 2 e^{-t/0.4}), ×1.4 from the flow onset on; λ a line
    through zero ``lag_on`` s after the flow onset; tilt 1° + 0.35°/s. Decay: V = 1.4 ×
    rigid until the flow stops, then 0.5 ×; λ a falling line through zero ``lag_de`` s
    after the flow stop. So the aligned λ̄ crosses zero at ``lag_on`` (``lag_de``) in
    every replica, and the flow tilt is 1 + 0.35 t_flow.

    ``disks(r, p_on, flow)`` -> (|δu_i|, |v_i|), each (S, N), gives a replica's per-disk
    record at the onset window's pile samples ``p_on`` (S,) [s] (none without).
    """
    flows = np.asarray(flows, dtype=np.float64)
    stops = np.full(len(flows), 1.0) if stops is None else np.asarray(stops, dtype=np.float64)
    sec = filled({"protocol": {"onset_window_s": onset_s, "decay_window_s": 12.0}})
    st = steps(sec)
    rng = np.random.default_rng(seed)
    n_on, n_de = st.onset // st.block, st.decay // st.block
    t_on = (np.arange(n_on) + 0.5) * st.block_s
    t_de = (np.arange(n_de) + 0.5) * st.block_s
    p_on = np.arange(round(onset_s / 0.1) + 1) * 0.1
    p_de = np.arange(121) * 0.1
    d = np.ones(3)
    paths = []
    for b in range(-(-len(flows) // batch_size)):
        recs = []
        for r in range(b * batch_size, min(len(flows), (b + 1) * batch_size)):
            f = flows[r] if np.isfinite(flows[r]) else 1e9
            v_on = RIGID * (0.9 + 2.0 * np.exp(-t_on / 0.4)) * np.where(t_on >= f, 1.4 / 0.9, 1)
            lam_on = 0.02 * (t_on - f - lag_on) + noise * rng.standard_normal(n_on)
            s_flow = 5.0 + stops[r]
            v_de = RIGID * np.where(t_de < s_flow, 1.4, 0.5)
            lam_de = -0.1 * (t_de - s_flow - lag_de) + noise * rng.standard_normal(n_de)
            # tilt, centroid angle, rigid speed and C(|du|, |v|) (0.2 + 0.01 r, 0.4)
            pile_on = np.stack([1.0 + 0.35 * p_on, 0.9 + 0.35 * p_on,
                                np.full(p_on.size, RIGID), np.full(p_on.size, 0.2 + 0.01 * r)],
                               -1)  # fmt: skip
            pile_de = np.stack([np.full(p_de.size, 8.0), np.full(p_de.size, 8.0),
                                np.full(p_de.size, RIGID), np.full(p_de.size, 0.4)],
                               -1)  # fmt: skip
            recs.append(
                ReplicaRecord(
                    replica=r, seed=r, lambda_onset=lam_on, speed_onset=v_on,
                    lambda_decay=lam_de, speed_decay=v_de, settle_time=3.0,
                    continuous_time=min(f, onset_s), decay_start=onset_s, wall_time=1.0,
                    n_steps=10, pile_onset=pile_on, pile_seconds_onset=p_on,
                    pile_decay=pile_de, pile_seconds_decay=p_de,
                    **_disk_fields(disks, r, p_on, flows[r]),
                )
            )  # fmt: skip
        paths.append(_write_batch(recs, st, d, tmp_path, b))
    return paths
