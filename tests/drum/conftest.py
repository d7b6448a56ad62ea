"""Shared fixtures of the drum tests: a tiny drum, synthetic run files."""

import numpy as np
import pytest

from granpipe.drum.layout import filled
from granpipe.drum.measures import ReplicaRecord, batch_dataset
from granpipe.drum.protocol import steps, tiny_section
from granpipe.io import write_dataset


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
        ds = batch_dataset(recs, st, d, 1.3846)
        path = tmp_path / f"batch_{b:04d}.nc"
        write_dataset(ds, path, config_subset={"synthetic": True}, study="drum", stage="runs",
                      batch=b)  # fmt: skip
        paths.append(path)
    return paths
