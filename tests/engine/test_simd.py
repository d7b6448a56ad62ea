"""The four-lane pair pass (granpipe.engine.simd) against the scalar passes it replaces."""

import numpy as np
import pytest

from granpipe.engine import Simulation, WallDisks
from granpipe.engine import kernels as K
from granpipe.engine.laws import drum_force
from granpipe.engine.simd import lanes_of
from tests.engine.conftest import DRUM_LAW, DT_DRUM
from tests.engine.scalar_reference import gather_tangent, scatter_tangent
from tests.engine.test_neighbours import dense_state


def _replica(state):
    s = {k: (v[0] if isinstance(v, np.ndarray) and v.ndim > 0 else v) for k, v in state._s.items()}
    s["pc"] = s["ivec"][K.PAIR_CONTACTS]
    return s


def _scalar_passes(s, law, npairs, tangent):
    """Gather, law and scatter as separate scalar/auto-vectorised passes (with the tangent
    vector: the test's own gather and scatter, :mod:`tests.engine.scalar_reference`)."""
    pc = s["pair_c"]
    start = s["pair_start"].copy()
    # the scatter reads its length from the CSR rows: cut them at npairs
    start[start > npairs] = npairs
    if tangent:
        gather_tangent(s["vec"], s["sca"], s["pair_ij"], s["buf"], npairs)
        out = K._drum_pairs_tangent(s["buf"], pc[K.P_SUM], pc[K.P_LIM], s["touch"], law, npairs)
        scatter_tangent(s["vec"], start, s["pair_ij"], s["buf"])
        return out
    K._gather(s["vec"], s["sca"], s["pair_ij"], s["buf"], npairs, 0)
    out = K._drum_pairs(s["buf"], pc[K.P_SUM], pc[K.P_LIM], s["touch"], law, npairs)
    K._scatter(s["vec"], s["sca"], s["ivec"], start, s["pair_ij"], s["buf"], s["touch"],
               False, False)  # fmt: skip
    return out


@pytest.mark.parametrize("tangent", [False, True])
def test_four_lane_pass_equals_scalar_passes_bit_for_bit(tangent):
    """Forces, perturbations, touch flags and counts of the fused four-lane pass are the
    scalar passes' to the last bit, for list lengths with every remainder modulo 4 (the
    last, partial group), on a dense state where some listed pairs are apart."""
    pos, radii, masses, is_wall, vel, _ = dense_state(3, shrink=0.99)
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=0.3), skin=0.2)
    state = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall)
    sim.random_tangent(state, np.random.default_rng(0))
    law = sim._params()[1]
    npairs = int(state._s["counters"][0, K.N_PAIRS])
    assert npairs > 50
    for cut in range(4):
        m = npairs - cut
        ref = state.copy()
        new = state.copy()
        a = _replica(ref)
        b = _replica(new)
        b["touch"][:] = a["touch"]
        out_ref = _scalar_passes(a, law, m, tangent)
        ncon, bad, changed = K._drum_pair_pass(
            b["vec"], b["pair_ij"], b["pair_c"], b["buf"], b["touch"], law, m, tangent, b["pc"]
        )
        assert ncon == out_ref[0]
        assert not bad and not out_ref[1]
        if tangent:
            assert changed == out_ref[2]
        np.testing.assert_array_equal(b["touch"][:m], a["touch"][:m])
        for row in (K.FRC, K.T_FRC) if tangent else (K.FRC,):
            np.testing.assert_array_equal(b["vec"][row], a["vec"][row])
        touching = a["touch"][:m].sum()
        assert 0 < touching < m  # both kinds of listed pairs


def test_four_lane_pass_flags_a_deep_pair():
    """A pair pushed deeper than its bound is flagged by the four-lane pass."""
    pos, radii, masses, is_wall, vel, _ = dense_state(4, shrink=0.99)
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=0.3), skin=0.2)
    state = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall)
    s = _replica(state)
    law = sim._params()[1]
    npairs = int(s["counters"][K.N_PAIRS])
    _, bad, _ = K._drum_pair_pass(
        s["vec"], s["pair_ij"], s["pair_c"], s["buf"], s["touch"], law, npairs, False, s["pc"]
    )
    assert not bad
    k = npairs - 2  # in the last (partial or full) group
    i, j = s["pair_ij"][K.PI, k], s["pair_ij"][K.PJ, k]
    s["vec"][K.POS, i] = s["vec"][K.POS, j] + [0.01, 0.0]
    _, bad, _ = K._drum_pair_pass(
        s["vec"], s["pair_ij"], s["pair_c"], s["buf"], s["touch"], law, npairs, False, s["pc"]
    )
    assert bad


def test_lane_law_refuses_to_branch_on_a_lane():
    """A law that branches (``if``) on a lane value cannot run on four lanes: clear error."""

    def branching(x):
        if x > 0.0:
            return x
        return -x

    law4 = lanes_of(branching)
    from granpipe.engine import simd

    class _FakeBuilder:
        def fcmp_ordered(self, op, a, b):
            return "mask"

    with pytest.raises(TypeError, match="may not branch"):
        law4(simd._Lanes(_FakeBuilder(), None))
    assert lanes_of(drum_force).__name__ == "drum_force"


def test_touch_bits_match_the_scalar_compaction_test():
    """The four-lane test of the compacted gather flags exactly the pairs the scalar test
    keeps, ``not (dx² + dy² > s²)``: random pairs on both sides of contact, pairs at
    exactly ``r = s``, and a NaN position (kept, so that the pass reports it)."""
    from numba import njit

    from granpipe.engine.simd import touch_bits4

    @njit
    def bits(pos, pi, pj, ssum):
        out = np.empty(pi.shape[0] // 4, np.int64)
        for g in range(out.shape[0]):
            out[g] = touch_bits4(pos, pi, pj, 4 * g, ssum)
        return out

    rng = np.random.default_rng(5)
    n, p = 300, 4000
    pos = rng.uniform(0.0, 6.0, (n, 2))
    pi = rng.integers(0, n, p).astype(np.uint32)
    pj = rng.integers(0, n, p).astype(np.uint32)
    d = pos[pi] - pos[pj]
    r2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    ssum = np.sqrt(r2) * rng.choice([0.9, 1.1], p)
    exact = rng.random(p) < 0.05  # the contact test's boundary: r² == s² exactly
    pos[pi[exact]] = [1.0, 1.0]
    pos[pj[exact]] = [4.0, 5.0]
    ssum[exact] = 5.0
    pos[7] = np.nan
    d = pos[pi] - pos[pj]
    r2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
    keep = ~(r2 > ssum * ssum)
    assert 0.3 < keep.mean() < 0.7 and (np.isnan(r2) & keep).any() and (r2 == 25.0).sum() > 50
    expect = (keep.reshape(-1, 4) * [1, 2, 4, 8]).sum(axis=1)
    np.testing.assert_array_equal(bits(pos.ravel(), pi, pj, ssum), expect)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 8])
def test_speed_sum_has_the_four_running_sums_of_the_scalar_loop(n):
    """``kernels._v2`` (four lanes) equals, bit for bit, four scalar running sums over
    the components ``k = c mod 4`` in increasing ``k`` with the tail on the first, added
    as ``(s0 + s1) + (s2 + s3)``; the half kick ``u = v + h (F/m)`` is the one it sums."""
    rng = np.random.default_rng(10 + n)
    vec = np.zeros((K.NV, n, 2))
    vec[K.VEL] = rng.normal(size=(n, 2))
    vec[K.FRC] = rng.normal(size=(n, 2)) * 1e3
    vec[K.IM2] = rng.uniform(0.5, 2.0, size=(n, 1))
    vec[K.MOB2] = (rng.uniform(size=(n, 1)) < 0.8).astype(float)
    h = 0.37e-3
    v, f, im, mob = (vec[r].ravel().tolist() for r in (K.VEL, K.FRC, K.IM2, K.MOB2))
    s = [0.0, 0.0, 0.0, 0.0]
    m = len(v) - len(v) % 4
    for k in range(len(v)):
        u = v[k] + h * (f[k] * im[k])
        s[k % 4 if k < m else 0] += u * u * mob[k]
    want = (s[0] + s[1]) + (s[2] + s[3])
    got = K._v2(vec, h)
    assert got == want
    # and it is the kinetic sum it claims to be (to round-off)
    u = vec[K.VEL] + h * vec[K.FRC] * vec[K.IM2]
    assert got == pytest.approx(float((u**2 * vec[K.MOB2]).sum()), rel=1e-14)


@pytest.mark.parametrize("mode", [0, 2])
def test_gather_rows_are_the_relative_coordinates_of_every_listed_pair(mode):
    """The four-pair gather writes ``r_i - r_j``, ``v_i - v_j`` (with ``mode`` 2 also the
    spins ``w_i``, ``w_j``) of listed pair k
    into column k of its rows, exactly, for list lengths with every remainder modulo 4,
    and nothing past the last pair."""
    pos, radii, masses, is_wall, vel, _ = dense_state(5, shrink=0.99)
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=0.3), skin=0.2)
    state = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall)
    sim.random_tangent(state, np.random.default_rng(2))
    s = _replica(state)
    npairs = int(s["counters"][K.N_PAIRS])
    i = s["pair_ij"][K.PI, :npairs].astype(np.intp)
    j = s["pair_ij"][K.PJ, :npairs].astype(np.intp)
    vec = s["vec"]
    fields = [vec[K.POS], vec[K.VEL]]
    want = np.concatenate([(f[i] - f[j]).T for f in fields])  # rows dx, dy, dvx, dvy, ...
    if mode == 2:
        w = s["sca"][K.SPIN]
        w[:] = np.random.default_rng(3).normal(size=w.shape)
        want = np.concatenate([want, [w[i], w[j]]])
    for cut in range(4):
        m = npairs - cut
        buf = s["buf"]
        buf[:] = np.nan
        K._gather(vec, s["sca"], s["pair_ij"], buf, m, mode)
        np.testing.assert_array_equal(buf[: len(want), :m], want[:, :m])
        assert np.isnan(buf[: len(want), m:]).all()


@pytest.mark.parametrize("tangent", [False, True])
def test_four_lane_pass_keeps_the_per_disk_contact_counts(tangent):
    """The counts of touching pairs per disk, moved by the pass for each touch flag that
    changes, equal a recount of the new flags (30 % of the flags stale before the pass,
    as after many steps, and a list length that leaves a partial last group)."""
    pos, radii, masses, is_wall, vel, _ = dense_state(3, shrink=0.99)
    sim = Simulation(DRUM_LAW, dt=DT_DRUM, wall_disks=WallDisks(omega=0.3), skin=0.2)
    state = sim.new_state(pos, radii, masses, velocities=vel, is_wall=is_wall)
    sim.random_tangent(state, np.random.default_rng(0))
    s = _replica(state)
    law = sim._params()[1]
    m = int(s["counters"][K.N_PAIRS]) - 1
    assert m % 4 != 0
    args = (s["vec"], s["pair_ij"], s["pair_c"], s["buf"], s["touch"], law, m, tangent, s["pc"])
    K._drum_pair_pass(*args)
    right = s["touch"][:m].copy()
    flip = np.random.default_rng(1).random(m) < 0.3
    s["touch"][:m] = np.where(flip, 1 - right, right)
    K._recount(s["ivec"], s["pair_ij"], s["touch"], m)  # right counts for the stale flags
    before = s["pc"].copy()
    _, _, changed = K._drum_pair_pass(*args)
    assert changed
    np.testing.assert_array_equal(s["touch"][:m], right)
    kept = s["pc"].copy()
    assert not np.array_equal(kept, before)
    K._recount(s["ivec"], s["pair_ij"], s["touch"], m)
    np.testing.assert_array_equal(kept, s["pc"])
