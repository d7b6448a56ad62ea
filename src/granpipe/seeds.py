"""Random streams per replica (docs/architecture.md, "Seeds, batches, growing ensembles").

A replica's stream depends only on (study, physics-parameter hash, replica index),
through :class:`numpy.random.SeedSequence`. Batches are fixed ranges of replica
indices, so the same replica gets the same stream whatever batch, batch size,
process or machine runs it, and a larger ensemble reuses every batch of a smaller
one.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping

import numpy as np

__all__ = [
    "canonical_json",
    "physics_hash",
    "replica_seed_sequence",
    "replica_rng",
    "replica_seed",
    "batch_replicas",
]


def canonical_json(obj) -> str:
    """JSON text of ``obj`` with sorted keys and no whitespace (stable across runs)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), default=_to_builtin)


def _to_builtin(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(f"cannot hash object of type {type(x).__name__}")


def physics_hash(physics: Mapping) -> str:
    """Hex SHA-256 of the canonical JSON of a physics-parameter mapping."""
    return hashlib.sha256(canonical_json(physics).encode()).hexdigest()


def _entropy(study: str, physics: Mapping) -> list[int]:
    digest = hashlib.sha256(f"{study}\0{canonical_json(physics)}".encode()).digest()
    # SeedSequence takes a list of 32-bit words as entropy.
    return [int.from_bytes(digest[i : i + 4], "little") for i in range(0, 32, 4)]


def replica_seed_sequence(study: str, physics: Mapping, replica: int) -> np.random.SeedSequence:
    """SeedSequence of replica ``replica`` of ``study`` at the given physics parameters.

    Parameters
    ----------
    study : str
        ``"drum"``, ``"column"`` or ``"box"``.
    physics : mapping
        The physics parameters that define the ensemble (not the sample sizes, not the
        analysis settings): changing them changes every stream, adding replicas does not.
    replica : int
        Replica index, ``>= 0``.
    """
    if int(replica) < 0:
        raise ValueError(f"replica index must be >= 0, got {replica}")
    return np.random.SeedSequence(entropy=_entropy(study, physics), spawn_key=(int(replica),))


def replica_rng(study: str, physics: Mapping, replica: int) -> np.random.Generator:
    """A PCG64 generator seeded by :func:`replica_seed_sequence`."""
    return np.random.Generator(np.random.PCG64(replica_seed_sequence(study, physics, replica)))


def replica_seed(study: str, physics: Mapping, replica: int) -> int:
    """A 63-bit integer seed for the replica (for kernels and for reporting in errors)."""
    state = replica_seed_sequence(study, physics, replica).generate_state(2, np.uint32)
    return int((int(state[0]) << 31) ^ int(state[1])) & ((1 << 63) - 1)


def batch_replicas(batch: int, batch_size: int) -> range:
    """Replica indices of batch ``batch``: ``range(batch*batch_size, (batch+1)*batch_size)``."""
    if batch < 0 or batch_size <= 0:
        raise ValueError(f"need batch >= 0 and batch_size > 0, got {batch}, {batch_size}")
    return range(batch * batch_size, (batch + 1) * batch_size)
